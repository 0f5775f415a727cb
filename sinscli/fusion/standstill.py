"""Standstill detector on the IMU: windowed statistics of the angular rate and the specific force.

A window of ``window`` seconds is at rest when every gyro axis' standard deviation (of the samples, or with
``lowpass`` of their means over bins of that length, so that engine vibration averages out) is under
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

from ..nav.earth import local_en


@njit(cache=True)
def rest_windows(t, dth, dv, t_start, window, rate_std, accel_std, accel_mag, g, lowpass, out):
    """Scan complete windows of the samples ``t`` (the first interval starts at ``t_start``).

    The statistics are those of the per-sample rates and specific forces, or, with ``lowpass`` > 0 s,
    of their means over consecutive bins of about ``lowpass`` s (at least 3 per window): an engine's
    vibration (20-40 Hz, 1-3 deg/s) averages out in a bin while a start, a turn or a step does not.
    Writes ``(t0, t1, mean rate x, y, z)`` of each window at rest into ``out`` (capacity: one row per
    window); returns ``(rows written, index of the first sample of the unfinished window)``.
    """
    n = t.shape[0]
    n_out = 0
    a = 0
    nbin_max = 1 + int(window / lowpass) if lowpass > 0.0 else 1
    bw = np.zeros((nbin_max, 3))
    bf = np.zeros((nbin_max, 3))
    bt = np.zeros(nbin_max)
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
        vw = np.zeros(3)
        vf = np.zeros(3)
        if lowpass > 0.0:
            # bin means: rate = sum dtheta / sum dt over each bin
            nb = max(3, int(round((t[b] - s_a) / lowpass)))
            nb = min(nb, nbin_max, m)
            for j in range(nb):
                bt[j] = 0.0
                for i in range(3):
                    bw[j, i] = 0.0
                    bf[j, i] = 0.0
            for k in range(a, b + 1):
                tp = t_start if k == 0 else t[k - 1]
                j = min(int((0.5 * (tp + t[k]) - s_a) / (t[b] - s_a) * nb), nb - 1)
                bt[j] += t[k] - tp
                for i in range(3):
                    bw[j, i] += dth[k, i]
                    bf[j, i] += dv[k, i]
                    sw[i] += dth[k, i]
            used = 0
            for j in range(nb):
                if bt[j] > 0.0:
                    used += 1
                    for i in range(3):
                        mw[i] += bw[j, i] / bt[j]
                        mf[i] += bf[j, i] / bt[j]
            for i in range(3):
                mw[i] /= used
                mf[i] /= used
            for j in range(nb):
                if bt[j] > 0.0:
                    for i in range(3):
                        e = bw[j, i] / bt[j] - mw[i]
                        vw[i] += e * e
                        e = bf[j, i] / bt[j] - mf[i]
                        vf[i] += e * e
            cnt = used
        else:
            for k in range(a, b + 1):
                dt = t[k] - (t_start if k == 0 else t[k - 1])
                for i in range(3):
                    mw[i] += dth[k, i] / dt
                    mf[i] += dv[k, i] / dt
                    sw[i] += dth[k, i]
            for i in range(3):
                mw[i] /= m
                mf[i] /= m
            for k in range(a, b + 1):
                dt = t[k] - (t_start if k == 0 else t[k - 1])
                for i in range(3):
                    e = dth[k, i] / dt - mw[i]
                    vw[i] += e * e
                    e = dv[k, i] / dt - mf[i]
                    vf[i] += e * e
            cnt = m
        rest = m >= 3 and cnt >= 3
        for i in range(3):
            if not (np.sqrt(vw[i] / cnt) < rate_std and np.sqrt(vf[i] / cnt) < accel_std):
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

    def __init__(self, window: float, rate_std: float, accel_std: float, accel_mag: float, g: float,
                 lowpass: float = 0.0):
        self.window, self.rate_std, self.accel_std, self.accel_mag, self.g = window, rate_std, accel_std, accel_mag, g
        self.lowpass = lowpass
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
                            self.g, self.lowpass, out)
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


STILL_SPEED = 0.2        # m/s: the GNSS speed under which a vehicle is still (beyond 3 sigma of the estimate)


def gnss_still(gnss, t0, t1, min_span: float = 10.0):
    """Whether the GNSS agrees that a vehicle is still over the windows ``[t0, t1]`` (arrays, s): 1 still,
    0 moving, -1 unknown (no fix around the window).

    The span looked at is the window widened symmetrically to at least ``min_span`` s.  With GNSS
    velocity: every fix in it slower than ``STILL_SPEED`` plus 3 sigma.  Without: the displacement between
    the first and the last fix in it, over their time apart, is under ``STILL_SPEED`` plus 3 sigma of
    that speed (the fixes' sigmas over the span), and moving when over ``STILL_SPEED`` by 3 sigma.  A
    rover driving straight at 1 m/s, which the IMU alone cannot tell from a standstill, moves several
    metres in such a span (the fused filter's ZUPT and the noise-from-data use only windows still by
    both)."""
    t0 = np.atleast_1d(np.asarray(t0, dtype=float))
    t1 = np.atleast_1d(np.asarray(t1, dtype=float))
    out = np.full(t0.shape, -1, dtype=np.int64)
    if gnss is None or len(gnss) == 0:
        return out
    t = gnss.time
    pad = np.maximum(0.5 * (min_span - (t1 - t0)), 0.0)
    i = np.searchsorted(t, t0 - pad, side="left")
    j = np.searchsorted(t, t1 + pad, side="right") - 1
    # a window inside an outage (no fix in its span, or one): the fixes that bracket it (a cruise at constant
    # speed through a tunnel looks still to the IMU; the fixes before and after it are far apart)
    gap = j <= i
    i = np.where(gap, np.searchsorted(t, t0, side="right") - 1, i)
    j = np.where(gap, np.searchsorted(t, t1, side="left"), j)
    gap &= (i >= 0) & (j < len(t))
    i = np.clip(i, 0, len(t) - 1)
    j = np.clip(j, 0, len(t) - 1)
    have = j >= i
    if gap.any():                   # their displacement decides, the velocity columns aside
        e, n = local_en(gnss.lat, gnss.lon, gnss.height)
        sp = gnss.position_sigma([1.5, 1.5, 3.0])
        sh = np.hypot(sp[:, 0], sp[:, 1]) / np.sqrt(2.0)
        k = np.nonzero(gap & (j > i))[0]
        span = np.maximum(t[j[k]] - t[i[k]], 1e-9)
        v = np.hypot(e[j[k]] - e[i[k]], n[j[k]] - n[i[k]]) / span
        sv = np.hypot(sh[i[k]], sh[j[k]]) / span
        out[k] = np.where(v - 3.0 * sv > STILL_SPEED, 0, np.where(v < STILL_SPEED + 3.0 * sv, 1, 0))
        out[k[3.0 * sv > 1.0]] = -1
        have &= ~gap
    if gnss.vel_n is not None:
        sv = gnss.std_vel if gnss.std_vel is not None else np.full((len(gnss), 3), 0.1)
        sv = np.where(np.isfinite(sv) & (sv > 0), sv, 0.1)
        speed = np.hypot(gnss.vel_n[:, 0], gnss.vel_n[:, 1]) - 3.0 * np.hypot(sv[:, 0], sv[:, 1]) / np.sqrt(2.0)
        cm = np.concatenate([[0], np.cumsum(speed > STILL_SPEED)])
        for k in np.nonzero(have)[0]:
            out[k] = 0 if cm[j[k] + 1] - cm[i[k]] > 0 else 1
        return out
    e, n = local_en(gnss.lat, gnss.lon, gnss.height)
    sp = gnss.position_sigma([1.5, 1.5, 3.0])
    sh = np.hypot(sp[:, 0], sp[:, 1]) / np.sqrt(2.0)
    two = have & (j > i)
    ii, jj = i[two], j[two]
    span = np.maximum(t[jj] - t[ii], 1e-9)
    v = np.hypot(e[jj] - e[ii], n[jj] - n[ii]) / span
    sv = np.hypot(sh[ii], sh[jj]) / span
    out[two] = np.where(v - 3.0 * sv > STILL_SPEED, 0, np.where(v < STILL_SPEED + 3.0 * sv, 1, 0))
    # windows whose span is too short to tell (3 sigma of the speed over 1 m/s): unknown
    out[np.nonzero(two)[0][3.0 * sv > 1.0]] = -1
    return out
