"""A constant time offset between the GNSS fixes and the IMU, found by cross-correlating their motion
(no I/O; issue 22).

The spans of the two logs say nothing when both count seconds from their own start, or when one was
cut: an 18 s offset then passes every time-base check (:mod:`sinscli.io.timebase`) and the filter
rejects good fixes.  Two signals that need no attitude are compared, each sampled on the GNSS epochs:

* the turn rate: ``|w_ib^b|`` of the gyros against the rate of the GNSS course,
  ``|vE aN - vN aE| / (vE^2 + vN^2)`` (where the speed is over :data:`MIN_SPEED`);
* the horizontal acceleration: the specific force across its mean direction (the up axis of a vehicle
  whose tilt stays small), ``|f - (f.u) u|``, against ``|(aE, aN)|`` of the GNSS velocity;

the IMU signal averaged over the window that the GNSS differences span (its velocity differences, or
its positions' second differences when it has no velocity).  Their normalized cross-correlation,
summed over the two signals, peaks at the lag ``tau`` at which the GNSS event at ``t`` shows in the IMU
at ``t + tau``: ``tau`` is the shift to add to the GNSS times (``gnss.time_offset``).

Periodic motion (a weave, a roll or a sway of constant period) correlates as well at every multiple of its
period: the best lag is then a choice among equals, not a measurement.  It is named only when no other peak of the correlation (a local maximum set apart from it by a dip) comes within
:data:`UNIQUE_SE` standard errors of a correlation over the logs' independent samples (:func:`_margin`); otherwise the candidates are listed in a
warning (:func:`offset_warning`) and nothing is refused.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .earth import dlon, radii_py
from .imu_stats import block_means

MIN_SPEED = 2.0          # m/s: the GNSS course rate is used above this speed
MAX_LAG = 120.0          # s: the lags searched (at most half of the overlap)
MIN_OFFSET = 1.0         # s: smaller offsets (latency) are the filter's business, not reported
MIN_PEAK = 0.6           # mean correlation of the two signals at the peak
MIN_GAIN = 0.3           # the peak beats the correlation without a shift by this much
UNIQUE_SE = 3.0          # standard errors by which the peak must beat every other local maximum (_margin)
LISTED = 6               # candidate shifts named in the warning of an ambiguous estimate
MIN_MOTION = 8           # GNSS epochs with motion (turns or accelerations) needed
MAX_EPOCHS = 20_000      # GNSS epochs compared at most (a longer log is thinned evenly)
COARSE_LAGS = 1_000      # lags of the first search; the second refines around its best over FINE_LAGS
FINE_LAGS = 200
POSITION_SMOOTH = 5      # GNSS epochs: both signals averaged over this many more when the GNSS has no velocity


@dataclass
class OffsetEstimate:
    """The lag of best agreement: ``shift`` s to add to the GNSS times, the mean correlation there and
    without a shift, and the number of GNSS epochs compared; ``margin`` how far above every other peak
    the best must be (:func:`_margin`, over ``n_eff`` independent samples) and ``candidates`` the shifts
    (s, nearest zero first, the best among them) of the peaks within it: empty when the best is unique."""
    shift: float
    peak: float
    at_zero: float
    epochs: int
    margin: float = 0.0
    n_eff: float = 0.0
    candidates: tuple = ()

    @property
    def ambiguous(self) -> bool:
        """Several lags agree about as well (periodic or repeated motion): none can be named."""
        return len(self.candidates) > 1


def _enu_velocity(t, lat_deg, lon_deg, h):
    """ENU velocity (n, 3) m/s of a GNSS track from its positions (central differences)."""
    lat = np.radians(lat_deg)
    rm, rn = radii_py(np.sin(lat))
    d_lon = np.radians(dlon(lon_deg[1:], lon_deg[:-1], 180.0))            # across the antimeridian too
    e = np.concatenate([[0.0], np.cumsum(d_lon * (rn[1:] + h[1:]) * np.cos(lat[1:]))])
    n = np.concatenate([[0.0], np.cumsum(np.diff(lat) * (rm[1:] + h[1:]))])
    pos = np.column_stack([e, n, h])
    return np.gradient(pos, t, axis=0)


def _gnss_signals(t, vel):
    """(turn rate, horizontal acceleration) at the GNSS epochs from the ENU velocity."""
    acc = np.gradient(vel, t, axis=0)
    speed2 = vel[:, 0] ** 2 + vel[:, 1] ** 2
    turn = np.where(speed2 > MIN_SPEED ** 2,
                    np.abs(vel[:, 0] * acc[:, 1] - vel[:, 1] * acc[:, 0]) / np.maximum(speed2, 1e-12), 0.0)
    return turn, np.hypot(acc[:, 0], acc[:, 1])


def _imu_signals(time, dtheta_b, dvel_b, t0, step):
    """(grid times, turn rate, horizontal specific force) of the IMU in blocks of ``step`` s."""
    w, f = block_means(time, dtheta_b, dvel_b, t0, step)
    tb = t0 + step * (np.arange(w.shape[0]) + 0.5)
    u = f.mean(axis=0)
    u = u / max(np.linalg.norm(u), 1e-12)
    f_h = np.linalg.norm(f - (f @ u)[:, None] * u[None, :], axis=1)
    return tb, np.linalg.norm(w, axis=1), f_h


def _smooth(y, width):
    """Moving mean over ``width`` samples (odd), the ends shortened."""
    width = max(1, int(width) | 1)
    if width == 1:
        return y
    c = np.concatenate([[0.0], np.cumsum(y)])
    k = np.arange(y.size)
    lo = np.maximum(k - width // 2, 0)
    hi = np.minimum(k + width // 2 + 1, y.size)
    return (c[hi] - c[lo]) / (hi - lo)


def _corr(a, b) -> float:
    a = a - a.mean()
    b = b - b.mean()
    d = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / d if d > 0 else 0.0


def estimate_offset(imu_time, dtheta_b, dvel_b, imu_t0: float, gnss_time, lat_deg, lon_deg, h,
                    vel_n=None) -> OffsetEstimate | None:
    """The GNSS-IMU time offset by cross-correlation (module docstring), or None when the logs hold too
    little motion to tell."""
    gt = np.asarray(gnss_time, dtype=float)
    if gt.size < MIN_MOTION:
        return None
    thin = slice(None, None, max(1, gt.size // MAX_EPOCHS))
    gt = gt[thin]
    lat_deg, lon_deg, h = (np.asarray(a, float)[thin] for a in (lat_deg, lon_deg, h))
    vel_n = None if vel_n is None else np.asarray(vel_n, float)[thin]
    imu_time = np.asarray(imu_time, dtype=float)
    dt_i = float(np.median(np.diff(imu_time))) if imu_time.size > 1 else 0.0
    dt_g = float(np.median(np.diff(gt)))
    if not (dt_g > 0.0 and dt_i > 0.0):
        return None
    vel = (np.asarray(vel_n, dtype=float) if vel_n is not None else
           _enu_velocity(gt, np.asarray(lat_deg, float), np.asarray(lon_deg, float), np.asarray(h, float)))
    g_turn, g_acc = _gnss_signals(gt, vel)
    step = max(min(0.1, dt_g / 4.0), dt_i, 1e-3)   # the IMU blocks: at least one sample, at most 0.1 s
    tb, i_turn, i_acc = _imu_signals(np.asarray(imu_time, float), np.asarray(dtheta_b, float),
                                     np.asarray(dvel_b, float), float(imu_t0), step)
    if tb.size < 10:
        return None
    width = 2.0 * dt_g / step                  # the span of a central difference of the GNSS velocity
    if vel_n is None:                          # velocity from positions, differenced again: noisier, so both
        width = 2.0 * width + POSITION_SMOOTH * dt_g / step          # signals are averaged further
        g_turn, g_acc = _smooth(g_turn, POSITION_SMOOTH), _smooth(g_acc, POSITION_SMOOTH)
    i_turn, i_acc = _smooth(i_turn, width), _smooth(i_acc, width)
    span_i = (float(tb[0]), float(tb[-1]))
    overlap = min(span_i[1], gt[-1]) - max(span_i[0], gt[0])
    max_lag = min(MAX_LAG, 0.5 * max(overlap, 0.0))
    if max_lag < 2.0 * MIN_OFFSET:
        return None
    moving = (g_turn > 0.02) | (g_acc > 0.3)
    if int(moving.sum()) < MIN_MOTION:
        return None

    def score(tau):
        tq = gt + tau
        sel = (tq >= span_i[0]) & (tq <= span_i[1])
        if sel.sum() < MIN_MOTION:
            return -1.0, 0
        r1 = _corr(np.interp(tq[sel], tb, i_turn), g_turn[sel])
        r2 = _corr(np.interp(tq[sel], tb, i_acc), g_acc[sel])
        return 0.5 * (r1 + r2), int(sel.sum())

    fine = max(step, dt_g / 10.0)               # coarse, then fine around the coarse best: bounded work
    coarse = max(fine, 2.0 * max_lag / COARSE_LAGS)
    lags = np.arange(-max_lag, max_lag + 0.5 * coarse, coarse)
    coarse_scores = np.array([score(tau)[0] for tau in lags])
    best = float(lags[int(np.argmax(coarse_scores))])
    coarse_lags = lags
    if coarse > fine:
        half = min(2.0 * coarse, 0.5 * FINE_LAGS * fine)
        lags = np.arange(best - half, best + half + 0.5 * fine, fine)
    scores = np.array([score(tau)[0] for tau in lags])
    k = int(np.argmax(scores))
    tau = float(lags[k])
    if 0 < k < lags.size - 1:                  # the parabola through the peak and its neighbours
        a, b, c = scores[k - 1], scores[k], scores[k + 1]
        den = a - 2.0 * b + c
        if den < 0:
            tau += 0.5 * (a - c) / den * float(lags[1] - lags[0])
    peak, n = score(tau)
    at_zero = score(0.0)[0]
    margin, n_eff = _margin(coarse_lags, coarse_scores, overlap)
    cands = _rivals(coarse_lags, coarse_scores, margin)
    return OffsetEstimate(shift=tau, peak=peak, at_zero=at_zero, epochs=n, margin=margin, n_eff=n_eff,
                          candidates=tuple(sorted([tau] + cands, key=abs)) if cands else ())


def _margin(lags, scores, overlap):
    """``(margin, n_eff)``: how much higher than any other the best correlation must be to be told from it.

    Samples of the signals closer than their correlation time are not independent: the time is the full
    width at half maximum of the correlation's main lobe, so the logs hold ``n_eff = overlap / width``
    independent samples, and a sample correlation over them has the standard error ``1 / sqrt(n_eff)``
    (that of a correlation coefficient of ``n_eff`` independent pairs).  Two peaks closer than
    :data:`UNIQUE_SE` standard errors could trade places with other noise: the margin (:func:`_rivals`)."""
    k = int(np.argmax(scores))
    half = 0.5 * scores[k]
    i0 = i1 = k
    while i0 > 0 and scores[i0 - 1] > half:
        i0 -= 1
    while i1 < scores.size - 1 and scores[i1 + 1] > half:
        i1 += 1
    width = max(float(lags[i1] - lags[i0]), float(lags[1] - lags[0]) if lags.size > 1 else 1.0)
    n_eff = max(overlap / width, 1.0)
    return UNIQUE_SE / math.sqrt(n_eff), n_eff


def _rivals(lags, scores, margin):
    """The lags (s) of the other peaks of ``scores`` that rival the best: local maxima within ``margin`` of
    it and separated from it by a dip of at least ``margin`` (a ripple on the best one's flank is not another
    peak), each refined by the parabola through its neighbours."""
    k = int(np.argmax(scores))
    floor = scores[k] - margin
    step = float(lags[1] - lags[0]) if lags.size > 1 else 0.0
    out = []
    for j in range(1, scores.size - 1):
        if j == k or scores[j] < floor or scores[j] < scores[j - 1] or scores[j] < scores[j + 1]:
            continue
        dip = float(scores[min(j, k):max(j, k) + 1].min())
        if scores[j] - dip < margin:
            continue
        a, b, c = scores[j - 1], scores[j], scores[j + 1]
        den = a - 2.0 * b + c
        out.append(float(lags[j]) + (0.5 * (a - c) / den * step if den < 0 else 0.0))
    return out


def offset_refusal(est: OffsetEstimate | None, gnss_name: str, configured: float = 0.0) -> str | None:
    """The one-line refusal for a clear offset (:data:`MIN_OFFSET`, :data:`MIN_PEAK`, :data:`MIN_GAIN`, and a
    unique peak), naming the shift to set; None otherwise.  ``configured``: the ``gnss.time_offset`` already
    applied."""
    if est is None or abs(est.shift) < MIN_OFFSET or est.peak < MIN_PEAK or est.peak - est.at_zero < MIN_GAIN \
            or est.ambiguous:
        return None
    total = configured + est.shift
    late = "late" if est.shift < 0 else "early"
    return (f"{gnss_name}: the GNSS times are {abs(est.shift):.2f} s {late} against the IMU: the vehicle's turns "
            f"and accelerations agree best with the GNSS times shifted by {est.shift:+.2f} s (correlation "
            f"{est.peak:.2f} there, {est.at_zero:.2f} unshifted, {est.epochs} fixes); set gnss.time_offset: "
            f"{total:.2f} (or --time-offset {total:.2f}), or --force to navigate as they are")


def offset_warning(est: OffsetEstimate | None, gnss_name: str, configured: float = 0.0) -> str | None:
    """The warning for an ambiguous estimate (several lags agree within the margin, none near zero): the run
    goes on with the times as they are, and the text names ``gnss.time_offset`` and the candidate shifts
    (the total to set: ``configured`` plus each); None when the estimate is unique, weak, or zero is among
    the lags that agree."""
    if est is None or not est.ambiguous or est.peak < MIN_PEAK or est.peak - est.at_zero <= est.margin:
        return None
    shown = ", ".join(f"{configured + c:+.2f}" for c in est.candidates[:LISTED])
    more = f" and {len(est.candidates) - LISTED} more" if len(est.candidates) > LISTED else ""
    return (f"{gnss_name}: the GNSS-IMU time offset cannot be told: the motion repeats (periodic turns or "
            f"accelerations), and the GNSS times shifted by {shown} s{more} agree about as well with the IMU "
            f"(correlation {est.peak:.2f}, none ahead by the {est.margin:.2f} that {est.n_eff:.0f} independent samples "
            f"would need; {est.at_zero:.2f} unshifted); navigating with the times as they are: if the clocks "
            f"differ, set gnss.time_offset to the right one of these")
