"""Engine vibration of the IMU mount: a narrowband motion of the sensor against the vehicle body.

The vibration is *motion*, not a sensor error: the mount (the sensor's plate) turns by a small
rotation vector ``theta(t)`` and moves by a small displacement ``d(t)`` against the vehicle body
(both in the body's FLU axes).  Per axis ``i`` each is a sum of ``K`` sinusoids with seeded random
frequencies in the band and random phases:

    theta_i(t) = sum_j (a_ij / w_ij) sin(w_ij t + p_ij)        theta_i' = sum_j a_ij cos(w_ij t + p_ij)
    d_i(t)     = -sum_j (b_ij / v_ij^2) sin(v_ij t + q_ij)     d_i''    = sum_j b_ij sin(v_ij t + q_ij)

with equal amplitudes ``a_ij = rms_i sqrt(2/K)`` (rate RMS per axis ``rms_i``) and likewise ``b_ij``,
all multiplied by a smooth start ``m(t) = S(t / ramp)`` (the septic step of :mod:`.segments`, 1 after
``ramp`` s: the engine starting), so that the mount sits exactly on the body at the start (``theta``,
``d`` and their rates 0: the initial state of ``init.yaml`` is the sensor's too) and the derivatives
carry the envelope's (``theta' = m' A + m A'``, ``d'' = m'' D + 2 m' D' + m D''``).
The vibrating frame ``v`` has ``C_v^n = C_b^n R``, ``R = exp([theta x])``, and its position is
``r_b + C_b^n d``; the sensor measures exactly (strapdown kinematics of a point on a turning body):

    w_iv^v = R^T w_ib^b + J_r(theta) theta'
    f^v    = R^T (f^b + d'' + 2 w_ib^b x d' + w_ib^b x (w_ib^b x d))

``J_r(theta) = I - (1 - cos t)/t^2 [theta x] + (t - sin t)/t^3 [theta x]^2`` (``R^T R' = [J_r theta' x]``).
Left out: ``dw_ib^b/dt x d`` (below 1e-6 m/s^2 for a car's 0.1 rad/s^2 and ``d`` of 1e-5 m) and the
gravity gradient across ``d`` (1e-11 m/s^2).  The truth trajectory is the vehicle body's: it excludes
the mount's oscillation (``theta`` RMS ``rms/w``, about 0.01 deg for 2 deg/s at 30 Hz; ``d'`` RMS
``rms/v``, about 2 mm/s for 0.3 m/s^2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..nav.coning import _jacobian_coeffs
from ..nav.rotation import exp_so3_delta, rotvec_coeffs, v_cross

SEED_TAG = 0x5EB0          # the vibration's own random stream: SeedSequence([seed, SEED_TAG])


@dataclass
class Vibration:
    """Drawn vibration lines, per axis (3, K): angular frequencies (rad/s), amplitudes, phases (rad)."""
    rot_w: np.ndarray          # rad/s
    rot_a: np.ndarray          # rad/s: amplitude of theta' (the rate)
    rot_p: np.ndarray          # rad
    lin_w: np.ndarray          # rad/s
    lin_b: np.ndarray          # m/s^2: amplitude of d''
    lin_p: np.ndarray          # rad
    ramp: float = 0.0          # s: the amplitudes rise smoothly from 0 over this time (0: full from the start)

    def max_frequency(self) -> float:
        """Largest angular frequency (rad/s) of a line with a non-zero amplitude (0 when none)."""
        w = [self.rot_w[self.rot_a != 0], self.lin_w[self.lin_b != 0]]
        return float(max((x.max() for x in w if x.size), default=0.0))

    def record(self) -> dict:
        """Plain values for the run's record (Hz, deg/s, m/s^2, deg) and the size of what the truth excludes."""
        return {"gyro_lines_hz": (self.rot_w / (2 * np.pi)).tolist(),
                "gyro_amplitude_deg_s": np.degrees(self.rot_a).tolist(),
                "gyro_phase_deg": np.degrees(self.rot_p).tolist(),
                "accel_lines_hz": (self.lin_w / (2 * np.pi)).tolist(),
                "accel_amplitude_m_s2": self.lin_b.tolist(),
                "accel_phase_deg": np.degrees(self.lin_p).tolist(),
                "excluded_from_truth": self.excluded()}

    def excluded(self) -> dict:
        """RMS per axis of the mount's angle (deg), velocity (m/s) and displacement (m) against the body."""
        def rms(amp, w, power):
            with np.errstate(divide="ignore", invalid="ignore"):
                x = np.where(amp != 0, amp / w ** power, 0.0)
            return np.sqrt(0.5 * np.sum(x * x, axis=1))
        return {"angle_rms_deg": np.degrees(rms(self.rot_a, self.rot_w, 1)).tolist(),
                "velocity_rms_m_s": rms(self.lin_b, self.lin_w, 1).tolist(),
                "displacement_rms_m": rms(self.lin_b, self.lin_w, 2).tolist()}


def draw_vibration(cfg: dict) -> Vibration:
    """The lines of a validated ``vibration`` scenario section (SI: rad/s, m/s^2, Hz band)."""
    k = int(cfg["lines"])
    lo, hi = cfg["band"]
    rng_rw, rng_rp, rng_lw, rng_lp = (np.random.default_rng(s) for s in
                                      np.random.SeedSequence([int(cfg["seed"]), SEED_TAG]).spawn(4))
    two_pi = 2.0 * np.pi
    rot_w = two_pi * rng_rw.uniform(lo, hi, (3, k))
    lin_w = two_pi * rng_lw.uniform(lo, hi, (3, k))
    rot_p = rng_rp.uniform(0.0, two_pi, (3, k))
    lin_p = rng_lp.uniform(0.0, two_pi, (3, k))
    amp = np.sqrt(2.0 / k)
    return Vibration(rot_w, np.repeat(cfg["gyro_rms"][:, None] * amp, k, axis=1), rot_p,
                     lin_w, np.repeat(cfg["accel_rms"][:, None] * amp, k, axis=1), lin_p, float(cfg["ramp"]))


def envelope(tau: np.ndarray, ramp: float):
    """``(m, m', m'')`` (n,) of the smooth start ``m = S(tau / ramp)`` (1 after ``ramp``; 1 for ramp 0)."""
    tau = np.asarray(tau, dtype=float)
    if ramp <= 0.0:
        return np.ones_like(tau), np.zeros_like(tau), np.zeros_like(tau)
    u = np.clip(tau / ramp, 0.0, 1.0)
    v = 1.0 - u
    m = u ** 4 * (35.0 - 84.0 * u + 70.0 * u * u - 20.0 * u ** 3)
    return m, 140.0 * (u * v) ** 3 / ramp, 420.0 * (u * v) ** 2 * (v - u) / ramp ** 2


def mount_motion(vib: Vibration, tau: np.ndarray):
    """``(theta, theta', d, d', d'')`` (n, 3) each at times ``tau`` (s since the start)."""
    tau = np.ascontiguousarray(tau, dtype=np.float64)
    m, m1, m2 = envelope(tau, vib.ramp)
    return _lines(tau, m, m1, m2, vib.rot_w, vib.rot_a, vib.rot_p, vib.lin_w, vib.lin_b, vib.lin_p)


@njit(cache=True)
def _lines(tau, m, m1, m2, rot_w, rot_a, rot_p, lin_w, lin_b, lin_p):
    """The sums of :func:`mount_motion` with the envelope ``m, m', m''`` (the module docstring's formulas)."""
    n = tau.shape[0]
    k = rot_w.shape[1]
    th, dth, d, dd, ddd = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    for j in range(n):
        t = tau[j]
        for i in range(3):
            a0 = 0.0
            a1 = 0.0
            d0 = 0.0
            d1 = 0.0
            d2 = 0.0
            for q in range(k):
                if rot_a[i, q] != 0.0:
                    ph = rot_w[i, q] * t + rot_p[i, q]
                    a0 += rot_a[i, q] / rot_w[i, q] * np.sin(ph)
                    a1 += rot_a[i, q] * np.cos(ph)
                if lin_b[i, q] != 0.0:
                    pl = lin_w[i, q] * t + lin_p[i, q]
                    s, c = np.sin(pl), np.cos(pl)
                    d0 -= lin_b[i, q] / (lin_w[i, q] * lin_w[i, q]) * s
                    d1 -= lin_b[i, q] / lin_w[i, q] * c
                    d2 += lin_b[i, q] * s
            th[j, i] = m[j] * a0
            dth[j, i] = m1[j] * a0 + m[j] * a1
            d[j, i] = m[j] * d0
            dd[j, i] = m1[j] * d0 + m[j] * d1
            ddd[j, i] = m2[j] * d0 + 2.0 * m1[j] * d1 + m[j] * d2
    return th, dth, d, dd, ddd


def vibrate(vib: Vibration | None, tau: np.ndarray, w_ib: np.ndarray, f_b: np.ndarray, extra=None):
    """The sensor outputs of the vibrating mount (see the module docstring) from the body's ``w_ib^b``,
    ``f^b`` (n, 3) at times ``tau``; ``extra`` = ``(theta, theta')`` (n, 3) a slower rotation of the mount
    added to the lines' (its flex, :mod:`.flex`); ``vib`` and ``extra`` None return the inputs."""
    if vib is None and extra is None:
        return w_ib, f_b
    if vib is None:
        z = np.zeros_like(w_ib)
        return mount_outputs(np.ascontiguousarray(extra[0]), np.ascontiguousarray(extra[1]), z, z, z, w_ib, f_b)
    theta, dtheta, d, dd, ddd = mount_motion(vib, tau)
    if extra is not None:
        theta, dtheta = theta + extra[0], dtheta + extra[1]
    return mount_outputs(theta, dtheta, d, dd, ddd, w_ib, f_b)


@njit(cache=True)
def mount_outputs(theta, dtheta, d, dd, ddd, w_ib, f_b):
    """``(w_iv^v, f^v)`` (n, 3): ``R^T w + J_r(theta) theta'`` and ``R^T (f + d'' + 2 w x d' + w x (w x d))``."""
    n = w_ib.shape[0]
    w_out = np.empty((n, 3))
    f_out = np.empty((n, 3))
    for k in range(n):
        th = (theta[k, 0], theta[k, 1], theta[k, 2])
        t2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2]
        a, b = rotvec_coeffs(t2)
        c1, c2 = _jacobian_coeffs(t2)
        rm = exp_so3_delta(th, a, b)                      # R - I
        jm = exp_so3_delta(th, -c1, c2)                   # J_r - I
        w = (w_ib[k, 0], w_ib[k, 1], w_ib[k, 2])
        td = (dtheta[k, 0], dtheta[k, 1], dtheta[k, 2])
        dk = (d[k, 0], d[k, 1], d[k, 2])
        v = (dd[k, 0], dd[k, 1], dd[k, 2])
        wxd = v_cross(w, dk)
        wxv = v_cross(w, v)
        wxwxd = v_cross(w, wxd)
        f = (f_b[k, 0] + ddd[k, 0] + 2.0 * wxv[0] + wxwxd[0],
             f_b[k, 1] + ddd[k, 1] + 2.0 * wxv[1] + wxwxd[1],
             f_b[k, 2] + ddd[k, 2] + 2.0 * wxv[2] + wxwxd[2])
        for i in range(3):
            # R^T x = x + (R - I)^T x ; J_r theta' = theta' + (J_r - I) theta'
            w_out[k, i] = (w[i] + rm[0][i] * w[0] + rm[1][i] * w[1] + rm[2][i] * w[2]
                           + td[i] + jm[i][0] * td[0] + jm[i][1] * td[1] + jm[i][2] * td[2])
            f_out[k, i] = f[i] + rm[0][i] * f[0] + rm[1][i] * f[1] + rm[2][i] * f[2]
    return w_out, f_out
