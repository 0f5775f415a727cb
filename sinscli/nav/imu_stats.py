"""Statistics of IMU increments and time stamps, shared by alignment, Allan analysis, the mounting check
and ``sins info``: mean rates over a window or over blocks, how far a base is from rest, time-stamp
statistics.  Numbers only (numpy), no I/O.

``dtheta_b`` (rad) and ``dvel_b`` (m/s) are the body increments over the intervals ending at ``time``
(s); the first interval starts at ``t0``.
"""
from __future__ import annotations

import numpy as np


def mean_rates(time, dtheta_b, dvel_b, t0):
    """Mean angular rate and specific force (body) over the whole window (t0, time[-1]]."""
    T = float(time[-1] - t0)
    return dtheta_b.sum(axis=0) / T, dvel_b.sum(axis=0) / T


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


def time_stats(t: np.ndarray) -> dict:
    """Start, end, rate, median interval, largest interval and the number of gaps (intervals longer than
    5 median intervals) of the time stamps ``t`` (s)."""
    out = {"start": None, "end": None, "rate_hz": None, "median_dt": None, "max_gap": None, "gaps": 0}
    if t.size == 0:
        return out
    out["start"], out["end"] = float(t[0]), float(t[-1])
    if t.size > 1:
        dt = np.diff(t)
        med = float(np.median(dt))
        out["median_dt"] = med
        out["rate_hz"] = (t.size - 1) / (t[-1] - t[0]) if t[-1] > t[0] else None
        out["max_gap"] = float(dt.max())
        out["gaps"] = int((dt > 5.0 * med).sum()) if med > 0 else 0
    return out


def start_means(time, dtheta_b, dvel_b, t0: float, window: float = 1.0) -> dict:
    """Mean specific force and angular rate over the first ``window`` s (at least 10 samples)."""
    n = max(int(np.searchsorted(time, t0 + window, side="right")), min(10, len(time)))
    span = float(time[n - 1] - t0)
    acc = dvel_b[:n].sum(axis=0) / span
    gyr = dtheta_b[:n].sum(axis=0) / span
    return {"messages": n, "mean_accel": acc.tolist(), "mean_gyro": gyr.tolist(),
            "accel_norm": float(np.linalg.norm(acc)), "gyro_norm": float(np.linalg.norm(gyr))}
