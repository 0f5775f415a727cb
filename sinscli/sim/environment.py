"""The sensor's response to its environment: g-sensitivity, vibration rectification, temperature drift.

Added to the exact outputs in the sensor axes (``w`` rad/s, ``f`` m/s^2) before the sensor description's
error model (:mod:`.errors`), per axis ``i``:

    w_i += sum_j G_ij f_j                   g-sensitive gyro bias (IEEE Std 1431-2004, the acceleration-
                                            sensitive drift D_a a; Groves 2013, "Principles of GNSS, Inertial,
                                            and Multisensor Integrated Navigation Systems", 2nd ed., sec. 4.4)
    f_i += K2_i f_i^2                       the accelerometer's second-order coefficient (IEEE Std 1293-1998,
                                            the model's K2 a^2), whose mean under vibration is the vibration
                                            rectification error K2 <f_vib^2> (Groves 2013, sec. 4.4)
    w_i += c_w,i dT(t),  f_i += c_f,i dT(t) temperature drift of the biases (IEEE Std 1431-2004, D_T dT)

with the chip's temperature change since the start (a warm-up plus a slow swing, e.g. the cabin's air
conditioning cycling)

    dT(t) = rise (1 - exp(-t / tau)) + swing sin(2 pi t / period),

so the turn-on bias is the sensor description's and the drift starts at 0.  Increments take the exact
integrals over each interval: ``G dv`` (linear), ``K2 int f_i^2 dt`` (the truth engine's second moments
of ``f``, :func:`sinscli.sim.truth.generate` with ``moments=True``: the mean of ``f^2``, not the square of
the interval's mean, a third short for 20-40 Hz vibration at 100 Hz), and ``c (I(t_k) - I(t_k-1))`` with
``I(t) = rise (t - tau (1 - exp(-t/tau))) + swing period/(2 pi) (1 - cos(2 pi t / period))``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import pinned as pm


@dataclass
class Environment:
    """Validated environment terms (SI, sensor axes); None: off."""
    g_sensitivity: np.ndarray | None = None      # (3, 3) rad/s per m/s^2: gyro i from specific force j
    rectification: np.ndarray | None = None      # (3,) 1/(m/s^2): K2 per accelerometer axis
    temperature: dict | None = None              # rise K, tau s, swing K, period s, gyro rad/s/K, accel m/s^2/K

    def active(self) -> bool:
        return self.g_sensitivity is not None or self.rectification is not None or self.temperature is not None


def temperature_change(temp: dict, t: np.ndarray) -> np.ndarray:
    """``dT(t)`` (K) at ``t`` s since the start (module docstring)."""
    t = np.asarray(t, dtype=np.float64)
    return temp["rise"] * (1.0 - pm.exp(-t / temp["tau"])) + temp["swing"] * pm.sin(2.0 * np.pi * t / temp["period"])


def temperature_integral(temp: dict, t: np.ndarray) -> np.ndarray:
    """``I(t) = int_0^t dT`` (K s), the exact integral of :func:`temperature_change`."""
    t = np.asarray(t, dtype=np.float64)
    w = 2.0 * np.pi / temp["period"]
    return (temp["rise"] * (t - temp["tau"] * (1.0 - pm.exp(-t / temp["tau"])))
            + temp["swing"] / w * (1.0 - pm.cos(w * t)))


def environment_increments(env: Environment, dtheta: np.ndarray, dvel: np.ndarray, tau: np.ndarray,
                           f2: np.ndarray | None):
    """Increments (N, 3) over the intervals ``tau[k-1]..tau[k]`` (s since the start) with the terms added:
    ``dvel`` the exact ones (sensor axes), ``f2`` (N, 3) the integrals of ``f_i^2`` (needed with
    ``rectification``)."""
    dth, dv = dtheta.copy(), dvel.copy()
    if env.g_sensitivity is not None:
        dth = dth + pm.matmul(dvel, env.g_sensitivity.T)
    if env.rectification is not None:
        dv = dv + env.rectification[None, :] * f2
    if env.temperature is not None:
        it = temperature_integral(env.temperature, tau)
        di = (it[1:] - it[:-1])[:, None]
        dth = dth + env.temperature["gyro"][None, :] * di
        dv = dv + env.temperature["accel"][None, :] * di
    return dth, dv


def environment_rates(env: Environment, gyro: np.ndarray, accel: np.ndarray, tau: np.ndarray):
    """Rate samples (n, 3) at ``tau`` (s since the start) with the terms added (``accel`` the exact ones)."""
    g, a = gyro.copy(), accel.copy()
    if env.g_sensitivity is not None:
        g = g + pm.matmul(accel, env.g_sensitivity.T)
    if env.rectification is not None:
        a = a + env.rectification[None, :] * accel * accel
    if env.temperature is not None:
        dt_k = temperature_change(env.temperature, tau)[:, None]
        g = g + env.temperature["gyro"][None, :] * dt_k
        a = a + env.temperature["accel"][None, :] * dt_k
    return g, a


def sensor_moments(ff_b: np.ndarray, c_out: np.ndarray) -> np.ndarray:
    """``int f_s,i^2 dt`` (N, 3) in the sensor axes (``f_s = f_b @ c_out``) from the body's second moments
    ``ff_b`` (N, 6) = ``int (f_x^2, f_y^2, f_z^2, f_x f_y, f_x f_z, f_y f_z) dt`` (FLU)."""
    m = np.empty((ff_b.shape[0], 3, 3))
    for (j, k), col in zip(((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)), range(6)):
        m[:, j, k] = ff_b[:, col]
        m[:, k, j] = ff_b[:, col]
    out = np.zeros((ff_b.shape[0], 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                out[:, i] = out[:, i] + (c_out[j, i] * c_out[k, i]) * m[:, j, k]
    return out
