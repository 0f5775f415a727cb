"""The alignment stage: IMU increments (and GNSS) + options -> the initial state with its 1-sigma.

``align(imu, opts, gnss) -> AlignResult``: selects the interval, checks the
input (length, base at rest for ``static``, GNSS coverage, position), runs the
method's kernels (:mod:`.coarse`, :mod:`.inertial` + :mod:`.wahba`,
:mod:`.kf`), decides where the heading comes from (:mod:`.observability`) and
returns the state at the end of the interval, where navigation starts.  No
file I/O: readers and writers are the CLI's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SinsError
from ..nav.earth import gravity, radii
from ..nav.pipeline import NavOptions
from ..nav.rotation import dcm_to_euler, dcm_to_euler_many, euler_to_dcm, rotvec_to_dcm
from ..types import GnssLog, ImuLog, NavState, time_tolerance
from . import coarse, inertial, kf, observability, wahba
from .options import MIN_DURATION, AlignOptions


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
    state: NavState                     # at the end of the interval
    method: str
    t0: float
    duration: float
    sigma: np.ndarray                   # (3,) rad: roll, pitch, heading (heading nan when unknown)
    heading_source: str                 # earth-rate | gnss-motion | gnss-course | user
    gyro_bias: np.ndarray | None = None     # (3,) rad/s body, estimated (kf)
    accel_bias: np.ndarray | None = None    # (3,) m/s^2 body, estimated (kf)
    notes: list = field(default_factory=list)
    series: Series | None = None
    roll_window: float | None = None
    sigma_basis: str = "config"             # config | data | config+data (see observability.budget)

    def yaml_extra(self, conv_name: str) -> dict:
        """The keys ``sins align`` adds to the FORMATS.md initial state."""
        d = math.degrees
        out = {"method": self.method, "duration": float(self.duration), "alignment_start": float(self.t0),
               "body": conv_name,
               "sigma_roll": d(float(self.sigma[0])), "sigma_pitch": d(float(self.sigma[1])),
               "sigma_heading": None if not np.isfinite(self.sigma[2]) else d(float(self.sigma[2])),
               "heading_source": self.heading_source,
               "sigma_basis": self.sigma_basis if self.sigma_basis == "config" else
               f"{self.sigma_basis} (lower bound: give align.sensor)"}
        if self.roll_window is not None:
            out["roll_window"] = float(self.roll_window)
        if self.gyro_bias is not None:
            out["gyro_bias"] = [float(x) for x in np.degrees(self.gyro_bias) * 3600.0]       # deg/h
            out["accel_bias"] = [float(x) for x in self.accel_bias / 9.80665e-6]             # micro-g
        return out


# --------------------------------------------------------------------------- input checks

def select_window(imu: ImuLog, opts: AlignOptions) -> Window:
    """The increments of (t0, t0 + duration]; raises when the log cannot give the method its minimum."""
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
    minimum = MIN_DURATION[opts.method]
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
                        f"at least {minimum:g} s")
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
    positions (seed 001 eq 13).  The 1-sigma is the file's ``std_vel``, else
    the scatter of the velocity about its neighbours' mean.
    """
    t = gnss.time
    if gnss.vel_n is not None and np.isfinite(gnss.vel_n).all():
        v = np.asarray(gnss.vel_n, dtype=float)
    else:
        lat = np.radians(gnss.lat)
        lon = np.radians(gnss.lon)
        rm, rn = radii(np.sin(lat[0]))
        h0 = float(gnss.height[0])
        p = np.stack([(lon - lon[0]) * (rn + h0) * np.cos(lat[0]), (lat - lat[0]) * (rm + h0),
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
    return v, s


# --------------------------------------------------------------------------- methods

@dataclass
class _Solution:
    """A coarse solution: the attitude at t0 and how to carry it to the epochs."""
    cbn0: np.ndarray                 # (3, 3) at t0
    rows: np.ndarray                 # (n,) rows (0 = t0) of the epochs
    times: np.ndarray                # (n,) epoch times
    propagate: object                # cbn0 (3,3) or (n,3,3) -> current attitude at the epochs (n, 3, 3)
    series0: np.ndarray              # (n, 3, 3) estimate of the start attitude using data up to each epoch
    tilt_sigma: np.ndarray           # (2,) rad roll, pitch
    heading: observability.HeadingCheck
    heading_kind: str                # earth-rate | gnss-motion
    vel_ep: np.ndarray | None = None     # (n, 3) GNSS velocity at the epochs (course)
    sig_v: float = 0.1
    budget: observability.Budget | None = None
    at_end: object = None                # cbn0 -> attitude at the last sample of the window (None: last epoch)


def _epoch_rows(time_rel: np.ndarray, interval: float) -> np.ndarray:
    """Rows (1..M of t0 + samples) nearest each multiple of ``interval``, and the last row."""
    T = time_rel[-1]
    marks = np.arange(interval, T + 1e-9, interval)
    k = np.clip(np.searchsorted(time_rel, marks - 1e-9), 0, len(time_rel) - 1)
    return np.unique(np.concatenate([k, [len(time_rel) - 1]])) + 1


def _rest_statistics(w: Window, opts: AlignOptions):
    """Motion statistics and the means used by the data-driven error budget."""
    dw, df, _, _ = coarse.motion_statistics(w.time, w.dtheta_b, w.dvel_b, w.t0, opts.static_block)
    moving = dw > opts.static_rate or df > opts.static_accel
    return moving, dw, df


def check_gravity(w: Window, g: float) -> None:
    """A base at rest or swaying measures gravity on average: refuse a log that cannot be levelled."""
    _, f = coarse.mean_rates(w.time, w.dtheta_b, w.dvel_b, w.t0)
    mag = float(np.linalg.norm(f))
    if 0.5 * g <= mag <= 1.5 * g:
        return
    if abs(mag * 9.80665 - g) < 0.1 * g:
        hint = "the file probably holds g: set imu.units.accel: g"
    elif abs(mag * 9.80665e-3 - g) < 0.1 * g:
        hint = "the file probably holds mg: set imu.units.accel: mg"
    else:
        hint = "check the accelerometer columns and units, and that the base is not accelerating"
    raise SinsError(f"{w.source}: the mean specific force over the alignment interval is {mag:.4g} m/s^2, far "
                    f"from gravity ({g:.4f} m/s^2), so the attitude cannot be levelled: {hint}")


def _budget(w: Window, opts: AlignOptions, at_rest: bool, g: float):
    if at_rest:
        w_mean, f_mean = coarse.mean_rates(w.time, w.dtheta_b, w.dvel_b, w.t0)
        wb, fb = coarse.block_means(w.time, w.dtheta_b, w.dvel_b, w.t0, opts.static_block)
        return observability.budget(opts.sensor, w_mean, f_mean, wb, fb, opts.static_block, g)
    return observability.budget(opts.sensor, g=g)


def _static(w: Window, opts: AlignOptions, lat: float, g: float) -> _Solution:
    moving, dw, df = _rest_statistics(w, opts)
    if moving:
        raise SinsError(f"{w.source}: the base moves during the interval (1 s mean angular rate varies by "
                        f"{math.degrees(dw):.3g} deg/s, limit {math.degrees(opts.static_rate):.3g}; specific force by "
                        f"{df:.3g} m/s^2, limit {opts.static_accel:.3g}): --method static needs a base at rest; "
                        f"use --method inertial (swaying base) or gnss-inertial (moving)")
    w_mean, f_mean = coarse.mean_rates(w.time, w.dtheta_b, w.dvel_b, w.t0)
    cbn = coarse.triad(f_mean, w_mean, lat)
    rows = _epoch_rows(w.time - w.t0, opts.obs_interval)
    times = w.all_times[rows]
    series = coarse.cumulative_triad(w.time, w.dtheta_b, w.dvel_b, w.t0, lat, rows - 1)
    b = _budget(w, opts, True, g)
    T = w.T
    ts = observability.tilt_sigma(T, b.accel_bias, b.accel_vrw, g)
    hc = observability.check_earth_rate(lat, T, b, g, opts.max_heading_sigma)

    def propagate(c0):
        c0 = np.asarray(c0)
        return np.broadcast_to(c0, (len(rows), 3, 3)).copy() if c0.ndim == 2 else c0.copy()

    return _Solution(cbn, rows, times, propagate, series, np.array([ts, ts]), hc, "earth-rate", budget=b)


def _combine_roll(c_full, c_win, conv):
    """Roll of ``c_win``, pitch and heading of ``c_full`` (seed 001's improvement)."""
    r, _, _ = dcm_to_euler(np.ascontiguousarray(c_win), conv)
    _, p, h = dcm_to_euler(np.ascontiguousarray(c_full), conv)
    return euler_to_dcm(r, p, h, conv)


def _inertial(w: Window, opts: AlignOptions, lat: float, h: float, g: float,
              gnss: GnssLog | None = None) -> _Solution:
    M = len(w.time)
    times_all = w.all_times
    rel = w.time - w.t0
    vel_ep = None
    sig_v = 0.0
    if gnss is None:
        lat_s = np.full(M + 1, lat)
        h_s = np.full(M + 1, h)
        vel_s = np.zeros((M + 1, 3))
        rows = _epoch_rows(rel, opts.obs_interval)
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
        rows = np.unique(k)
        sig_v = float(np.median(s_g[inside]))
    cbb0, alpha, cnn0, beta = inertial.integrate(w.dtheta_b, w.dvel_b, w.dt, lat_s, h_s, vel_s, opts.coning)
    a_ep = alpha[rows]
    if gnss is not None and np.any(opts.lever_arm != 0.0):
        w_ib = _body_rate(w, np.concatenate([[0], rows]))
        a_all = inertial.lever_arm_alpha(np.concatenate([alpha[:1], a_ep]),
                                         np.concatenate([cbb0[:1], cbb0[rows]]), w_ib, opts.lever_arm)
        a_ep = a_all[1:]
    b_ep = beta[rows]
    centered = gnss is not None and opts.estimate_v0
    increments = opts.vectors == "increments" or (opts.vectors == "auto" and gnss is None)
    if increments:
        # the integral vectors of each observation interval (differences between epochs): at rest their
        # errors (accelerometer noise, the random walk of the cumulative vectors) are independent
        da = np.diff(np.concatenate([alpha[:1], a_ep]), axis=0)
        db = np.diff(np.concatenate([beta[:1], b_ep]), axis=0)
        series0 = wahba.solve_cumulative(da, db)
    else:
        series0 = wahba.solve_cumulative(a_ep, b_ep, centered=centered)
    cbn0 = series0[-1]
    times = times_all[rows]
    if opts.roll_window is not None:
        j = int(np.searchsorted(times - w.t0, opts.roll_window + 1e-9)) - 1
        j = max(j, 0)
        c_win = series0[j]
        cbn0 = _combine_roll(cbn0, c_win, opts.conv)
        s = series0.copy()
        for i in range(j + 1, len(s)):
            s[i] = _combine_roll(series0[i], c_win, opts.conv)
        series0 = s

    def propagate(c0):
        return inertial.attitude_at(c0, cbb0[rows], cnn0[rows])

    def at_end(c0):
        # the GNSS epochs may end up to a fix interval before the window's last sample
        return inertial.attitude_at(c0, cbb0[-1:], cnn0[-1:])[0]

    T = w.T
    if gnss is None:
        moving, _, _ = _rest_statistics(w, opts)
        b = _budget(w, opts, not moving, g)
        # the gyro bias turns the fitted gravity directions by ~eps T / 2 (the drift the roll window removes)
        ts = math.hypot(observability.tilt_sigma(T, b.accel_bias, b.accel_vrw, g), b.gyro_bias * T / 2.0)
        tilt = np.array([ts, ts])
        if opts.roll_window is not None:
            S = opts.roll_window
            tilt[0] = math.hypot(observability.tilt_sigma(S, b.accel_bias, b.accel_vrw, g), b.gyro_bias * S / 2.0)
        hc = observability.check_earth_rate(lat, T, b, g, opts.max_heading_sigma, accel_noise=True)
        return _Solution(cbn0, rows, times, propagate, series0, tilt, hc, "earth-rate", budget=b, at_end=at_end)
    # moving base: error budget of the fit, per epoch (GNSS velocity noise, accelerometer and gyro errors)
    b = _budget(w, opts, False, g)
    t_ep = times - w.t0
    gyro_bias = b.gyro_bias if opts.sensor.gyro_bias is not None else 0.0
    if centered:
        a_ep = a_ep - a_ep.mean(axis=0)
        b_ep = b_ep - b_ep.mean(axis=0)
    resid = b_ep - a_ep @ cbn0.T
    s_res = float(np.sqrt((resid ** 2).mean()))
    sig = np.sqrt(sig_v ** 2 + b.accel_vrw ** 2 * t_ep + (b.accel_bias * t_ep) ** 2
                  + (gyro_bias * g * t_ep ** 2 / 2.0) ** 2 + s_res ** 2)
    cov = wahba.covariance(cbn0, a_ep, sig)
    hs = observability.motion_heading_sigma(cov)
    ts = math.sqrt(max(cov[0, 0], cov[1, 1]) + (b.accel_bias / g) ** 2)
    what = (f"the fit of {len(rows)} GNSS epochs gives a heading 1-sigma of {math.degrees(hs):.3g} deg "
            f"(GNSS velocity 1-sigma {sig_v:.3g} m/s, fit residual {s_res:.3g} m/s)")
    if hs > opts.max_heading_sigma:
        hc = observability.HeadingCheck(False, hs, f"heading is not observable from earth rate or the motion: "
                                                   f"{what} (> {math.degrees(opts.max_heading_sigma):.3g} deg, "
                                                   f"align.max_heading_sigma)")
    else:
        hc = observability.HeadingCheck(True, hs, f"heading from earth rate and motion: {what}")
    vel_ep = vel_s[rows]
    return _Solution(cbn0, rows, times, propagate, series0, np.array([ts, ts]), hc, "gnss-motion", at_end=at_end,
                     vel_ep=vel_ep, sig_v=max(sig_v, 1e-3), budget=b)


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


def _resolve_heading(sol: _Solution, opts: AlignOptions, notes: list):
    """``(cbn0, cbn_epochs, heading_sigma, source)`` with the heading from its proper source."""
    cur = sol.propagate(sol.cbn0)
    if opts.heading is not None:
        h_end = dcm_to_euler(np.ascontiguousarray(cur[-1]), opts.conv)[2]
        delta = opts.heading - h_end
        cbn0 = _rz(delta) @ sol.cbn0
        cur = sol.propagate(cbn0)
        r, p, _ = dcm_to_euler(np.ascontiguousarray(cur[-1]), opts.conv)
        cur[-1] = euler_to_dcm(r, p, opts.heading, opts.conv)
        if not sol.heading.observable:
            notes.append(sol.heading.reason + f"; using --heading {math.degrees(opts.heading):.6g} deg")
        sigma = opts.heading_sigma if opts.heading_sigma is not None else float("nan")
        return cbn0, cur, sigma, "user"
    if sol.heading.observable:
        notes.append(sol.heading.reason)
        return sol.cbn0, cur, sol.heading.sigma, sol.heading_kind
    if sol.vel_ep is not None:
        h_ep = dcm_to_euler_many(np.ascontiguousarray(cur), opts.conv)[:, 2]
        co = observability.course_offset(sol.vel_ep, h_ep, opts.course_min_speed, sol.sig_v,
                                         opts.course_sigma_floor)
        if co is not None:
            delta, sigma, n = co
            cbn0 = _rz(delta) @ sol.cbn0
            cur = sol.propagate(cbn0)
            notes.append(sol.heading.reason + f"; heading from the GNSS course over {n} epochs faster than "
                         f"{opts.course_min_speed:g} m/s: 1-sigma {math.degrees(sigma):.3g} deg")
            return cbn0, cur, sigma, "gnss-course"
        raise SinsError(sol.heading.reason + f"; the GNSS course cannot replace it (fewer than 2 epochs faster "
                        f"than {opts.course_min_speed:g} m/s): give --heading DEG")
    raise SinsError(sol.heading.reason + "; give --heading DEG, or --gnss with a moving vehicle "
                    "(heading from the GNSS course)")


def _tilt_to_roll_pitch(P_h, heading):
    """Roll and pitch 1-sigma from a 2x2 ENU horizontal tilt covariance at ``heading`` (rad)."""
    fwd = np.array([math.sin(heading), math.cos(heading)])
    right = np.array([math.cos(heading), -math.sin(heading)])
    return math.sqrt(max(fwd @ P_h @ fwd, 0.0)), math.sqrt(max(right @ P_h @ right, 0.0))


# --------------------------------------------------------------------------- main entry

def align(imu: ImuLog, opts: AlignOptions, gnss: GnssLog | None = None, progress=None) -> AlignResult:
    """Align over the selected interval (see the module docstring)."""
    if opts.method == "kf" and opts.epoch == "start":
        raise SinsError("--epoch start: the Kalman filter gives the attitude at the end of the interval; "
                        "use --epoch end with --method kf")
    w = select_window(imu, opts)
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
    notes: list[str] = []
    coarse_method = opts.method
    if opts.method == "kf":
        coarse_method = opts.kf_coarse if opts.kf_coarse != "auto" else (
            "gnss-inertial" if gnss is not None else "inertial")
        Tc = opts.kf_coarse_duration if opts.kf_coarse_duration is not None else min(w.T / 2.0, 120.0)
        Tc = min(Tc, w.T)
        if Tc < MIN_DURATION[coarse_method]:
            raise SinsError(f"kf.coarse_duration {Tc:.4g} s: the {coarse_method} stage needs at least "
                            f"{MIN_DURATION[coarse_method]:g} s")
        k = int(np.searchsorted(w.time, w.t0 + Tc + 1e-6, side="right"))
        wc = Window(w.t0, w.time[:k], w.dtheta_b[:k], w.dvel_b[:k], w.source)
    else:
        wc = w
    if coarse_method in ("static", "inertial"):
        check_gravity(wc, g)
    if coarse_method == "static":
        sol = _static(wc, opts, lat, g)
    elif coarse_method == "inertial":
        sol = _inertial(wc, opts, lat, h, g)
    else:
        sol = _inertial(wc, opts, lat, h, g, gnss)
    cbn0, cur, h_sigma, source = _resolve_heading(sol, opts, notes)
    basis = sol.budget.source if sol.budget is not None else "config"
    if basis != "config":
        notes.append("sensor errors not all configured (align.sensor): the 1-sigma figures use what the data "
                     "show and are lower bounds")
    series0 = sol.series0
    if source in ("user", "gnss-course") and series0 is not None:
        series0 = np.matmul(_rz(float(dcm_to_euler(np.ascontiguousarray(cbn0), opts.conv)[2]
                                      - dcm_to_euler(np.ascontiguousarray(sol.cbn0), opts.conv)[2])), series0)
    if opts.method != "kf":
        r_s, p_s = sol.tilt_sigma
        sigma = np.array([r_s, p_s, h_sigma])
        cbn_end = sol.at_end(cbn0) if sol.at_end is not None else cur[-1]
        series = Series(sol.times, sol.propagate(series0) if series0 is not None else cur, series0)
        if source == "user":
            series.cbn[-1] = cbn_end
        if opts.epoch == "start":
            vel, pos = _start_velocity_position(w, opts, gnss, cbn0, (lat, lon, h), moving_gnss)
            state = NavState(w.t0, pos[0], pos[1], pos[2], vel, cbn0)
        else:
            vel, pos = _end_velocity_position(w, opts, gnss, cbn_end, (lat, lon, h), moving_gnss)
            state = NavState(t1, pos[0], pos[1], pos[2], vel, cbn_end)
        return AlignResult(state, opts.method, w.t0, w.T, sigma, source, notes=notes, series=series,
                           roll_window=opts.roll_window, sigma_basis=basis)
    res = _fine(w, opts, gnss, sol, cbn0, h_sigma, source, (lat, lon, h), g, notes, moving_gnss, progress)
    res.sigma_basis = basis
    return res


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


def _fine(w, opts, gnss, sol, cbn0, h_sigma, source, pos0, g, notes, moving_gnss, progress):
    """Kalman fine alignment over the whole interval from the coarse attitude at t0."""
    b = sol.budget
    lat, lon, h = pos0
    rel = w.time - w.t0
    if moving_gnss:
        v_g, s_g = gnss_velocity(gnss)
        inside = (gnss.time > w.t0) & (gnss.time <= w.time[-1] + 1e-9)
        k_up = np.unique(np.clip(np.searchsorted(w.time, gnss.time[inside] - 1e-9), 0, len(w.time) - 1))
        t_up = w.time[k_up]
        v_ref = np.stack([np.interp(t_up, gnss.time, v_g[:, i]) for i in range(3)], axis=-1)
        sig = s_g if opts.kf_vel_sigma is None else np.full_like(s_g, opts.kf_vel_sigma)
        r_var = np.stack([np.interp(t_up, gnss.time, sig[:, i]) for i in range(3)], axis=-1) ** 2
        v0 = np.array([np.interp(w.t0, gnss.time, v_g[:, i]) for i in range(3)])
        arm = np.asarray(opts.lever_arm, dtype=float)
        lever = arm if np.any(arm != 0.0) else None
        w_ib = _body_rate(w, k_up + 1) if lever is not None else None
        if lever is not None:
            v0 = v0 - cbn0 @ np.cross(_body_rate(w, np.array([0]))[0], arm)

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
    gyro_b = b.gyro_bias if b.gyro_bias > 0 else math.radians(1.0) / 3600.0
    accel_b = b.accel_bias if b.accel_bias > 0 else 100 * 9.80665e-6
    arw = b.gyro_arw if b.gyro_arw > 0 else math.radians(0.01) / 60.0
    vrw = b.accel_vrw if b.accel_vrw > 0 else 20 * 9.80665e-6
    P0 = np.zeros((kf.NX, kf.NX))
    tilt0 = max(float(sol.tilt_sigma.max()), math.radians(0.01))
    head0 = h_sigma if np.isfinite(h_sigma) else math.radians(5.0)
    P0[kf.PHI, kf.PHI] = np.diag([tilt0 ** 2, tilt0 ** 2, max(head0, math.radians(0.01)) ** 2])
    P0[kf.DV, kf.DV] = np.eye(3) * max(v_sig0, 0.01) ** 2
    P0[kf.EPS, kf.EPS] = np.eye(3) * gyro_b ** 2
    P0[kf.NAB, kf.NAB] = np.eye(3) * accel_b ** 2
    init = NavState(w.t0, p_start[0], p_start[1], p_start[2], v0, cbn0)
    imu = ImuLog(w.time, w.dtheta_b, w.dvel_b, t0=w.t0, source=w.source)
    res = kf.fine_align(imu, k_up, init, v_ref, r_var, P0, arw ** 2, vrw ** 2, position=position,
                        lever_b=lever, w_ib_b=w_ib, nav_opts=NavOptions(attitude="quat", coning=opts.coning,
                                                                       conv=opts.conv),
                        progress=progress)
    st = res.state
    cbn_end = st.Cbn
    heading_end = dcm_to_euler(np.ascontiguousarray(cbn_end), opts.conv)[2]
    P = res.P
    r_s, p_s = _tilt_to_roll_pitch(P[0:2, 0:2], heading_end)
    h_s = math.sqrt(P[2, 2])
    if source == "user":
        r, p, _ = dcm_to_euler(np.ascontiguousarray(cbn_end), opts.conv)
        cbn_end = euler_to_dcm(r, p, opts.heading, opts.conv)
        h_s = h_sigma
        res.cbn[-1] = cbn_end
    elif source == "gnss-course":
        h_s = max(h_s, h_sigma) if np.isfinite(h_sigma) else h_s
    vel = st.vel_n
    pos = (st.lat, st.lon, st.height)
    if moving_gnss:
        vel, pos = _end_velocity_position(w, opts, gnss, cbn_end, pos0, True)
    else:
        vel = np.zeros(3)
    state = NavState(st.time, pos[0], pos[1], pos[2], vel, cbn_end)
    notes.append(f"Kalman fine alignment from the {sol.heading_kind if source != 'user' else 'user'}-headed "
                 f"coarse solution, {len(k_up)} velocity updates")
    series = Series(res.times, res.cbn, None)
    return AlignResult(state, "kf", w.t0, w.T, np.array([r_s, p_s, h_s]), source, gyro_bias=res.gyro_bias,
                       accel_bias=res.accel_bias, notes=notes, series=series, roll_window=opts.roll_window)
