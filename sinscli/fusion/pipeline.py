"""The fusion stage: IMU blocks + GNSS (+ body velocity) + initial state -> fused trajectory chunks,
innovation records and a summary.  No file I/O: readers and writers are the CLI's.

``Fusion(init, nav_opts, fopts, gnss, ...)`` prepares the measurement rows, the filter model from one
sensor description (:func:`filter_model`) and the initial covariance; ``feed(block)`` runs the numba
kernel (:func:`sinscli.fusion.kernel.fuse`) on a block and returns its output rows;
``finish()`` checks that the log had a sample after the initial time; ``smoothed()`` runs the smoother
(:mod:`sinscli.fusion.smoother`) when asked, ``summary(traj)`` the summary.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..gnss.signals import SYS_CHARS
from ..nav import strapdown as sd
from ..nav.earth import gravity, local_en
from ..nav.pipeline import BLOCK, NavOptions, concat, stream_blocks
from ..nav.rotation import conv_to_flu
from ..sensors import G0, SensorDescription, load_sensor, read_sensor
from ..types import GnssLog, ImuLog, NavState, Trajectory, time_tolerance
from ..units import DEG, UG_DECIMAL
from . import kernel as kn
from .model import BA, BG, PHI, SA, SG, V
from .noise import FACTOR, apply_data_noise
from .raw import satellite_counts, tdcp_notes
from .tdcp import TD_T
from .summary import (FusionSummary, RawSummary, clock, exit_fixes, few_satellite_spans, fix_residuals,
                      ground_vehicle_hint, heading_course_check, LeverCheck, outages, standstill_intervals)
from .options import FusionOptions
from .standstill import StandstillDetector, gnss_still
from .smoother import smooth_rows

log = logging.getLogger("sins")

DEFAULT_SENSOR = "mems"
REQUIRED_TERMS = {"gyro": ("arw", "bias_sigma", "bias_instability", "bias_tau"),
                  "accel": ("vrw", "bias_sigma", "bias_instability", "bias_tau")}
PRIO = {kn.MT_COURSE: 0, kn.MT_CLOCK: 1, kn.MT_GNSS_POS: 2, kn.MT_PR: 2, kn.MT_GNSS_VEL: 3, kn.MT_DOP: 3,
        kn.MT_ZUPT: 4, kn.MT_ZARU: 5, kn.MT_NHC: 6, kn.MT_ODOM: 7}
PRIO[kn.MT_TDCP] = 3                # after the epoch's range rates (the sort is stable: raw.py's order)
PRIO_OF_KIND = np.array([PRIO[k] for k in range(len(kn.MEAS_NAMES))])     # the same, indexed by kind
AXES = np.array(["e", "n", "u", "x", "y", "z", "los"])
INNOVATION_DTYPE = np.dtype([("time", "f8"), ("type", "U16"), ("axis", "U8"), ("innovation", "f8"),
                             ("sigma", "f8"), ("nis", "f8"), ("accepted", "?"), ("sat", "U4")])
SIGMA_COLUMNS = ["pos_e_std", "pos_n_std", "pos_u_std", "vel_e_std", "vel_n_std", "vel_u_std",
                 "roll_std", "pitch_std", "heading_std"]
BIAS_COLUMNS = ["gyro_bias_x", "gyro_bias_y", "gyro_bias_z", "accel_bias_x", "accel_bias_y", "accel_bias_z"]
SF_COLUMNS = ["gyro_sf_x", "gyro_sf_y", "gyro_sf_z", "accel_sf_x", "accel_sf_y", "accel_sf_z"]


@dataclass(frozen=True)
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


def filter_model(sensor: SensorDescription | None, states: int, src: str, bias_model: str = "gm-noise") -> FilterModel:
    """The filter's noise model from the sensor description read for the run (None: the stated conservative
    default, the :data:`DEFAULT_SENSOR` preset)."""
    default = sensor is None
    if default:
        sensor = read_sensor(DEFAULT_SENSOR, src, None)
    sens, where = sensor.as_dict(), sensor.source
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


def chi2_gate(p: float, m: int) -> float:
    """The chi-square gate of an ``m``-dimensional innovation: the ``p`` quantile of chi2(m) (scipy.stats)."""
    from scipy.stats import chi2   # 0.3-0.6 s of import: only when a fused run builds its gates, not at import
    return float(chi2.ppf(p, m))


def gnss_rows(gnss: GnssLog, fopts: FusionOptions, t_min: float) -> np.ndarray:
    """Measurement rows of a GNSS log: position, velocity (when used) and the course candidates for the
    heading (:func:`course_rows`)."""
    n = len(gnss)
    sp = gnss.position_sigma(fopts.gnss_pos_sigma)
    if not np.all(np.isfinite(sp)) or np.any(sp <= 0):
        k = int(np.argmax(~(np.isfinite(sp).all(axis=1) & (sp > 0).all(axis=1))))
        raise SinsError(f"{gnss.source}: fix {k + 1} (time {gnss.time[k]!r}): position sigma must be finite and > 0")
    rows = [np.column_stack([gnss.time, np.full(n, kn.MT_GNSS_POS), np.radians(gnss.lat), np.radians(gnss.lon),
                             gnss.height, sp, np.zeros((n, 2))])]
    if gnss.vel_n is not None and fopts.use_gnss_velocity:
        rows.append(np.column_stack([gnss.time, np.full(n, kn.MT_GNSS_VEL), gnss.vel_n, velocity_sigma(gnss, fopts),
                                     np.zeros((n, 2))]))
    rows.append(course_rows(gnss, fopts, sp, t_min).rows)
    out = np.vstack(rows)
    return out[out[:, 0] > t_min]


def velocity_sigma(gnss: GnssLog, fopts: FusionOptions) -> np.ndarray:
    """``(N, 3)`` velocity 1-sigma (m/s, ENU): the fix's own where positive and finite, else the config's.
    A horizontal-only velocity (NaN up, kept NaN in its measurement row) is applied as east and north alone
    (:func:`sinscli.fusion.kernel._model`)."""
    n = len(gnss)
    sv = gnss.std_vel if gnss.std_vel is not None else np.tile(fopts.gnss_vel_sigma, (n, 1))
    return np.where(np.isfinite(sv) & (sv > 0), sv, fopts.gnss_vel_sigma[None, :])


COURSE_FROM_VELOCITY, COURSE_FROM_DISPLACEMENT = 1.0, 2.0     # the course row's aux[0]: its source


@dataclass
class CourseRows:
    """The course candidates (measurement rows ``MT_COURSE``) and what the log offered (for the warning
    when none qualifies)."""
    rows: np.ndarray
    best_sigma: float = math.inf        # rad: the smallest course sigma found (any baseline)
    best_time: float = math.nan
    source: str = ""                    # "velocity" | "displacement" of the first candidate


def course_rows(gnss: GnssLog, fopts: FusionOptions, sp: np.ndarray, t_min: float) -> CourseRows:
    """Heading from motion: candidate rows ``[t, MT_COURSE, course, v_e, v_n, sigma, speed sigma, 0, 0, 0]``.

    Two sources, each giving the course with its sigma; a candidate is kept when the sigma is under
    ``heading_init.max_course_sigma`` (and the speed over ``heading_init.min_speed``), so that a walker
    at 1 m/s qualifies as soon as the GNSS says where he goes, whatever his speed:

    * the GNSS velocity: ``sigma = atan(sigma_v / speed)``;
    * the displacement between two fixes at most ``heading_init.max_baseline_time`` apart: enough travel
      that the fixes' sigmas are small against it, ``sigma = atan(sqrt(s_a^2 + s_b^2) / d)``, plus the
      bending of the path between them (the largest distance of the fixes in between from the chord,
      beyond twice their sigma: an arc of sagitta ``e`` over a chord ``d`` turns by ``4 e / d``).

    The sigma reported adds ``heading_init.sigma_floor`` (sideslip, a handheld device off the path).  The
    filter takes the first candidate while the heading is unknown (:mod:`sinscli.fusion.kernel`)."""
    f = fopts
    empty = np.zeros((0, kn.MW))
    n = len(gnss)
    if n < 2:
        return CourseRows(empty)
    cands = []
    best, best_t = math.inf, math.nan
    if gnss.vel_n is not None:
        sv = velocity_sigma(gnss, f)
        ve, vn = gnss.vel_n[:, 0], gnss.vel_n[:, 1]
        speed = np.hypot(ve, vn)
        svh = np.hypot(sv[:, 0], sv[:, 1]) / math.sqrt(2.0)
        csig = np.arctan2(svh, np.maximum(speed, 1e-12))
        after = gnss.time > t_min
        if after.any():
            k = int(np.argmin(np.where(after, csig, np.inf)))
            best, best_t = float(csig[k]), float(gnss.time[k])
        ok = after & (csig <= f.heading_max_course_sigma) & (speed >= max(f.heading_min_speed, 1e-9))
        if ok.any():
            k = np.nonzero(ok)[0][:8]
            cands.append(np.column_stack([gnss.time[k], np.full(k.size, kn.MT_COURSE),
                                          np.mod(np.arctan2(ve[k], vn[k]), 2 * math.pi), ve[k], vn[k],
                                          csig[k] + f.heading_sigma_floor, svh[k], np.zeros(k.size),
                                          np.full(k.size, COURSE_FROM_VELOCITY), np.zeros(k.size)]))
    # displacement baselines: ENU offsets of the fixes from the first (small-angle: a few km at most apart)
    e, nn = local_en(gnss.lat, gnss.lon, gnss.height)
    sh = np.hypot(sp[:, 0], sp[:, 1]) / math.sqrt(2.0)
    t = gnss.time
    i0 = np.searchsorted(t, t - f.heading_max_baseline_time, side="left")
    d = np.hypot(e - e[i0], nn - nn[i0])
    srel = np.hypot(sh, sh[i0])
    dsig = np.where(d > 0, np.arctan2(srel, d), np.inf)
    dt = t - t[i0]
    after = (t > t_min) & (dt > 0)
    found = 0
    for j in np.nonzero(after & (dsig <= f.heading_max_course_sigma))[0]:
        i = int(i0[j])
        ue, un = (e[j] - e[i]) / d[j], (nn[j] - nn[i]) / d[j]
        lateral = np.abs((e[i:j + 1] - e[i]) * un - (nn[i:j + 1] - nn[i]) * ue)
        bend = 4.0 * max(0.0, float(np.max(lateral - 2.0 * sh[i:j + 1]))) / d[j]
        sig = math.hypot(float(dsig[j]), bend)
        if sig < best:
            best, best_t = sig, float(t[j])
        speed = d[j] / dt[j]
        if sig > f.heading_max_course_sigma or speed < max(f.heading_min_speed, 1e-9):
            continue
        vel_e, vel_n = (e[j] - e[i]) / dt[j], (nn[j] - nn[i]) / dt[j]
        cands.append(np.array([[t[j], kn.MT_COURSE, math.atan2(vel_e, vel_n) % (2 * math.pi), vel_e, vel_n,
                                sig + f.heading_sigma_floor, srel[j] * math.sqrt(2.0) / dt[j], 0.0,
                                COURSE_FROM_DISPLACEMENT, 0.0]]))
        found += 1
        if found >= 8:
            break
    if not found and np.isfinite(dsig[after]).any():
        k = np.nonzero(after)[0]
        j = int(k[np.argmin(dsig[k])])
        if dsig[j] < best:
            best, best_t = float(dsig[j]), float(t[j])
    if not cands:
        return CourseRows(empty, best, best_t)
    rows = np.vstack(cands)
    rows = rows[np.argsort(rows[:, 0], kind="stable")]
    return CourseRows(rows, best, best_t, "velocity" if rows[0, 8] == COURSE_FROM_VELOCITY else "displacement")


def sort_rows(rows: np.ndarray) -> np.ndarray:
    if len(rows) == 0:
        return rows.reshape(0, kn.MW)
    prio = PRIO_OF_KIND[rows[:, 1].astype(int)]
    return rows[np.lexsort((prio, rows[:, 0]))]


class EpochStore:
    """The smoother's epochs (:func:`sinscli.fusion.kernel._store_epoch`), grown as the filter runs:
    per epoch the time, P- and P+ (upper triangles), the transition matrix since the previous epoch
    (:func:`sinscli.fusion.kernel.epoch_width` floats), the fed-back correction and the reset flag
    (about 3 kB for 15 states)."""
    EMPTY = (np.empty(0), np.empty((0, 1)), np.empty((0, 1)), np.empty((0, 1)), np.empty((0, 1)), np.empty(0))

    def __init__(self, nx: int, nnz: int):
        self.nx, self.nnz, self.n = nx, nnz, 0      # nnz: floats of the transition matrix per epoch
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
                 init_bias: dict | None = None, data_noise=None, t_log0: float | None = None,
                 drift_base: float = 1.0, r_base=None, raw=None, bias_var=None, gnss_gm=None,
                 lever_diagnosis: bool = False):
        nav.check()
        if nav.attitude not in ("quat", "dcm") or nav.frame != "enu":
            raise SinsError(f"--gnss: the fusion filter runs with --attitude quat or dcm in the ENU frame, "
                            f"not {nav.attitude} / {nav.frame}")
        self.nav, self.fopts, self.gnss, self.init = nav, fopts, gnss, init
        self.smooth = smooth
        # the lever arm as states: asked by fusion.estimate, or for a diagnosis of the configured one
        # (calibrated_run: a pass whose fixes contradicted the filter)
        est_lever = "lever_arm" in fopts.estimate or lever_diagnosis
        self.model = filter_model(fopts.sensor, 21 if est_lever else fopts.states,
                                  src, fopts.bias_model)
        self.data_notes = []
        if data_noise is not None and fopts.noise_from_data:
            self.model, self.data_notes = apply_data_noise(self.model, data_noise,
                                                           float(gravity(math.sin(init.lat), init.height)),
                                                           handheld=fopts.vehicle == "pedestrian")
        self.data_noise = data_noise
        self.bias_var = None if bias_var is None else np.asarray(bias_var, dtype=float)
        if self.bias_var is not None:      # a calibration pass found the turn-on bias priors too small
            self.model = replace(self.model, p0_bg=np.maximum(self.model.p0_bg, self.bias_var[:3]),
                                 p0_ba=np.maximum(self.model.p0_ba, self.bias_var[3:]))
        # an unestimated gyro scale factor (0.5 % for a consumer IMU) biases the lever arm by centimetres
        # through the turns that make it observable: estimating the lever arm estimates the scale factors
        ncore = 21 if est_lever else fopts.states
        self.sf_for_lever = ncore != fopts.states
        nx = ncore
        self.la = self.td = -1
        if est_lever:
            self.la, nx = nx, nx + 3
        if "time_offset" in fopts.estimate:
            self.td, nx = nx, nx + 1
        # raw GNSS (tightly coupled, sinscli.fusion.raw): the receiver clock bias and drift, an inter-system
        # bias per extra constellation
        self.raw = raw
        self.clk = -1
        self.isb = {}
        if raw is not None:
            self.clk, nx = nx, nx + 2
            for s_ in raw.isb_systems:
                self.isb[s_], nx = nx, nx + 1
        self.clone = -1                     # TDCP: the antenna and clock-bias clones (sinscli.fusion.tdcp)
        if raw is not None and raw.tdcp:
            self.clone, nx = nx, nx + 4
        self.sat = raw.sat if raw is not None else np.zeros((0, kn.SW))
        # the fixes' time-correlated error (loosely coupled): (sigma_h, sigma_v, tau_h, tau_v), given or found by a
        # calibration pass (gnss_gm_from)
        self.gnss_gm = gnss_gm if gnss_gm is not None else configured_gm(fopts, gnss)
        self.ge = -1
        if self.gnss_gm is not None and raw is None:
            self.ge, nx = nx, nx + 3
        self.ncore, self.nx = ncore, nx
        c = np.asarray(init.Cbn, dtype=float)
        self.method = nav.method_code()
        self.st = sd.new_state(init.time, init.lat, init.lon, init.height, np.asarray(init.vel_n, float), c,
                               self.method, nav.conv)
        self.cflu = conv_to_flu(nav.conv)
        self.mats, self.vecs, self.s3 = kn.workspace(nx)
        lever = fopts.lever_arm if fopts.lever_arm is not None else np.zeros(3)
        self.lever = np.asarray(lever, dtype=float)
        self.gnss_interval = float(np.median(np.diff(gnss.time))) if len(gnss) > 2 else math.inf
        self.drift_base = float(drift_base)
        self.r_base = np.ones(3 * kn.NK) if r_base is None else np.asarray(r_base, dtype=float)
        self.cv = self._config_vector()
        self.fs = np.zeros(kn.FS_SIZE)
        self.fs[kn.F_QS_DRIFT] = self.drift_base
        self.fs[kn.F_T_QS] = init.time
        self.fs[kn.F_RS:kn.F_RS + 3 * kn.NK] = self.r_base
        self.fs[kn.F_T_FIX] = -np.inf
        self.fs[kn.F_TDCP + TD_T] = -np.inf           # no clone yet
        self.fs[kn.F_CT] = -np.inf
        self.fs[kn.F_CL] = self.fs[kn.F_CD] = 1.0
        self.fs[kn.F_LEVER:kn.F_LEVER + 3] = self.lever
        self.fs[kn.F_TPREV] = init.time
        self.fs[kn.F_T_EPOCH] = init.time
        if raw is not None:                 # the clock from the first epoch's data, brought back to the start
            b0, d0 = raw.clock0
            self.fs[kn.F_CLK] = b0 - d0 * (raw.t0 - init.time)
            self.fs[kn.F_CLK + 1] = d0
            for s_, v in raw.isb0.items():
                self.fs[kn.F_ISB + s_] = v
        if init_bias:
            self.fs[kn.F_BG:kn.F_BG + 3] = init_bias.get("gyro", np.zeros(3))
            self.fs[kn.F_BA:kn.F_BA + 3] = init_bias.get("accel", np.zeros(3))
        self.P = self._initial_covariance(init_sigma or {})
        self.g = float(gravity(math.sin(init.lat), init.height))
        self.detector = StandstillDetector(fopts.standstill_window, fopts.standstill_rate_std,
                                           fopts.standstill_accel_std, fopts.standstill_accel_mag, self.g,
                                           fopts.standstill_lowpass)
        t_end = float(gnss.time[-1]) if len(gnss) else init.time
        t_min = init.time + time_tolerance(init.time)
        self.course = course_rows(gnss, fopts, gnss.position_sigma(fopts.gnss_pos_sigma), t_min) if len(gnss) \
            else CourseRows(np.zeros((0, kn.MW)))
        if raw is None:
            rows = [gnss_rows(gnss, fopts, t_min)]
        else:                               # the satellites' measurements; the fixes give the course only
            rows = [raw.rows[raw.rows[:, 0] > t_min], self.course.rows]
        # body-velocity rows measure the lateral and vertical body velocity the NHC would constrain: the two
        # together would count the same information twice (a filter sure of itself twice over); the
        # odometry's rows replace the NHC's
        self.nhc_by_odometry = bool(body_vel is not None and fopts.odometry and len(body_vel.time) and fopts.nhc)
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
        self.rows = self.rows[self.rows[:, 0] > t_min]
        self._t_nhc = init.time
        self._t_end_gnss = t_end
        self.inn_parts, self.ev_parts = [], []
        self.epochs = EpochStore(nx, kn.epoch_width(ncore, nx, self.clk, self.clone)) if smooth else None
        self.smoother_guard = None
        self.guard_times = None
        self.forward_rows = []          # kept for the smoother: (trajectory, variances, sensor estimates)
        self.applied = 0
        self.heading_known = bool(self.fs[kn.F_HEAD_KNOWN] > 0)
        self._source = "<memory>"
        self._block_t0 = init.time
        self.t_log0 = init.time if t_log0 is None else float(t_log0)
        self.heading_check = None
        self.lever_check = None         # a diagnosis pass's contradiction of the configured lever arm (LeverCheck)

    # ------------------------------------------------------------------ set-up
    def _config_vector(self):
        f, m, n = self.fopts, self.model, self.nav
        cv = np.zeros(kn.CV_SIZE)
        cv[kn.C_NX] = self.nx
        cv[kn.C_NCORE] = self.ncore
        cv[kn.C_LA] = self.la
        cv[kn.C_TD] = self.td
        cv[kn.C_METHOD] = self.method
        cv[kn.C_ORDER] = n.coning
        cv[kn.C_NSUB] = n.subsamples
        cv[kn.C_EVERY] = n.every
        cv[kn.C_CONV] = n.conv
        cv[kn.C_PROP_DT] = f.propagation_interval
        for mm in (1, 2, 3):
            cv[kn.C_GATE + mm - 1] = chi2_gate(f.gate_probability, mm)
            cv[kn.C_ROBUST + mm - 1] = chi2_gate(f.robust_probability, mm) if f.robust_probability else 0.0
        cv[kn.C_ARW2:kn.C_ARW2 + 3] = m.arw2
        cv[kn.C_VRW2:kn.C_VRW2 + 3] = m.vrw2
        cv[kn.C_QBG:kn.C_QBG + 3] = m.q_bg
        cv[kn.C_QBA:kn.C_QBA + 3] = m.q_ba
        cv[kn.C_ITG:kn.C_ITG + 3] = m.inv_tau_g
        cv[kn.C_ITA:kn.C_ITA + 3] = m.inv_tau_a
        cv[kn.C_SFG] = m.sfmis_g * f.scale_factor_tau
        cv[kn.C_SFA] = m.sfmis_a * f.scale_factor_tau
        cv[kn.C_SF_TAU] = f.scale_factor_tau
        cv[kn.C_REJ_RUN] = f.rejection_run
        cv[kn.C_RADAPT_N] = f.adapt_window if f.adapt and f.adapt_measurement_noise else 0.0
        cv[kn.C_RADAPT_MAX] = f.adapt_max_scale
        cv[kn.C_RBASE:kn.C_RBASE + 3 * kn.NK] = self.r_base
        # consecutive differences share a measurement: the window's estimate has about 2/3 of its count's
        # degrees of freedom
        nw = max(int(round(f.adapt_window / 1.5)), 1)
        cv[kn.C_RADAPT_BAND] = chi2_gate(1e-4, nw) / nw
        cv[kn.C_RADAPT_BAND + 1] = chi2_gate(1.0 - 1e-4, nw) / nw
        cv[kn.C_QB_MAX] = f.adapt_max_bias_scale if f.adapt and f.adapt_outage_exits else 1.0
        cv[kn.C_QB_TAU] = f.adapt_decay
        cv[kn.C_QB_THR] = f.adapt_exit_ratio
        cv[kn.C_QB_BASE] = self.drift_base
        cv[kn.C_OUTAGE_DT] = f.outage * self.gnss_interval
        cv[kn.C_SMOOTH_DT] = f.smoother_interval if self.smooth else 0.0
        cv[kn.C_ZUPT_MAXV] = f.zupt_max_speed
        fwd = 1 if n.conv == 1 else 0           # RFU: y forward; FLU, FRD: x forward
        lat_axes = [i for i in range(3) if i != fwd]
        cv[kn.C_NHC_AX], cv[kn.C_NHC_AX + 1] = lat_axes
        cv[kn.C_FWD] = fwd
        cv[kn.C_CLK] = self.clk
        cv[kn.C_ISB:kn.C_ISB + 7] = -1.0
        for s_, k in self.isb.items():
            cv[kn.C_ISB + s_] = k
        cv[kn.C_QCLK], cv[kn.C_QCLK + 1] = f.clock_densities()
        cv[kn.C_QISB] = f.clock_isb_walk ** 2
        cv[kn.C_CLK_JUMP] = f.clock_jump
        cv[kn.C_CLK_P0] = f.clock_bias_sigma
        cv[kn.C_TDCP], cv[kn.C_TDCP + 1] = self.clone, f.raw_slip_test
        # the consistency test of the fixes (kernel._consistency): weight 1/window per fix; its mean of NIS/m
        # behaves as chi2(nu)/nu with nu = 3 (2 - a)/a (an exponentially weighted mean of chi2(3)/3): the
        # 1 - 1e-4 quantile is its threshold
        a = 1.0 / f.adapt_window
        nu = 3.0 * (2.0 - a) / a
        cv[kn.C_FADE_ALPHA] = a if f.adapt and f.adapt_widen else 0.0
        cv[kn.C_FADE_THR] = chi2_gate(1.0 - 1e-4, nu) / nu
        cv[kn.C_FADE_MAX] = f.adapt_max_scale
        cv[kn.C_GE] = self.ge
        if self.ge >= 0:
            kh, kv, th, tv = self.gnss_gm
            cv[kn.C_GE_RATIO2:kn.C_GE_RATIO2 + 3] = (kh * kh, kh * kh, kv * kv)
            cv[kn.C_GE_TAU:kn.C_GE_TAU + 3] = (th, th, tv)
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
        if self.ncore == 21:
            P[SG:SG + 3, SG:SG + 3] = np.diag(m.p0_sg)
            P[SA:SA + 3, SA:SA + 3] = np.diag(m.p0_sa)
        if self.la >= 0:
            P[self.la:self.la + 3, self.la:self.la + 3] = np.eye(3) * f.lever_arm_sigma ** 2
        if self.td >= 0:
            P[self.td, self.td] = f.time_offset_sigma ** 2
        if self.ge >= 0:                # the first fix's level (kernel._gnss_error_level)
            kh, kv = self.gnss_gm[:2]
            s0 = self.gnss.position_sigma(f.gnss_pos_sigma)[0] if len(self.gnss) else np.ones(3)
            v0 = np.array([kh, kh, kv]) ** 2 * s0 ** 2
            P[self.ge:self.ge + 3, self.ge:self.ge + 3] = np.diag(v0)
            self.fs[kn.F_GE_V:kn.F_GE_V + 3] = v0
        if self.clk >= 0:
            P[self.clk, self.clk] = max(f.clock_bias_sigma, self.raw.clock0_sigma[0]) ** 2
            P[self.clk + 1, self.clk + 1] = f.clock_drift_sigma ** 2
            for k in self.isb.values():
                P[k, k] = f.clock_isb_sigma ** 2
        if self.clone >= 0:                 # unused until the first raw epoch clones into them
            P[self.clone:self.clone + 4, self.clone:self.clone + 4] = np.eye(4)
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
            if len(t1):                     # still by the IMU, and not moving by the GNSS
                ok = gnss_still(self.gnss, t0, t1) != 0
                t0, t1, w = t0[ok], t1[ok], w[ok]
            n = len(t1)
            if n:
                zs = np.full(n, f.zupt_sigma)
                if f.zupt:
                    parts.append(np.column_stack([t1, np.full(n, kn.MT_ZUPT), np.zeros((n, 3)), zs, zs, zs,
                                                  np.zeros((n, 2))]))
                if f.zaru:
                    sig = f.zaru_sigma if f.zaru_sigma is not None else self._zaru_sigma(t1 - t0)
                    sig = np.broadcast_to(sig, (n,))
                    parts.append(np.column_stack([t1, np.full(n, kn.MT_ZARU), w, sig, sig, sig, np.zeros((n, 2))]))
        if f.nhc and not self.nhc_by_odometry:
            tn = np.arange(self._t_nhc + f.nhc_interval, imu_t[-1] + 1e-9, f.nhc_interval)
            if len(tn):
                self._t_nhc = float(tn[-1])
                n = len(tn)
                s = np.zeros((n, 3))
                ax = self.cv[kn.C_NHC_AX:kn.C_NHC_AX + 2].astype(int)
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

    def _zaru_sigma(self, span):
        """The ZARU 1-sigma of windows ``span`` s long: the spread of a window's mean rate at rest, from the
        log's own standstill (white noise and vibration, :func:`apply_data_noise`) where it is more than
        :data:`~sinscli.fusion.noise.FACTOR` over the model's ``ARW / sqrt(span)``, else the model's."""
        dn = self.data_noise
        white = self.model.arw2.max() / span
        if dn is not None and dn.fitted and self.fopts.noise_from_data:
            # the data's spread where it proves the model's too small (beyond FACTOR in sigma), else the model's
            data = np.max(dn.rate_mean_var(span), axis=-1)
            return np.sqrt(np.where(data > FACTOR ** 2 * white, data, white))
        return np.sqrt(white)

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
        out = (np.empty(cap), np.empty((cap, 3)), np.empty((cap, 3)), np.empty((cap, 3, 3)), np.empty((cap, kn.NVAR)),
               np.empty((cap, kn.NBIAS)))
        inn = np.empty((3 * nm + 3, kn.NREC))
        evs = np.empty((2 * nm + 8, 4))
        if self.smooth:
            ep = self.epochs
            ep.reserve(nm + int((time[-1] - self.fs[kn.F_TPREV]) / self.fopts.smoother_interval) + 4)
            arrays, n0 = ep.arrays(), ep.n
        else:
            arrays, n0 = EpochStore.EMPTY, 0
        n, used, n_inn, n_evs, n_ep = kn.fuse((time, dth, dv), (self.st, self.fs, self.cv, self.P, self.cflu), meas,
                                              (self.mats, self.vecs, self.s3), out, (inn, evs), arrays, n0,
                                              self.sat)
        if self.smooth:
            self.epochs.n = n_ep
        if used < nm:                       # rows at the block's very end go with the next block
            self.rows = sort_rows(np.vstack([meas[used:], self.rows]))
        self.inn_parts.append(inn[:n_inn].copy())
        self.ev_parts.append(evs[:min(n_evs, len(evs))].copy())
        for e in evs[:min(n_evs, len(evs))]:
            self._log_event(e)
        if self.fs[kn.F_ERR] != 0:
            reason = ("turned non-finite" if self.fs[kn.F_ERR] == kn.ERR_NONFINITE
                      else "lost positive definiteness")
            raise SinsError(f"{self._source}: the filter covariance {reason} at t = {self.fs[kn.F_ERR_T]!r} s; "
                            f"stopped there (check the fusion config's sigmas and the sensor description)")
        out_t, out_pos, out_vel, out_cbn, out_var, out_bias = out
        traj = Trajectory(out_t[:n], out_pos[:n, 0], out_pos[:n, 1], out_pos[:n, 2], out_vel[:n], out_cbn[:n])
        var, bias = out_var[:n], out_bias[:n]
        if self.smooth:
            self.forward_rows.append((traj, var, bias))
        else:
            traj.extra = self._columns(var, bias)
        return traj

    def _log_event(self, e):
        t, kind = float(e[0]), e[1]
        c = clock(t, self.t_log0)
        if kind == kn.EV_REJECTION_RUN:
            log.info("fusion: %d consecutive GNSS fixes rejected from %s to %s (the filter diverged or the GNSS "
                     "jumped): navigation covariance widened, fix accepted", int(e[3]),
                     clock(float(e[2]), self.t_log0), c)
        elif kind == kn.EV_HEADING_INIT:
            log.info("fusion: heading initialized from the GNSS course at %s (changed by %.3f deg)", c,
                     math.degrees(e[2]))
        elif kind == kn.EV_RSCALE:
            log.info("fusion: %s innovations at %s: measurement noise variance scale now %.3g",
                     self._axis_name(int(e[2])), c, e[3])
        elif kind == kn.EV_QSCALE:
            log.info("fusion: outage exit at %s: innovation %.3g x its predicted variance: drift process noise "
                     "scale now %.3g", c, e[2], e[3])
        elif kind == kn.EV_REACQUIRE:
            log.info("fusion: outage exit at %s beyond the gate (NIS %.3g): position covariance widened, fix "
                     "accepted", c, e[2])
        elif kind == kn.EV_WIDEN:
            log.info("fusion: GNSS fixes at %s consistent with one another but %.3g x the filter's predicted "
                     "variance: covariance widened x%.3g", c, e[2], e[3])
        elif kind == kn.EV_CLOCK_JUMP:
            log.info("fusion: receiver clock jump of %.6g m (%.4g ms) at %s: the clock bias state reset", e[2],
                     e[2] / 299792.458, c)

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
            out[k] = bias[:, 3 + i] / UG_DECIMAL
        if self.ncore == 21:
            for i, k in enumerate(SF_COLUMNS):
                out[k] = bias[:, 6 + i] * 1e6
        return out

    # ------------------------------------------------------------------ end
    def innovations(self) -> np.ndarray:
        inn = np.vstack(self.inn_parts) if self.inn_parts else np.zeros((0, kn.NREC))
        rec = np.empty(len(inn), dtype=INNOVATION_DTYPE)
        rec["time"] = inn[:, 0]
        rec["type"] = np.array(kn.MEAS_NAMES)[inn[:, 1].astype(int)] if len(inn) else []
        rec["axis"] = AXES[inn[:, 2].astype(int)] if len(inn) else []
        rec["innovation"] = inn[:, 3]
        rec["sigma"] = inn[:, 4]
        rec["nis"] = inn[:, 5]
        rec["accepted"] = inn[:, 6] > 0
        rec["sat"] = ""
        if self.raw is not None and len(inn):
            names = self.raw.sat_names()
            k = inn[:, 11].astype(int)
            mine = k >= 0
            rec["sat"][mine] = names[k[mine]]
        return rec

    def events(self) -> np.ndarray:
        return np.vstack(self.ev_parts) if self.ev_parts else np.zeros((0, 4))

    def smoothed(self) -> Trajectory:
        """The RTS-smoothed trajectory at the forward output rows (the forward rows are consumed)."""
        traj = concat([r[0] for r in self.forward_rows])
        var = np.concatenate([r[1] for r in self.forward_rows])
        bias = np.concatenate([r[2] for r in self.forward_rows])
        self.forward_rows = []
        epochs = self.epochs.trimmed()
        self.smoother_guard = smooth_rows(traj.time, traj.lat, traj.lon, traj.height, traj.vel_n, traj.Cbn, var,
                                          bias, epochs, self.ncore, self.nx, int(self.cv[kn.C_FWD]), self.clk,
                                          self.clone)
        g = self.smoother_guard
        ep_t = epochs[0]
        # the epochs (after the smoothing step's start k: its prior at k + 1) of the first and worst clipped pivot
        self.guard_times = tuple(float(ep_t[min(int(i) + 1, len(ep_t) - 1)]) for i in g[4:6]) if g[4] >= 0 else None
        traj.extra = self._columns(var, bias)
        return traj

    def summary(self, traj: Trajectory) -> FusionSummary:
        rec = self.innovations()
        f = self.fopts
        t0 = self.t_log0
        s = FusionSummary(t0=t0, vehicle=f.vehicle, sensor=self.model.source)
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
        ex = exit_fixes(self.gnss.time, f.outage)
        rej_t = np.unique(rec["time"][(rec["type"] == "gnss_pos") & ~rec["accepted"]])
        s.rejected_outside = int(np.count_nonzero(~np.isin(rej_t, self.gnss.time[ex])))
        s.outages = outages(self.gnss.time[inside], f.outage)
        s.standstill = standstill_intervals(rec, f.standstill_window)
        s.residuals = fix_residuals(traj, self.gnss, self.fs[kn.F_LEVER:kn.F_LEVER + 3], inside, f.outage)
        if self.raw is not None:
            s.raw = self._raw_summary(rec, t1)
            s.outages = []                  # the fixes' gaps are no outage of a tightly coupled filter
        if len(traj):
            s.final_sigma = {k: float(traj.extra[k][-1]) for k in SIGMA_COLUMNS}
        # the sensor model and where its terms came from
        if self.model.default:
            s.sensor_notes.append(f"no sensor description given (fusion.sensor / --sensor): the conservative "
                                  f"'{DEFAULT_SENSOR}' preset where the log does not tell")
        elif self.model.assumed:
            s.sensor_notes.append(f"description without {', '.join(self.model.assumed)}: the '{DEFAULT_SENSOR}' "
                                  f"preset's value assumed")
        s.sensor_notes.extend(self.data_notes)
        ev = self.events()
        for e in ev:
            if e[1] == kn.EV_HEADING_INIT and s.heading_init is None:
                s.heading_init_time = float(e[0])
                s.heading_init = (f"heading from the GNSS course ({self.course.source}) at {clock(float(e[0]), t0)}: "
                                  f"changed by {math.degrees(e[2]):.1f} deg, 1-sigma {math.degrees(e[3]):.2g} deg")
            elif e[1] == kn.EV_REJECTION_RUN:
                s.rejection_runs.append((float(e[2]), float(e[0]), int(e[3])))
        self._adaptation_lines(ev, s)
        if self.fs[kn.F_HEAD_KNOWN] == 0.0:
            s.heading_never = self._why_no_heading()
            s.warnings.append(s.heading_never)
        if self.sf_for_lever:
            s.estimates.append("scale factors (21 states), since the lever arm is estimated: an unestimated scale "
                               "factor would bias it")
        self._unobserved(s)
        if self.la >= 0:
            sig = np.sqrt(np.diag(self.P)[self.la:self.la + 3])
            s.estimates.append("lever arm [{:.3f}, {:.3f}, {:.3f}] m +- [{:.2g}, {:.2g}, {:.2g}] m (body axes)".format(
                *self.fs[kn.F_LEVER:kn.F_LEVER + 3], *sig))
        if self.td >= 0:
            s.estimates.append(f"GNSS time offset {self.fs[kn.F_TD]:+.4f} s +- {math.sqrt(self.P[self.td, self.td]):.2g} s "
                               f"(to add to the GNSS stamps: gnss.time_offset)")
        if self.smooth:
            g = self.smoother_guard
            where = ""
            if g is not None and g[0] and self.guard_times is not None:
                where = (f" from {clock(self.guard_times[0], t0)}, the worst at {clock(self.guard_times[1], t0)}: "
                         f"the filter's covariance before that update was not its propagation plus process noise")
            s.smoothed = "smoothed (RTS, factored Joseph form)" + (
                f"; guard: {int(g[0])} pivot(s) clipped (worst {g[1]:.2g} of its diagonal){where}, {int(g[2])} "
                f"gain(s) with a ridge, over {int(g[3])} epochs" if g is not None and (g[0] or g[2]) else "")
        if len(traj) and self.fs[kn.F_HEAD_KNOWN] > 0.0 and f.vehicle != "aircraft":
            hc = heading_course_check(traj, self.gnss, int(self.cv[kn.C_FWD]), traj.extra.get("heading_std"))
            self.heading_check = s.heading_check = hc
            if hc.mismatch:
                s.warnings.append(
                    f"the heading is {hc.median_offset:+.1f} deg off the GNSS course on {hc.segments} straight "
                    f"segments (beyond 3 sigma on {100 * hc.beyond_3sigma:.0f} %, sigma {hc.median_sigma:.2g} deg): "
                    f"the IMU's mounting yaw is likely off by that much (imu.mounting, or imu.mounting: auto)")
        lc = self.lever_check
        if lc is not None and lc.contradicted.any():
            bad = [a for a, c in zip("xyz", lc.contradicted) if c]
            s.warnings.append(
                f"the fixes contradict the lever arm {[round(float(v), 3) for v in self.lever]} m: a pass that "
                f"estimated it found [{lc.estimate[0]:.3f}, {lc.estimate[1]:.3f}, {lc.estimate[2]:.3f}] m +- "
                f"[{lc.sigma[0]:.2g}, {lc.sigma[1]:.2g}, {lc.sigma[2]:.2g}] m (body axes; off along "
                f"{', '.join(bad)}): set gnss.lever_arm, or fusion.estimate: [lever_arm]")
        if self.nhc_by_odometry:
            s.hints.append("NHC not applied: the body-velocity (odometry) rows measure the lateral and vertical "
                           "velocity it would constrain")
        if f.vehicle == "none":
            hint = ground_vehicle_hint(self.gnss)
            if hint:
                s.hints.append(hint)
        return s

    def _raw_summary(self, rec, t1: float) -> RawSummary:
        """What the tightly coupled run did with the satellites (:class:`sinscli.fusion.summary.RawSummary`)."""
        raw = self.raw
        inside = (raw.epoch_time > self.init.time) & (raw.epoch_time <= t1 + time_tolerance(t1))
        n = raw.epoch_nsat[inside]
        rs = RawSummary(epochs=int(inside.sum()), few=int(((n > 0) & (n < 4)).sum()), none=int((n == 0).sum()))
        rs.few_spans = few_satellite_spans(raw.epoch_time[inside], n)
        m = (rec["type"] == "pseudorange") | (rec["type"] == "doppler")
        sats = rec["sat"][m]
        letters = np.array([x[:1] for x in sats])
        rs.per_system = satellite_counts(letters, rec["type"][m], rec["accepted"][m])
        for c in rs.per_system:
            rs.satellites[c] = int(len(np.unique(sats[letters == c])))
        for t, unit in (("pseudorange", "m"), ("doppler", "m/s")):
            a = rec[(rec["type"] == t) & rec["accepted"]]
            if len(a):
                rs.rms[t] = float(np.sqrt(np.mean(a["innovation"] ** 2)))
        c, P = self.clk, self.P
        rs.clock = (float(self.fs[kn.F_CLK]), math.sqrt(P[c, c]), float(self.fs[kn.F_CLK + 1]),
                    math.sqrt(P[c + 1, c + 1]))
        ref = SYS_CHARS[raw.ref]
        for s_, k in self.isb.items():
            rs.isb.append((f"{SYS_CHARS[s_]}-{ref}", float(self.fs[kn.F_ISB + s_]), math.sqrt(P[k, k])))
        ev = self.events()
        rs.jumps = int(np.sum(ev[:, 1] == kn.EV_CLOCK_JUMP)) if len(ev) else 0
        rs.ref = ref
        rs.notes = list(raw.notes) + (tdcp_notes(rec, ev, raw.tdcp_info) if raw.tdcp_info else [])
        return rs

    def _adaptation_lines(self, ev, s: FusionSummary) -> None:
        """Every adaptation of the run with its cause (:mod:`sinscli.fusion.kernel`)."""
        t0 = self.t_log0
        if not len(ev):
            ev = np.zeros((0, 4))
        for code in np.unique(ev[ev[:, 1] == kn.EV_RSCALE, 2]).astype(int):
            e = ev[(ev[:, 1] == kn.EV_RSCALE) & (ev[:, 2] == code)]
            s.adaptations.append(
                f"{self._axis_name(code)} noise variance x{e[-1, 3]:.3g} at the end (max x{e[:, 3].max():.3g}, "
                f"{len(e)} change(s) from {clock(float(e[0, 0]), t0)}): its innovations said it was noisier "
                f"than its stated sigma")
        kpos = 3 * kn.K_OF_KIND[kn.MT_GNSS_POS]
        for i in np.nonzero(self.r_base != 1.0)[0]:
            name = self._axis_name(3 * kn.K_OF_KIND.index(i // 3) + i % 3)
            if self.ge >= 0 and kpos <= i < kpos + 3:
                s.adaptations.append(f"{name} white noise variance x{self.r_base[i]:.3g} of the stated: the rest "
                                     f"of the fixes' error is in the GNSS error states")
                continue
            s.adaptations.append(
                f"{name} noise variance x{self.r_base[i]:.3g} from the start: calibrated by a first pass on the "
                f"log's innovations (their variance and their correlation from one measurement to the next)")
        if self.ge >= 0:
            kh, kv, th, tv = self.gnss_gm
            med = stated_sigma(self.gnss, self.fopts)
            sh, sv = kh * med[0], kv * med[1]
            src = ("fusion.gnss_error" if configured_gm(self.fopts, self.gnss) is not None else
                   "found by a first pass: the innovations of the fixes were correlated from one fix to the next")
            s.adaptations.append(
                f"the fixes' time-correlated error estimated as states (Gauss-Markov, 1-sigma {kh:.3g} / {kv:.3g} "
                f"times each fix's stated sigma horizontal / vertical, {sh:.3g} / {sv:.3g} m at the median fix, "
                f"correlation time {th:.3g} s / {tv:.3g} s): {src}")
        if self.bias_var is not None:
            d = 3600.0 / DEG
            sg, sa = np.sqrt(self.model.p0_bg), np.sqrt(self.model.p0_ba)
            s.adaptations.append(
                f"turn-on bias 1-sigma gyro [{sg[0] * d:.3g}, {sg[1] * d:.3g}, {sg[2] * d:.3g}] deg/h, accelerometer "
                f"[{sa[0] / UG_DECIMAL:.3g}, {sa[1] / UG_DECIMAL:.3g}, {sa[2] / UG_DECIMAL:.3g}] ug from the start: a "
                f"first pass over the log estimated biases beyond {BIAS_OUTSIDE:g} sigma of the sensor model's")
        if self.drift_base != 1.0:
            s.adaptations.append(
                f"drift process noise (bias instability, scale factor, misalignment) x{self.drift_base:.3g} from "
                f"the start: calibrated by a first pass over the log on its outage exits (the worst at the 99 % "
                f"level of its predicted variance)")
        q = ev[ev[:, 1] == kn.EV_QSCALE]
        if len(q):
            s.adaptations.append(
                f"drift process noise (bias instability, scale factor, misalignment) x{q[:, 3].min():.3g} to "
                f"x{q[:, 3].max():.3g} ({len(q)} change(s) from {clock(float(q[0, 0]), t0)}: outage exits whose "
                f"innovation was {q[:, 2].min():.3g}-{q[:, 2].max():.3g}x its predicted variance), decaying to 1 "
                f"with {self.fopts.adapt_decay:g} s")
        w = ev[ev[:, 1] == kn.EV_WIDEN]
        if len(w):
            s.adaptations.append(
                f"covariance widened {len(w)} time(s) x{w[:, 3].min():.3g} to x{w[:, 3].max():.3g} (first at "
                f"{clock(float(w[0, 0]), t0)}): GNSS fixes consistent with one another drifted away from the "
                f"filter's prediction by {w[:, 2].min():.3g}-{w[:, 2].max():.3g}x its variance")
        rq = ev[ev[:, 1] == kn.EV_REACQUIRE]
        s.reacquired = len(rq)

    def on_gnss_clock(self, traj: Trajectory) -> Trajectory:
        """With the time offset estimated, the output moved onto the GNSS clock: ``t - tau`` (the IMU clock is
        the GNSS's plus ``tau``, the final estimate)."""
        if self.td >= 0 and len(traj):
            traj.time = traj.time - self.fs[kn.F_TD]
        return traj

    def _unobserved(self, s: FusionSummary) -> None:
        """An estimated parameter whose sigma the motion left above UNOBSERVED of its prior: a warning; its estimate
        stays at the configured value (the filter's gain for it was near zero) and that value is the one to
        keep."""
        f = self.fopts
        if self.la >= 0:
            sig = np.sqrt(np.diag(self.P)[self.la:self.la + 3])
            bad = [a for a, x in zip("xyz", sig) if x > UNOBSERVED * f.lever_arm_sigma]
            if bad:
                s.warnings.append(f"the motion did not observe the lever arm's {', '.join(bad)} (1-sigma still over "
                                  f"{UNOBSERVED:g} of its prior {f.lever_arm_sigma:g} m): keep the configured value "
                                  f"{[round(float(v), 3) for v in self.lever]} m for {', '.join(bad)}")
        if self.td >= 0 and math.sqrt(self.P[self.td, self.td]) > UNOBSERVED * f.time_offset_sigma:
            s.warnings.append(f"the motion did not observe the GNSS time offset (1-sigma still over {UNOBSERVED:g} of "
                              f"its prior {f.time_offset_sigma:g} s): keep the configured gnss.time_offset")

    def _axis_name(self, code: int) -> str:
        """``gnss_pos u`` of an R-scale event's code ``3 kind + component``."""
        kind, a = divmod(code, 3)
        if kind == kn.MT_NHC:
            axis = "xyz"[int(self.cv[kn.C_NHC_AX + a])]
        elif kind == kn.MT_ODOM:
            axis = "xyz"[a]
        else:
            axis = "enu"[a]
        return f"{kn.MEAS_NAMES[kind]} {axis}"

    def _why_no_heading(self) -> str:
        f, c = self.fopts, self.course
        if len(self.gnss) < 2:
            why = "the GNSS log has fewer than two fixes"
        elif not np.isfinite(c.best_sigma):
            why = "the GNSS never showed motion"
        else:
            why = (f"the best GNSS course had a 1-sigma of {math.degrees(c.best_sigma):.3g} deg "
                   f"(at {clock(c.best_time, self.t_log0)}), over heading_init.max_course_sigma "
                   f"{math.degrees(f.heading_max_course_sigma):.3g} deg: too little travel against the fixes' sigma "
                   f"(or speed under heading_init.min_speed {f.heading_min_speed:g} m/s)")
        return (f"the heading was never initialized: {why}; GNSS velocity, NHC and odometry were not used "
                f"(give --init with a heading, or --align)")

    def finish(self) -> None:
        """Refuse a log with no IMU sample after the initial time (the smoother and the summary are
        :meth:`smoothed` and :meth:`summary`)."""
        if self.applied == 0:
            raise SinsError(f"{self._source}: no IMU sample after the initial time {self.init.time!r}: "
                            f"the init time is outside the log")


UNOBSERVED = 0.3            # an estimated parameter whose sigma stays over this share of its prior: not observed
EXIT_QUANTILE = 4.605170185988091 / 2.0     # the 99 % quantile of chi-square(2) / 2: an exit's ratio
EXIT_FAR = 18.420680743952364 / 2.0         # its 1 - 1e-4 quantile
BIAS_OUTSIDE = 3.0          # a first pass's bias estimate beyond this many prior sigmas: the prior was wrong
MAX_TURN_ON_GYRO = 10.0 * DEG       # rad/s: the largest turn-on gyro bias taken from a pass (a phone's: 4 deg/s)
MAX_TURN_ON_ACCEL = 0.5 * G0        # m/s^2: the same of an accelerometer (a consumer chip's: under 0.1 g)


def bias_var_from(fusion: Fusion):
    """The turn-on bias variances (gyro rad^2/s^2, accelerometer m^2/s^4 per body axis, ``(6,)``) a pass over
    the log implies, or None: where its final bias estimate stands beyond :data:`BIAS_OUTSIDE` sigmas of the
    prior the pass ran with, the prior was not this sensor's (a phone's gyro with a turn-on bias of degrees
    per second described as a tactical one: its innovations drift away until the consistency test widens
    the covariance, and only then can the estimate move), and the square of the estimate becomes that
    axis' prior variance; the next pass then starts honest."""
    m = fusion.model
    p0 = np.concatenate([m.p0_bg, m.p0_ba])
    est = np.asarray(fusion.fs[kn.F_BG:kn.F_BA + 3], dtype=float) ** 2
    # an estimate beyond what any IMU turns on with is the pass's divergence, not a bias: not taken
    plausible = est <= np.repeat(np.array([MAX_TURN_ON_GYRO, MAX_TURN_ON_ACCEL]) ** 2, 3)
    out = np.where((est > BIAS_OUTSIDE ** 2 * p0) & plausible, est, p0)
    return out if np.any(out != p0) else None


def drift_base_from(fusion: Fusion, min_exits: int = 3) -> float:
    """The drift process-noise base scale a pass over the log (``fusion``, run to its end, itself with a
    base ``b``) implies: its outage exits' ratios (horizontal innovation squared over predicted variance,
    those where the prediction dominates the innovation variance) scaled so that the largest sits at the
    99 % quantile of a consistent exit's (chi-square(2)/2): ``b * r_max / 2.3``, within
    ``[1/max, max]`` (``adapt.max_bias_scale``).  With fewer than ``min_exits`` such exits, or within a
    factor 2 of ``b``, ``b`` itself.  Aiming the worst exit at the 99 % quantile keeps every outage
    inside its 3 sigma when the description is optimistic, and lowers a pessimistic one (whose exits all
    fall far inside) without letting any exit out.  With fewer exits the base is only raised, and only by
    an exit beyond the 1 - 1e-4 quantile (:data:`EXIT_FAR`): one exit that far out is evidence enough that
    the drift terms were optimistic; a few exits well inside are not evidence that they were pessimistic."""
    b0 = fusion.drift_base
    ev = fusion.events()
    ex = ev[ev[:, 1] == kn.EV_EXIT] if len(ev) else ev
    r = ex[ex[:, 3] < 0.25, 2] if len(ex) else np.zeros(0)
    r = r[r > 0]
    if not len(r) or (len(r) < min_exits and r.max() <= EXIT_FAR):
        return b0
    base = b0 * float(r.max()) / EXIT_QUANTILE
    if 0.5 * b0 < base < 2.0 * b0:
        return b0
    m = fusion.fopts.adapt_max_bias_scale
    return float(min(max(base, 1.0 / m), m))


MAX_CORRELATION_FACTOR = 100.0


def r_base_from(fusion: Fusion, min_n: int = 30) -> np.ndarray:
    """The measurement-noise scales (per adapted kind and component, :data:`kernel.K_OF_KIND`) a pass over
    the log implies, by covariance matching over the whole log: ``s = sum(min(z^2, 9 S) - H P H^T) /
    sum(R)`` (outage exits left out), times the variance inflation ``(1 + rho) / (1 - rho)`` of the
    measurement errors' correlation between consecutive measurements (``rho`` the lag-1 correlation of the
    normalized innovations, when over 0.1 and significant at 3 sigma): a receiver's time-correlated error
    carries less information than as many independent fixes (at most 10x).  Within ``[1,
    adapt.max_scale]``; 1 with fewer than ``min_n`` measurements, within 25 % of 1 or within the
    estimate's 3-sigma band of 1, or when the pass had a rejection run (its innovations then
    hold the filter's own excursion, not the measurements' noise).  (Within one pass the online adaptation only sees the white part,
    :func:`sinscli.fusion.kernel._adapt_r`: a slowly diverging filter cannot pass for noisy
    measurements there; across passes it is one measured step, not a loop.)"""
    out = fusion.r_base.copy()
    inn = np.vstack(fusion.inn_parts) if fusion.inn_parts else np.zeros((0, kn.NREC))
    ev = fusion.events()
    if not len(inn) or (len(ev) and np.any(ev[:, 1] == kn.EV_REJECTION_RUN)):
        return out              # a pass that lost the fixes (a GNSS jump, a divergence) tells nothing of R
    for kind, k in enumerate(kn.K_OF_KIND):
        if k < 0:
            continue
        for a in range(3):
            x = inn[(inn[:, 1] == kind) & (inn[:, 10] == a) & (inn[:, 9] == 0)]
            if len(x) < min_n:
                continue
            z, S, hph, r = x[:, 3], x[:, 4] ** 2, x[:, 7], x[:, 8]
            s = float(np.sum(np.minimum(z * z, 9.0 * S) - hph) / np.sum(r))
            u = z / np.sqrt(S)
            dt = np.diff(x[:, 0])
            ok = dt <= 1.5 * np.median(dt)
            n = int(ok.sum())
            rho = float(np.corrcoef(u[:-1][ok], u[1:][ok])[0, 1]) if n > 10 else 0.0
            if np.isfinite(rho) and rho > max(0.1, 3.0 / math.sqrt(max(n, 1))):    # significant at 3 sigma
                s *= min((1.0 + rho) / (1.0 - rho), MAX_CORRELATION_FACTOR)
            s = min(max(s, 1.0), fusion.fopts.adapt_max_scale)
            if s > max(1.25, 1.0 + 3.0 * math.sqrt(2.0 / len(x))):                   # beyond its 3-sigma band
                out[3 * k + a] = s
    return out


def stated_sigma(gnss: GnssLog, fopts: FusionOptions) -> np.ndarray:
    """``(2,)`` the median stated 1-sigma of the fixes (m): horizontal (east and north pooled), vertical."""
    sp = gnss.position_sigma(fopts.gnss_pos_sigma) if len(gnss) else np.tile(fopts.gnss_pos_sigma, (1, 1))
    return np.array([float(np.median(sp[:, :2])), float(np.median(sp[:, 2]))])


def configured_gm(fopts: FusionOptions, gnss: GnssLog):
    """``(k_h, k_v, tau_h, tau_v)`` of the GNSS error states the config sets in full (``fusion.gnss_error`` with
    both ``tau`` > 0 and ``sigma``): ``k`` the configured sigma over the fixes' median stated sigma (each fix's
    correlated error is its stated sigma times ``k``, kernel._gnss_error_level); else None (off, or to be
    found by :func:`gnss_gm_from`)."""
    tau, sig = fopts.gnss_error_tau, fopts.gnss_error_sigma
    if tau is None or sig is None or not np.all(tau > 0):
        return None
    med = stated_sigma(gnss, fopts)
    return (float(sig[0] / med[0]), float(sig[1] / med[1]), float(tau[0]), float(tau[1]))


GM_MIN_RHO = 0.5        # a lag-1 correlation of the fixes' innovations over this (and significant): a correlated error
GM_TAU_MIN = 20.0       # s: the shortest correlation time taken for it (receivers' position errors, multipath and
                        # atmosphere, stay correlated over minutes: Groves 2013, "Principles of GNSS, Inertial, and
                        # Multisensor Integrated Navigation Systems", 2nd ed., sec. 9.3)
GM_MAX_LAG = 400        # fixes: the longest lag of the autocorrelation fitted


def _acf_gm(t, z, min_n):
    """``(tau s, share)`` of a first-order Gauss-Markov part in innovations ``z`` at times ``t`` (nearly regular):
    the autocorrelation ``r(k) = share * exp(-k dt / tau)`` fitted (least squares on ``log r``, lags from 1 to
    where ``r`` first falls under 0.1), or None when the lag-1 correlation is under :data:`GM_MIN_RHO` or not
    significant at 3 sigma."""
    n = len(z)
    if n < min_n:
        return None
    dt = float(np.median(np.diff(t)))
    if not dt > 0.0:
        return None
    zc = z - z.mean()
    v = float(np.mean(zc * zc))
    if not v > 0.0:
        return None
    lags, r = [], []
    for k in range(1, min(GM_MAX_LAG, n // 4)):
        rk = float(np.mean(zc[:-k] * zc[k:])) / v
        if rk < 0.1:
            break
        lags.append(k)
        r.append(rk)
    if not r or r[0] < max(GM_MIN_RHO, 3.0 / math.sqrt(n)):
        return None
    if len(r) < 2:                          # one lag only: the correlation time from it
        tau = -dt / math.log(min(r[0], 1.0 - 1e-9))
        return tau, 1.0
    x, y = np.asarray(lags, float) * dt, np.log(np.asarray(r))
    slope, icpt = np.polyfit(x, y, 1)
    if not slope < 0.0:
        return None
    return float(-1.0 / slope), float(min(math.exp(icpt), 1.0))


def gnss_gm_from(fusion: Fusion, min_n: int = 60):
    """The GNSS error states a pass over the log implies, ``((k_h, k_v, tau_h, tau_v), white (3,))``, or None:
    where the innovations of its fixes (outage exits left out), in units of each fix's stated sigma, are
    correlated from one fix to the next (:func:`_acf_gm`), their correlated share of the mean square is the
    steady variance ``k^2`` (per stated variance) and the fitted decay the correlation time, the rest the
    white noise's share ``white``: of the mean square, never under the stated variance, and the time never
    under :data:`GM_TAU_MIN`; the horizontal axes pooled, the vertical on its own (an axis without a
    correlated part gets the other's time and 1/10 of its stated sigma).  Off when the config set
    ``fusion.gnss_error.tau: 0``, when the pass already had them, for a tightly coupled run, and (unless the
    config asks for them) when the GNSS time offset is estimated: along the track a slowly varying fix error
    and a time offset look alike."""
    f = fusion.fopts
    if fusion.ge >= 0 or fusion.raw is not None or (f.gnss_error_tau is not None and not np.all(f.gnss_error_tau > 0)):
        return None
    if fusion.td >= 0 and f.gnss_error_tau is None:
        return None             # along the track a slow fix error and a time offset are one: the offset is asked for
    inn = np.vstack(fusion.inn_parts) if fusion.inn_parts else np.zeros((0, kn.NREC))
    x = inn[(inn[:, 1] == kn.MT_GNSS_POS) & (inn[:, 9] == 0)]
    fits, ms = [], []
    for a in range(3):
        y = x[x[:, 10] == a]
        zn = y[:, 3] / np.sqrt(y[:, 8]) if len(y) else y[:, 3]       # in units of each fix's stated sigma
        fits.append(_acf_gm(y[:, 0], zn, min_n) if len(y) else None)
        ms.append(float(np.mean(zn ** 2)) if len(y) else 0.0)
    if all(fi is None for fi in fits):
        return None
    out = []
    white = np.ones(3)
    for axes in ((0, 1), (2,)):
        got = [a for a in axes if fits[a] is not None]
        if got:
            # the fixes' error is never taken smaller than the receiver states it (a first pass's filter follows
            # part of a slow error, its innovations are smaller than the error); the correlation time never
            # shorter than GM_TAU_MIN (the same following shortens the innovations' correlation)
            tot = [max(ms[a], 1.0) for a in got]
            var = float(np.mean([fits[a][1] * m for a, m in zip(got, tot)]))
            tau = max(float(np.exp(np.mean([math.log(fits[a][0]) for a in got]))), GM_TAU_MIN)
            for a, m in zip(got, tot):      # the rest of the mean square is the white noise's
                white[a] = _white_scale((1.0 - fits[a][1]) * m, 1.0)
        else:
            var, tau = None, None
        out.append((var, tau))
    taus = [tau for _, tau in out if tau is not None]
    res = []
    for (var, tau), axes in zip(out, ((0, 1), (2,))):
        if var is None:                 # an axis without a correlated part: a tenth of its stated sigma
            var, tau = 0.01, float(np.exp(np.mean(np.log(taus))))
        if f.gnss_error_tau is not None:
            tau = float(f.gnss_error_tau[0 if axes == (0, 1) else 1])
        res.append((math.sqrt(max(var, 1e-12)), tau))
    if f.gnss_error_sigma is not None:
        med = stated_sigma(fusion.gnss, f)
        res = [(float(f.gnss_error_sigma[0] / med[0]), res[0][1]), (float(f.gnss_error_sigma[1] / med[1]), res[1][1])]
    return (res[0][0], res[1][0], res[0][1], res[1][1]), white


WHITE_MIN = 0.01        # the fixes' white noise kept at least this share of their stated variance


def _white_scale(var_white: float, r_stated: float) -> float:
    """The fixes' white-noise variance as a scale of their stated variance (the rest of their error is in the
    Gauss-Markov states): at least :data:`WHITE_MIN`, at most 1 (the receiver's sigma holds both parts)."""
    return float(min(max(var_white / max(r_stated, 1e-300), WHITE_MIN), 1.0))


def calibrated_run(make, run, smooth: bool = False, passes: int = 3):
    """Run the log through ``make(smooth=.., drift_base=b, r_base=rb, bias_var=bv, gnss_gm=gm)`` (a
    :class:`Fusion`; ``run(f)`` feeds it the log and returns its chunks), then again with the turn-on bias
    priors (:func:`bias_var_from`), the drift process noise (:func:`drift_base_from`), the measurement noise
    (:func:`r_base_from`) and the fixes' correlated error (:func:`gnss_gm_from`, from the first pass whose bias
    priors held) its innovations imply, until a pass confirms its own (at most ``passes``; a consistent log
    costs one).  Returns ``(fusion, chunks)`` of the last pass."""
    base, rb, bv, gm = 1.0, None, None, None
    for i in range(passes):
        f = make(smooth=smooth, drift_base=base, r_base=rb, bias_var=bv, gnss_gm=gm)
        chunks = run(f)
        if not (f.fopts.adapt and f.fopts.adapt_passes) or i == passes - 1:
            break
        new_bv = bias_var_from(f) if bv is None else None        # the bias priors once: the next pass is honest
        new_base = drift_base_from(f) if has_outages(f.gnss, f.fopts) else base
        # the measurement noise (and the fixes' correlated error) from a pass whose bias priors held (else its
        # innovations hold the filter's own excursion), once
        new_gm, new_rb = None, f.r_base
        if rb is None and new_bv is None:
            got = gnss_gm_from(f)
            new_rb = r_base_from(f)
            if got is not None:             # the fixes' correlated error is now a state: their white R the rest
                k = 3 * kn.K_OF_KIND[kn.MT_GNSS_POS]
                new_gm, new_rb[k:k + 3] = got
        if new_bv is None and new_gm is None and new_base == base and np.array_equal(new_rb, f.r_base):
            break
        base, rb = new_base, (rb if new_bv is not None else new_rb)
        bv = new_bv if new_bv is not None else bv
        gm = new_gm if new_gm is not None else gm
    if f.fopts.adapt and f.fopts.adapt_passes and f.la < 0 and f.raw is None and contradicted(f):
        # the fixes contradicted the filter: one pass with the lever arm as states says whether the configured
        # lever arm is the cause (a wrong one shows in every turn); its output is not used
        d = make(smooth=False, drift_base=base, r_base=rb, bias_var=bv, gnss_gm=gm, lever_diagnosis=True)
        run(d)
        f.lever_check = lever_diagnosis(d)
    return f, chunks


def contradicted(fusion: Fusion) -> bool:
    """Whether the fixes contradicted a pass: a widening of its covariance or a rejection run."""
    ev = fusion.events()
    return bool(len(ev) and np.any((ev[:, 1] == kn.EV_WIDEN) | (ev[:, 1] == kn.EV_REJECTION_RUN)))


def lever_diagnosis(d: Fusion) -> LeverCheck | None:
    """The configured lever arm against a diagnosis pass's estimate of it (:class:`LeverCheck`), or None when
    the motion did not observe it (every axis' sigma over :data:`UNOBSERVED` of its prior)."""
    sig = np.sqrt(np.diag(d.P)[d.la:d.la + 3])
    observed = sig < UNOBSERVED * d.fopts.lever_arm_sigma
    if not observed.any():
        return None
    est = np.asarray(d.fs[kn.F_LEVER:kn.F_LEVER + 3], dtype=float)
    return LeverCheck(estimate=est, error=d.lever - est, sigma=np.where(observed, sig, np.inf))


def has_outages(gnss: GnssLog, fopts: FusionOptions) -> bool:
    """Whether the GNSS log has an outage (a gap over ``fusion.outage`` nominal intervals)."""
    return len(outages(gnss.time, fopts.outage)) > 0


def fuse_blocks(blocks, fusion: Fusion, progress=None):
    """Yield forward-filtered trajectory chunks (the initial row first) for an iterable of IMU blocks."""
    yield from stream_blocks(fusion, blocks, progress)


def run_fusion(imu: ImuLog, init: NavState, gnss: GnssLog, fopts: FusionOptions | None = None,
               nav: NavOptions | None = None, smooth: bool = False, init_sigma=None, body_vel=None,
               init_bias=None, data_noise=None, raw=None):
    """Fuse a whole in-memory log; returns ``(trajectory, innovations, summary, fusion)``.  With adaptation
    on, the passes of :func:`calibrated_run` (one for a consistent log).  ``raw``: tightly coupled on these
    raw GNSS rows (:func:`sinscli.fusion.raw.raw_measurements`; ``gnss`` then its single-point fixes)."""
    fopts = fopts or FusionOptions()

    def make(**kw):
        return Fusion(init, nav or NavOptions(), fopts, gnss, init_sigma=init_sigma, body_vel=body_vel,
                      init_bias=init_bias, data_noise=data_noise, t_log0=imu.t0, raw=raw, **kw)

    f, chunks = calibrated_run(make, lambda f: list(fuse_blocks([imu], f)), smooth)
    traj = concat(chunks)
    if smooth:
        traj = f.smoothed()
    traj = f.on_gnss_clock(traj)
    return traj, f.innovations(), f.summary(traj), f
