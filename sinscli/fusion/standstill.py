"""Standstill detector on the IMU: windowed statistics of the angular rate and the specific force.

A window of ``window`` seconds is at rest when every gyro axis' standard deviation is under
``rate_std``, every accelerometer axis' under ``accel_std``, and the mean specific force's magnitude
is within ``accel_mag`` of gravity.  A vehicle moving straight at constant speed without vibration
(as a simulator makes it) looks the same to an IMU, so the filter applies ZUPT/ZARU only while its
own speed is under ``zupt.max_speed`` (:mod:`sinscli.fusion.kernel`).  Windows do not overlap, so
the ZUPT/ZARU measurements of successive windows have independent noise.  The window statistics are
a numba kernel (:func:`rest_windows`); the class only carries the samples of an unfinished window from
one block to the next.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def rest_windows(t, dth, dv, t_start, window, rate_std, accel_std, accel_mag, g, out):
    """Scan complete windows of the samples ``t`` (the first interval starts at ``t_start``).

    Writes ``(t0, t1, mean rate x, y, z)`` of each window at rest into ``out`` (capacity: one row per
    window); returns ``(rows written, index of the first sample of the unfinished window)``.
    """
    n = t.shape[0]
    n_out = 0
    a = 0
    while a < n:
        s_a = t_start if a == 0 else t[a - 1]
        t_end = s_a + window * (1.0 - 1e-9)
        b = a
        while b < n and t[b] < t_end:
            b += 1
        if b >= n:
            break
        m = b - a + 1
        mw = np.zeros(3)
        mf = np.zeros(3)
        sw = np.zeros(3)
        for k in range(a, b + 1):
            dt = t[k] - (t_start if k == 0 else t[k - 1])
            for i in range(3):
                mw[i] += dth[k, i] / dt
                mf[i] += dv[k, i] / dt
                sw[i] += dth[k, i]
        for i in range(3):
            mw[i] /= m
            mf[i] /= m
        vw = np.zeros(3)
        vf = np.zeros(3)
        for k in range(a, b + 1):
            dt = t[k] - (t_start if k == 0 else t[k - 1])
            for i in range(3):
                e = dth[k, i] / dt - mw[i]
                vw[i] += e * e
                e = dv[k, i] / dt - mf[i]
                vf[i] += e * e
        rest = m >= 3
        for i in range(3):
            if not (np.sqrt(vw[i] / m) < rate_std and np.sqrt(vf[i] / m) < accel_std):
                rest = False
        if rest and abs(np.sqrt(mf[0] * mf[0] + mf[1] * mf[1] + mf[2] * mf[2]) - g) < accel_mag:
            t1 = t[b]
            out[n_out, 0] = s_a
            out[n_out, 1] = t1
            for i in range(3):
                out[n_out, 2 + i] = sw[i] / (t1 - s_a)
            n_out += 1
        a = b + 1
    return n_out, a


class StandstillDetector:
    """Feed IMU blocks in time order; get the windows at rest: ``(t_start, t_end, mean raw rate (3))``."""

    def __init__(self, window: float, rate_std: float, accel_std: float, accel_mag: float, g: float):
        self.window, self.rate_std, self.accel_std, self.accel_mag, self.g = window, rate_std, accel_std, accel_mag, g
        self._t = np.empty(0)
        self._dth = np.empty((0, 3))
        self._dv = np.empty((0, 3))
        self._t_prev = None
        self.intervals: list[list[float]] = []      # merged [start, end] of consecutive windows at rest

    def feed(self, time, dtheta_b, dvel_b, t_start=None):
        """Windows at rest completed by this block (arrays ``t0 (n,), t1 (n,), w (n, 3)``)."""
        if self._t_prev is None:
            self._t_prev = float(t_start if t_start is not None else time[0])
        if len(self._t):
            t = np.concatenate([self._t, time])
            dth = np.concatenate([self._dth, dtheta_b])
            dv = np.concatenate([self._dv, dvel_b])
        else:
            t, dth, dv = (np.ascontiguousarray(time, dtype=float), np.ascontiguousarray(dtheta_b, dtype=float),
                          np.ascontiguousarray(dvel_b, dtype=float))
        if len(t) == 0:
            return np.empty(0), np.empty(0), np.empty((0, 3))
        span = float(t[-1] - self._t_prev)
        out = np.empty((int(span / self.window) + 2, 5))
        n, a = rest_windows(t, dth, dv, self._t_prev, self.window, self.rate_std, self.accel_std, self.accel_mag,
                            self.g, out)
        out = out[:n]
        for t0, t1 in out[:, :2]:
            if self.intervals and abs(self.intervals[-1][1] - t0) <= 1e-9 * max(1.0, abs(t0)):
                self.intervals[-1][1] = float(t1)
            else:
                self.intervals.append([float(t0), float(t1)])
        if a > 0:
            self._t_prev = float(t[a - 1])
        self._t, self._dth, self._dv = t[a:].copy(), dth[a:].copy(), dv[a:].copy()
        return out[:, 0].copy(), out[:, 1].copy(), out[:, 2:5].copy()
