"""Inertial sensor error models applied to exact increments, seeded and reproducible.

Per sensor triad and per interval ``k`` of length ``dt`` (increment form):

    d_meas = (I + diag(s) + N) d_true + (b + b_gm[k]) dt + sigma_rw sqrt(dt) n_k

then quantized with the remainder carried to the next sample (as an
integrating sensor does).  ``s`` scale factors, ``N`` the misalignment
(off-diagonal small angles ``[[0, xy, xz], [yx, 0, yz], [zx, zy, 0]]``), ``b``
the constant bias, ``b_gm`` a first-order Gauss-Markov bias instability
``b_gm[k] = e^{-dt/tau} b_gm[k-1] + sigma sqrt(1 - e^{-2 dt/tau}) w_k`` (steady
state from the start), ``sigma_rw`` the angle or velocity random walk.

Random draws come from ``numpy.random.default_rng`` streams spawned from one
``SeedSequence(seed)``: one stream per sensor and term, so that switching a
term off leaves the other realizations as they were.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from . import pinned as pm


def gauss_markov(phi, sigma_w, b0, w):
    """First-order Gauss-Markov sequence (N, 3): ``b[k] = phi b[k-1] + sigma_w w[k]``, ``b[-1] = b0``
    (``phi``, ``sigma_w`` per axis (3,), or per step and axis (N, 3))."""
    n = w.shape[0]
    return gauss_markov_steps(np.ascontiguousarray(np.broadcast_to(phi, (n, 3)), dtype=np.float64),
                              np.ascontiguousarray(np.broadcast_to(sigma_w, (n, 3)), dtype=np.float64),
                              np.asarray(b0, dtype=np.float64).copy(), w)


@njit(cache=True)
def gauss_markov_steps(phi, sigma_w, b0, w):
    """``b[k] = phi[k] b[k-1] + sigma_w[k] w[k]`` (N, 3), ``b[-1] = b0``: the recursion of :func:`gauss_markov`."""
    n = w.shape[0]
    out = np.empty_like(w)
    prev = b0.copy()
    for k in range(n):
        for i in range(3):
            prev[i] = phi[k, i] * prev[i] + sigma_w[k, i] * w[k, i]
            out[k, i] = prev[i]
    return out


def gauss_markov_times(tau: np.ndarray, sigma: np.ndarray, tc: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Steady-state first-order Gauss-Markov values (N, 3) at irregular times ``tau`` (s): sigma (3,),
    correlation times ``tc`` (3,) s (0: white), unit normal draws ``w`` (N, 3).

    ``e[0] = sigma w[0]``, ``e[k] = phi_k e[k-1] + sigma sqrt(1 - phi_k^2) w[k]``,
    ``phi_k = exp(-(tau_k - tau_{k-1}) / tc)``: the exact discretization, also across gaps."""
    n = w.shape[0]
    dt = np.diff(np.asarray(tau, dtype=float), prepend=-np.inf)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(tc[None, :] > 0, np.exp(-dt / np.where(tc > 0, tc, 1.0)[None, :]), 0.0)
    phi = np.broadcast_to(phi, (n, 3))
    return gauss_markov_steps(np.ascontiguousarray(phi), np.ascontiguousarray(sigma[None, :] * np.sqrt(1.0 - phi * phi)),
                              np.zeros(3), w)


@njit(cache=True)
def quantize(inc, q):
    """Quantize increments (N, 3) to steps ``q`` (3,), carrying the remainder (no lost angle)."""
    out = np.empty_like(inc)
    rem = np.zeros(3)
    for k in range(inc.shape[0]):
        for i in range(3):
            if q[i] > 0.0:
                acc = rem[i] + inc[k, i]
                out[k, i] = np.round(acc / q[i]) * q[i]
                rem[i] = acc - out[k, i]
            else:
                out[k, i] = inc[k, i]
    return out


def _misalignment_matrix(m6):
    xy, xz, yx, yz, zx, zy = m6
    return np.array([[0.0, xy, xz], [yx, 0.0, yz], [zx, zy, 0.0]])


def corrupt(inc: np.ndarray, dt: np.ndarray, spec: dict, seedseq: np.random.SeedSequence,
            noise_key: str) -> tuple[np.ndarray, dict]:
    """Apply one triad's errors to exact increments ``inc`` (N, 3) over intervals ``dt`` (N,).

    Returns the measured increments and the realized errors (SI) for the record: the constants and
    ``bias_gm`` (N, 3), the bias instability of each interval (None without one).
    """
    rng_bias, rng_sf, rng_mis, rng_gm, rng_noise = (np.random.default_rng(s) for s in seedseq.spawn(5))
    n = inc.shape[0]
    bias = spec.get("bias", np.zeros(3)).copy()
    if "bias_sigma" in spec:
        bias += spec["bias_sigma"] * rng_bias.standard_normal(3)
    sf = spec.get("scale_factor", np.zeros(3)).copy()
    if "scale_factor_sigma" in spec:
        sf += spec["scale_factor_sigma"] * rng_sf.standard_normal(3)
    mis = spec.get("misalignment", np.zeros(6)).copy()
    if "misalignment_sigma" in spec:
        mis += spec["misalignment_sigma"] * rng_mis.standard_normal(6)
    M = np.eye(3) + np.diag(sf) + _misalignment_matrix(mis)
    out = pm.matmul(inc, M.T) + bias[None, :] * dt[:, None]
    gm = None
    if "bias_instability" in spec and np.any(spec["bias_instability"] > 0):
        sig, tau = spec["bias_instability"], spec["bias_tau"]
        dtm = float(np.mean(dt))
        phi = pm.exp(-dtm / tau)
        b0 = sig * rng_gm.standard_normal(3)
        gm = gauss_markov(phi, sig * np.sqrt(1.0 - phi * phi), b0, rng_gm.standard_normal((n, 3)))
        out += gm * dt[:, None]
    if noise_key in spec and np.any(spec[noise_key] > 0):
        out += spec[noise_key][None, :] * np.sqrt(dt)[:, None] * rng_noise.standard_normal((n, 3))
    if "quantization" in spec and np.any(spec["quantization"] > 0):
        out = quantize(out, spec["quantization"])
    return out, {"bias": bias, "scale_factor": sf, "misalignment": mis, "bias_gm": gm}


def apply_imu_errors(dtheta: np.ndarray, dvel: np.ndarray, dt: np.ndarray, sensor: dict, seed: int):
    """Measured ``(dtheta, dvel, realized)`` from exact increments, seeded (bit-reproducible)."""
    gyro_ss, accel_ss = np.random.SeedSequence(seed).spawn(3)[:2]
    dth, g_real = corrupt(dtheta, dt, sensor.get("gyro", {}), gyro_ss, "arw")
    dv, a_real = corrupt(dvel, dt, sensor.get("accel", {}), accel_ss, "vrw")
    return dth, dv, {"gyro": g_real, "accel": a_real}


def gnss_seedseq(seed: int) -> np.random.SeedSequence:
    """The GNSS noise stream of ``seed`` (third child of the run's SeedSequence)."""
    return np.random.SeedSequence(seed).spawn(3)[2]
