"""The sensor error budget of an alignment: the sensor description, checked against the log itself.

Every 1-sigma ``sins align`` writes is computed from one :class:`Budget` (SI units, per axis, the
largest axis): the constant gyro and accelerometer bias over the interval, their white noise (ARW,
VRW), scale factor and misalignment, and the bias instability as a random walk (the Kalman filter's
process noise).  Where the figures come from:

* **Noise, always from the data as well.**  The rate (specific force) averaged over clusters of m
  samples, differenced three times (which removes any motion quadratic over four clusters), gives
  ``N^2 = var * tau / 20`` for white noise of density N (a Hadamard-like variance); the scale is the
  median absolute deviation, so manoeuvres and glitches do not count.  m = 1, 2, 4, 8 (clusters up to
  0.25 s) are tried and the largest estimate is kept, stopping where it jumps by more than 3x (motion
  of the base, not noise); taking the largest covers noise that the sensor or the rate-to-increment
  conversion smoothed at the sample interval, and counts quantization as noise (conservative).  The
  noise used is the larger of the description's and this estimate at its upper confidence limit.
* **Is the description optimistic?**  The same statistic is predicted from the description (its noise
  and quantization added to the smoothed log and put through the same estimator); a log noisier than
  that by a factor k > 1 makes every figure of that sensor's description suspect by the same factor:
  its bias, scale factor and misalignment are multiplied by k.
* **Bias components the data show.**  Where the log holds a stretch at rest (>= ``REST_MIN`` s), the
  mean specific force and rate give three bias components directly: the vertical accelerometer bias
  ``|f| - g``, and of the gyro the vertical ``w . up - W_ie sin L`` and the north one ``|w_h| - W_ie
  cos L`` (the east one is what the earth-rate heading cannot tell from a heading error, and the
  horizontal accelerometer biases what the tilt cannot tell from a tilt).  A description whose bias
  these reject (chi-square above its 99 % point) is replaced by the data's figure below.
* **Without a description** (or with one the data reject), the bias 1-sigma is taken from those
  components, assuming the axes of one sensor share a bias magnitude: with n components of mean
  square s^2 the unseen component follows a Student t with n degrees of freedom, and the reported
  1-sigma is ``s t_n(0.995) / z(0.995)`` (so that 3 of it covers the unseen bias as often as 3 sigma
  of a known Gaussian would cover 99 %): x24.7 for one component, x3.85 for two.  Without rest and
  without a description the bias is only bounded by ``BIAS_CAP`` (any working IMU) and the fit that
  uses the budget (:mod:`.fit`) estimates what the motion makes observable.

No I/O here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..nav.earth import OMEGA_IE
from ..nav import imu_stats

DEG = math.pi / 180.0
UG = 9.80665e-6
# physical bounds on a working IMU's constant bias (a consumer MEMS: a few deg/s, tens of mg)
BIAS_CAP = {"gyro": 2.0 * DEG, "accel": 0.5}
# and on its gyro scale factor and misalignment, when no description gives them (the fits estimate
# what the turns make observable)
GYRO_SF_CAP = 0.01
GYRO_MIS_CAP = 1.0 * DEG
REST_MIN = 10.0          # s of rest needed to read bias components from the means
G_NOMINAL = 9.80665      # m/s^2: scale of the specific force at rest (for scale-factor terms)
REST_FORCE = 1.0         # m/s^2: |f| - g at rest is at most this (the largest accelerometer bias)
Z995 = 2.5758293035489   # standard normal 99.5 % point
# Student t 99.5 % points (two-sided 99 %) by degrees of freedom
_T995 = {1: 63.657, 2: 9.925, 3: 5.841, 4: 4.604, 5: 4.032, 6: 3.707, 7: 3.499, 8: 3.355, 9: 3.250,
         10: 3.169, 12: 3.055, 15: 2.947, 20: 2.845, 30: 2.750, 60: 2.660}


def t995(dof: float) -> float:
    """Student t 99.5 % point (interpolated in 1/dof between the tabulated values)."""
    if dof < 1:
        return _T995[1]
    keys = sorted(_T995)
    if dof >= keys[-1]:
        x = 1.0 / dof
        return Z995 + (_T995[60] - Z995) * x * 60.0
    for a, b in zip(keys, keys[1:]):
        if a <= dof <= b:
            f = (1.0 / dof - 1.0 / a) / (1.0 / b - 1.0 / a)
            return _T995[a] + f * (_T995[b] - _T995[a])
    return Z995


def chi2_99(dof: float) -> float:
    """Chi-square 99 % point (Wilson-Hilferty; exact to ~1 % from 1 degree of freedom up)."""
    if dof <= 1.0:
        return 6.635
    if dof <= 2.0:
        return 9.210
    z = 2.3263478740408408
    a = 2.0 / (9.0 * dof)
    return dof * (1.0 - a + z * math.sqrt(a)) ** 3


def student_sigma(values, sigma_meas=None):
    """Bias 1-sigma from observed components ``values`` (see the module docstring): ``(sigma, s, n)``."""
    x = np.asarray(values, dtype=float)
    n = x.size
    if n == 0:
        return None, None, 0
    s = float(np.sqrt(np.mean(x ** 2)))
    if sigma_meas is not None:
        s = max(s, float(np.max(sigma_meas)))
    return s * t995(n) / Z995, s, n


# --------------------------------------------------------------------------- noise from the data

NOISE_CLUSTERS = (1, 2, 4, 8)
NOISE_MAX_TAU = 0.25     # s: the longest cluster (longer ones see the base's motion)
NOISE_JUMP = 3.0         # an estimate this much above the previous cluster's is motion, not noise


def _hadamard3(inc, dt, m):
    """White-noise density per axis (unit/sqrt(s)) from third differences of m-sample cluster means
    (median absolute deviation scale); ``(N (3,), clusters)`` or ``(None, k)`` when too short."""
    n = (inc.shape[0] // m) * m
    k = n // m
    if k < 30:
        return None, k
    c = inc[:n].reshape(k, m, 3).sum(axis=1)
    tau = dt[:n].reshape(k, m).sum(axis=1)
    y = c / tau[:, None]
    d = y[3:] - 3.0 * y[2:-1] + 3.0 * y[1:-2] - y[:-3]
    if d.shape[0] > ALLAN_MAX:                   # the MAD of an even subsample: as good, much faster
        d = d[:: d.shape[0] // ALLAN_MAX + 1]
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return 1.482602218505602 * mad * math.sqrt(float(np.median(tau)) / 20.0), k


def noise_statistic(inc, dt):
    """Data noise density (largest axis) by :func:`_hadamard3` over the cluster sizes of the module
    docstring: ``(N, N_upper, m)`` (``N_upper`` at the upper confidence limit) or ``(0, 0, 0)``."""
    inc = np.asarray(inc, dtype=float)
    dt = np.asarray(dt, dtype=float)
    step = float(np.median(dt)) if dt.size else 0.0
    best, best_up, best_m, prev = 0.0, 0.0, 0, None
    for m in NOISE_CLUSTERS:
        if m > 1 and m * step > NOISE_MAX_TAU:
            break
        N, k = _hadamard3(inc, dt, m)
        if N is None:
            break
        v = float(N.max())
        if prev is not None and prev > 0.0 and v > NOISE_JUMP * prev:
            break
        prev = v
        if v >= best:
            # the MAD scale of k cluster differences: relative standard error ~1.7/sqrt(k) (third
            # differences overlap); upper limit at 2.5 standard errors
            best, best_up, best_m = v, v * (1.0 + 2.5 * 1.7 / math.sqrt(k)), m
    return best, best_up, best_m


ALLAN_MAX = 1 << 17        # samples of a rest stretch for its Allan variance (plenty for white noise)


def allan_white(inc, dt, max_frac=0.1):
    """White-noise density of a stretch at rest from its Allan variance: ``(N, N_upper)`` (largest axis)
    or None.

    The overlapping Allan variance of the rate (the first ``ALLAN_MAX`` samples) at cluster times
    ``tau`` from one sample to ``max_frac`` of the stretch is fitted (weighted least squares, non-negative) by
    ``N^2 / tau + 3 Q^2 / tau^2``: white noise and quantization (which the short clusters of
    :func:`noise_statistic` cannot tell apart).  ``N_upper`` is 2.5 standard errors above."""
    inc = np.asarray(inc, dtype=float)[:ALLAN_MAX]
    dt = np.asarray(dt, dtype=float)[:ALLAN_MAX]
    n = inc.shape[0]
    step = float(np.median(dt))
    m_max = int(n * max_frac)
    if m_max < 4:
        return None
    ms = np.unique(np.round(np.logspace(0, math.log10(m_max), 24)).astype(np.int64))
    from ..allan.adev import overlapping_avar          # the project's one Allan variance
    avar = overlapping_avar(inc, step, ms)
    best = None
    for i in range(3):
        tau = ms * step
        av = avar[:, i]
        neff = np.maximum(n / ms - 1.0, 1.0)
        wsd = av * np.sqrt(2.0 / neff)                        # 1-sigma of each Allan variance
        A = np.stack([1.0 / tau, 3.0 / tau ** 2], axis=-1) / wsd[:, None]
        y = av / wsd
        x, cov = _nnls2(A, y)
        if x is None:
            continue
        N2, se = x[0], math.sqrt(max(cov[0, 0], 0.0))
        if best is None or N2 > best[0]:
            best = (N2, se)
    if best is None or best[0] <= 0.0:
        return None
    N2, se = best
    return math.sqrt(N2), math.sqrt(N2 + 2.5 * se)


def _nnls2(A, y):
    """Least squares with two non-negative unknowns: ``(x, covariance)`` (None when degenerate)."""
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    if np.all(x >= 0.0):
        return x, np.linalg.pinv(A.T @ A)
    out = np.zeros(2)
    # one term only: the white noise (quantization zero)
    a = A[:, 0]
    out[0] = max(float(a @ y / (a @ a)), 0.0)
    cov = np.zeros((2, 2))
    cov[0, 0] = 1.0 / float(a @ a)
    return out, cov


def predicted_noise_statistic(signal_rate, dt, density, quant, m, seed=0):
    """The statistic :func:`_hadamard3` at cluster size ``m`` would give for a sensor of white-noise
    ``density`` and carried quantization ``quant`` (per count) measuring the noise-free rate
    ``signal_rate`` (n, 3): the described errors added to it and put through the same estimator (the
    quantization's share depends on the signal, so it is simulated rather than written in closed form)."""
    from ..sim.errors import quantize
    dt = np.asarray(dt, dtype=float)
    rng = np.random.default_rng(seed + 0x5EED)
    syn = np.asarray(signal_rate, dtype=float) * dt[:, None] + float(density) * np.sqrt(dt)[:, None] * \
        rng.standard_normal((dt.size, 3))
    q = float(quant or 0.0)
    if q > 0.0:
        syn = quantize(np.ascontiguousarray(syn), np.full(3, q))
    N, _ = _hadamard3(syn, dt, m)
    return 0.0 if N is None else float(N.max())


def smooth_rate(inc, dt, t_rel, block=1.0):
    """The rate of a log with its noise averaged out: block means over ``block`` s, linearly
    interpolated to the samples (the signal for :func:`predicted_noise_statistic`)."""
    inc = np.asarray(inc, dtype=float)
    nb = max(int(t_rel[-1] // block), 1)
    edges = np.searchsorted(t_rel, np.arange(1, nb + 1) * block - 1e-9 * block)
    edges = np.unique(np.clip(np.concatenate([[0], edges]), 0, len(t_rel)))
    mids, means = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        if b > a:
            means.append(inc[a:b].sum(axis=0) / dt[a:b].sum())
            mids.append(0.5 * (t_rel[a] + t_rel[b - 1]))
    mids = np.array(mids)
    means = np.array(means)
    return np.stack([np.interp(t_rel, mids, means[:, i]) for i in range(3)], axis=-1)


# --------------------------------------------------------------------------- rest and its components

def rest_span(time, dtheta_b, dvel_b, t0, g, rate_tol, accel_tol, block=1.0):
    """The longest run of ``block``-s blocks at rest: ``(k0, k1)`` sample slice or None.

    A block is at rest when its mean rate and force differ from the previous block's by less than
    ``rate_tol``/``accel_tol``, its rate is below 2 deg/s (no turn) and its specific force has
    magnitude g within ``REST_FORCE`` (a large accelerometer bias shifts it; steady acceleration
    barely does, so the block-to-block change is the test of motion)."""
    t = np.asarray(time, dtype=float) - t0
    if t[-1] < 2.0 * block:
        return None
    wb, fb = imu_stats.block_means(time, dtheta_b, dvel_b, t0, block)
    nb = wb.shape[0]
    quiet = np.abs(np.linalg.norm(fb, axis=1) - g) < REST_FORCE
    quiet &= np.linalg.norm(wb, axis=1) < 2.0 * DEG
    dw = np.r_[0.0, np.linalg.norm(np.diff(wb, axis=0), axis=1)]
    df = np.r_[0.0, np.linalg.norm(np.diff(fb, axis=0), axis=1)]
    quiet &= (dw < rate_tol) & (df < accel_tol)
    best, cur, best_end = 0, 0, -1
    for i in range(nb):
        cur = cur + 1 if quiet[i] else 0
        if cur > best:
            best, best_end = cur, i
    if best * block < REST_MIN:
        return None
    b0 = best_end - best + 1
    k0 = int(np.searchsorted(t, b0 * block + 1e-9 * block, side="left"))
    k1 = int(np.searchsorted(t, (best_end + 1) * block + 1e-9 * block, side="right"))
    return k0, min(k1, len(t))


def rest_components(w_mean_b, f_mean_b, lat, g, T, arw, vrw):
    """Bias components seen at rest (module docstring) and their measurement 1-sigma:
    ``(gyro [vertical, north] rad/s, gyro sigma, accel [vertical] m/s^2, accel sigma)``."""
    f = np.asarray(f_mean_b, dtype=float)
    w = np.asarray(w_mean_b, dtype=float)
    up = f / np.linalg.norm(f)
    w_up = float(w @ up)
    w_h = float(np.linalg.norm(w - w_up * up))
    gyro = np.array([w_up - OMEGA_IE * math.sin(lat), w_h - OMEGA_IE * math.cos(lat)])
    accel = np.array([float(np.linalg.norm(f)) - g])
    return gyro, arw / math.sqrt(T), accel, vrw / math.sqrt(T)


# --------------------------------------------------------------------------- the budget

@dataclass
class Budget:
    """Sensor errors for the error budget (SI, 1-sigma per axis) and where each came from."""
    gyro_bias: float
    gyro_arw: float
    accel_bias: float
    accel_vrw: float
    source: str = "config"           # config | data | config+data
    gyro_sf: float = 0.0
    accel_sf: float = 0.0
    gyro_mis: float = 0.0            # rad
    accel_mis: float = 0.0           # rad
    gyro_bias_rw: float = 0.0        # rad/s/sqrt(s): bias instability as a random walk (2 sigma^2 / tau)
    accel_bias_rw: float = 0.0
    # the prior the estimators use (the data's point scale where the reported figure is its Student t
    # inflation: a Gaussian prior as wide as the t's tail would let the fit trade a tilt for a bias it
    # cannot see); the reported covariance is that estimate's error under the reported prior
    gyro_bias_est: float | None = None
    accel_bias_est: float | None = None
    gyro_sf_est: float | None = None
    gyro_mis_est: float | None = None
    data_gyro_bias: float = 0.0      # rad/s: the bias scale the rest components show (not inflated)
    data_gyro_arw: float = 0.0       # rad/sqrt(s): the noise the log shows (point estimate)
    data_accel_vrw: float = 0.0
    bias_known: dict = field(default_factory=lambda: {"gyro": True, "accel": True, "matrix": True})
    optimism: dict = field(default_factory=lambda: {"gyro": 1.0, "accel": 1.0})
    detail: dict = field(default_factory=dict)     # term -> where it came from (for the output and notes)
    notes: list = field(default_factory=list)

    def __post_init__(self):
        if self.gyro_bias_est is None:
            self.gyro_bias_est = self.gyro_bias
        if self.accel_bias_est is None:
            self.accel_bias_est = self.accel_bias
        if self.gyro_sf_est is None:
            self.gyro_sf_est = self.gyro_sf
        if self.gyro_mis_est is None:
            self.gyro_mis_est = self.gyro_mis

    def summary(self) -> dict:
        """The figures used, in the units of the config (deg/h, deg/sqrt(h), micro-g, micro-g/sqrt(Hz))."""
        return {"gyro_bias": self.gyro_bias / DEG * 3600.0, "gyro_arw": self.gyro_arw / DEG * 60.0,
                "accel_bias": self.accel_bias / UG, "accel_vrw": self.accel_vrw / UG,
                "gyro_scale_factor": self.gyro_sf * 1e6, "accel_scale_factor": self.accel_sf * 1e6,
                "gyro_misalignment": self.gyro_mis / DEG * 3600.0,
                "accel_misalignment": self.accel_mis / DEG * 3600.0,
                "from": dict(self.detail)}


@dataclass
class Evidence:
    """What the log shows about its sensors (see the module docstring)."""
    arw: float                  # rad/sqrt(s), point estimate
    arw_up: float               # upper confidence limit
    vrw: float
    vrw_up: float
    m_gyro: int                 # cluster size of the noise estimates
    m_accel: int
    rest: tuple | None          # (k0, k1) sample slice at rest
    rest_T: float = 0.0
    rest_arw: tuple | None = None   # (N, N_upper) from the Allan variance at rest
    rest_vrw: tuple | None = None
    gyro_comp: np.ndarray | None = None
    gyro_comp_sigma: float = 0.0
    accel_comp: np.ndarray | None = None
    accel_comp_sigma: float = 0.0


def gather_evidence(time, dtheta_b, dvel_b, t0, lat, g, rate_tol, accel_tol, block=1.0) -> Evidence:
    """Noise and rest components of one window of increments."""
    dt = np.diff(np.concatenate([[t0], time]))
    arw, arw_up, mg = noise_statistic(dtheta_b, dt)
    vrw, vrw_up, ma = noise_statistic(dvel_b, dt)
    ev = Evidence(arw, arw_up, vrw, vrw_up, mg, ma, None)
    span = rest_span(time, dtheta_b, dvel_b, t0, g, rate_tol, accel_tol, block)
    if span is not None:
        k0, k1 = span
        ts = t0 if k0 == 0 else float(time[k0 - 1])
        T = float(time[k1 - 1] - ts)
        w_mean = dtheta_b[k0:k1].sum(axis=0) / T
        f_mean = dvel_b[k0:k1].sum(axis=0) / T
        dtr = dt[k0:k1]
        # at rest the Allan variance tells white noise from quantization: it replaces the short
        # clusters' estimate, which counts quantization as noise
        ev.rest_arw = allan_white(dtheta_b[k0:k1], dtr)
        ev.rest_vrw = allan_white(dvel_b[k0:k1], dtr)
        if ev.rest_arw is not None:
            ev.arw, ev.arw_up = ev.rest_arw
            arw_up = ev.arw_up
        if ev.rest_vrw is not None:
            ev.vrw, ev.vrw_up = ev.rest_vrw
            vrw_up = ev.vrw_up
        gc, gs, ac, as_ = rest_components(w_mean, f_mean, lat, g, T, arw_up, vrw_up)
        ev.rest, ev.rest_T = span, T
        ev.gyro_comp, ev.gyro_comp_sigma, ev.accel_comp, ev.accel_comp_sigma = gc, gs, ac, as_
    return ev


def _fmt(which, v):
    if which == "gyro":
        return f"{v / DEG * 3600.0:.3g} deg/h"
    return f"{v / UG:.3g} micro-g"


def resolve(spec, ev: Evidence, time=None, dtheta_b=None, dvel_b=None, t0=None, quasi_static=False) -> Budget:
    """The budget from a description ``spec`` (:class:`~sinscli.align.options.SensorSpec`, fields
    None where unknown) and the evidence of the log (module docstring).  The increments are needed
    only to predict the noise statistic of a description that gives quantization or noise.
    ``quasi_static``: the base stays where it is (no vehicle vibration), so without a stretch at rest
    the sample-rate noise statistic may judge the description as the Allan variance at rest does."""
    notes, detail = [], {}
    used = set()
    out = {}
    dt = None if time is None else np.diff(np.concatenate([[t0], time]))
    for which, noise_key, data_n, data_up, m, inc, rest_n in (
            ("gyro", "gyro_arw", ev.arw, ev.arw_up, ev.m_gyro, dtheta_b, ev.rest_arw),
            ("accel", "accel_vrw", ev.vrw, ev.vrw_up, ev.m_accel, dvel_b, ev.rest_vrw)):
        cfg_n = getattr(spec, noise_key)
        k = 1.0
        if cfg_n is None:
            out[noise_key] = data_up
            detail[noise_key] = "data"
            used.add("data")
        else:
            q = getattr(spec, f"{which}_quant") or 0.0
            if rest_n is not None:
                # the Allan variance at rest: the white noise itself, against the description's
                k = max(1.0, rest_n[0] / cfg_n) if cfg_n > 0 else math.inf
            elif inc is not None and m > 0 and data_n > 0.0:
                # on a moving base the short clusters also see vibration: the noise figure is raised
                # to them, but the description's other figures are not judged by them
                # (white noise alone gives the density itself; quantization only adds, and a noise-free
                # quantized signal can make the median absolute deviation 0)
                pred = max(predicted_noise_statistic(smooth_rate(inc, dt, np.asarray(time) - t0), dt, cfg_n, q, m),
                           cfg_n)
                if quasi_static:
                    # a base that stays where it is moves slowly: one-sample clusters see its noise alone
                    # (longer ones may see a sway); the description predicts them on a constant rate
                    d1, _ = _hadamard3(inc, dt, 1)
                    mean_rate = np.broadcast_to(inc.sum(axis=0) / dt.sum(), inc.shape)
                    p1 = max(predicted_noise_statistic(mean_rate, dt, cfg_n, q, 1), cfg_n)
                    if d1 is not None and p1 > 0.0:
                        k = max(1.0, float(d1.max()) / p1)
                elif pred > 0.0 and data_n / pred > 1.5:
                    notes.append(f"the log's {which} noise at the sample rate is {data_n / pred:.3g}x what the "
                                 f"sensor description predicts (vibration or noise; no rest to tell): the noise "
                                 f"figure is raised to it")
            if data_up > cfg_n:
                out[noise_key] = data_up
                detail[noise_key] = "data (above the description)"
                used.add("data")
            else:
                out[noise_key] = cfg_n
                detail[noise_key] = "config"
                used.add("config")
        if k > 1.5:
            notes.append(f"the log's {which} noise is {k:.3g}x what the sensor description predicts: its "
                         f"{which} figures are taken {min(k, 1e6):.3g}x larger")
        # bias
        cfg_b = getattr(spec, f"{which}_bias")
        comp = ev.gyro_comp if which == "gyro" else ev.accel_comp
        comp_s = ev.gyro_comp_sigma if which == "gyro" else ev.accel_comp_sigma
        data_sigma, s, n = student_sigma(comp, comp_s) if comp is not None else (None, None, 0)
        known = True
        est = None               # the prior the estimators use, where it differs from the reported one
        if cfg_b is not None and math.isfinite(k):
            b = cfg_b * k
            src = "config" if k < 1.05 else f"config x{k:.3g} (the log's noise)"
            if comp is not None:
                # what the components see besides the bias: the scale factor (and misalignment) times g
                extra = 0.0
                if which == "accel":
                    extra = (G_NOMINAL * k * math.hypot(spec.accel_sf or 0.0, spec.accel_mis or 0.0)) ** 2
                var = b ** 2 + extra + comp_s ** 2
                chi2 = float(np.sum(comp ** 2) / var) if var > 0 else math.inf
                if chi2 > chi2_99(n):
                    notes.append(f"the {which} bias the log shows at rest ({_fmt(which, s)} rms over {n} "
                                 f"component(s)) is not consistent with the description's "
                                 f"{_fmt(which, b)}: the {which} bias is taken from the data")
                    est = max(b, s)
                    b = max(b, data_sigma)
                    src = f"data ({n} component(s) at rest, Student t)"
            used.add("config" if src.startswith("config") else "data")
        elif comp is not None:
            b, est = data_sigma, s
            src = f"data ({n} component(s) at rest, Student t)"
            used.add("data")
        else:
            b = BIAS_CAP[which]
            src = "unknown (bounded by a working IMU's)"
            known = False
            used.add("data")
        if which == "gyro" and s is not None:
            out["data_gyro_bias"] = s
        out[f"{which}_bias"] = b
        out[f"{which}_bias_est"] = b if est is None else est
        detail[f"{which}_bias"] = src
        out.setdefault("bias_known", {"matrix": True})[which] = known
        out.setdefault("optimism", {})[which] = k if math.isfinite(k) else 1e6
        kk = k if math.isfinite(k) else 1e6
        for term in ("sf", "mis"):
            v = getattr(spec, f"{which}_{term}")
            if v is None and which == "gyro" and not spec.given:
                out[f"{which}_{term}"] = GYRO_SF_CAP if term == "sf" else GYRO_MIS_CAP
                detail[f"{which}_{term}"] = "unknown (bounded by a working IMU's)"
                out["bias_known"]["matrix"] = False
            else:
                out[f"{which}_{term}"] = 0.0 if v is None else v * kk
        v = getattr(spec, f"{which}_bias_rw")
        out[f"{which}_bias_rw"] = 0.0 if v is None else v * kk
    src = "+".join(sorted(used, key=lambda x: x != "config"))
    return Budget(gyro_bias=out["gyro_bias"], gyro_arw=out["gyro_arw"], accel_bias=out["accel_bias"],
                  accel_vrw=out["accel_vrw"], source=src, gyro_sf=out["gyro_sf"], accel_sf=out["accel_sf"],
                  gyro_mis=out["gyro_mis"], accel_mis=out["accel_mis"], gyro_bias_rw=out["gyro_bias_rw"],
                  accel_bias_rw=out["accel_bias_rw"], gyro_bias_est=out["gyro_bias_est"],
                  accel_bias_est=out["accel_bias_est"], data_gyro_bias=out.get("data_gyro_bias", 0.0),
                  data_gyro_arw=ev.arw, data_accel_vrw=ev.vrw, bias_known=out["bias_known"],
                  optimism=out["optimism"], detail=detail, notes=notes)
