"""Noise terms from the standstill windows of any log (a drive's stops, an engine idling), for the fused
filter's noise-from-data (:mod:`sinscli.fusion.noise`).

The windows at rest are those of the fused filter's own standstill detector (with the vehicle's
settings: a low-pass that lets engine vibration through as rest).  In each window the overlapping Allan
variance of every axis is computed (:mod:`.adev`); the windows are pooled cluster size by cluster size
(weighted by their number of terms), and the model

    AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau (1 - 3 / (4 m) for trapezoid rates) + B^2

is fitted by nonnegative weighted least squares (:func:`sinscli.allan.fit._nnls_small`).  ``N`` is the
white noise (ARW/VRW) the filter's process noise takes; the ``1/tau^2`` term holds quantization and the
vibration of the mount (a narrowband process averages out as ``1/tau^2`` over a few of its periods), the
constant a flicker floor, so that neither inflates ``N``.  Cluster times from ``TAU_MIN`` (or one sample) to a
quarter of the longest window (``TAU_MIN`` = 0.25 s: below it an engine's vibration is not yet
``1/tau^2`` and would pass for white noise).  No I/O.
"""
from __future__ import annotations

import numpy as np

from ..fusion.noise import MIN_REST_FIT, RestNoise
from ..fusion.standstill import StandstillDetector, gnss_still
from ..types import GnssLog, ImuLog
from ..units import G0
from .adev import overlapping_avar
from .fit import _nnls_small

MIN_REST = MIN_REST_FIT     # s at rest in all, at least
MIN_WINDOW = 3.0           # s: shorter intervals at rest are not used
TAU_MIN = 0.25             # s: the shortest cluster time fitted (five periods of a 20 Hz vibration: its Allan
                           # variance is in its 1/tau^2 regime from there)
G_NOMINAL = G0             # the detector's gravity (its 0.3 m/s^2 tolerance covers every latitude)
SEPARATION = 2.0           # standard errors of N^2 above zero for the fit to tell white noise apart
GAP = 1.5                  # a sample interval over this many median ones: dropped rows, the span is cut there
TRUE_REST_ANGLE = 1.0e-3   # rad (0.06 deg): the RMS rotation of the bounded motion at rest (the gyro's 1/tau^2
                           # term Q) under which the rest is a true rest: an engine's vibration turns the mount by
                           # hundredths of a degree, a hand holding a device by tenths to degrees


def _unfitted(rest_seconds: float) -> RestNoise:
    """The rest noise of a log whose windows at rest are too short to fit: nothing but their time."""
    z = np.zeros(3)
    return RestNoise(rest_seconds=rest_seconds, windows=0, gyro_white=z, accel_white=z, gyro_q=z, accel_q=z,
                     gyro_mean=z, accel_mean=z, fitted=False, true_rest=False)


def true_rest(fits, quant=(0.0, 0.0)) -> bool:
    """Whether the windows were a true rest, evidence about the sensor's own terms: the sensor did not turn
    beyond a mount's vibration (gyro ``Q`` under :data:`TRUE_REST_ANGLE`), and at the shortest cluster time fitted
    the bounded motion's term ``3 Q^2 / tau^2`` stays under the white noise's ``N^2 / tau`` on every axis (an
    engine's vibration that dominates there leaves the white-noise fit a vibration figure, not the sensor's).
    ``fits`` (6, 4): ``(Q, N, B, separated)`` of the gyro then accelerometer axes; ``quant`` the part of ``Q``
    the counters' quantization explains (gyro, accelerometer: ``step / sqrt(3)`` for increment logs, IEEE Std
    952-1997 Annex C), which is not motion."""
    q2 = fits[:, 0] ** 2 - np.repeat(np.asarray(quant, dtype=float) ** 2, 3)
    n = fits[:, 1]
    return bool(np.max(fits[:3, 0]) < TRUE_REST_ANGLE and np.all(3.0 * np.maximum(q2, 0.0) / TAU_MIN <= n * n))


def white_floor(step: float, dt: float, kind: str) -> float:
    """The white-noise density (unit/sqrt(s)) that a resolution of ``step`` sets at sample interval ``dt``: a
    rate log rounds every sample on its own, an error uniform over one step (variance ``step^2 / 12``, Widrow &
    Kollar 2008, "Quantization Noise", ch. 4), ``step sqrt(dt / 12)``.  An increment log's counters carry the
    remainder to the next sample (the error of any sum stays under one step: an Allan term in ``1/tau^2``, not
    white noise): no floor (0)."""
    if step <= 0.0 or dt <= 0.0 or kind != "rates":
        return 0.0
    return step * np.sqrt(dt / 12.0)


def rest_intervals(imu: ImuLog, fopts, gnss: GnssLog | None = None) -> list[tuple[float, float]]:
    """The merged intervals at rest ``(start, end)`` of the whole log: the fused filter's detector, each
    window kept unless the GNSS, when given, shows motion around it (:func:`sinscli.fusion.standstill.gnss_still`)."""
    det = StandstillDetector(fopts.standstill_window, fopts.standstill_rate_std, fopts.standstill_accel_std,
                             fopts.standstill_accel_mag, G_NOMINAL, fopts.standstill_lowpass)
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    a, b, _ = det.feed(imu.time, imu.dtheta_b, imu.dvel_b, t_start=t0)
    if gnss is not None and len(a):
        ok = gnss_still(gnss, a, b) != 0
        a, b = a[ok], b[ok]
    out = []
    for x, y in zip(a, b):
        if out and abs(out[-1][1] - x) <= 1e-9 * max(1.0, abs(x)):
            out[-1][1] = float(y)
        else:
            out.append([float(x), float(y)])
    return [(x, y) for x, y in out]


def _fit(tau, m, avar, rel, trapezoid):
    """``(Q, N, B, separated)`` of one axis (see the module docstring): ``separated`` when the white-noise
    coefficient ``N^2`` stands :data:`SEPARATION` standard errors clear of zero (the weighted least squares'
    covariance over the coefficients the fit keeps), i.e. when the fit tells white noise apart from the
    vibration and quantization (``1/tau^2``) and flicker terms."""
    white = (1.0 - 0.75 / m) / tau if trapezoid else 1.0 / tau
    A = np.column_stack([3.0 / tau ** 2, white, np.ones_like(tau)])
    scale = np.maximum(avar, 1e-300) * 2.0 * rel
    for _ in range(2):                                  # reweight with the model instead of the noisy curve
        coef, _ = _nnls_small(A / scale[:, None], avar / scale)
        model = A @ coef
        scale = np.where(model > 0, model, avar) * 2.0 * rel
    separated = False
    act = np.nonzero(coef > 0)[0]
    if coef[1] > 0 and act.size <= tau.size:
        Aw = A[:, act] / scale[:, None]
        cov = np.linalg.pinv(Aw.T @ Aw)
        k = int(np.nonzero(act == 1)[0][0])
        separated = bool(coef[1] >= SEPARATION * np.sqrt(max(cov[k, k], 0.0)))
    return (*np.sqrt(coef), separated)


def noise_from_rest(imu: ImuLog, fopts, gnss: GnssLog | None = None) -> RestNoise | None:
    """The :class:`~sinscli.fusion.noise.RestNoise` of the log's standstill windows (where the GNSS, when
    given, does not move); when they hold some rest but under ``MIN_REST`` s in all (or too few cluster times),
    one that says so (``fitted`` False, its rest time: the description's values kept, said in the summary);
    None without any rest."""
    if len(imu) < 10:
        return None
    # each interval less a detector window at both ends (where a start or a stop ramps in unseen)
    w = fopts.standstill_window
    windows = [(a + w, b - w) for a, b in rest_intervals(imu, fopts, gnss) if b - a - 2 * w >= MIN_WINDOW]
    t = imu.time
    # a span of uniform samples each: an Allan variance over a gap (dropped rows: one increment over two or more
    # intervals) would take the gap's increment for noise
    dtm = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    gaps = np.nonzero(np.diff(t) > GAP * dtm)[0] + 1
    spans = []
    for a, b in windows:
        i, j = int(np.searchsorted(t, a, side="right")), int(np.searchsorted(t, b, side="right"))
        cuts = [i] + [int(g) for g in gaps if i < g < j] + [j]
        for x, y in zip(cuts[:-1], cuts[1:]):
            if y - x >= 20:
                spans.append((x, y))
    if not spans:
        rest = sum(b - a for a, b in rest_intervals(imu, fopts, gnss))
        return _unfitted(rest) if rest > 0.0 else None
    if sum(t[j - 1] - t[i] for i, j in spans) < MIN_REST:
        return _unfitted(float(sum(t[j - 1] - t[i] for i, j in spans)))
    tau0 = float(np.median(np.diff(t)))
    n_max = max(j - i for i, j in spans)
    m_lo = max(1, int(round(TAU_MIN / tau0)))
    ms = np.unique(np.round(np.geomspace(m_lo, max(m_lo, n_max // 4), 16)).astype(np.int64))
    acc = np.zeros((ms.size, 6))
    wsum = np.zeros(ms.size)
    ksum = np.zeros(ms.size)
    sum_th = np.zeros(3)
    sum_dv = np.zeros(3)
    sum_dt = 0.0
    for i, j in spans:
        n = j - i
        inc = np.hstack([imu.dtheta_b[i:j], imu.dvel_b[i:j]])
        sum_th += imu.dtheta_b[i:j].sum(axis=0)
        sum_dv += imu.dvel_b[i:j].sum(axis=0)
        sum_dt += float(t[j - 1] - (t[i - 1] if i > 0 else t[i] - tau0))
        ok = ms <= n // 4
        if not ok.any():
            continue
        av = overlapping_avar(inc, tau0, ms[ok])
        w = (n + 1 - 2 * ms[ok]).astype(float)
        acc[ok] += av * w[:, None]
        wsum[ok] += w
        ksum[ok] += n / ms[ok]
    use = wsum > 0
    if use.sum() < 3:
        return _unfitted(float(sum(t[j - 1] - t[i] for i, j in spans)))
    tau = ms[use] * tau0
    avar = acc[use] / wsum[use][:, None]
    rel = 1.0 / np.sqrt(2.0 * np.maximum(ksum[use] - 1.0, 1.0))
    trap = imu.kind == "rates"
    fits = np.array([_fit(tau, ms[use].astype(float), avar[:, c], rel, trap) for c in range(6)])
    rest_s = float(sum(t[j - 1] - t[i] for i, j in spans))
    kind = "rates" if trap else "increments"
    return RestNoise(rest_seconds=rest_s, windows=len(spans), gyro_white=fits[:3, 1], accel_white=fits[3:, 1],
                     gyro_q=fits[:3, 0], accel_q=fits[3:, 0], gyro_mean=sum_th / sum_dt, accel_mean=sum_dv / sum_dt,
                     gyro_separated=fits[:3, 3] > 0, accel_separated=fits[3:, 3] > 0,
                     gyro_floor=white_floor(imu.resolution[0], tau0, kind),
                     accel_floor=white_floor(imu.resolution[1], tau0, kind),
                     true_rest=true_rest(fits, (0.0, 0.0) if trap else np.asarray(imu.resolution) / np.sqrt(3.0)))
