"""Static analytic coarse alignment (double-vector / TRIAD) and the at-rest check.

At rest the accelerometers measure ``f^b = -C_n^b g^n`` and the gyros
``w^b = C_n^b w_ie^n``.  With the vertical as the primary vector,

    body:  r1 = f/|f|,   r2 = (f x w)/|f x w|,           r3 = r1 x r2
    nav:   n1 = up,      n2 = (up x w_ie)/|up x w_ie|,   n3 = n1 x n2
    Cbn = [n1 n2 n3] [r1 r2 r3]^T

so the tilt comes from the specific force alone (error ~ horizontal
accelerometer bias / g) and the heading from the horizontal earth rate
(error ~ east gyro bias / (W_ie cos L)).  Means over the interval are the
summed increments over its length.  No I/O here.
"""
from __future__ import annotations

import numpy as np

from ..nav.earth import OMEGA_IE


def _frame(v1, v2):
    """Orthonormal triad (columns) from a primary and a secondary vector; (..., 3, 3)."""
    r1 = v1 / np.linalg.norm(v1, axis=-1, keepdims=True)
    c = np.cross(v1, v2)
    r2 = c / np.linalg.norm(c, axis=-1, keepdims=True)
    r3 = np.cross(r1, r2)
    return np.stack([r1, r2, r3], axis=-1)


def triad(f_b, w_b, lat):
    """``Cbn`` from the mean specific force ``f_b`` and angular rate ``w_b`` (body, (3,) or (n, 3)) at latitude ``lat`` (rad)."""
    f_b = np.asarray(f_b, dtype=float)
    w_b = np.asarray(w_b, dtype=float)
    up = np.array([0.0, 0.0, 1.0])
    w_n = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    nav = _frame(up, w_n)
    body = _frame(f_b, w_b)
    return np.matmul(nav, np.swapaxes(body, -1, -2))


def mean_rates(time, dtheta_b, dvel_b, t0):
    """Mean angular rate and specific force (body) over the whole window (t0, time[-1]]."""
    T = float(time[-1] - t0)
    return dtheta_b.sum(axis=0) / T, dvel_b.sum(axis=0) / T


def cumulative_triad(time, dtheta_b, dvel_b, t0, lat, rows=None):
    """The static solution over (t0, time[k]] for the samples k in ``rows`` (all when None): (n, 3, 3)."""
    k = np.arange(len(time)) if rows is None else np.asarray(rows)
    T = (np.asarray(time, dtype=float)[k] - t0)[:, None]
    return triad(np.cumsum(dvel_b, axis=0)[k] / T, np.cumsum(dtheta_b, axis=0)[k] / T, lat)


def block_means(time, dtheta_b, dvel_b, t0, block: float):
    """Mean rates and specific forces over consecutive blocks of ``block`` seconds: ``(w (k,3), f (k,3))``."""
    t = np.asarray(time, dtype=float) - t0
    nfull = max(int(np.floor(t[-1] / block + 1e-9)), 1)
    idx = np.clip(np.ceil(t / block - 1e-9).astype(np.int64) - 1, 0, nfull - 1)
    last = np.searchsorted(idx, np.arange(nfull), side="right") - 1
    nb = nfull
    edges = np.concatenate([[0.0], t[last]])
    span = np.diff(edges)
    w = np.stack([np.bincount(idx, dtheta_b[:, i], minlength=nb) for i in range(3)], axis=-1) / span[:, None]
    f = np.stack([np.bincount(idx, dvel_b[:, i], minlength=nb) for i in range(3)], axis=-1) / span[:, None]
    return w, f


def motion_statistics(time, dtheta_b, dvel_b, t0, block: float = 1.0):
    """How far the base is from rest: the largest deviation of the block-mean rate and specific force
    from their window means, ``(rate_dev rad/s, force_dev m/s^2, block, n_blocks)``.

    At rest these are sensor noise over one block; a swaying or moving base
    shows its motion (a +-5 deg sway at 0.15 Hz gives ~0.08 rad/s).
    """
    dw, df = block_deviations(time, dtheta_b, dvel_b, t0, block)
    if dw.shape[0] < 2:
        return 0.0, 0.0, block, dw.shape[0]
    return float(dw.max()), float(df.max()), block, dw.shape[0]


def block_deviations(time, dtheta_b, dvel_b, t0, block: float = 1.0):
    """Per block of ``block`` seconds, ``|w_block - w_mean|`` (rad/s) and ``|f_block - f_mean|`` (m/s^2)."""
    w, f = block_means(time, dtheta_b, dvel_b, t0, block)
    return np.linalg.norm(w - w.mean(axis=0), axis=1), np.linalg.norm(f - f.mean(axis=0), axis=1)
