"""The alignment stage: IMU increments (and GNSS) + options -> the initial state with its 1-sigma.

``align(imu, opts, gnss) -> AlignResult``: selects the interval, checks the
input (length, base at rest for ``static``, a translating base for
``inertial``, GNSS coverage, position), resolves the sensor error budget
(:mod:`.budget`: the description checked against the log, or the log alone),
runs the method's kernels (:mod:`.coarse`, :mod:`.inertial` + :mod:`.wahba` +
:mod:`.fit`, :mod:`.kf`), decides where the heading comes from
(:mod:`.observability`) and returns the state at the end of the interval,
where navigation starts, with its attitude covariance: never below the
noise-only floor of the method, never 0.  No file I/O: readers and writers are
the CLI's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SinsError
from ..nav.earth import dlon, gravity, radii
from ..nav.pipeline import NavOptions
from ..nav import imu_stats
from ..nav.rotation import conv_to_flu, dcm_to_euler, dcm_to_euler_many, euler_to_dcm, rotvec_to_dcm
from ..types import GnssLog, ImuLog, NavState, time_tolerance
from ..units import G0, MG, UG_DECIMAL
from . import budget as budget_mod
from . import coarse, fit, inertial, kf, observability, wahba
from .options import AlignOptions


@dataclass
class Window:
    """The IMU increments of the alignment interval (t0, t0 + T]."""
    t0: float
    time: np.ndarray        # (M,) interval ends
    dtheta_b: np.ndarray    # (M, 3)
    dvel_b: np.ndarray      # (M, 3)
    source: str

    @property
    def T(self) -> float:
        return float(self.time[-1] - self.t0)

    @property
    def dt(self) -> np.ndarray:
        return np.diff(np.concatenate([[self.t0], self.time]))

    @property
    def all_times(self) -> np.ndarray:
        """t0 and the M sample times (the rows of the integrated arrays)."""
        return np.concatenate([[self.t0], self.time])


@dataclass
class Series:
    """Attitude estimate against alignment time."""
    time: np.ndarray                    # (n,) s
    cbn: np.ndarray                     # (n, 3, 3) estimate of the current attitude
    cbn0: np.ndarray | None = None      # (n, 3, 3) estimate of the attitude at the start


@dataclass
class AlignResult:
    state: NavState                     # at the end of the interval (or its start with --epoch start)
    method: str
    t0: float
    duration: float
    sigma: np.ndarray                   # (3,) rad: roll, pitch, heading (heading nan when unknown)
    heading_source: str                 # earth-rate | gnss-motion | gnss-course | user
    gyro_bias: np.ndarray | None = None     # (3,) rad/s body, estimated (kf, inertial-frame fit)
    accel_bias: np.ndarray | None = None    # (3,) m/s^2 body, estimated
    notes: list = field(default_factory=list)
    series: Series | None = None
    roll_window: float | None = None
    sigma_basis: str = "config"             # config | data | config+data (see budget.resolve)
    cov: np.ndarray | None = None           # (3, 3) rad^2 attitude error covariance, ENU at the state's time
    sigma_floor: np.ndarray | None = None   # (3,) rad: the noise-only (Cramer-Rao-like) floor of the method
    gyro_bias_sigma: np.ndarray | None = None   # (3,) rad/s 1-sigma of gyro_bias
    accel_bias_sigma: np.ndarray | None = None  # (3,) m/s^2
    budget: object = None                   # budget.Budget used
    residual: dict = field(default_factory=dict)    # fit statistics: chi2_dof, unmodelled noise
    dropped: dict = field(default_factory=dict)     # outliers rejected: gnss_velocity, course, kf_updates

    def yaml_extra(self, conv_name: str) -> dict:
        """The keys ``sins align`` adds to the docs/formats.md initial state."""
        d = math.degrees
        out = {"method": self.method, "duration": float(self.duration), "alignment_start": float(self.t0),
               "body": conv_name,
               "sigma_roll": d(float(self.sigma[0])), "sigma_pitch": d(float(self.sigma[1])),
               "sigma_heading": None if not np.isfinite(self.sigma[2]) else d(float(self.sigma[2])),
               "heading_source": self.heading_source,
               "sigma_basis": self.sigma_basis}
        if self.sigma_floor is not None:
            out["sigma_floor"] = [d(float(x)) for x in self.sigma_floor]
        if self.budget is not None:
            out["sensor_budget"] = {k: (float(v) if not isinstance(v, dict) else v)
                                    for k, v in self.budget.summary().items()}
        if self.residual:
            out["residual"] = {k: float(v) for k, v in self.residual.items()}
        if self.dropped:
            out["outliers_dropped"] = {k: int(v) for k, v in self.dropped.items()}
        if self.roll_window is not None:
            out["roll_window"] = float(self.roll_window)
        if self.gyro_bias is not None:
            out["gyro_bias"] = [float(x) for x in np.degrees(self.gyro_bias) * 3600.0]       # deg/h
            out["accel_bias"] = [float(x) for x in self.accel_bias / UG_DECIMAL]             # micro-g
            if self.gyro_bias_sigma is not None:
                out["gyro_bias_sigma"] = [float(x) for x in np.degrees(self.gyro_bias_sigma) * 3600.0]
                out["accel_bias_sigma"] = [float(x) for x in self.accel_bias_sigma / UG_DECIMAL]
        return out


# --------------------------------------------------------------------------- input checks

def hard_minimum(method: str, opts: AlignOptions) -> float:
    """The interval below which a method cannot run at all, s (the recommended one is
    ``opts.min_duration``: shorter than that runs with a warning)."""
    return {"static": 1.0, "inertial": 3.0 * opts.obs_interval, "gnss-inertial": 3.0,
            "kf": 2.0 * max(3.0 * opts.obs_interval, 3.0)}[method]


def select_window(imu: ImuLog, opts: AlignOptions, notes: list | None = None) -> Window:
    """The increments of (t0, t0 + duration]; raises when the log cannot give the method its hard
    minimum, and adds a warning to ``notes`` when the interval is shorter than the recommended one."""
    n = len(imu)
    if n < 2:
        raise SinsError(f"{imu.source}: the IMU log has {n} sample(s); alignment needs an interval")
    log_t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    tol = time_tolerance(log_t0)
    if opts.start is None:
        t0, k0 = log_t0, 0
    else:
        if opts.start < log_t0 - tol or opts.start >= imu.time[-1]:
            raise SinsError(f"{imu.source}: --start {opts.start!r} is outside the log ({log_t0!r} .. "
                            f"{float(imu.time[-1])!r} s)")
        k0 = int(np.searchsorted(imu.time, opts.start + tol, side="right"))
        t0 = float(imu.time[k0 - 1]) if k0 > 0 else log_t0
    available = float(imu.time[-1] - t0)
    minimum = hard_minimum(opts.method, opts)
    recommended = opts.min_duration[opts.method]
    if opts.duration is None:
        k1 = n
    else:
        if opts.duration > available * (1.0 + 1e-9) + 1e-6:
            raise SinsError(f"{imu.source}: --duration {opts.duration:g} s: the log holds only "
                            f"{available:.6g} s after the start {t0!r}")
        k1 = int(np.searchsorted(imu.time, t0 + opts.duration + 1e-6, side="right"))
    w = Window(t0, imu.time[k0:k1], imu.dtheta_b[k0:k1], imu.dvel_b[k0:k1], imu.source)
    step = float(np.median(np.diff(imu.time[: min(n, 1000)])))
    if len(w.time) < 2 or w.T < minimum - 1.5 * step:
        T = w.T if len(w.time) else 0.0
        raise SinsError(f"{imu.source}: the alignment interval is {T:.4g} s; --method {opts.method} needs "
                        f"at least {minimum:g} s (recommended: {recommended:g} s, align.min_duration."
                        f"{opts.method})")
    if w.T < recommended - 1.5 * step and notes is not None:
        notes.append(f"warning: the alignment interval is {w.T:.4g} s, shorter than the {recommended:g} s "
                     f"recommended for --method {opts.method} (align.min_duration.{opts.method}); the 1-sigma "
                     f"figures account for the short interval")
    if opts.roll_window is not None and not opts.obs_interval <= opts.roll_window <= w.T:
        raise SinsError(f"--roll-window {opts.roll_window:g} s: must lie between the observation interval "
                        f"({opts.obs_interval:g} s) and the alignment interval ({w.T:.4g} s)")
    return w


def resolve_position(opts: AlignOptions, gnss: GnssLog | None, t0: float):
    """``(lat, lon, h)`` (rad, rad, m) at the start: --position / config, else the GNSS log."""
    if opts.position is not None:
        return opts.position
    if gnss is not None and len(gnss):
        lat = float(np.interp(t0, gnss.time, gnss.lat))
        lon = float(np.interp(t0, gnss.time, gnss.lon))
        h = float(np.interp(t0, gnss.time, gnss.height))
        return math.radians(lat), math.radians(lon), h
    raise SinsError(f"--method {opts.method} needs the latitude (earth rate and gravity): give --position "
                    f"LAT,LON,H, align.position in the config, or --gnss FILE")


def check_gnss_coverage(gnss: GnssLog, t0: float, t1: float) -> None:
    """Refuse a GNSS log that does not cover ``[t0, t1]`` with fixes (gaps up to 5 intervals or 3 s)."""
    if gnss is None or len(gnss) < 3:
        raise SinsError(f"{getattr(gnss, 'source', 'GNSS')}: a GNSS log with at least 3 fixes over the "
                        f"alignment interval is needed")
    t = gnss.time
    step = float(np.median(np.diff(t)))
    if t[0] > t0 + step + 1e-6 or t[-1] < t1 - step - 1e-6:
        raise SinsError(f"{gnss.source}: the fixes span {t[0]!r} .. {t[-1]!r} s, which does not cover the "
                        f"alignment interval {t0!r} .. {t1!r} s")
    inside = t[(t >= t0 - step) & (t <= t1 + step)]
    gaps = np.diff(inside)
    limit = max(5.0 * step, 3.0)
    if gaps.size and gaps.max() > limit:
        k = int(np.argmax(gaps))
        raise SinsError(f"{gnss.source}: a gap of {gaps[k]:.3g} s without fixes after {inside[k]!r} s inside the "
                        f"alignment interval {t0!r} .. {t1!r} s (at most {limit:.3g} s allowed)")


def gnss_velocity(gnss: GnssLog):
    """ENU velocity at the fixes, m/s (n, 3), and its 1-sigma (n, 3).

    From the velocity columns when present, else central differences of the
    positions (seed 001 eq 13); a horizontal-only velocity (speed and course: up NaN) takes its up
    component from the positions.  The 1-sigma is the file's ``std_vel``, else
    the scatter of the velocity about its neighbours' mean.
    """
    t = gnss.time
    if gnss.vel_n is not None and np.isfinite(gnss.vel_n).all():
        v = np.asarray(gnss.vel_n, dtype=float)
    elif gnss.vel_n is not None and np.isfinite(gnss.vel_n[:, :2]).all():
        v = np.asarray(gnss.vel_n, dtype=float).copy()
        up = np.isnan(v[:, 2])
        v[up, 2] = np.gradient(gnss.height, t)[up] if len(t) > 1 else 0.0
    else:
        lat = np.radians(gnss.lat)
        lon = np.radians(gnss.lon)
        rm, rn = radii(np.sin(lat[0]))
        h0 = float(gnss.height[0])
        p = np.stack([dlon(lon, lon[0]) * (rn + h0) * np.cos(lat[0]), (lat - lat[0]) * (rm + h0),
                      gnss.height - h0], axis=-1)
        v = np.stack([np.gradient(p[:, i], t) for i in range(3)], axis=-1)
    if gnss.std_vel is not None and np.isfinite(gnss.std_vel).all():
        s = np.asarray(gnss.std_vel, dtype=float)
    else:
        if v.shape[0] >= 5:
            r = v[1:-1] - 0.5 * (v[:-2] + v[2:])
            sig = np.sqrt(np.median(r ** 2, axis=0) / 0.455) * math.sqrt(2.0 / 3.0)   # robust
            sig = np.maximum(sig, 1e-3)
        else:
            sig = np.full(3, 0.1)
        s = np.broadcast_to(sig, v.shape).copy()
        if gnss.std_vel is not None:                # the file's where it has one (a horizontal-only sigma)
            s = np.where(np.isfinite(gnss.std_vel) & (gnss.std_vel > 0), gnss.std_vel, s)
    return v, s


# --------------------------------------------------------------------------- methods

@dataclass
class _Solution:
    """A coarse solution: the attitude at t0, how to carry it to the epochs, and its covariance."""
    cbn0: np.ndarray                 # (3, 3) at t0
    rows: np.ndarray                 # (n,) rows (0 = t0) of the epochs
    times: np.ndarray                # (n,) epoch times
    propagate: object                # cbn0 (3,3) or (n,3,3) -> current attitude at the epochs (n, 3, 3)
    series0: np.ndarray              # (n, 3, 3) estimate of the start attitude using data up to each epoch
    cov0: np.ndarray                 # (3, 3) rad^2 attitude error covariance at t0 (ENU)
    cov_end: np.ndarray              # (3, 3) at the window's last sample
    floor0: np.ndarray               # (3, 3) the noise-only covariance at t0
    floor_end: np.ndarray            # (3, 3) at the last sample
    heading: observability.HeadingCheck
    heading_kind: str                # earth-rate | gnss-motion
    at_end: object                   # cbn0 -> attitude at the last sample of the window
    vel_ep: np.ndarray | None = None     # (n, 3) GNSS velocity at the epochs (course)
    sig_v: np.ndarray | float = 0.1      # GNSS velocity 1-sigma at the epochs
    gyro_bias: np.ndarray | None = None          # (3,) estimated, rad/s body
    accel_bias: np.ndarray | None = None
    gyro_bias_sigma: np.ndarray | None = None
    accel_bias_sigma: np.ndarray | None = None
    residual: dict = field(default_factory=dict)
    dropped: dict = field(default_factory=dict)


def _epoch_rows(time_rel: np.ndarray, interval: float) -> np.ndarray:
    """Rows (1..M of t0 + samples) nearest each multiple of ``interval``, and the last row."""
    T = time_rel[-1]
    marks = np.arange(interval, T + 1e-9, interval)
    k = np.clip(np.searchsorted(time_rel, marks - 1e-9), 0, len(time_rel) - 1)
    return np.unique(np.concatenate([k, [len(time_rel) - 1]])) + 1


def _rest_statistics(w: Window, opts: AlignOptions):
    """Motion statistics of the window: ``(moving, rate deviation, force deviation)``."""
    dw, df, _, _ = imu_stats.motion_statistics(w.time, w.dtheta_b, w.dvel_b, w.t0, opts.static_block)
    moving = dw > opts.static_rate or df > opts.static_accel
    return moving, dw, df


def check_gravity(w: Window, g: float) -> None:
    """A base at rest or swaying measures gravity on average: refuse a log that cannot be levelled."""
    _, f = imu_stats.mean_rates(w.time, w.dtheta_b, w.dvel_b, w.t0)
    mag = float(np.linalg.norm(f))
    if 0.5 * g <= mag <= 1.5 * g:
        return
    if abs(mag * G0 - g) < 0.1 * g:
        hint = "the file probably holds g: set imu.units.accel: g"
    elif abs(mag * MG - g) < 0.1 * g:
        hint = "the file probably holds mg: set imu.units.accel: mg"
    else:
        hint = "check the accelerometer columns and units, and that the base is not accelerating"
    raise SinsError(f"{w.source}: the mean specific force over the alignment interval is {mag:.4g} m/s^2, far "
                    f"from gravity ({g:.4f} m/s^2), so the attitude cannot be levelled: {hint}")


def resolve_budget(w: Window, opts: AlignOptions, lat: float, g: float,
                   quasi_static: bool = False) -> budget_mod.Budget:
    """The sensor budget of a window: the description (``opts.sensor``) checked against the log
    (``quasi_static``: the method takes the base as staying where it is, :func:`budget.resolve`)."""
    ev = budget_mod.gather_evidence(w.time, w.dtheta_b, w.dvel_b, w.t0, lat, g, opts.static_rate,
                                    opts.static_accel, opts.static_block)
    return budget_mod.resolve(opts.sensor, ev, w.time, w.dtheta_b, w.dvel_b, w.t0, quasi_static=quasi_static)


def _accel_prior(b, g, est=False):
    """1-sigma of what acts as a constant accelerometer bias during an alignment: the bias, and the
    misalignment and scale factor times gravity (a misaligned axis sees ``g sin m``).  ``est``: the
    estimators' prior (:class:`~sinscli.align.budget.Budget`), else the reported one."""
    return math.sqrt((b.accel_bias_est if est else b.accel_bias) ** 2 + (g * b.accel_mis) ** 2
                     + (g * b.accel_sf) ** 2)


TURN_MIN = math.radians(5.0)     # rad of rotation (beyond a constant rate) for the gyro matrix to matter


def _turning(w: Window) -> bool:
    """Does the body turn (its rate change) by more than ``TURN_MIN`` over the window?  Without it the
    gyro scale factor and misalignment act as a constant bias (``E w`` with ``w`` constant), which
    the bias term already carries."""
    dw, _ = imu_stats.block_deviations(w.time, w.dtheta_b, w.dvel_b, w.t0, 1.0)
    return float(dw.sum()) > TURN_MIN


def _level_axes(w: Window) -> np.ndarray:
    """Body axes (columns) whose third is up (the mean specific force's direction) and first two level."""
    up = w.dvel_b.sum(axis=0)
    up = up / np.linalg.norm(up)
    a = np.eye(3)[int(np.argmin(np.abs(up)))]
    x = np.cross(a, up)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(up, x), up], axis=-1)


def _gyro_matrix_cov(b) -> np.ndarray:
    """(9, 9) covariance of the gyro matrix E (row-major): scale factors on the diagonal elements,
    misalignments off it (the budget's reported 1-sigma)."""
    v = np.full(9, b.gyro_mis ** 2)
    v[fit.DIAG_E] = b.gyro_sf ** 2
    return np.diag(v)


def _earth_rate_check(lat, T, sigma, b, opts, g) -> observability.HeadingCheck:
    """The earth-rate heading check with the budget's 1-sigma, then with the bias and noise the log
    itself shows (a heading the data make unobservable is refused whatever the description says)."""
    hc = observability.check_earth_rate(lat, T, sigma, b.gyro_bias, b.gyro_arw, b.detail.get("gyro_bias", "config"),
                                        opts.max_heading_sigma)
    if hc.observable:
        sd = observability.earth_rate_heading_sigma(lat, T, b.data_gyro_bias, b.data_gyro_arw, 0.0, g)
        if sd > opts.max_heading_sigma:
            hc = observability.check_earth_rate(lat, T, sd, b.data_gyro_bias, b.data_gyro_arw, "shown by the log",
                                                opts.max_heading_sigma)
    return hc


def _static(w: Window, opts: AlignOptions, lat: float, g: float, b) -> _Solution:
    moving, dw, df = _rest_statistics(w, opts)
    if moving:
        raise SinsError(f"{w.source}: the base moves during the interval (1 s mean angular rate varies by "
                        f"{math.degrees(dw):.3g} deg/s, limit {math.degrees(opts.static_rate):.3g}; specific force by "
                        f"{df:.3g} m/s^2, limit {opts.static_accel:.3g}): --method static needs a base at rest; "
                        f"use --method inertial (swaying base) or gnss-inertial (moving)")
    w_mean, f_mean = imu_stats.mean_rates(w.time, w.dtheta_b, w.dvel_b, w.t0)
    cbn = coarse.triad(f_mean, w_mean, lat)
    rows = _epoch_rows(w.time - w.t0, opts.obs_interval)
    times = w.all_times[rows]
    series = coarse.cumulative_triad(w.time, w.dtheta_b, w.dvel_b, w.t0, lat, rows - 1)
    T = w.T
    sa = _accel_prior(b, g)
    ts = observability.tilt_sigma(T, sa, b.accel_vrw, g)
    hs = observability.earth_rate_heading_sigma(lat, T, b.gyro_bias, b.gyro_arw, sa, g)
    cov = np.diag([ts ** 2, ts ** 2, hs ** 2])
    floor = np.diag([observability.tilt_sigma(T, 0.0, b.accel_vrw, g) ** 2] * 2
                    + [observability.earth_rate_heading_sigma(lat, T, 0.0, b.gyro_arw, 0.0, g) ** 2])
    hc = _earth_rate_check(lat, T, hs, b, opts, g)

    def propagate(c0):
        c0 = np.asarray(c0)
        return np.broadcast_to(c0, (len(rows), 3, 3)).copy() if c0.ndim == 2 else c0.copy()

    return _Solution(cbn, rows, times, propagate, series, cov, cov, floor, floor, hc, "earth-rate",
                     at_end=lambda c0: np.asarray(c0).copy())


def _combine_roll(c_full, c_win, conv):
    """Roll of ``c_win``, pitch and heading of ``c_full`` (seed 001's improvement)."""
    r, _, _ = dcm_to_euler(np.ascontiguousarray(c_win), conv)
    _, p, h = dcm_to_euler(np.ascontiguousarray(c_full), conv)
    return euler_to_dcm(r, p, h, conv)


@dataclass
class _Observations:
    """The seed 001 vectors of one window at the fit epochs."""
    cbb0: np.ndarray
    alpha: np.ndarray
    cnn0: np.ndarray
    beta: np.ndarray
    rows: np.ndarray             # (n,) sample rows (1..M) of the epochs
    times: np.ndarray            # (n,) epoch times
    s_v: np.ndarray              # (n,) GNSS velocity 1-sigma at the epochs (0 at rest)
    vel_ep: np.ndarray | None    # (n, 3) GNSS velocity at the epochs
    alpha_adjust: object         # lever arm to the body side, or None
    s_common: float              # 1-sigma of the velocity subtracted from every beta (no v0 estimate)
    centered: bool
    order: int                   # coning/sculling order of the body integration


def _observations(w: Window, opts: AlignOptions, lat: float, h: float, gnss: GnssLog | None) -> _Observations:
    M = len(w.time)
    times_all = w.all_times
    rel = w.time - w.t0
    if gnss is None:
        lat_s = np.full(M + 1, lat)
        h_s = np.full(M + 1, h)
        vel_s = np.zeros((M + 1, 3))
        rows = _epoch_rows(rel, opts.obs_interval)
        s_v = np.zeros(len(rows))
        vel_ep = None
    else:
        v_g, s_g = gnss_velocity(gnss)
        lat_s = np.radians(np.interp(times_all, gnss.time, gnss.lat))
        h_s = np.interp(times_all, gnss.time, gnss.height)
        vel_s = np.stack([np.interp(times_all, gnss.time, v_g[:, i]) for i in range(3)], axis=-1)
        inside = (gnss.time > w.t0) & (gnss.time <= w.time[-1] + 1e-9)
        k = np.searchsorted(times_all, gnss.time[inside])
        k = np.clip(k, 1, M)
        prev_closer = np.abs(times_all[k - 1] - gnss.time[inside]) < np.abs(times_all[k] - gnss.time[inside])
        k = np.where(prev_closer & (k > 1), k - 1, k)
        rows, first = np.unique(k, return_index=True)
        s_v = s_g[inside][first].max(axis=1)
        vel_ep = None
    cbb0, alpha, cnn0, beta = inertial.integrate(w.dtheta_b, w.dvel_b, w.dt, lat_s, h_s, vel_s, opts.coning)
    if gnss is not None:
        vel_ep = vel_s[rows]
    adjust = None
    if gnss is not None and np.any(opts.lever_arm != 0.0):
        w_ib = _body_rate(w, np.concatenate([[0], rows]))

        def adjust(a_ep, cbb0_ep, _w=w_ib):
            a_all = inertial.lever_arm_alpha(np.concatenate([np.zeros((1, 3)), a_ep]),
                                             np.concatenate([np.eye(3)[None], cbb0_ep]), _w, opts.lever_arm)
            return a_all[1:]
    centered = gnss is not None and opts.estimate_v0
    s_common = float(s_v[0]) if gnss is not None and not centered else 0.0
    return _Observations(cbb0, alpha, cnn0, beta, rows, times_all[rows], s_v, vel_ep, adjust, s_common, centered,
                         opts.coning)


def _fit(w: Window, ob: _Observations, cbn0, g, b, rows_mask=None, robust=False, notes=None):
    """The bias-aware fit (:mod:`.fit`) with the budget's priors.  A bias the budget does not know (no
    description, no rest) gets the prior the components the motion determined give (Student t), and the
    fit is repeated with it (the budget is updated in place).  A fit that the data reject (its residual
    chi-square significantly above its degrees of freedom) is tried again by continuation
    (:func:`_continued`); the one the data fit better is kept."""

    def select(mask):
        """The sample rows, epoch times (s since t0), GNSS 1-sigma and lever-arm adjustment of the epochs
        ``mask`` (bool over ``ob.rows``; None: all)."""
        m = slice(None) if mask is None else mask
        a_adj = ob.alpha_adjust
        if a_adj is not None and mask is not None:
            full = ob.alpha_adjust

            def a_adj(a_ep, cbb0_ep, _full=full, _mask=mask):
                out = np.zeros((len(ob.rows), 3))
                cb = np.broadcast_to(np.eye(3), (len(ob.rows), 3, 3)).copy()
                out[_mask], cb[_mask] = a_ep, cbb0_ep
                return _full(out, cb)[_mask]
        return ob.rows[m], ob.times[m] - w.t0, ob.s_v[m], a_adj

    turning = _turning(w)
    # without GNSS the base's own motion (heave, sway) is unmodelled and the gyro matrix's effect
    # oscillates with the sway as heave does: it is not estimated, only carried in the covariance
    # (a consider parameter: an estimation prior 1e-3 of the reported one holds it at zero); so are the
    # horizontal accelerometer bias components, which at rest a tilt absorbs and on a swaying base only
    # the sway (with the heave it does not model) would tell from one (the vertical one is estimated);
    # a misfit widens only the white noise (the bias components a base at rest shows were checked
    # against the description already, budget.resolve), so the gyro bias is estimated with its
    # reported (Student t) 1-sigma rather than the point scale: a gyro bias the few components
    # understated would otherwise stay unexplained
    e_est = 1.0 if ob.vel_ep is not None else 1e-3
    axes = None if e_est == 1.0 else _level_axes(w)
    scale = np.ones(3) if axes is None else np.array([e_est, e_est, 1.0])

    def run(mask=rows_mask, c0=cbn0, start=None, stage=False, statistics=True):
        """The fit over the epochs ``mask`` from ``c0`` (and the sensor errors ``start``); a ``stage`` of the
        continuation gives its solution only (no outliers, no residual statistics, halved overshoots)."""
        rows, t_ep, s_v, a_adj = select(mask)
        return fit.fit(w.dtheta_b, w.dvel_b, w.dt, rows, ob.beta[rows], c0, t_ep, g=g,
                       vrw=b.accel_vrw, arw=b.gyro_arw, s_v=s_v, prior_accel=_accel_prior(b, g, True) * scale,
                       prior_gyro=b.gyro_bias_est if axes is None else b.gyro_bias,
                       report_accel=np.full(3, _accel_prior(b, g)), report_gyro=b.gyro_bias,
                       accel_axes=axes,
                       prior_sf=b.gyro_sf_est * e_est if turning else 0.0,
                       prior_mis=b.gyro_mis_est * e_est if turning else 0.0,
                       report_sf=b.gyro_sf, report_mis=b.gyro_mis,
                       centered=ob.centered, s_common=ob.s_common, order=ob.order, alpha_adjust=a_adj,
                       robust=robust and not stage, widen_priors=ob.vel_ep is not None, start=start,
                       statistics=statistics and not stage, halving=stage, max_iter=STAGE_ITERATIONS if stage else 8,
                       gyro_rw=b.gyro_bias_rw, accel_rw=b.accel_bias_rw)

    def best():
        # the residual statistics only run on a fit the data reject: without them first (the same fit
        # when the data accept it), and with them on the better of the direct and the continued fit
        res = run(statistics=False)
        if fit.consistent(res.chi2, res.dof):
            return res
        alt = _continued(run, ob.times - w.t0, rows_mask, b.gyro_bias_est)
        return alt if alt is not None and alt.chi2 / alt.dof < res.chi2 / res.dof else run()

    res = best()
    _widen_budget(b, res, notes)
    if not all(b.bias_known.values()):
        # what the budget does not know (no description, no rest): the prior from the components the
        # fit with the bounds of a working IMU determined (posterior 1-sigma < 0.3 prior), Student t
        for which, sl, prior in (("gyro", fit.P_EPS, b.gyro_bias_est), ("accel", fit.P_NAB, _accel_prior(b, g, True)),
                                 ("matrix", fit.P_E, max(b.gyro_sf_est, b.gyro_mis_est))):
            if b.bias_known[which] or (which == "matrix" and (e_est < 1.0 or not turning)):
                continue
            x = {"gyro": res.gyro_bias, "accel": res.accel_bias, "matrix": res.gyro_matrix.ravel()}[which]
            comp, cs = fit.observed_components(x, res.cov[sl, sl], prior)
            if comp.size:
                sig, s, n = budget_mod.student_sigma(comp, cs)
                what = f"data ({n} component(s) the fit determined, Student t)"
                if which == "matrix":
                    for term in ("sf", "mis"):
                        b.detail[f"gyro_{term}"] = what
                        setattr(b, f"gyro_{term}", min(getattr(b, f"gyro_{term}"), sig))
                        setattr(b, f"gyro_{term}_est", min(getattr(b, f"gyro_{term}_est"), s))
                else:
                    b.detail[f"{which}_bias"] = what
                    setattr(b, f"{which}_bias", min(getattr(b, f"{which}_bias"), sig))
                    setattr(b, f"{which}_bias_est", min(getattr(b, f"{which}_bias_est"), s))
                    if which == "gyro":
                        b.data_gyro_bias = max(b.data_gyro_bias, s)
            b.bias_known[which] = True
        res = best()
        _widen_budget(b, res, notes)
    return res


STAGE_TURN = 0.3          # rad: the frame turn, at the gyro prior, over the continuation's first window
STAGE_EPOCHS = 6          # the fewest epochs of a continuation window
STAGE_ITERATIONS = 30     # Gauss-Newton steps of a continuation window (overshoots halved)


def _continued(run, t_ep, mask, gyro_prior):
    """The fit by continuation over growing windows: the first as long as a gyro bias at the prior
    (rad/s per axis) turns the frame by ``STAGE_TURN`` (where the first-order model of the bias holds),
    each next twice as long, started from the last one's attitude and sensor errors, the whole interval
    last.  Gauss-Newton from the Wahba solution over the whole interval may not reach the minimum when
    the gyro bias turns the frame by tens of degrees over it (a phone's 3 deg/s over a minute); each
    window here starts close to its own.  ``t_ep`` (n,) s since t0 of every epoch, ``mask`` the epochs
    of the fit (None: all).  None when no window shorter than the interval has ``STAGE_EPOCHS``."""
    sel = np.ones(t_ep.shape[0], dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    t = t_ep[sel]
    T = float(t[-1])
    if t.shape[0] < 2 * STAGE_EPOCHS:
        return None
    t_len = max(STAGE_TURN / max(math.sqrt(3.0) * gyro_prior, 1e-12), float(t[STAGE_EPOCHS - 1]))
    c0, start, staged = None, None, False
    while t_len < T:
        res = run(sel & (t_ep <= t_len + 1e-9), **({} if c0 is None else {"c0": c0}), start=start, stage=True)
        c0, start, staged = res.cbn0, (res.gyro_bias, res.accel_bias, res.gyro_matrix), True
        t_len *= 2.0
    return run(c0=c0, start=start) if staged else None


def _widen_budget(b, res, notes):
    """Take a sensor's figures larger by the factors the fit's prior statistic found (``res.widen``
    for the estimators' prior, ``res.report_widen`` for the reported one)."""
    for which, k in (res.widen or {}).items():
        if k <= 1.0:
            continue
        kr = res.report_widen[which]
        terms = ("accel_bias",) if which == "accel" else ("gyro_bias", "gyro_sf", "gyro_mis")
        for t in terms:
            setattr(b, f"{t}_est", getattr(b, f"{t}_est") * k)
            setattr(b, t, getattr(b, t) * kr)
        if which == "accel":
            b.accel_sf *= k
            b.accel_mis *= k
        key = f"{which}_bias"
        b.detail[key] = f"{b.detail.get(key, 'config')}, x{k:.3g} (the fit's residual)"
        if notes is not None:
            notes.append(f"the sensor errors the fit estimates are beyond what the budget allows (the prior's "
                         f"chi-square above its 99 % point): the {'accelerometer' if which == 'accel' else 'gyro'} "
                         f"figures are taken {k:.3g}x larger ({kr:.3g}x in the 1-sigma, Student t)")


def _inertial(w: Window, opts: AlignOptions, lat: float, h: float, g: float, b,
              gnss: GnssLog | None = None, notes: list | None = None) -> _Solution:
    ob = _observations(w, opts, lat, h, gnss)
    rows = ob.rows
    a_ep = ob.alpha[rows]
    if ob.alpha_adjust is not None:
        a_ep = ob.alpha_adjust(a_ep, ob.cbb0[rows])
    b_ep = ob.beta[rows]
    increments = opts.vectors == "increments" or (opts.vectors == "auto" and gnss is None)
    if increments:
        # the integral vectors of each observation interval (differences between epochs): at rest their
        # errors (accelerometer noise, the random walk of the cumulative vectors) are independent
        da = np.diff(np.concatenate([ob.alpha[:1], a_ep]), axis=0)
        db = np.diff(np.concatenate([ob.beta[:1], b_ep]), axis=0)
        series0 = wahba.solve_cumulative(da, db)
    else:
        series0 = wahba.solve_cumulative(a_ep, b_ep, centered=ob.centered)
    T = w.T
    res = _fit(w, ob, series0[-1], g, b, robust=gnss is not None, notes=notes)
    cbn0 = res.cbn0
    cbb0 = res.cbb0
    cov0 = res.cov[:3, :3]
    cov_end = res.end_cov(ob.cnn0[-1], b.gyro_arw, T, b.gyro_bias_rw)
    R = ob.cnn0[-1].T
    floor0 = res.cov_floor
    floor_end = R @ floor0 @ R.T          # a lower bound: the angle random walk after the start left out
    series0 = series0.copy()
    series0[-1] = cbn0
    times = ob.times
    if opts.roll_window is not None:
        j = max(int(np.searchsorted(times - w.t0, opts.roll_window + 1e-9)) - 1, 0)
        mask = np.zeros(len(rows), dtype=bool)
        mask[: j + 1] = True
        if mask.sum() >= 3:
            res_w = _fit(w, ob, series0[j], g, b, rows_mask=mask, robust=gnss is not None)
            c_win = res_w.cbn0
            cw0 = res_w.cov[:3, :3]
            cwe = res_w.end_cov(ob.cnn0[-1], b.gyro_arw, T, b.gyro_bias_rw)
        else:
            c_win, cw0, cwe = series0[j], cov0, cov_end
        cbn0 = _combine_roll(cbn0, c_win, opts.conv)
        s = series0.copy()
        for i in range(j, len(s)):
            s[i] = _combine_roll(series0[i] if i < len(s) - 1 else cbn0, c_win, opts.conv)
        series0 = s
        # roll is about the forward axis: its variance from the window's fit
        cov0, cov_end = _replace_roll(cov0, cw0, cbn0, opts.conv), _replace_roll(cov_end, cwe, cbn0, opts.conv)

    def propagate(c0):
        return inertial.attitude_at(c0, cbb0[rows], ob.cnn0[rows])

    def at_end(c0):
        # the GNSS epochs may end up to a fix interval before the window's last sample
        return inertial.attitude_at(c0, cbb0[-1:], ob.cnn0[-1:])[0]

    common = dict(gyro_bias=res.gyro_bias, accel_bias=res.accel_bias,
                  gyro_bias_sigma=np.sqrt(np.maximum(np.diag(res.cov[fit.P_EPS, fit.P_EPS]), 0.0)),
                  accel_bias_sigma=np.sqrt(np.maximum(np.diag(res.cov[fit.P_NAB, fit.P_NAB]), 0.0)),
                  residual={"chi2_dof": res.chi2 / res.dof, "unmodelled_velocity_noise": res.s_white})
    hs = math.sqrt(max(cov_end[2, 2], 0.0))
    _check_tilt(w, res, cov_end)
    if gnss is None:
        _check_translation(w, opts, res, times, g, b)
        hc = _earth_rate_check(lat, T, hs, b, opts, g)
        return _Solution(cbn0, rows, times, propagate, series0, cov0, cov_end, floor0, floor_end, hc, "earth-rate",
                         at_end=at_end, **common)
    if res.dropped and notes is not None:
        notes.append(f"the fit dropped {len(res.dropped)} GNSS velocity fix(es) as outliers (at "
                     f"{', '.join(f'{times[i]:.6g}' for i in res.dropped[:5])}{' ...' if len(res.dropped) > 5 else ''} s)")
    sig_v = float(np.median(ob.s_v))
    what = (f"the fit of {int(res.kept.sum())} GNSS epochs gives a heading 1-sigma of {math.degrees(hs):.3g} deg "
            f"(GNSS velocity 1-sigma {sig_v:.3g} m/s, residual chi-square/dof {res.chi2 / res.dof:.3g}"
            + (f", unmodelled velocity noise {res.s_white:.3g} m/s added" if res.s_white > 0 else "") + ")")
    if not hs <= opts.max_heading_sigma:
        hc = observability.HeadingCheck(False, hs, f"heading is not observable from earth rate or the motion: "
                                                   f"{what} (> {math.degrees(opts.max_heading_sigma):.3g} deg, "
                                                   f"align.max_heading_sigma)")
    else:
        hc = observability.HeadingCheck(True, hs, f"heading from earth rate and motion: {what}")
    dropped = {"gnss_velocity": len(res.dropped)}
    return _Solution(cbn0, rows, times, propagate, series0, cov0, cov_end, floor0, floor_end, hc, "gnss-motion",
                     at_end=at_end, vel_ep=ob.vel_ep, sig_v=np.maximum(ob.s_v, 1e-3), dropped=dropped, **common)


MAX_TILT_SIGMA = math.radians(10.0)   # rad: beyond, sin x differs from x by > 0.5 %: no covariance describes the error


def _check_tilt(w: Window, res, cov_end) -> None:
    """Refuse a fit that the data reject (its residual chi-square significantly above its degrees of
    freedom, so that the residual statistic widened its covariance) when its tilt 1-sigma (the larger
    horizontal axis of the ENU covariance at the end) exceeds :data:`MAX_TILT_SIGMA`: the fit's small-angle model (and the navigation filter's) does not hold there, so
    the figure would claim nothing.  The usual causes: the units, the axes, the lever arm, or a GNSS velocity
    off the IMU's."""
    if fit.consistent(res.chi2, res.dof):
        return
    tilt = math.sqrt(max(float(np.linalg.eigvalsh(0.5 * (cov_end[:2, :2] + cov_end[:2, :2].T)).max()), 0.0))
    if tilt <= MAX_TILT_SIGMA:
        return
    extra = f", {res.s_white:.3g} m/s of unmodelled velocity noise added" if res.s_white > 0 else ""
    raise SinsError(f"{w.source}: the alignment fit does not explain the data over {w.T:.4g} s (residual "
                    f"chi-square/dof {res.chi2 / res.dof:.3g}{extra}): its roll/pitch 1-sigma is {math.degrees(tilt):.3g} "
                    f"deg, beyond the {math.degrees(MAX_TILT_SIGMA):.0f} deg where an attitude error is small; check the "
                    f"IMU units and axes (imu.units, imu.body, imu.mounting), gnss.lever_arm and the GNSS velocity, "
                    f"or align over another interval (--start, --duration)")


def _replace_roll(cov, cov_win, cbn, conv):
    """``cov`` (ENU) with the variance about the body's roll axis taken from ``cov_win``."""
    fwd = cbn @ _forward_axis(conv)
    P = np.outer(fwd, fwd)
    Q = np.eye(3) - P
    return Q @ cov @ Q + P * float(fwd @ cov_win @ fwd)


def _forward_axis(conv):
    """The body's forward axis in the axes of body convention ``conv``."""
    return conv_to_flu(conv).T @ np.array([1.0, 0.0, 0.0])


def _check_translation(w: Window, opts: AlignOptions, res, times, g, b):
    """Refuse a base that translates (inertial without GNSS): the residual velocity in the inertial
    frame, after the fit has explained what sensor errors can, integrated to a displacement.  A
    swaying base's stays within ``motion_check.displacement`` (its heave and surge are bounded);
    a translating one's grows with its distance."""
    t = np.concatenate([[0.0], times - w.t0])
    v = np.concatenate([np.zeros((1, 2)), res.resid[:, :2]])
    disp = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], axis=0)])
    moved = float(np.linalg.norm(disp, axis=1).max())
    T = float(t[-1])
    s_d = math.hypot(b.accel_vrw * T ** 1.5 / math.sqrt(3.0), g * b.gyro_arw * T ** 2.5 / math.sqrt(20.0))
    limit = max(opts.motion_displacement, 4.0 * s_d)
    if moved > limit:
        vmax = float(np.linalg.norm(v, axis=1).max())
        raise SinsError(f"{w.source}: the base translates: the velocity integral in the inertial frame grows to "
                        f"{vmax:.3g} m/s and moves the base {moved:.3g} m in {T:.4g} s (a swaying base stays within "
                        f"{limit:.3g} m, align.motion_check.displacement): --method inertial needs a static or "
                        f"swaying base; use --method gnss-inertial or kf with --gnss")


def _body_rate(w: Window, rows: np.ndarray, half: int = 2) -> np.ndarray:
    """Body angular rate (rad/s) around each row (mean over +-``half`` samples)."""
    M = len(w.time)
    out = np.empty((len(rows), 3))
    dt = w.dt
    for i, r in enumerate(rows):
        a = max(r - half, 0)
        b = min(max(r + half, 1), M)
        out[i] = w.dtheta_b[a:b].sum(axis=0) / dt[a:b].sum()
    return out


# --------------------------------------------------------------------------- heading

def _rz(delta):
    """Pre-multiplier that adds ``delta`` (rad) to the heading (rotation about up by -delta)."""
    return rotvec_to_dcm(np.array([0.0, 0.0, -delta]))


def _with_heading_var(cov, var):
    """``cov`` (ENU) with the heading (rotation about up) variance replaced by ``var`` (no cross terms)."""
    c = np.array(cov, dtype=float)
    c[2, :] = 0.0
    c[:, 2] = 0.0
    c[2, 2] = var
    return c


@dataclass
class _Heading:
    cbn0: np.ndarray            # start attitude with the heading from its source
    cur: np.ndarray             # (n, 3, 3) current attitude at the epochs
    cbn_end: np.ndarray         # (3, 3) at the window's last sample
    sigma: float                # rad, 1-sigma at the end (nan: unknown)
    sigma0: float               # rad, at the start
    source: str
    dropped: int = 0


def _resolve_heading(sol: _Solution, opts: AlignOptions, notes: list, b, t0: float, t1: float,
                     heading_optional: bool = False) -> _Heading:
    """The heading from its proper source: the user, the method (earth rate or motion), else the GNSS
    course (``t0``, ``t1``: the window's start and last sample).  With ``heading_optional`` (the fused
    run, which gets it from the motion later) an unobservable heading is left unknown (sigma nan) instead
    of refused."""
    cur = sol.propagate(sol.cbn0)
    end = sol.at_end(sol.cbn0)
    if opts.heading is not None:
        r, p, h_end = dcm_to_euler(np.ascontiguousarray(end), opts.conv)
        cbn0 = _rz(opts.heading - h_end) @ sol.cbn0
        if not sol.heading.observable:
            notes.append(sol.heading.reason + f"; using --heading {math.degrees(opts.heading):.6g} deg")
        sigma = opts.heading_sigma if opts.heading_sigma is not None else float("nan")
        return _Heading(cbn0, sol.propagate(cbn0), euler_to_dcm(r, p, opts.heading, opts.conv), sigma, sigma, "user")
    if sol.heading.observable:
        notes.append(sol.heading.reason)
        return _Heading(sol.cbn0, cur, end, math.sqrt(sol.cov_end[2, 2]), math.sqrt(sol.cov0[2, 2]),
                        sol.heading_kind)
    if sol.vel_ep is not None:
        h_ep = dcm_to_euler_many(np.ascontiguousarray(cur), opts.conv)[:, 2]
        t_ep = sol.times - t0
        # the drift of the estimate's heading: its gyro bias about up
        co = observability.course_heading(t_ep, sol.vel_ep, h_ep, opts.course_min_speed, sol.sig_v,
                                          opts.course_sigma_floor, b.gyro_bias)
        if co is not None and co.broken:
            why = (f"; the GNSS course cannot replace it: the robust course fit drops {co.glitches} of {co.considered} "
                   f"epochs faster than {opts.course_min_speed:g} m/s as glitches (past a robust fit's breakdown point, half): "
                   f"the estimate's heading does not follow the course")
            if not heading_optional:
                raise SinsError(sol.heading.reason + why + ": give --heading DEG")
            notes.append(sol.heading.reason + why + "; the heading is left to the fused run (heading from motion)")
            nan = float("nan")
            return _Heading(sol.cbn0, cur, end, nan, nan, "none")
        if co is not None:
            t_last = float(t_ep[-1])
            cbn0 = _rz(float(co.delta(-t_last))) @ sol.cbn0
            cur = np.matmul(_rz_many(co.delta(t_ep - t_last)), cur)
            cbn_end = _rz(float(co.delta(t1 - t0 - t_last))) @ end
            extra = f", {co.dropped} dropped as glitches" if co.dropped else ""
            s_end = co.sigma(t1 - t0 - t_last)
            notes.append(sol.heading.reason + f"; heading from the GNSS course over {co.used} epochs faster than "
                         f"{opts.course_min_speed:g} m/s{extra} (robust fit with the heading drift, variance "
                         f"scaled by {co.factor:.3g}: residual chi-square/dof"
                         + (f" and their correlation {co.correlation:.2f}" if co.correlation > 3.0 / math.sqrt(co.used) else "")
                         + f"): 1-sigma {math.degrees(s_end):.3g} deg")
            return _Heading(cbn0, cur, cbn_end, s_end, co.sigma(-t_last), "gnss-course", co.dropped)
        if not heading_optional:
            raise SinsError(sol.heading.reason + f"; the GNSS course cannot replace it (fewer than 2 epochs faster "
                            f"than {opts.course_min_speed:g} m/s): give --heading DEG")
    if heading_optional:
        notes.append(sol.heading.reason + "; the heading is left to the fused run (heading from motion)")
        nan = float("nan")
        return _Heading(sol.cbn0, cur, end, nan, nan, "none")
    raise SinsError(sol.heading.reason + "; give --heading DEG, or --gnss with a moving vehicle "
                    "(heading from the GNSS course)")


def _rz_many(delta):
    """(n, 3, 3) pre-multipliers adding ``delta`` (n,) rad to the heading."""
    return np.stack([_rz(float(d)) for d in np.atleast_1d(delta)])


def _tilt_to_roll_pitch(P_h, heading):
    """Roll and pitch 1-sigma from a 2x2 ENU horizontal tilt covariance at ``heading`` (rad)."""
    fwd = np.array([math.sin(heading), math.cos(heading)])
    right = np.array([math.cos(heading), -math.sin(heading)])
    return math.sqrt(max(fwd @ P_h @ fwd, 0.0)), math.sqrt(max(right @ P_h @ right, 0.0))


def _sigmas(cov, cbn, conv):
    """Roll, pitch, heading 1-sigma (rad) from an ENU attitude covariance at attitude ``cbn``."""
    heading = dcm_to_euler(np.ascontiguousarray(cbn), conv)[2]
    r, p = _tilt_to_roll_pitch(cov[:2, :2], heading)
    return np.array([r, p, math.sqrt(max(cov[2, 2], 0.0))])


SIGMA_MIN = 1e-9     # rad: no sigma is ever written as 0 (a perfect, noise-free log still has rounding)


# --------------------------------------------------------------------------- main entry

def align(imu: ImuLog, opts: AlignOptions, gnss: GnssLog | None = None, progress=None,
          heading_optional: bool = False) -> AlignResult:
    """Align over the selected interval (see the module docstring); ``heading_optional``: an unobservable
    heading is left unknown (sigma nan) instead of refused (the fused run gets it from the motion)."""
    if opts.method == "kf" and opts.epoch == "start":
        raise SinsError("--epoch start: the Kalman filter gives the attitude at the end of the interval; "
                        "use --epoch end with --method kf")
    notes: list[str] = []
    w = select_window(imu, opts, notes)
    t1 = float(w.time[-1])
    moving_gnss = opts.method == "gnss-inertial" or (opts.method == "kf" and (
        opts.kf_coarse == "gnss-inertial" or (opts.kf_coarse == "auto" and gnss is not None)))
    if moving_gnss:
        if gnss is None:
            raise SinsError(f"--method {opts.method}{' (coarse gnss-inertial)' if opts.method == 'kf' else ''} "
                            f"needs a GNSS log: give --gnss FILE")
        check_gnss_coverage(gnss, w.t0, t1)
    lat, lon, h = resolve_position(opts, gnss, w.t0)
    g = float(gravity(math.sin(lat), h))
    b = resolve_budget(w, opts, lat, g, quasi_static=not moving_gnss)
    notes.extend(b.notes)
    coarse_method = opts.method
    if opts.method == "kf":
        coarse_method = opts.kf_coarse if opts.kf_coarse != "auto" else (
            "gnss-inertial" if gnss is not None else "inertial")
        Tc = opts.kf_coarse_duration if opts.kf_coarse_duration is not None else min(w.T / 2.0, 120.0)
        Tc = min(Tc, w.T)
        if Tc < hard_minimum(coarse_method, opts):
            raise SinsError(f"kf.coarse_duration {Tc:.4g} s: the {coarse_method} stage needs at least "
                            f"{hard_minimum(coarse_method, opts):g} s")
        if Tc < opts.min_duration[coarse_method]:
            notes.append(f"warning: the kf's coarse {coarse_method} stage is {Tc:.4g} s, shorter than the "
                         f"{opts.min_duration[coarse_method]:g} s recommended (align.min_duration.{coarse_method})")
        k = int(np.searchsorted(w.time, w.t0 + Tc + 1e-6, side="right"))
        wc = Window(w.t0, w.time[:k], w.dtheta_b[:k], w.dvel_b[:k], w.source)
    else:
        wc = w
    if coarse_method in ("static", "inertial"):
        check_gravity(wc, g)
    if coarse_method == "static":
        sol = _static(wc, opts, lat, g, b)
    elif coarse_method == "inertial":
        sol = _inertial(wc, opts, lat, h, g, b, notes=notes)
    else:
        sol = _inertial(wc, opts, lat, h, g, b, gnss, notes=notes)
    t1c = float(wc.time[-1])
    hd = _resolve_heading(sol, opts, notes, b, w.t0, t1c, heading_optional)
    dropped = dict(sol.dropped)
    if hd.source == "gnss-course":
        dropped["course"] = hd.dropped
    basis = b.source
    if not opts.sensor.given:
        notes.append("no sensor description (align.sensor): the 1-sigma figures use the noise and the biases the log "
                     "shows (Student t for the bias components it cannot show); give align.sensor for tighter figures")
    series0 = sol.series0
    if hd.source in ("user", "gnss-course") and series0 is not None:
        series0 = np.matmul(_rz(float(dcm_to_euler(np.ascontiguousarray(hd.cbn0), opts.conv)[2]
                                      - dcm_to_euler(np.ascontiguousarray(sol.cbn0), opts.conv)[2])), series0)
    if opts.method == "kf":
        res = _fine(w, opts, gnss, sol, hd, (lat, lon, h), g, notes, moving_gnss, progress, b)
        res.sigma_basis = basis
        res.dropped.update(dropped)
        return res
    start = opts.epoch == "start"
    cov = sol.cov0 if start else sol.cov_end
    floor = sol.floor0 if start else sol.floor_end
    if hd.source in ("user", "gnss-course", "none"):
        # the heading does not come from the fit: neither its covariance nor its floor apply
        hv = hd.sigma0 if start else hd.sigma
        cov = _with_heading_var(cov, hv ** 2 if np.isfinite(hv) else 0.0)
        floor = _with_heading_var(floor, 0.0)
    series = Series(sol.times, hd.cur if hd.source == "gnss-course" else
                    (sol.propagate(series0) if series0 is not None else hd.cur), series0)
    if start:
        vel, pos = _start_velocity_position(w, opts, gnss, hd.cbn0, (lat, lon, h), moving_gnss)
        state = NavState(w.t0, pos[0], pos[1], pos[2], vel, hd.cbn0)
    else:
        series.cbn[-1] = hd.cbn_end if sol.times[-1] >= t1 - 1e-9 else series.cbn[-1]
        vel, pos = _end_velocity_position(w, opts, gnss, hd.cbn_end, (lat, lon, h), moving_gnss)
        state = NavState(t1, pos[0], pos[1], pos[2], vel, hd.cbn_end)
    sigma, s_floor = _final_sigmas(cov, floor, state.Cbn, opts.conv)
    if hd.source in ("user", "none") and not np.isfinite(hd.sigma):
        sigma[2] = float("nan")
    return AlignResult(state, opts.method, w.t0, w.T, sigma, hd.source, gyro_bias=sol.gyro_bias,
                       accel_bias=sol.accel_bias, notes=notes, series=series, roll_window=opts.roll_window,
                       sigma_basis=basis, cov=cov, sigma_floor=s_floor, gyro_bias_sigma=sol.gyro_bias_sigma,
                       accel_bias_sigma=sol.accel_bias_sigma, budget=b, residual=sol.residual, dropped=dropped)


def _final_sigmas(cov, floor, cbn, conv):
    """Roll, pitch, heading 1-sigma from the covariance, never below the noise-only floor nor 0."""
    s_floor = np.maximum(_sigmas(floor, cbn, conv), SIGMA_MIN)
    return np.maximum(_sigmas(cov, cbn, conv), s_floor), s_floor


def _start_velocity_position(w: Window, opts, gnss, cbn0, pos0, moving_gnss):
    if not moving_gnss:
        return np.zeros(3), pos0
    return _antenna_to_imu(w, opts, gnss, cbn0, w.t0, 0)


def _end_velocity_position(w: Window, opts, gnss, cbn_end, pos0, moving_gnss):
    if not moving_gnss:
        return np.zeros(3), pos0
    return _antenna_to_imu(w, opts, gnss, cbn_end, float(w.time[-1]), len(w.time))


def _antenna_to_imu(w: Window, opts, gnss, cbn, t1, row):
    """IMU velocity and position at ``t1`` from the GNSS antenna's (lever arm removed)."""
    v_g, _ = gnss_velocity(gnss)
    v_ant = np.array([np.interp(t1, gnss.time, v_g[:, i]) for i in range(3)])
    lat = math.radians(float(np.interp(t1, gnss.time, gnss.lat)))
    lon = math.radians(float(np.interp(t1, gnss.time, gnss.lon)))
    h = float(np.interp(t1, gnss.time, gnss.height))
    arm = np.asarray(opts.lever_arm, dtype=float)
    if np.any(arm != 0.0):
        w_ib = _body_rate(w, np.array([row]))[0]
        v_ant = v_ant - cbn @ np.cross(w_ib, arm)
        d = cbn @ arm                                       # antenna - IMU, ENU m
        rm, rn = radii(math.sin(lat))
        lat, lon, h = lat - d[1] / (rm + h), lon - d[0] / ((rn + h) * math.cos(lat)), h - d[2]
    return v_ant, (lat, lon, h)


def _whole_window_fit(w: Window, opts, lat, h, gnss, cbn0, g, b):
    """The robust GNSS-aided fit over the whole window, for the kf: ``(floor, outlier fix times)``.

    ``floor``: the noise-only attitude covariance (ENU at the end), the attitude taken as constant but
    for the known rotation (a lower bound: with the angle random walk the end attitude is known less
    well).  The outliers are the GNSS velocity fixes the fit rejects (:mod:`.fit`)."""
    ob = _observations(w, opts, lat, h, gnss)
    res = _fit(w, ob, cbn0, g, b, robust=True)
    R = ob.cnn0[-1].T
    return R @ res.cov_floor @ R.T, ob.times[res.dropped]


def _fine(w, opts, gnss, sol, hd, pos0, g, notes, moving_gnss, progress, b):
    """Kalman fine alignment over the whole interval from the coarse attitude at t0.

    The filter's initial covariance: the coarse stage's attitude covariance taken at 3 sigma (the
    coarse stage used the first part of the same data, which the filter reads again), the budget's
    biases (with the accelerometer misalignment and scale factor times g) and their instability as
    process noise.  Its final covariance is scaled by the mean normalized innovation squared when
    that is significantly above its 3 degrees of freedom, and the gyro scale-factor and misalignment
    term of the window's rotation (not in the 12 states) is added."""
    lat, lon, h = pos0
    rel = w.time - w.t0
    if moving_gnss:
        v_g, s_g = gnss_velocity(gnss)
        inside = (gnss.time > w.t0) & (gnss.time <= w.time[-1] + 1e-9)
        k_up = np.unique(np.clip(np.searchsorted(w.time, gnss.time[inside] - 1e-9), 0, len(w.time) - 1))
        t_up = w.time[k_up]
        floor, bad_t = _whole_window_fit(w, opts, lat, h, gnss, hd.cbn0, g, b)
        if bad_t.size:
            # the fixes the robust fit over the whole window rejected are not used as updates
            near = np.abs(t_up[:, None] - bad_t[None, :]).min(axis=1) < 0.5 * float(np.median(np.diff(gnss.time)))
            k_up, t_up = k_up[~near], t_up[~near]
        v_ref = np.stack([np.interp(t_up, gnss.time, v_g[:, i]) for i in range(3)], axis=-1)
        sig = s_g if opts.kf_vel_sigma is None else np.full_like(s_g, opts.kf_vel_sigma)
        r_var = np.stack([np.interp(t_up, gnss.time, sig[:, i]) for i in range(3)], axis=-1) ** 2
        v0 = np.array([np.interp(w.t0, gnss.time, v_g[:, i]) for i in range(3)])
        arm = np.asarray(opts.lever_arm, dtype=float)
        lever = arm if np.any(arm != 0.0) else None
        w_ib = _body_rate(w, k_up + 1) if lever is not None else None
        if lever is not None:
            v0 = v0 - hd.cbn0 @ np.cross(_body_rate(w, np.array([0]))[0], arm)

        def position(t):
            la = math.radians(float(np.interp(t, gnss.time, gnss.lat)))
            lo = math.radians(float(np.interp(t, gnss.time, gnss.lon)))
            return la, lo, float(np.interp(t, gnss.time, gnss.height))
        p_start = position(w.t0)
        v_sig0 = float(np.sqrt(r_var[0].max()))
    else:
        k_up = np.unique(_epoch_rows(rel, opts.kf_update_interval) - 1)
        v_ref = np.zeros((len(k_up), 3))
        r_var = np.full((len(k_up), 3), opts.kf_zupt_sigma ** 2)
        v0 = np.zeros(3)
        lever = w_ib = None

        def position(t):
            return lat, lon, h
        p_start = (lat, lon, h)
        v_sig0 = opts.kf_zupt_sigma
    # the coarse attitude at 3 sigma (the filter reads its data again); a user heading as given
    c0 = 9.0 * sol.cov0
    if hd.source == "gnss-course":
        c0 = _with_heading_var(c0, 9.0 * hd.sigma0 ** 2)
    elif hd.source == "user":
        c0 = _with_heading_var(c0, hd.sigma0 ** 2 if np.isfinite(hd.sigma0) else math.radians(5.0) ** 2)
    P0 = np.zeros((kf.NX, kf.NX))
    P0[kf.PHI, kf.PHI] = c0 + np.eye(3) * math.radians(1e-4) ** 2
    P0[kf.DV, kf.DV] = np.eye(3) * max(v_sig0, 0.01) ** 2
    P0[kf.EPS, kf.EPS] = np.eye(3) * b.gyro_bias_est ** 2
    P0[kf.NAB, kf.NAB] = np.eye(3) * _accel_prior(b, g, True) ** 2
    # the error covariance is carried for the reported bias 1-sigma (the filter's gains are its own)
    P0_true = P0.copy()
    P0_true[kf.EPS, kf.EPS] = np.eye(3) * b.gyro_bias ** 2
    P0_true[kf.NAB, kf.NAB] = np.eye(3) * _accel_prior(b, g) ** 2
    init = NavState(w.t0, p_start[0], p_start[1], p_start[2], v0, hd.cbn0)
    imu = ImuLog(w.time, w.dtheta_b, w.dvel_b, t0=w.t0, source=w.source)
    res = kf.fine_align(imu, k_up, init, v_ref, r_var, P0, b.gyro_arw ** 2, b.accel_vrw ** 2, position=position,
                        lever_b=lever, w_ib_b=w_ib, nav_opts=NavOptions(attitude="quat", coning=opts.coning,
                                                                       conv=opts.conv),
                        progress=progress, q_bias_g=b.gyro_bias_rw ** 2, q_bias_a=b.accel_bias_rw ** 2,
                        gate=None, P0_true=P0_true,
                        E_cov=_gyro_matrix_cov(b) if _turning(w) else None)
    st = res.state
    cbn_end = st.Cbn
    n_used = max(res.n_updates - res.n_rejected, 1)
    nis = res.nis_sum / (3.0 * n_used)
    factor = nis if nis > 1.0 + 3.0 * math.sqrt(2.0 / (3.0 * n_used)) else 1.0
    P = res.P_true
    cov = P[kf.PHI, kf.PHI] * factor
    if not moving_gnss:
        # with velocity updates at rest the horizontal accelerometer bias and the east gyro bias stay
        # unobservable: the filter cannot know the attitude better than the static-base limit (its
        # closed-loop corrections turn the estimate and can make it seem to separate them)
        sa = _accel_prior(b, g)
        ts = observability.tilt_sigma(w.T, sa, b.accel_vrw, g)
        hs = observability.earth_rate_heading_sigma(lat, w.T, b.gyro_bias, b.gyro_arw, sa, g)
        cov = cov + np.diag(np.maximum(np.array([ts, ts, hs]) ** 2 - np.diag(cov), 0.0))
    if not moving_gnss:
        bad_t = np.zeros(0)
        floor = np.diag([observability.tilt_sigma(w.T, 0.0, b.accel_vrw, g) ** 2] * 2
                        + [observability.earth_rate_heading_sigma(lat, w.T, 0.0, b.gyro_arw, 0.0, g) ** 2])
    if hd.source == "user":
        r, p, _ = dcm_to_euler(np.ascontiguousarray(cbn_end), opts.conv)
        cbn_end = euler_to_dcm(r, p, opts.heading, opts.conv)
        cov = _with_heading_var(cov, hd.sigma ** 2 if np.isfinite(hd.sigma) else 0.0)
        floor = _with_heading_var(floor, 0.0)
        res.cbn[-1] = cbn_end
    vel = st.vel_n
    pos = (st.lat, st.lon, st.height)
    if moving_gnss:
        vel, pos = _end_velocity_position(w, opts, gnss, cbn_end, pos0, True)
    else:
        vel = np.zeros(3)
    state = NavState(st.time, pos[0], pos[1], pos[2], vel, cbn_end)
    notes.append(f"Kalman fine alignment from the {sol.heading_kind if hd.source != 'user' else 'user'}-headed "
                 f"coarse solution, {len(k_up)} velocity updates"
                 + (f" ({bad_t.size} GNSS fixes left out as outliers)" if bad_t.size else "")
                 + f"; mean normalized innovation squared {nis:.3g} per axis"
                 + (": the covariance is scaled by it" if factor > 1.0 else ""))
    sigma, s_floor = _final_sigmas(cov, floor, cbn_end, opts.conv)
    if hd.source in ("user", "none") and not np.isfinite(hd.sigma):
        sigma[2] = float("nan")
    series = Series(res.times, res.cbn, None)
    return AlignResult(state, "kf", w.t0, w.T, sigma, hd.source, gyro_bias=res.gyro_bias,
                       accel_bias=res.accel_bias, notes=notes, series=series, roll_window=opts.roll_window,
                       cov=cov, sigma_floor=s_floor,
                       gyro_bias_sigma=np.sqrt(np.maximum(np.diag(P)[kf.EPS], 0.0) * factor),
                       accel_bias_sigma=np.sqrt(np.maximum(np.diag(P)[kf.NAB], 0.0) * factor), budget=b,
                       residual={"nis_per_axis": nis}, dropped={"kf_gnss_velocity": int(bad_t.size)})
