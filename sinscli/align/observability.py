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

The sensor errors come from :mod:`.budget` (the description checked against
the log, or the log alone).  On a moving base the heading comes from the fit
(:mod:`.fit`) or from the GNSS course (:func:`course_heading`).
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


@dataclass
class HeadingCheck:
    observable: bool
    sigma: float            # rad
    reason: str             # one line for the user


def check_earth_rate(lat, T, sigma, gyro_bias, gyro_arw, source, max_sigma) -> HeadingCheck:
    """Earth-rate heading observability: ``sigma`` (rad) the heading 1-sigma the method computed with
    a gyro bias ``gyro_bias`` (rad/s) and random walk ``gyro_arw`` (rad/sqrt(s)) from ``source``."""
    wh_dph = math.degrees(OMEGA_IE * math.cos(lat)) * 3600.0
    bias_dph = math.degrees(gyro_bias) * 3600.0
    arw = math.degrees(gyro_arw) * 60.0
    sd = math.degrees(sigma)
    sig = f"{sd:.3g} deg" if sd <= 180.0 else "over 180 deg (no heading information)"
    what = (f"gyro bias {bias_dph:.3g} deg/h and random walk {arw:.3g} deg/sqrt(h) ({source}) against "
            f"the horizontal earth rate {wh_dph:.3g} deg/h give a heading 1-sigma of {sig} in {T:.4g} s")
    if not sigma <= max_sigma:
        return HeadingCheck(False, sigma, f"heading is not observable from earth rate: {what} "
                                          f"(> {math.degrees(max_sigma):.3g} deg, align.max_heading_sigma)")
    return HeadingCheck(True, sigma, f"heading from earth rate: {what}")


@dataclass
class CourseFit:
    """The heading from the GNSS course: ``delta(t) = delta_end + drift (t - t_last)`` is the correction
    to add to the estimate's heading at time t (see :func:`course_heading`)."""
    delta_end: float        # rad: at the last epoch
    drift: float            # rad/s: the estimate's heading drift against the course (gyro bias)
    cov: np.ndarray         # (2, 2) of (delta_end, drift), scaled by ``factor``
    floor: float            # rad: sideslip and mounting, added to every sigma
    used: int               # epochs used
    dropped: int            # epochs rejected as glitches (or reversing)
    factor: float           # residual chi-square / dof (>= 1), times the correlation's inflation: applied to the cov
    glitches: int = 0       # of ``dropped``: neither along the estimate's heading nor reversing
    considered: int = 0     # epochs faster than the minimum speed
    correlation: float = 0.0    # lag-one correlation of the whitened residuals (time order)

    @property
    def broken(self) -> bool:
        """Glitches in half the epochs or more: past the breakdown point of any robust fit (50 %), the epochs
        kept are a chosen minority, not a sample: the estimate's heading does not follow the course as
        ``a + b t`` (its drift is not a constant gyro bias, or the estimate is wrong)."""
        return 2 * self.glitches >= max(self.considered, 2)

    def delta(self, dt):
        """The correction at ``dt`` s after the last epoch."""
        return self.delta_end + self.drift * np.asarray(dt, dtype=float)

    def sigma(self, dt=0.0) -> float:
        """1-sigma (rad) of the corrected heading ``dt`` s after the last epoch."""
        a = np.array([1.0, float(dt)])
        return math.sqrt(float(a @ self.cov @ a) + self.floor ** 2)


def course_heading(t, vel_n, heading_est, min_speed, sigma_v, floor, drift_sigma):
    """Robust fit of the GNSS course against the estimate's heading: ``CourseFit`` or None.

    A land vehicle drives along its forward axis, so at each epoch faster than ``min_speed``
    ``course - heading_est = a + b (t - t_end) + noise``, with the course noise ``sigma_v / speed``
    (rad).  ``b`` is the drift of the estimate's heading (its gyro bias about up) with the prior
    ``N(0, drift_sigma^2)``; ``a`` is the correction at the last epoch.  The fit is Huber-weighted
    (iteratively reweighted least squares, k = 1.345 on the residuals over their robust scale); epochs
    more than 30 deg off (reversing, a glitch) and then more than 5 robust sigma off are dropped.  The
    variance of ``a`` is scaled by the residual chi-square per degree of freedom when that exceeds 1 and by
    ``(1 + rho) / (1 - rho)`` (at most n) when the residuals' lag-one correlation ``rho`` is significant
    (systematic, not noise), and the sideslip/mounting ``floor`` is added in quadrature (it does not average out).  A fit that
    drops half its epochs or more as glitches is :attr:`CourseFit.broken`: the caller does not use it.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(vel_n, dtype=float)
    speed = np.hypot(v[:, 0], v[:, 1])
    ok = speed >= min_speed
    if ok.sum() < 2:
        return None
    tt = t[ok] - t[-1]
    course = np.arctan2(v[ok, 0], v[ok, 1])
    d = np.angle(np.exp(1j * (course - np.asarray(heading_est, dtype=float)[ok])))
    s = np.broadcast_to(np.asarray(sigma_v, dtype=float), t.shape)[ok] / speed[ok]
    w0 = 1.0 / s ** 2
    mean = math.atan2(float((w0 * np.sin(d)).sum()), float((w0 * np.cos(d)).sum()))
    d = mean + np.angle(np.exp(1j * (d - mean)))            # unwrapped about the mean
    keep = np.abs(d - mean) < math.radians(30.0)
    reversing = int((np.abs(np.angle(np.exp(1j * (d - mean - math.pi)))) < math.radians(30.0)).sum())
    dropped = int((~keep).sum())
    prior = 0.0 if not drift_sigma or not np.isfinite(drift_sigma) else 1.0 / drift_sigma ** 2
    A = np.stack([np.ones_like(tt), tt], axis=-1)
    hub = np.ones_like(tt)
    for _ in range(3):
        for _ in range(20):
            if keep.sum() < 2:
                return None
            W = w0 * hub * keep
            N = A.T @ (W[:, None] * A) + np.diag([0.0, prior])
            x = np.linalg.solve(N, A.T @ (W * d))
            u = (d - A @ x) / s
            scale = max(1.4826 * float(np.median(np.abs(u[keep]))), 1.0)
            new = np.minimum(1.0, 1.345 * scale / np.maximum(np.abs(u), 1e-300))
            if np.allclose(new, hub, atol=1e-6):
                break
            hub = new
        bad = keep & (np.abs(u) > 5.0 * scale)
        if not bad.any():
            break
        keep &= ~bad
        dropped += int(bad.sum())
    W = w0 * keep
    N = A.T @ (W[:, None] * A) + np.diag([0.0, prior])
    x = np.linalg.solve(N, A.T @ (W * d))
    cov = np.linalg.inv(N)
    n = int(keep.sum())
    chi2 = float((W * (d - A @ x) ** 2).sum())
    dof = max(n - 2 + (1 if prior > 0 else 0), 1)
    factor = max(1.0, chi2 / dof)
    # residuals that follow each other (the estimate's heading bends away from a + b t) average out less
    # than white ones: the variance of a mean of n AR(1) terms is (1 + rho) / (1 - rho) times the white
    # one's (at most n: all of them one sample); applied when rho is beyond 3 standard errors of white noise
    u = ((d - A @ x) / s)[keep]
    rho = float((u[1:] * u[:-1]).sum() / max(float((u * u).sum()), 1e-300)) if n > 2 else 0.0
    if n > 2 and rho > 3.0 / math.sqrt(n):
        factor *= min((1.0 + rho) / max(1.0 - rho, 1e-12), float(n))
    return CourseFit(float(x[0]), float(x[1]), cov * factor, float(floor), n, dropped, factor,
                     glitches=dropped - reversing, considered=int(ok.sum()), correlation=rho)
