"""Standstill detector on the IMU: windowed statistics of the angular rate and the specific force.

A window of ``window`` seconds is at rest when every gyro axis' standard deviation is under
``rate_std``, every accelerometer axis' under ``accel_std``, and the mean specific force's magnitude
is within ``accel_mag`` of gravity.  A vehicle moving straight at constant speed without vibration
(as a simulator makes it) looks the same to an IMU, so the filter applies ZUPT/ZARU only while its
own speed is under ``zupt.max_speed`` (:mod:`sinscli.fusion.kernel`).  Windows do not overlap, so
the ZUPT/ZARU measurements of successive windows have independent noise.
"""
from __future__ import annotations

import numpy as np


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
        t = np.concatenate([self._t, time])
        dth = np.concatenate([self._dth, dtheta_b])
        dv = np.concatenate([self._dv, dvel_b])
        starts = np.concatenate([[self._t_prev], t[:-1]]) if len(t) else t
        out0, out1, outw = [], [], []
        a = 0
        while a < len(t):
            b = int(np.searchsorted(t, starts[a] + self.window * (1.0 - 1e-9), side="left"))
            if b >= len(t):
                break
            dt = t[a:b + 1] - starts[a:b + 1]
            w = dth[a:b + 1] / dt[:, None]
            f = dv[a:b + 1] / dt[:, None]
            fm = f.mean(axis=0)
            if (len(dt) >= 3 and np.all(w.std(axis=0) < self.rate_std) and np.all(f.std(axis=0) < self.accel_std)
                    and abs(np.linalg.norm(fm) - self.g) < self.accel_mag):
                t0, t1 = float(starts[a]), float(t[b])
                out0.append(t0)
                out1.append(t1)
                outw.append(dth[a:b + 1].sum(axis=0) / (t1 - t0))
                if self.intervals and abs(self.intervals[-1][1] - t0) <= 1e-9 * max(1.0, abs(t0)):
                    self.intervals[-1][1] = t1
                else:
                    self.intervals.append([t0, t1])
            a = b + 1
        self._t, self._dth, self._dv = t[a:], dth[a:], dv[a:]
        self._t_prev = float(starts[a]) if a < len(t) else (float(t[-1]) if len(t) else self._t_prev)
        return np.array(out0), np.array(out1), np.array(outw).reshape(-1, 3)
