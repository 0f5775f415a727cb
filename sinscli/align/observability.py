"""Is the heading observable?  Error budgets of the alignment and the GNSS-course heading.

On a base at rest the heading comes from the horizontal earth rate
``W_ie cos L`` (15.04 deg/h x cos L).  Its error is (static analytic
alignment; the inertial-frame method has the same limits)

    sigma_heading^2 = (eps_E / (W_ie cos L))^2 + (ARW / sqrt(T) / (W_ie cos L))^2 + (nabla_E tan L / g)^2
    sigma_tilt^2    = (nabla_h / g)^2 + (VRW / (g sqrt(T)))^2

with ``eps_E`` the east gyro bias, ``nabla`` the accelerometer bias.  A
gyro whose bias is a sizeable fraction of the earth rate (any MEMS, tens to
thousands of deg/h) cannot see it: the heading would be noise.  Such a heading
is never written: it is taken from the user, from the GNSS course when the
vehicle moves, or the alignment fails with the reason.

Where the sensor errors are not given, the data bound them from below: at
rest the measured angular rate must have the earth rate's magnitude
(``| |w| - W_ie |`` is at most the bias), and the scatter of 1 s block means
gives the random walk.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..nav.earth import OMEGA_IE


def earth_rate_heading_sigma(lat, T, gyro_bias, gyro_arw, accel_bias, g, accel_vrw=0.0):
    """1-sigma heading error (rad) of an earth-rate heading over ``T`` s (see the module docstring).

    ``accel_vrw`` adds the term of the inertial-frame method, whose heading is the turn of the
    gravity vector that the accelerometers see: ``2 sqrt(3) VRW / (g W_ie cos L T^1.5)`` (least
    squares of the east-north drift of the integrated specific force, with the tilt about east
    estimated at the same time).
    """
    wh = OMEGA_IE * math.cos(lat)
    return math.sqrt((gyro_bias / wh) ** 2 + (gyro_arw / math.sqrt(T) / wh) ** 2
                     + (accel_bias * math.tan(lat) / g) ** 2
                     + (2.0 * math.sqrt(3.0) * accel_vrw / (g * wh * T ** 1.5)) ** 2)


def tilt_sigma(T, accel_bias, accel_vrw, g):
    """1-sigma roll/pitch error (rad) from the accelerometers over ``T`` s."""
    return math.sqrt((accel_bias / g) ** 2 + (accel_vrw / (g * math.sqrt(T))) ** 2)


def gyro_bias_floor(w_mean_b):
    """Lower bound of the gyro bias at rest: ``| |w| - W_ie |`` (rad/s)."""
    return abs(float(np.linalg.norm(w_mean_b)) - OMEGA_IE)


def accel_bias_floor(f_mean_b, g):
    """Lower bound of the accelerometer bias at rest: ``| |f| - g |`` (m/s^2)."""
    return abs(float(np.linalg.norm(f_mean_b)) - g)


def random_walk_from_blocks(block_means, block):
    """Random-walk coefficient (unit/sqrt(s)) from the scatter of block means over ``block`` s."""
    if block_means.shape[0] < 3:
        return 0.0
    d = block_means - block_means.mean(axis=0)
    return float(np.sqrt((d ** 2).mean())) * math.sqrt(block)


@dataclass
class Budget:
    """The sensor errors used for the error budget (SI) and where each came from."""
    gyro_bias: float
    gyro_arw: float
    accel_bias: float
    accel_vrw: float
    source: str          # "config", "data" or "config+data"


def budget(spec, w_mean_b=None, f_mean_b=None, w_blocks=None, f_blocks=None, block=1.0, g=9.8) -> Budget:
    """Sensor errors for the budget: the configured ones, raised to what the data show at rest."""
    data = {"gyro_bias": 0.0, "gyro_arw": 0.0, "accel_bias": 0.0, "accel_vrw": 0.0}
    if w_mean_b is not None:
        data["gyro_bias"] = gyro_bias_floor(w_mean_b)
    if f_mean_b is not None:
        data["accel_bias"] = accel_bias_floor(f_mean_b, g)
    if w_blocks is not None:
        data["gyro_arw"] = random_walk_from_blocks(w_blocks, block)
    if f_blocks is not None:
        data["accel_vrw"] = random_walk_from_blocks(f_blocks, block)
    out, used = {}, set()
    for k, v in data.items():
        c = getattr(spec, k)
        if c is None:
            out[k] = v
            used.add("data")
        else:
            out[k] = max(c, v)
            used.add("config" if c >= v else "data")
    src = "+".join(sorted(used, key=lambda s: s != "config"))
    return Budget(source=src, **out)


@dataclass
class HeadingCheck:
    observable: bool
    sigma: float            # rad
    reason: str             # one line for the user


def check_earth_rate(lat, T, b: Budget, g, max_sigma, accel_noise: bool = False) -> HeadingCheck:
    """Earth-rate heading observability at rest for a budget ``b`` (``accel_noise``: inertial-frame method)."""
    s = earth_rate_heading_sigma(lat, T, b.gyro_bias, b.gyro_arw, b.accel_bias, g,
                                 b.accel_vrw if accel_noise else 0.0)
    wh_dph = math.degrees(OMEGA_IE * math.cos(lat)) * 3600.0
    bias_dph = math.degrees(b.gyro_bias) * 3600.0
    arw = math.degrees(b.gyro_arw) * 60.0
    sd = math.degrees(s)
    sig = f"{sd:.3g} deg" if sd <= 180.0 else "over 180 deg (no heading information)"
    what = (f"gyro bias {bias_dph:.3g} deg/h and random walk {arw:.3g} deg/sqrt(h) ({b.source}) against "
            f"the horizontal earth rate {wh_dph:.3g} deg/h give a heading 1-sigma of {sig} in {T:.4g} s")
    if s > max_sigma:
        return HeadingCheck(False, s, f"heading is not observable from earth rate: {what} "
                                      f"(> {math.degrees(max_sigma):.3g} deg, align.max_heading_sigma)")
    return HeadingCheck(True, s, f"heading from earth rate: {what}")


def motion_heading_sigma(cov):
    """Heading (rotation about up) 1-sigma (rad) from a navigation-axes attitude covariance."""
    return math.sqrt(max(float(cov[2, 2]), 0.0))


def course_offset(vel_n, heading_est, min_speed, sigma_v, floor):
    """Heading correction from the GNSS course: ``(delta rad, sigma rad, n epochs)`` or None.

    ``vel_n`` (n, 3) ENU velocities at epochs where ``heading_est`` (n,) rad is
    the heading of the current estimate.  A land vehicle drives along its
    forward axis, so course = heading; ``delta`` is the speed-weighted circular
    mean of ``course - heading_est`` over epochs faster than ``min_speed``
    (epochs more than 30 deg from a first estimate, e.g. reversing, are
    dropped), with 1-sigma ``sqrt(1/sum (speed/sigma_v)^2 + floor^2)``.
    """
    speed = np.hypot(vel_n[:, 0], vel_n[:, 1])
    ok = speed >= min_speed
    if ok.sum() < 2:
        return None
    course = np.arctan2(vel_n[ok, 0], vel_n[ok, 1])
    d = course - heading_est[ok]
    w = (speed[ok] / sigma_v) ** 2
    mean = math.atan2(float((w * np.sin(d)).sum()), float((w * np.cos(d)).sum()))
    resid = np.angle(np.exp(1j * (d - mean)))
    keep = np.abs(resid) < math.radians(30.0)
    if keep.sum() < 2:
        return None
    mean = math.atan2(float((w[keep] * np.sin(d[keep])).sum()), float((w[keep] * np.cos(d[keep])).sum()))
    sigma = math.sqrt(1.0 / float(w[keep].sum()) + floor ** 2)
    return mean, sigma, int(keep.sum())
