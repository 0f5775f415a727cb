"""``sins allan`` stage: a static IMU log -> Allan deviations, fitted noise terms, a sensor description.

``characterize(imu, ...)`` checks the interval (length, rest), computes the
overlapping Allan deviation of the three gyro and three accelerometer axes
(:mod:`.adev`), fits the noise terms (:mod:`.fit`) and maps them to the sensor
schema of ``sinscli/data/sensors/*.yaml`` (:mod:`sinscli.sensors`).  No file
I/O: the writers are in :mod:`.output`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..nav.imu_stats import block_deviations
from ..errors import SinsError
from ..sensors import ACCEL_UNITS, GYRO_UNITS
from ..types import ImuLog, time_tolerance
from .adev import adev_relative_sigma, cluster_sizes, overlapping_avar
from .fit import FLICKER_RATIO, GM_PEAK_RATIO, GM_PEAK_X, AxisFit, fit_axis

AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
MIN_SAMPLES = 1000
MIN_DURATION = 60.0          # s


@dataclass
class AllanResult:
    """Allan deviations (rad/s, m/s^2) at cluster times, their 1-sigma, and the fit of each axis."""
    tau: np.ndarray              # (T,) s
    m: np.ndarray                # (T,) samples per cluster
    adev: np.ndarray             # (T, 6) gyro x, y, z (rad/s), accel x, y, z (m/s^2)
    rel_sigma: np.ndarray        # (T,) relative 1-sigma of every deviation
    fits: list                   # 6 AxisFit
    tau0: float                  # s, sample interval
    n: int                       # samples
    t_start: float
    t_end: float
    source: str
    trapezoid: bool              # increments made from rate samples
    notes: list = field(default_factory=list)

    @property
    def duration(self) -> float:
        return self.n * self.tau0


def select(imu: ImuLog, start: float | None, end: float | None) -> ImuLog:
    """The samples of (start, end] (log time, s); the whole log when both are None."""
    t = imu.time
    tol = time_tolerance(float(t[-1]))
    for opt, v in (("--start", start), ("--end", end)):
        if v is not None and not (t[0] - tol - (t[1] - t[0]) <= v <= t[-1] + tol):
            raise SinsError(f"{imu.source}: {opt} {v!r} is outside the log ({float(t[0])!r} .. {float(t[-1])!r} s)")
    if start is not None and end is not None and end <= start:
        raise SinsError(f"--end {end!r} must be later than --start {start!r}")
    k0 = 0 if start is None else int(np.searchsorted(t, start + tol, side="right"))
    k1 = t.shape[0] if end is None else int(np.searchsorted(t, end + tol, side="right"))
    t0 = imu.t0 if k0 == 0 else float(t[k0 - 1])
    return ImuLog(t[k0:k1], imu.dtheta_b[k0:k1], imu.dvel_b[k0:k1], t0, imu.source, imu.kind, imu.resolution)


def check_static(imu: ImuLog, rate_limit: float, accel_limit: float, block: float) -> None:
    """Refuse a log whose block-mean rate or specific force departs from its mean (sins align's rest check)."""
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    dw, df = block_deviations(imu.time, imu.dtheta_b, imu.dvel_b, t0, block)
    bad_w, bad_f = dw > rate_limit, df > accel_limit
    if bad_w.any() or bad_f.any():
        k = int(np.argmax(bad_w | bad_f))
        kw, kf = int(np.argmax(dw)), int(np.argmax(df))
        raise SinsError(
            f"{imu.source}: not a static log: {block:g} s means off the interval's mean by up to "
            f"{math.degrees(dw[kw]):.3g} deg/s (limit {math.degrees(rate_limit):.3g}, at {kw * block:.1f} s) and "
            f"{df[kf]:.3g} m/s^2 (limit {accel_limit:.3g}, at {kf * block:.1f} s), first {k * block:.1f} s after "
            f"t = {t0!r} s; the Allan deviation needs the IMU at rest: choose a static stretch with --start/--end "
            "(limits: align.static_check in --config)")


def characterize(imu: ImuLog, start: float | None = None, end: float | None = None,
                 static_rate: float = math.radians(0.2), static_accel: float = 0.1, static_block: float = 1.0,
                 per_decade: int = 10, progress=None, on_sizes=None) -> AllanResult:
    """Allan deviations and noise fits of a static log; ``on_sizes(n)`` is told the number of cluster sizes,
    ``progress(1)`` is called after each."""
    if len(imu) < 2:
        raise SinsError(f"{imu.source}: the IMU log has {len(imu)} sample(s)")
    w = select(imu, start, end)
    n = len(w)
    dt = np.diff(w.time)
    tau0 = float(np.median(dt)) if n > 1 else 0.0
    if n < MIN_SAMPLES or n * tau0 < MIN_DURATION * (1.0 - 1e-9):
        raise SinsError(f"{imu.source}: {n} samples over {n * tau0:.4g} s; the Allan deviation needs at least "
                        f"{MIN_SAMPLES} samples and {MIN_DURATION:g} s (hours for the bias terms)")
    check_static(w, static_rate, static_accel, static_block)
    notes = []
    jitter = float(np.max(np.abs(dt - tau0))) / tau0
    if jitter > 0.5:
        notes.append(f"sample intervals vary by up to {100 * jitter:.0f} % of the median {tau0:.6g} s; the Allan "
                     "deviation treats the samples as evenly spaced")
    ms = cluster_sizes(n, per_decade)
    if on_sizes is not None:
        on_sizes(len(ms))
    avar = overlapping_avar((w.dtheta_b, w.dvel_b), tau0, ms, progress)
    rel = adev_relative_sigma(n, ms)
    # an axis whose deviation stays at the rounding level of its signal (1e-9 of the earth rate or of g)
    span = w.time[-1] - (w.t0 if w.t0 is not None else w.time[0] - tau0)
    scale = [max(float(np.linalg.norm(w.dtheta_b.sum(axis=0))) / span, 7.292115e-5),
             max(float(np.linalg.norm(w.dvel_b.sum(axis=0))) / span, 1.0)]
    flat = [AXES[c] for c in range(6) if not np.nanmax(np.sqrt(np.maximum(avar[:, c], 0))) > 1e-9 * scale[c // 3]]
    if flat:
        raise SinsError(f"{imu.source}: {', '.join(flat)}: the increments do not vary beyond rounding (a noise-free "
                        "log, e.g. sins simulate --perfect?); there is no noise to characterize")
    trapezoid = w.kind == "rates"
    tau = ms * tau0
    fits = [fit_axis(tau, ms, avar[:, c], rel, n, trapezoid) for c in range(6)]
    return AllanResult(tau=tau, m=ms, adev=np.sqrt(avar), rel_sigma=rel, fits=fits, tau0=tau0, n=n,
                       t_start=float(w.t0 if w.t0 is not None else w.time[0] - tau0), t_end=float(w.time[-1]),
                       source=w.source, trapezoid=trapezoid, notes=notes)


# --------------------------------------------------------------------------- the sensor description

def sensor_values(fits: list[AxisFit]) -> dict:
    """``{"gyro": {key: [x, y, z]}, "accel": {...}}`` in the units of the sensor YAML schema, plus
    ``{"<which>_notes": [...]}`` saying what is not identifiable.

    Keys written: ``arw``/``vrw``; ``bias_instability`` and ``bias_tau`` on every axis (the fusion filter
    needs them): the fitted Gauss-Markov term where identified, else the largest one the curve allows, the
    Gauss-Markov curve whose peak touches the curve's minimum (``sigma = min ADEV / 0.6174``,
    ``T = tau_min / 1.8926``), an upper bound; ``quantization`` where identified; ``bias_sigma`` 0.
    """
    out = {}
    for which, units, white_key, sl in (("gyro", GYRO_UNITS, "arw", slice(0, 3)),
                                        ("accel", ACCEL_UNITS, "vrw", slice(3, 6))):
        f = fits[sl]
        d = {white_key: [x.white / units[white_key] for x in f], "bias_sigma": [0.0, 0.0, 0.0]}
        notes = []
        gm = [x.identified["gauss_markov"] for x in f]
        bound = [(x.flicker_b * FLICKER_RATIO / GM_PEAK_RATIO, x.tau_min_adev / GM_PEAK_X) for x in f]
        d["bias_instability"] = [(x.gm_sigma if ok else b[0]) / units["bias_instability"]
                                 for x, ok, b in zip(f, gm, bound)]
        d["bias_tau"] = [x.gm_tau if ok else b[1] for x, ok, b in zip(f, gm, bound)]
        if not all(gm):
            axes = ", ".join("xyz"[i] for i, ok in enumerate(gm) if not ok)
            notes.append(f"bias instability not identifiable on axis {axes} (no Gauss-Markov hump with its peak "
                         "inside the log; a log of about 17 correlation times is needed): written as the upper "
                         "bound, the Gauss-Markov curve whose peak touches the Allan deviation's minimum")
        q = [x.identified["quantization"] for x in f]
        if any(q):
            d["quantization"] = [math.sqrt(12.0) * x.quantization if ok else 0.0 for x, ok in zip(f, q)]
        rrw_unit = units["bias_instability"] / math.sqrt(3600.0)      # per sqrt(h)
        out[which] = d
        out[f"{which}_notes"] = notes
        out[f"{which}_rrw"] = ([x.rrw / rrw_unit for x in f], [x.identified["rate_random_walk"] for x in f])
    return out
