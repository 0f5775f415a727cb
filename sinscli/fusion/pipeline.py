"""The fusion stage: IMU blocks + GNSS (+ body velocity) + initial state -> fused trajectory chunks,
innovation records and a summary.  No file I/O: readers and writers are the CLI's.

``Fusion(init, nav_opts, fopts, gnss, ...)`` prepares the measurement rows, the filter model from one
sensor description (:func:`filter_model`) and the initial covariance; ``feed(block)`` runs the numba
kernel (:func:`sinscli.fusion.kernel.fuse`) on a block and returns its output rows;
``finish()`` runs the smoother when asked (:mod:`sinscli.fusion.smoother`) and the summary.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..nav import strapdown as sd
from ..nav.earth import dlon, gravity, radii_py
from ..nav.pipeline import BLOCK, NavOptions, concat, stream_blocks
from ..nav.rotation import conv_to_flu
from ..sensors import G0, load_sensor
from ..types import GnssLog, ImuLog, NavState, Trajectory, time_tolerance
from . import kernel as kn
from .model import BA, BG, PHI, SA, SG, V, sparsity
from .options import FusionOptions
from .standstill import StandstillDetector

log = logging.getLogger("sins")

DEG = math.pi / 180.0
DEFAULT_SENSOR = "mems"
REQUIRED_TERMS = {"gyro": ("arw", "bias_sigma", "bias_instability", "bias_tau"),
                  "accel": ("vrw", "bias_sigma", "bias_instability", "bias_tau")}
PRIO = {kn.MT_COURSE: 0, kn.MT_GNSS_POS: 1, kn.MT_GNSS_VEL: 2, kn.MT_ZUPT: 3, kn.MT_ZARU: 4, kn.MT_NHC: 5,
        kn.MT_ODOM: 6}
AXES = np.array(["e", "n", "u", "x", "y", "z"])
INNOVATION_DTYPE = np.dtype([("time", "f8"), ("type", "U16"), ("axis", "U8"), ("innovation", "f8"),
                             ("sigma", "f8"), ("nis", "f8"), ("accepted", "?")])
SIGMA_COLUMNS = ["pos_e_std", "pos_n_std", "pos_u_std", "vel_e_std", "vel_n_std", "vel_u_std",
                 "roll_std", "pitch_std", "heading_std"]
BIAS_COLUMNS = ["gyro_bias_x", "gyro_bias_y", "gyro_bias_z", "accel_bias_x", "accel_bias_y", "accel_bias_z"]
SF_COLUMNS = ["gyro_sf_x", "gyro_sf_y", "gyro_sf_z", "accel_sf_x", "accel_sf_y", "accel_sf_z"]


def fusion_columns(states: int) -> list[str]:
    """The extra trajectory columns of a fused trajectory (docs/formats.md aided-trajectory columns)."""
    return SIGMA_COLUMNS + BIAS_COLUMNS + (SF_COLUMNS if states == 21 else [])


@dataclass
class FilterModel:
    """Noise densities and initial sensor variances from one sensor description (SI)."""
    arw2: np.ndarray            # (3,) rad^2/s
    vrw2: np.ndarray            # (3,) (m/s)^2/s
    q_bg: np.ndarray            # (3,) Gauss-Markov densities 2 sigma^2 / tau
    q_ba: np.ndarray
    inv_tau_g: np.ndarray
    inv_tau_a: np.ndarray
    p0_bg: np.ndarray           # (3,) initial variances
    p0_ba: np.ndarray
    p0_sg: np.ndarray
    p0_sa: np.ndarray
    sfmis_g: float              # sigma_sf^2 + sigma_mis^2 (unestimated part), gyro
    sfmis_a: float
    source: str                 # where it came from (for the summary)
    default: bool = False
    assumed: list = field(default_factory=list)     # terms taken from the default preset (unknown)


def filter_model(spec, base_dir, states: int, src: str, bias_model: str = "gm-noise") -> FilterModel:
    """The filter's noise model from a sensor preset/file (None: the stated conservative default)."""
    default = spec is None
    spec = DEFAULT_SENSOR if default else spec
    sens = load_sensor(spec, None, src, Path(base_dir) if base_dir is not None else Path.cwd())
    where = f"<preset {spec}>" if isinstance(spec, str) and spec.lower() in ("mems", "tactical", "navigation") \
        else (str(spec) if not isinstance(spec, dict) else f"{src}: fusion.sensor")
    for which, keys in REQUIRED_TERMS.items():
        for k in keys:
            if k not in sens[which]:
                raise SinsError(f"{where}: {which}.{k}: missing; the fusion filter needs {', '.join(keys)} "
                                f"of the {which}")
    g, a = sens["gyro"], sens["accel"]
    assumed = _fill_unknown_terms(sens, src)

    def gm(d):
        # bias_model (docs/fusion.md): "gm-noise", the Gauss-Markov density 2 sigma^2 / tau with F = 0 (a
        # random walk, the GM's own growth for t << tau; the filter's bias error also holds the turn-on
        # part, which does not decay); "gm-decay", F = -1/tau on the whole bias error as the GM prescribes
        # (its variance then shrinks unobserved toward sigma_BI^2: overconfident, Monte Carlo NEES).
        q = 2.0 * d["bias_instability"] ** 2 / d["bias_tau"]
        return q, (1.0 / d["bias_tau"] if bias_model == "gm-decay" else np.zeros(3))

    q_bg, itg = gm(g)
    q_ba, ita = gm(a)
    sf_g = g.get("scale_factor_sigma", np.zeros(3))
    sf_a = a.get("scale_factor_sigma", np.zeros(3))
    mis_g = g.get("misalignment_sigma", np.zeros(6))
    mis_a = a.get("misalignment_sigma", np.zeros(6))
    est_sf = states == 21
    sfmis_g = float((0.0 if est_sf else np.max(sf_g) ** 2) + 2.0 * np.max(mis_g) ** 2)
    sfmis_a = float((0.0 if est_sf else np.max(sf_a) ** 2) + 2.0 * np.max(mis_a) ** 2)
    # under gravity alone, scale factor and misalignment are a constant accelerometer bias
    grav = (np.max(mis_a) ** 2 * 2.0 + (0.0 if est_sf else np.max(sf_a) ** 2)) * G0 ** 2
    p0_ba = a["bias_sigma"] ** 2 + a["bias_instability"] ** 2 + grav
    p0_bg = g["bias_sigma"] ** 2 + g["bias_instability"] ** 2
    return FilterModel(g["arw"] ** 2, a["vrw"] ** 2, q_bg, q_ba, itg, ita, p0_bg, p0_ba,
                       np.maximum(sf_g, 1e-6) ** 2, np.maximum(sf_a, 1e-6) ** 2, sfmis_g, sfmis_a,
                       where + (" (no sensor given: conservative default)" if default else ""), default,
                       assumed)


def _fill_unknown_terms(sens: dict, src: str) -> list:
    """Terms a sensor description leaves unknown take the conservative default preset's values (said in
    the summary): a missing scale factor or misalignment (a description from ``sins allan`` has none),
    and a ``bias_sigma`` of 0 (what ``sins allan`` writes: a static log cannot observe the turn-on bias,
    so 0 means unknown, not perfect).  Returns the notes."""
    ref = load_sensor(DEFAULT_SENSOR, None, src, Path.cwd())
    notes = []
    for which in ("gyro", "accel"):
        d = sens[which]
        for k in ("scale_factor_sigma", "misalignment_sigma"):
            if k not in d:
                d[k] = ref[which][k]
                notes.append(f"{which}.{k}")
        if np.all(d["bias_sigma"] == 0.0):
            d["bias_sigma"] = ref[which]["bias_sigma"]
            notes.append(f"{which}.bias_sigma (0: unknown)")
    return notes


def chi2_cdf(x: float, k: int) -> float:
    """Chi-square CDF with ``k`` degrees of freedom: the regularized lower gamma P(k/2, x/2)."""
    if x <= 0.0:
        return 0.0
    a, z = 0.5 * k, 0.5 * x
    if z < a + 1.0:                          # series
        term = total = 1.0 / a
        n = a
        while abs(term) > 1e-16 * abs(total):
            n += 1.0
            term *= z / n
            total += term
        return total * math.exp(-z + a * math.log(z) - math.lgamma(a))
    # continued fraction for Q (Lentz), P = 1 - Q
    b = z + 1.0 - a
    c = 1.0 / 1e-300
    dd = 1.0 / b
    h = dd
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2.0
        dd = an * dd + b
        dd = 1.0 / (dd if abs(dd) > 1e-300 else 1e-300)
        c = b + an / c
        c = c if abs(c) > 1e-300 else 1e-300
        delta = dd * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return 1.0 - math.exp(-z + a * math.log(z) - math.lgamma(a)) * h


def chi2_ppf(p: float, k: int) -> float:
    """The ``p`` quantile of the chi-square distribution with ``k`` degrees of freedom (bisection)."""
    lo, hi = 0.0, max(10.0, 4.0 * k)
    while chi2_cdf(hi, k) < p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_cdf(mid, k) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def chi2_gate(p: float, m: int) -> float:
    return chi2_ppf(p, m)


@dataclass
class FusionSummary:
    fixes_used: int = 0
    fixes_rejected: int = 0
    fixes_total: int = 0
    counts: dict = field(default_factory=dict)          # type -> (accepted, rejected) measurements
    outages: list = field(default_factory=list)         # (start, length) s
    standstill: list = field(default_factory=list)      # [start, end] s
    residual_rms_h: float = float("nan")                # m, fused antenna track against the fixes
    residual_rms_u: float = float("nan")
    final_sigma: dict = field(default_factory=dict)
    events: list = field(default_factory=list)          # strings
    sensor: str = ""
    heading_init_time: float | None = None
    smoothed: bool = False

    def text(self) -> str:
        s = [f"fusion: {self.fixes_used} of {self.fixes_total} GNSS fixes used, {self.fixes_rejected} rejected"]
        for k, (a, r) in self.counts.items():
            if k != "gnss_pos":
                s.append(f"{k} {a} used/{r} rejected")
        s.append(f"{len(self.outages)} outage(s)" + (": " + ", ".join(f"{t:.6g} s for {d:.3g} s"
                                                                     for t, d in self.outages[:5]) if self.outages else ""))
        s.append(f"{len(self.standstill)} standstill interval(s)" + (": " + ", ".join(
            f"{a:.6g}-{b:.6g} s" for a, b in self.standstill[:5]) if self.standstill else ""))
        s.append(f"residual RMS against the fixes {self.residual_rms_h:.3g} m horizontal, "
                 f"{self.residual_rms_u:.3g} m vertical")
        fs = self.final_sigma
        if fs:
            s.append("final 1-sigma: position {:.3g}/{:.3g}/{:.3g} m, velocity {:.3g}/{:.3g}/{:.3g} m/s, "
                     "roll/pitch/heading {:.3g}/{:.3g}/{:.3g} deg".format(*[fs[c] for c in SIGMA_COLUMNS]))
        if self.heading_init_time is not None:
            s.append(f"heading initialized from the GNSS course at {self.heading_init_time:.6g} s")
        s.append(f"sensor model {self.sensor}")
        if self.smoothed:
            s.append("smoothed (RTS)")
        return "; ".join(s) + "." + ("".join(f" {e}." for e in self.events))


def gnss_rows(gnss: GnssLog, fopts: FusionOptions, t_min: float) -> np.ndarray:
    """Measurement rows of a GNSS log: position, velocity (when used) and the course for the heading."""
    n = len(gnss)
    sp = gnss.position_sigma(fopts.gnss_pos_sigma)
    if not np.all(np.isfinite(sp)) or np.any(sp <= 0):
        k = int(np.argmax(~(np.isfinite(sp).all(axis=1) & (sp > 0).all(axis=1))))
        raise SinsError(f"{gnss.source}: fix {k + 1} (time {gnss.time[k]!r}): position sigma must be finite and > 0")
    rows = [np.column_stack([gnss.time, np.full(n, kn.MT_GNSS_POS), np.radians(gnss.lat), np.radians(gnss.lon),
                             gnss.height, sp, np.zeros((n, 2))])]
    if gnss.vel_n is not None:
        sv = gnss.std_vel if gnss.std_vel is not None else np.tile(fopts.gnss_vel_sigma, (n, 1))
        sv = np.where(np.isfinite(sv) & (sv > 0), sv, fopts.gnss_vel_sigma[None, :])
        if fopts.use_gnss_velocity:
            rows.append(np.column_stack([gnss.time, np.full(n, kn.MT_GNSS_VEL), gnss.vel_n, sv, np.zeros((n, 2))]))
        ve, vn, svh = gnss.vel_n[:, 0], gnss.vel_n[:, 1], np.hypot(sv[:, 0], sv[:, 1]) / math.sqrt(2.0)
        tc = gnss.time
    elif n >= 2:
        rm, rn = radii_py(np.sin(np.radians(gnss.lat)))
        dt = np.diff(gnss.time)
        ve = dlon(np.radians(gnss.lon[1:]), np.radians(gnss.lon[:-1])) * (rn[1:] + gnss.height[1:]) * \
            np.cos(np.radians(gnss.lat[1:])) / dt
        vn = np.diff(np.radians(gnss.lat)) * (rm[1:] + gnss.height[1:]) / dt
        svh = np.hypot(sp[1:, 0], sp[1:, 1]) / dt
        tc = gnss.time[1:]
    else:
        ve = vn = svh = tc = np.empty(0)
    speed = np.hypot(ve, vn)
    ok = speed > fopts.heading_min_speed
    course = np.mod(np.arctan2(ve, vn), 2 * math.pi)
    csig = np.arctan2(svh, np.maximum(speed, 1e-9)) + fopts.heading_sigma_floor
    rows.append(np.column_stack([tc[ok], np.full(ok.sum(), kn.MT_COURSE), course[ok], ve[ok], vn[ok], csig[ok],
                                 svh[ok], np.zeros(ok.sum()), np.zeros((ok.sum(), 2))]))
    out = np.vstack(rows)
    return out[out[:, 0] > t_min]


def sort_rows(rows: np.ndarray) -> np.ndarray:
    if len(rows) == 0:
        return rows.reshape(0, kn.MW)
    prio = np.vectorize(PRIO.get)(rows[:, 1].astype(int))
    return rows[np.lexsort((prio, rows[:, 0]))]


def outages(time: np.ndarray, factor: float) -> list:
    """GNSS gaps longer than ``factor`` nominal (median) intervals: ``(start, length)``."""
    if len(time) < 3:
        return []
    d = np.diff(time)
    nominal = float(np.median(d))
    k = np.nonzero(d > factor * nominal)[0]
    return [(float(time[i]), float(d[i])) for i in k]


class EpochStore:
    """The smoother's epochs (:func:`sinscli.fusion.kernel._store_epoch`), grown as the filter runs:
    per epoch the time, P- and P+ (upper triangles), the integral of F over its pattern, the fed-back
    correction and the reset flag (about 2.6 kB for 15 states)."""
    EMPTY = (np.empty(0), np.empty((0, 1)), np.empty((0, 1)), np.empty((0, 1)), np.empty((0, 1)), np.empty(0))

    def __init__(self, nx: int, nnz: int):
        self.nx, self.nnz, self.n = nx, nnz, 0
        self._a = self._alloc(0)

    def _alloc(self, cap):
        nu = self.nx * (self.nx + 1) // 2
        return (np.empty(cap), np.empty((cap, nu)), np.empty((cap, nu)), np.empty((cap, self.nnz)),
                np.empty((cap, self.nx)), np.empty(cap))

    def reserve(self, more: int) -> None:
        """Room for ``more`` epochs after the ``n`` stored (grown by half again, copied once)."""
        cap = len(self._a[0])
        if self.n + more <= cap:
            return
        new = self._alloc(max(self.n + more, int(1.5 * cap)))
        for a, b in zip(self._a, new):
            b[:self.n] = a[:self.n]
        self._a = new

    def arrays(self):
        return self._a

    def trimmed(self):
        return tuple(a[:self.n] for a in self._a)


class Fusion:
    """Stateful fused navigator: feed IMU blocks in time order, get trajectory chunks back."""

    def __init__(self, init: NavState, nav: NavOptions, fopts: FusionOptions, gnss: GnssLog,
                 init_sigma: dict | None = None, body_vel=None, smooth: bool = False, src: str = "config",
                 init_bias: dict | None = None):
        nav.check()
        if nav.attitude not in ("quat", "dcm") or nav.frame != "enu":
            raise SinsError(f"--gnss: the fusion filter runs with --attitude quat or dcm in the ENU frame, "
                            f"not {nav.attitude} / {nav.frame}")
        self.nav, self.fopts, self.gnss, self.init = nav, fopts, gnss, init
        self.smooth = smooth
        self.model = filter_model(fopts.sensor, fopts.base_dir, fopts.states, src, fopts.bias_model)
        nx = fopts.states
        self.nx = nx
        c = np.asarray(init.Cbn, dtype=float)
        self.method = nav.method_code()
        self.st = sd.new_state(init.time, init.lat, init.lon, init.height, np.asarray(init.vel_n, float), c,
                               self.method, nav.conv)
        self.cflu = conv_to_flu(nav.conv)
        self.ptr, self.col = sparsity(nx, bool(np.any(self.model.inv_tau_g > 0) or np.any(self.model.inv_tau_a > 0)))
        self.ftv = np.zeros(len(self.col))
        self.mats, self.vecs, self.s3 = kn.workspace(nx)
        lever = fopts.lever_arm if fopts.lever_arm is not None else np.zeros(3)
        self.lever = np.asarray(lever, dtype=float)
        self.cv = self._config_vector()
        self.fs = np.zeros(kn.FS_SIZE)
        self.fs[kn.F_QSCALE] = 1.0
        self.fs[kn.F_TPREV] = init.time
        self.fs[kn.F_T_EPOCH] = init.time
        if init_bias:
            self.fs[kn.F_BG:kn.F_BG + 3] = init_bias.get("gyro", np.zeros(3))
            self.fs[kn.F_BA:kn.F_BA + 3] = init_bias.get("accel", np.zeros(3))
        self.P = self._initial_covariance(init_sigma or {})
        self.g = float(gravity(math.sin(init.lat), init.height))
        self.detector = StandstillDetector(fopts.standstill_window, fopts.standstill_rate_std,
                                           fopts.standstill_accel_std, fopts.standstill_accel_mag, self.g)
        t_end = float(gnss.time[-1]) if len(gnss) else init.time
        rows = [gnss_rows(gnss, fopts, init.time + time_tolerance(init.time))]
        if body_vel is not None and fopts.odometry and len(body_vel.time):
            # the log's sigma (a wheel-odometry controller's covariance is often a placeholder: 1e-3) no
            # smaller than the floor (wheel slip of a skid-steered vehicle, ~10 % at 1 m/s); or the config's
            sv = body_vel.std if body_vel.std is not None else np.zeros((len(body_vel.time), 3))
            sv = np.maximum(sv, fopts.odometry_sigma_floor)
            if fopts.odometry_sigma is not None:
                sv = np.full_like(sv, fopts.odometry_sigma)
            n = len(body_vel.time)
            rows.append(np.column_stack([body_vel.time, np.full(n, kn.MT_ODOM), body_vel.vel_b, sv, np.zeros((n, 2))]))
        self.rows = sort_rows(np.vstack(rows))
        self.rows = self.rows[self.rows[:, 0] > init.time + time_tolerance(init.time)]
        self._t_nhc = init.time
        self._t_end_gnss = t_end
        self.inn_parts, self.ev_parts = [], []
        self.epochs = EpochStore(nx, len(self.col)) if smooth else None
        self.forward_rows = []          # kept for the smoother: (trajectory, variances, sensor estimates)
        self.applied = 0
        self.heading_known = bool(self.fs[kn.F_HEAD_KNOWN] > 0)
        self._source = "<memory>"
        self._block_t0 = init.time

    # ------------------------------------------------------------------ set-up
    def _config_vector(self):
        f, m, n = self.fopts, self.model, self.nav
        cv = np.zeros(kn.CV_SIZE)
        cv[kn.C_NX] = f.states
        cv[kn.C_METHOD] = self.method
        cv[kn.C_ORDER] = n.coning
        cv[kn.C_NSUB] = n.subsamples
        cv[kn.C_EVERY] = n.every
        cv[kn.C_CONV] = n.conv
        cv[kn.C_PROP_DT] = f.propagation_interval
        for mm in (1, 2, 3):
            cv[kn.C_GATE1 + mm - 1] = chi2_gate(f.gate_probability, mm)
        cv[kn.C_ARW2:kn.C_ARW2 + 3] = m.arw2
        cv[kn.C_VRW2:kn.C_VRW2 + 3] = m.vrw2
        cv[kn.C_QBG:kn.C_QBG + 3] = m.q_bg
        cv[kn.C_QBA:kn.C_QBA + 3] = m.q_ba
        cv[kn.C_ITG:kn.C_ITG + 3] = m.inv_tau_g
        cv[kn.C_ITA:kn.C_ITA + 3] = m.inv_tau_a
        cv[kn.C_SFG] = m.sfmis_g * f.scale_factor_tau
        cv[kn.C_SFA] = m.sfmis_a * f.scale_factor_tau
        cv[kn.C_LEVER:kn.C_LEVER + 3] = self.lever
        cv[kn.C_REJ_RUN] = f.rejection_run
        # the window's mean NIS per dof (3 dof per measurement) above its chi-square quantile
        m_n = 3 * f.adapt_window
        cv[kn.C_ADAPT_THR] = chi2_ppf(f.adapt_probability, m_n) / m_n if f.adapt else 0.0
        cv[kn.C_ADAPT_N] = f.adapt_window
        cv[kn.C_SMOOTH_DT] = f.smoother_interval if self.smooth else 0.0
        cv[kn.C_ZUPT_MAXV] = f.zupt_max_speed
        fwd = 1 if n.conv == 1 else 0           # RFU: y forward; FLU, FRD: x forward
        lat_axes = [i for i in range(3) if i != fwd]
        cv[kn.C_NHC_AX0], cv[kn.C_NHC_AX1] = lat_axes
        cv[kn.C_HEAD_MINSPEED] = f.heading_min_speed
        cv[kn.C_QMAX] = f.adapt_max_scale
        cv[kn.C_ZARU_Q] = 1.0 if f.zaru_sigma is None else 0.0
        cv[kn.C_FWD] = fwd
        return cv

    def _initial_covariance(self, s: dict):
        f, m, nx = self.fopts, self.model, self.nx
        P = np.zeros((nx, nx))
        P[0:3, 0:3] = np.diag(np.asarray(s.get("position", f.init_pos_sigma), float) ** 2)
        P[V:V + 3, V:V + 3] = np.diag(np.asarray(s.get("velocity", f.init_vel_sigma), float) ** 2)
        att = np.asarray(s.get("attitude", f.init_att_sigma), dtype=float)
        tilt = max(att[0], att[1])
        P[PHI, PHI] = P[PHI + 1, PHI + 1] = tilt ** 2
        head = att[2]
        if not np.isfinite(head) or head > f.heading_max_sigma:
            self.fs[kn.F_HEAD_KNOWN] = 0.0
            self.heading_prior = math.pi / math.sqrt(3.0)
        else:
            self.fs[kn.F_HEAD_KNOWN] = 1.0
            P[PHI + 2, PHI + 2] = head ** 2
            self.heading_prior = head
        P[BG:BG + 3, BG:BG + 3] = np.diag(m.p0_bg)
        P[BA:BA + 3, BA:BA + 3] = np.diag(m.p0_ba)
        if nx == 21:
            P[SG:SG + 3, SG:SG + 3] = np.diag(m.p0_sg)
            P[SA:SA + 3, SA:SA + 3] = np.diag(m.p0_sa)
        return P

    # ------------------------------------------------------------------ running
    def initial_row(self) -> Trajectory:
        s = self.init
        var = np.zeros((1, kn.NVAR))
        bias = np.zeros((1, kn.NBIAS))
        kn.row_variances(var, 0, tuple(tuple(r) for r in np.asarray(s.Cbn, float)), int(self.cv[kn.C_FWD]),
                         *np.diag(self.P)[:9], self.P[PHI, PHI + 1], self.fs[kn.F_HEAD_KNOWN] > 0)
        bias[0] = self.fs[:kn.NBIAS]
        traj = Trajectory(np.array([s.time]), np.array([s.lat]), np.array([s.lon]), np.array([s.height]),
                          np.asarray(s.vel_n, float)[None, :].copy(), np.asarray(s.Cbn, float)[None].copy())
        if self.smooth:
            self.forward_rows.append((traj, var, bias))
        else:
            traj.extra = self._columns(var, bias)
        return traj

    def _measurement_rows(self, imu_t, dth, dv, t_start):
        """This block's rows: the log's rows up to its end, with ZUPT/ZARU and NHC rows of the block."""
        f = self.fopts
        parts = []
        if f.zupt or f.zaru:
            t0, t1, w = self.detector.feed(imu_t, dth, dv, t_start)
            n = len(t1)
            if n:
                zs = np.full(n, f.zupt_sigma)
                if f.zupt:
                    parts.append(np.column_stack([t1, np.full(n, kn.MT_ZUPT), np.zeros((n, 3)), zs, zs, zs,
                                                  np.zeros((n, 2))]))
                if f.zaru:
                    sig = f.zaru_sigma if f.zaru_sigma is not None else np.sqrt(
                        self.model.arw2.max() / (t1 - t0))
                    sig = np.broadcast_to(sig, (n,))
                    parts.append(np.column_stack([t1, np.full(n, kn.MT_ZARU), w, sig, sig, sig, np.zeros((n, 2))]))
        if f.nhc:
            tn = np.arange(self._t_nhc + f.nhc_interval, imu_t[-1] + 1e-9, f.nhc_interval)
            if len(tn):
                self._t_nhc = float(tn[-1])
                n = len(tn)
                s = np.zeros((n, 3))
                ax = self.cv[kn.C_NHC_AX0:kn.C_NHC_AX0 + 2].astype(int)
                s[:, ax[0]] = f.nhc_sigma[0]
                s[:, ax[1]] = f.nhc_sigma[1]
                s[:, [i for i in range(3) if i not in ax][0]] = 1.0
                parts.append(np.column_stack([tn, np.full(n, kn.MT_NHC), np.zeros((n, 3)), s, np.zeros((n, 2))]))
        t_last = float(imu_t[-1])
        tol = time_tolerance(t_last)
        k = int(np.searchsorted(self.rows[:, 0], t_last + tol, side="right"))
        parts.append(self.rows[:k])
        self.rows = self.rows[k:]
        return sort_rows(np.vstack(parts)) if parts else np.zeros((0, kn.MW))

    def feed(self, imu: ImuLog) -> Trajectory | None:
        self._source = imu.source
        tol = time_tolerance(self.init.time)
        sel = imu.time > self.init.time + tol
        time, dth, dv = imu.time[sel], imu.dtheta_b[sel], imu.dvel_b[sel]
        out = []
        for a in range(0, time.shape[0], BLOCK):
            b = min(a + BLOCK, time.shape[0])
            out.append(self._run(np.ascontiguousarray(time[a:b]), np.ascontiguousarray(dth[a:b]),
                                 np.ascontiguousarray(dv[a:b])))
        self.applied += time.shape[0]
        rows = [c for c in out if c is not None and len(c)]
        return concat(rows) if rows else None

    def _run(self, time, dth, dv):
        if len(time) == 0:
            return None
        meas = np.ascontiguousarray(self._measurement_rows(time, dth, dv, self.fs[kn.F_TPREV]))
        per = self.nav.subsamples * self.nav.every
        cap = time.shape[0] // per + 2
        nm = len(meas)
        out_t = np.empty(cap)
        out_pos = np.empty((cap, 3))
        out_vel = np.empty((cap, 3))
        out_cbn = np.empty((cap, 3, 3))
        out_var = np.empty((cap, kn.NVAR))
        out_bias = np.empty((cap, kn.NBIAS))
        inn = np.empty((3 * nm + 3, 7))
        evs = np.empty((nm + 8, 4))
        if self.smooth:
            ep = self.epochs
            ep.reserve(nm + int((time[-1] - self.fs[kn.F_TPREV]) / self.fopts.smoother_interval) + 4)
            arrays, n0 = ep.arrays(), ep.n
        else:
            arrays, n0 = EpochStore.EMPTY, 0
        n, used, n_inn, n_evs, n_ep = kn.fuse(time, dth, dv, self.st, self.fs, self.cv, self.P, meas, self.ptr,
                                              self.col, self.ftv, self.cflu, self.mats, self.vecs, self.s3,
                                              out_t, out_pos, out_vel, out_cbn, out_var, out_bias, inn, evs,
                                              *arrays, n0)
        if self.smooth:
            self.epochs.n = n_ep
        if used < nm:                       # rows at the block's very end go with the next block
            self.rows = sort_rows(np.vstack([meas[used:], self.rows]))
        self.inn_parts.append(inn[:n_inn].copy())
        self.ev_parts.append(evs[:n_evs].copy())
        for e in evs[:n_evs]:
            self._log_event(e)
        if self.fs[kn.F_ERR] != 0:
            reason = ("turned non-finite" if self.fs[kn.F_ERR] == kn.ERR_NONFINITE
                      else "lost positive definiteness")
            raise SinsError(f"{self._source}: the filter covariance {reason} at t = {self.fs[kn.F_ERR_T]!r} s; "
                            f"stopped there (check the fusion config's sigmas and the sensor description)")
        traj = Trajectory(out_t[:n], out_pos[:n, 0], out_pos[:n, 1], out_pos[:n, 2], out_vel[:n], out_cbn[:n])
        var, bias = out_var[:n], out_bias[:n]
        if self.smooth:
            self.forward_rows.append((traj, var, bias))
        else:
            traj.extra = self._columns(var, bias)
        return traj

    def _log_event(self, e):
        t, kind = float(e[0]), e[1]
        if kind == kn.EV_REJECTION_RUN:
            log.warning("fusion: %d consecutive GNSS fixes rejected from %.6f to %.6f s (the filter diverged or "
                        "the GNSS jumped): position covariance widened by the innovation, fix accepted",
                        int(e[3]), e[2], t)
        elif kind == kn.EV_HEADING_INIT:
            log.info("fusion: heading initialized from the GNSS course at %.6f s (changed by %.3f deg)", t,
                     math.degrees(e[2]))
        elif kind == kn.EV_ADAPT:
            log.info("fusion: innovations larger than the covariance claims at %.6f s: P and Q widened x%.3g "
                     "(process noise scale now %.3g)", t, e[2], e[3])

    def _columns(self, var, bias) -> dict:
        """docs/formats.md aided-trajectory columns from the row variances and the sensor estimates (SI)."""
        d = math.degrees(1.0)
        out = {}
        for i, k in enumerate(SIGMA_COLUMNS[:6]):
            out[k] = np.sqrt(var[:, i])
        out["roll_std"] = np.sqrt(var[:, 6]) * d
        out["pitch_std"] = np.sqrt(var[:, 7]) * d
        out["heading_std"] = np.sqrt(np.where(var[:, 8] < 0, self.heading_prior ** 2, var[:, 8])) * d
        for i, k in enumerate(BIAS_COLUMNS[:3]):
            out[k] = bias[:, i] * d * 3600.0
        for i, k in enumerate(BIAS_COLUMNS[3:]):
            out[k] = bias[:, 3 + i] / 9.80665e-6
        if self.nx == 21:
            for i, k in enumerate(SF_COLUMNS):
                out[k] = bias[:, 6 + i] * 1e6
        return out

    # ------------------------------------------------------------------ end
    def innovations(self) -> np.ndarray:
        inn = np.vstack(self.inn_parts) if self.inn_parts else np.zeros((0, 7))
        rec = np.empty(len(inn), dtype=INNOVATION_DTYPE)
        rec["time"] = inn[:, 0]
        rec["type"] = np.array(kn.MEAS_NAMES)[inn[:, 1].astype(int)] if len(inn) else []
        rec["axis"] = AXES[inn[:, 2].astype(int)] if len(inn) else []
        rec["innovation"] = inn[:, 3]
        rec["sigma"] = inn[:, 4]
        rec["nis"] = inn[:, 5]
        rec["accepted"] = inn[:, 6] > 0
        return rec

    def events(self) -> np.ndarray:
        return np.vstack(self.ev_parts) if self.ev_parts else np.zeros((0, 4))

    def smoothed(self) -> Trajectory:
        """The RTS-smoothed trajectory at the forward output rows (the forward rows are consumed)."""
        from .smoother import smooth_rows
        traj = concat([r[0] for r in self.forward_rows])
        var = np.concatenate([r[1] for r in self.forward_rows])
        bias = np.concatenate([r[2] for r in self.forward_rows])
        self.forward_rows = []
        smooth_rows(traj.time, traj.lat, traj.lon, traj.height, traj.vel_n, traj.Cbn, var, bias,
                    self.epochs.trimmed(), self.ptr, self.col, self.nx, int(self.cv[kn.C_FWD]))
        traj.extra = self._columns(var, bias)
        return traj

    def summary(self, traj: Trajectory) -> FusionSummary:
        rec = self.innovations()
        s = FusionSummary(sensor=self.model.source, smoothed=self.smooth)
        t1 = float(traj.time[-1]) if len(traj) else self.init.time
        inside = (self.gnss.time > self.init.time) & (self.gnss.time <= t1 + time_tolerance(t1))
        s.fixes_total = int(inside.sum())
        for name in kn.MEAS_NAMES[:6]:
            r = rec[rec["type"] == name]
            if len(r):
                dof = 2 if name == "nhc" else 3
                s.counts[name] = (int(r["accepted"].sum()) // dof, int((~r["accepted"]).sum()) // dof)
        a, r = s.counts.get("gnss_pos", (0, 0))
        s.fixes_used, s.fixes_rejected = a, r
        s.outages = outages(self.gnss.time[inside], self.fopts.outage)
        s.standstill = standstill_intervals(rec, self.fopts.standstill_window)
        s.residual_rms_h, s.residual_rms_u = residuals(traj, self.gnss, self.lever, inside)
        if len(traj):
            s.final_sigma = {k: float(traj.extra[k][-1]) for k in SIGMA_COLUMNS}
        ev = self.events()
        for e in ev:
            if e[1] == kn.EV_HEADING_INIT and s.heading_init_time is None:
                s.heading_init_time = float(e[0])
            elif e[1] == kn.EV_REJECTION_RUN:
                s.events.append(f"warning: {int(e[3])} consecutive fixes rejected {e[2]:.6g}-{e[0]:.6g} s "
                                f"(position covariance widened, fix re-accepted)")
        ad = ev[ev[:, 1] == kn.EV_ADAPT] if len(ev) else ev
        if len(ad):
            s.events.append(f"innovations inconsistent with the covariance (sensor description too optimistic?): "
                            f"P and Q widened {len(ad)} time(s) from {ad[0, 0]:.6g} s, process-noise scale now "
                            f"x{ad[-1, 3]:.3g}")
        if self.model.default:
            s.events.append(f"no sensor description given (fusion.sensor / --sensor): the conservative "
                            f"default '{DEFAULT_SENSOR}' preset is assumed")
        elif self.model.assumed:
            s.events.append(f"sensor description without {', '.join(self.model.assumed)}: the default "
                            f"'{DEFAULT_SENSOR}' preset's value assumed")
        return s

    def finish(self) -> None:
        if self.applied == 0:
            raise SinsError(f"{self._source}: no IMU sample after the initial time {self.init.time!r}: "
                            f"the init time is outside the log")


def standstill_intervals(rec, window: float) -> list:
    """Intervals where the filter applied ZUPT/ZARU (detected at rest and slow enough): ``(start, end)``."""
    t = np.unique(rec["time"][(rec["type"] == "zupt") | (rec["type"] == "zaru")])
    out = []
    for x in t:
        if out and x - out[-1][1] <= 1.5 * window:
            out[-1][1] = float(x)
        else:
            out.append([float(x) - window, float(x)])
    return [tuple(iv) for iv in out]


def residuals(traj: Trajectory, gnss: GnssLog, lever, inside) -> tuple[float, float]:
    """RMS (horizontal, vertical) of the fused antenna track minus the fixes, at the fix times (m)."""
    if len(traj) < 2 or not inside.any():
        return float("nan"), float("nan")
    t = gnss.time[inside]
    t = t[(t >= traj.time[0]) & (t <= traj.time[-1])]
    if len(t) == 0:
        return float("nan"), float("nan")
    sel = np.isin(gnss.time, t)
    lat = np.interp(t, traj.time, traj.lat)
    lon = np.interp(t, traj.time, traj.lon)
    h = np.interp(t, traj.time, traj.height)
    k = np.clip(np.searchsorted(traj.time, t), 0, len(traj) - 1)
    l_n = traj.Cbn[k] @ np.asarray(lever, dtype=float)
    rm, rn = radii_py(np.sin(lat))
    de = dlon(lon, np.radians(gnss.lon[sel])) * (rn + h) * np.cos(lat) + l_n[:, 0]
    dn = (lat - np.radians(gnss.lat[sel])) * (rm + h) + l_n[:, 1]
    du = h - gnss.height[sel] + l_n[:, 2]
    return float(np.sqrt(np.mean(de ** 2 + dn ** 2))), float(np.sqrt(np.mean(du ** 2)))


def fuse_blocks(blocks, fusion: Fusion, progress=None):
    """Yield forward-filtered trajectory chunks (the initial row first) for an iterable of IMU blocks."""
    yield from stream_blocks(fusion, blocks, progress)


def run_fusion(imu: ImuLog, init: NavState, gnss: GnssLog, fopts: FusionOptions | None = None,
               nav: NavOptions | None = None, smooth: bool = False, init_sigma=None, body_vel=None,
               init_bias=None):
    """Fuse a whole in-memory log; returns ``(trajectory, innovations, summary, fusion)``."""
    fopts = fopts or FusionOptions()
    f = Fusion(init, nav or NavOptions(), fopts, gnss, init_sigma=init_sigma, body_vel=body_vel, smooth=smooth,
               init_bias=init_bias)
    traj = concat(list(fuse_blocks([imu], f)))
    if smooth:
        traj = f.smoothed()
    return traj, f.innovations(), f.summary(traj), f
