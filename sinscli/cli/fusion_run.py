"""Wiring of ``sins navigate --gnss`` / ``--gnss-raw``: readers -> alignment (``--align``) -> the fusion stage ->
writers.

Kept apart from :mod:`sinscli.cli.navigate` so that plain navigation does not import the filter.
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from ..allan.rest import noise_from_rest
from ..errors import SinsError
from ..fusion.mounting import estimate_mounting, refine
from ..fusion.options import build_fusion_options
from ..fusion.pipeline import Fusion, calibrated_run, fuse_blocks
from ..fusion.standstill import StandstillDetector, gnss_still
from ..io.atomic import atomic_path, prepare_output
from ..io.gnss_csv import check_gnss_against_imu, check_init_against_gnss
from ..io.imu_csv import apply_mounting
from ..io.init_state import align_estimates, read_init
from ..io.innovations import write_innovations
from ..io.readers import _is_log, read_body_velocity, read_gnss, read_imu
from ..io.receiver import is_receiver_log
from ..io.trajectory import check_trajectory_output, guard_trajectory, write_trajectory
from ..nav.earth import gravity, radii_py
from ..nav.pipeline import concat
from ..nav.sanity import accel_unit_check, gyro_unit_check, mounting_warning
from ..nav.timesync import estimate_offset, offset_refusal, offset_warning
from ..nav.window import Window, check_in_log, check_init, clip_imu, from_start, trim
from ..sensors import read_sensor
from ..types import ImuLog
from ..units import G0
from .base import log, progress, summary_line


def _span(t) -> str:
    return f"{float(t[0])!r} to {float(t[-1])!r} s" if len(t) else "no rows"


def run_fused(imu_path, gnss_path, init_path, align_method, smooth, innovations_path, sensor, cfg, config_path,
              opts, output, quiet, window=None, odom_path=None, vehicle=None, force=False, raw=None, tdcp=False):
    """``raw = (OBS, NAV paths)``: tightly coupled on the raw observations (:mod:`sinscli.fusion.raw`), their
    single-point fixes standing in for the GNSS log where the filter needs fixes (heading from motion,
    standstill test, ``--align``); else ``gnss_path`` the fixes (loosely coupled).  ``tdcp``: ``--tdcp``
    (``fusion.raw.tdcp`` on)."""
    src = str(config_path) if config_path else "config"
    base = Path(config_path).parent if config_path else Path.cwd()
    section = cfg.fusion
    if sensor is not None and isinstance(section, dict):      # --sensor replaces fusion.sensor: not read
        section = {**section, "sensor": None}
    fopts = build_fusion_options(section, src, base_dir=base, vehicle=vehicle)
    if tdcp:
        fopts = replace(fopts, raw_tdcp=True)
    if sensor is not None:                  # the sensor description, read once, a typed value for the filter
        fopts = replace(fopts, sensor=read_sensor(sensor, "command line", Path.cwd(), key="--sensor"))
    if fopts.lever_arm is None:
        fopts = replace(fopts, lever_arm=np.asarray(cfg.gnss.lever_arm, dtype=float))
    check_trajectory_output(output)
    if innovations_path is not None:
        prepare_output(innovations_path)
    imu = read_imu(imu_path, cfg, allow_gaps=cfg.navigation.allow_gaps)
    if len(imu) == 0:
        raise SinsError(f"{imu_path}: no IMU samples")
    # accelerometers in g read as m/s^2 (or the reverse): before anything uses the specific force
    accel_unit_check(imu, imu.t0 if imu.t0 is not None else float(imu.time[0]), cfg.imu, force, ros=_is_log(imu_path))
    spp = None
    if raw is not None:
        obs, nav, spp, gnss = _read_raw(raw, fopts, cfg)
    else:
        gnss = read_gnss(gnss_path, cfg)
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    window = (window or Window()).resolve(t0)
    check_in_log(window, t0, float(imu.time[-1]), str(imu_path))
    imu = clip_imu(imu, window.end)
    if align_method is not None and window.start is not None:     # aligned on the window's first seconds
        imu = from_start(imu, window.start)
        t0 = float(imu.t0)
    try:
        check_gnss_against_imu(gnss if raw is None else _epochs_log(obs, cfg), t0, float(imu.time[-1]))
    except SinsError as exc:
        offset = cfg.gnss.time_offset
        if not offset and raw is not None:
            raise SinsError(f"{exc} (raw observations are stamped in GPS time: --time-offset or gnss.time_offset "
                            f"maps them onto the IMU's clock)") from None
        if raw is None and "leap seconds" in str(exc) and is_receiver_log(gnss_path):
            other = "utc" if cfg.imu.time_system == "gps" else "gps"
            raise SinsError(f"{exc}; for an NMEA or UBX log say the IMU's time system instead: imu.time_system: "
                            f"{other} (now {cfg.imu.time_system})") from None
        if not offset:
            raise
        raise SinsError(f"{exc} (after the GNSS time offset of {offset:g} s, --time-offset or gnss.time_offset)") \
            from None
    if raw is not None and len(gnss) == 0 and (align_method is not None or cfg.imu.mounting == "auto"):
        what = f"--align {align_method}" if align_method is not None else "imu.mounting: auto"
        raise SinsError(f"{raw[0]}: no epoch has a single-point fix (4 satellites or more): {what} needs fixes; "
                        f"give --init with the initial state and the mounting")
    if not force and len(gnss) > 0:            # a constant offset the spans cannot show (nav/timesync.py)
        est = estimate_offset(imu.time, imu.dtheta_b, imu.dvel_b, t0, gnss.time, gnss.lat, gnss.lon, gnss.height,
                              gnss.vel_n)
        text = offset_refusal(est, str(gnss.source), cfg.gnss.time_offset)
        if text:
            raise SinsError(text)
        note = offset_warning(est, str(gnss.source), cfg.gnss.time_offset)    # periodic motion: candidates only
        if note:
            log.warning(note)

    def gyro_units(lat_g, height):
        """Before anything runs on the increments (the mounting too): at the first fix, or (raw observations
        without any fix: no mounting or alignment runs before) at the initial state."""
        gyro_unit_check(imu, t0, gravity(np.sin(lat_g), height), lat_g, cfg.imu,
                        (fopts.sensor or read_sensor("mems", src, base)).as_dict(), force, ros=_is_log(imu_path))
    if len(gnss) > 0:
        gyro_units(float(np.radians(gnss.lat[0])), float(gnss.height[0]))
    mounting = None
    if cfg.imu.mounting == "auto":
        imu, mounting = _auto_mounting(imu, gnss, opts.conv, fopts, output)
    body_vel = None
    if odom_path is not None:
        body_vel = read_body_velocity(odom_path, cfg)
        if len(body_vel.time) == 0 or body_vel.time[-1] < t0 or body_vel.time[0] > imu.time[-1]:
            raise SinsError(f"{body_vel.source}: the body velocity ({_span(body_vel.time)}) does not overlap the "
                            f"IMU log ({t0!r} to {float(imu.time[-1])!r} s)")
    init_bias = None
    if align_method is not None:             # the attitude comes from the log: check its up axis
        note = mounting_warning(imu, t0, gravity(np.sin(np.radians(gnss.lat[0])), float(gnss.height[0])), opts.conv,
                                None, cfg.imu)
        if note:
            log.warning(note)
        init, init_sigma, init_bias = _align(imu, gnss, align_method, cfg, config_path, opts.conv, fopts)
    else:
        init = read_init(init_path, t0 if window.start is None else window.start, opts.conv, cfg.limits,
                         cfg.init)
        check_init(init.time, window, str(init_path))
        check_init_against_gnss(init, gnss, cfg.limits.speed, str(init_path))
        if len(gnss) == 0:
            gyro_units(float(init.lat), float(init.height))
        init_sigma, init_bias = align_estimates(init, init_path, cfg.limits)
        note = mounting_warning(imu, max(t0, init.time), gravity(np.sin(init.lat), init.height), opts.conv,
                                init.Cbn, cfg.imu)
        if note:
            log.warning(note)
    data_noise = noise_from_rest(imu, fopts, gnss) if fopts.noise_from_data else None
    if mounting is not None:                 # stage 3 of imu.mounting: auto: a fused pass without NHC refines it
        imu, mounting, init = _refine_mounting(imu, mounting, init, opts, fopts, gnss, init_sigma, init_bias,
                                               data_noise, t0, src)

    rawm = None
    if raw is not None:
        from ..fusion.raw import raw_measurements  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
        rawm = raw_measurements(obs, nav, fopts, cfg.gnss.time_offset, init, spp=spp)

    def make(**kw):
        return Fusion(init, opts, fopts, gnss, init_sigma=init_sigma, src=src, init_bias=init_bias,
                      body_vel=body_vel, data_noise=data_noise, t_log0=t0, raw=rawm, **kw)

    step = 1 << 16

    def blocks():
        return (ImuLog(imu.time[a:a + step], imu.dtheta_b[a:a + step], imu.dvel_b[a:a + step],
                       t0=imu.t0 if a == 0 else None, source=imu.source) for a in range(0, len(imu), step))
    with progress(len(imu), "fusing", quiet or len(imu) < 200_000) as bar:
        def run(f):                             # each calibration pass restarts the bar
            bar.update(-bar.pos if hasattr(bar, "pos") else 0)
            return list(fuse_blocks(blocks(), f, progress=bar.update))
        fusion, chunks = calibrated_run(make, run, smooth)
        traj = concat(chunks)
    if smooth:
        traj = fusion.smoothed()
    traj = fusion.on_gnss_clock(traj)
    if window.active:
        traj = trim(traj, window)
        if len(traj) == 0:
            raise SinsError(f"{imu_path}: no navigation epoch in the window {window.text()}")
    summary = fusion.summary(traj)
    records = fusion.innovations()
    for r in records[~records["accepted"]]:
        log.debug("rejected %s %s at %.6f s: innovation %.4g, sigma %.4g, NIS %.3g", r["type"], r["axis"],
                  r["time"], r["innovation"], r["sigma"], r["nis"])
    guard_trajectory(output, traj)               # both outputs or neither: the guard before either is written
    if innovations_path is not None:               # both staged in the command's output set (io/atomic.py):
        write_innovations(innovations_path, records)   # in place together, or neither (an earlier pair kept)
    write_trajectory(output, traj, opts.conv)
    if mounting is not None:
        with atomic_path(mounting_snippet_path(output), suffix=".yaml") as tmp:
            Path(tmp).write_text(mounting.snippet(), encoding="utf-8")
    for line in summary.lines():
        click.echo(f"sins: {line}", err=True)
    for w in summary.warnings:
        log.warning("fusion: %s", w)
    if not quiet:
        summary_line(imu_path, len(traj), float(traj.time[0]), float(traj.time[-1]), output)


def _read_raw(raw, fopts, cfg):
    """``(obs, nav, spp, fixes)`` of ``--gnss-raw OBS --nav NAV``: the tables, their single-point solution and its
    fixes as a GNSS log on the IMU's clock (``gnss.time_offset``)."""
    from ..fusion.raw import raw_spp, spp_log  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
    from ..io.raw_input import read_raw  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
    obs_path, nav_paths = raw
    obs, nav = read_raw(obs_path, nav_paths)
    if len(obs) == 0:
        raise SinsError(f"{obs_path}: no observation epochs")
    spp = raw_spp(obs, nav, fopts)
    return obs, nav, spp, spp_log(spp, cfg.gnss.time_offset, str(obs_path))


def _epochs_log(obs, cfg):
    """The raw epochs' times (GPS time + ``gnss.time_offset``) as a GNSS log, for the time-base check."""
    from ..types import GnssLog  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
    t = obs.time + cfg.gnss.time_offset
    z = np.zeros(len(t))
    return GnssLog(t, z, z, z, source=obs.source)


def mounting_snippet_path(output) -> Path:
    """Where ``imu.mounting: auto`` writes its estimate as a config snippet: beside the output."""
    return Path(output).with_name(Path(output).stem + ".mounting.yaml")


def _auto_mounting(imu, gnss, conv, fopts, output):
    """``imu.mounting: auto``: the mounting estimated from the log (:mod:`sinscli.fusion.mounting`), applied
    to the increments read in sensor axes, reported and written as a config snippet beside the output."""
    est = estimate_mounting(imu, gnss, conv, fopts)
    r, p, y = est.rpy
    sr, sp, sy = est.sigma
    snippet = mounting_snippet_path(output)
    prepare_output(snippet)
    click.echo(f"sins: mounting: imu.mounting estimated as {{roll: {r:.2f}, pitch: {p:.2f}, yaw: {y:.2f}}} deg "
               f"(1-sigma {sr:.2g}, {sp:.2g}, {sy:.2g} deg): {'; '.join(est.notes)}; the config snippet goes to "
               f"{snippet}", err=True)
    return apply_mounting(imu, est.C), est


def _refine_mounting(imu, est, init, opts, fopts, gnss, init_sigma, init_bias, data_noise, t0, src):
    """Stage 3 of ``imu.mounting: auto`` (:func:`sinscli.fusion.mounting.refine`): a forward pass with the
    stages 1-2 mounting, GNSS only (no NHC, no adaptation passes), gives the vehicle's axes in that body
    frame; the increments and the initial attitude are turned by the residual rotation."""
    f = Fusion(init, opts, replace(fopts, nhc=False, adapt=False), gnss, init_sigma=init_sigma, src=src,
               init_bias=init_bias, data_noise=data_noise, t_log0=t0)
    traj = concat(list(fuse_blocks([imu], f)))
    new = refine(est, traj, opts.conv)
    D = new.C @ est.C.T                             # body_new = D body_old
    r, p, y = new.rpy
    sr, sp, sy = new.sigma
    click.echo(f"sins: mounting: refined by a fused pass to {{roll: {r:.2f}, pitch: {p:.2f}, yaw: {y:.2f}}} deg "
               f"(1-sigma {sr:.2g}, {sp:.2g}, {sy:.2g} deg)", err=True)
    init = replace(init, Cbn=np.asarray(init.Cbn, dtype=float) @ D.T)
    return apply_mounting(imu, D), new, init


ALIGN_WINDOW = 60.0          # s: the alignment window of a log that does not start at rest
NEEDS_REST = ("static", "inertial")


def first_rest(imu, fopts, gnss) -> float:
    """Seconds the log stays at rest from its start (the fused filter's detector, still by the GNSS too);
    0 when it starts moving."""
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    k = int(np.searchsorted(imu.time, t0 + 600.0))
    det = StandstillDetector(fopts.standstill_window, fopts.standstill_rate_std, fopts.standstill_accel_std,
                             fopts.standstill_accel_mag, G0, fopts.standstill_lowpass)
    a, b, _ = det.feed(imu.time[:k], imu.dtheta_b[:k], imu.dvel_b[:k], t_start=t0)
    end = t0
    for x, y, still in zip(a, b, gnss_still(gnss, a, b) if len(a) else []):
        if abs(x - end) > 1e-6 * max(1.0, abs(end)) or still == 0:
            break
        end = float(y)
    return end - t0


def _align(imu, gnss, method, cfg, config_path, conv, fopts):
    """``--align METHOD`` inside the fused run: ``sins align`` on the log's first window (``align.duration``,
    else the first standstill, else 60 s), its state at the window's start (the filter then runs the log
    from its start); an unobservable heading is left to the heading from motion.  ``kf`` gives the
    attitude at its window's end only: inside the fused run its coarse stage gives the start and the
    fusion filter is the fine alignment."""
    from ..align.options import build_options, merge_section  # the alignment only with --align
    from ..align.pipeline import align  # the alignment only with --align
    src = str(config_path) if config_path else "config"
    al = merge_section(cfg.align, src)
    if method == "kf":
        coarse = al["kf"]["coarse"]
        method = coarse if coarse != "auto" else "gnss-inertial"
        click.echo(f"sins: note: --align kf inside the fused run: its coarse stage ({method}) gives the state at "
                   f"the log's start and the fusion filter is the fine alignment", err=True)
    al["method"] = method
    al["epoch"] = "start"
    rest = first_rest(imu, fopts, gnss)
    if al["duration"] is None:
        span = float(imu.time[-1] - (imu.t0 if imu.t0 is not None else imu.time[0]))
        al["duration"] = min(rest if rest >= 5.0 else ALIGN_WINDOW, span)
        why = f"the first standstill ({rest:.3g} s)" if rest >= 5.0 else f"the first {al['duration']:.3g} s"
    else:
        why = f"align.duration {al['duration']:g} s"
    if method in NEEDS_REST and rest < min(al["duration"], 5.0):
        raise SinsError(f"{imu.source}: --align {method} needs the log to start at rest, and its first "
                        f"{al['duration']:.3g} s move (at rest for {rest:.3g} s); use --align gnss-inertial, or "
                        f"--init with the initial state")
    aopts = build_options(al, src, conv=conv, lever_arm=cfg.gnss.lever_arm)
    res = align(imu, aopts, gnss, heading_optional=True)
    for note in res.notes:
        click.echo(f"sins: note: {note}", err=True)
    head_sigma = res.sigma[2] if np.isfinite(res.sigma[2]) else np.inf
    if res.heading_source == "gnss-course":
        # the course's heading carried back to the window's start through the gyros (their bias over the
        # window): the filter's own heading from motion does the same job where it happens, consistently
        click.echo("sins: note: the alignment's heading came from the GNSS course: the fused run takes its "
                   "heading from the motion itself (fusion.heading_init) instead", err=True)
        head_sigma = np.inf
    sig = {"attitude": np.array([res.sigma[0], res.sigma[1], head_sigma])}
    k = int(np.clip(np.searchsorted(gnss.time, res.state.time), 0, len(gnss) - 1))
    sig["position"] = np.maximum(gnss.position_sigma(fopts.gnss_pos_sigma)[k], 0.01) * 2.0
    # the IMU's position from the antenna's fix, whatever the method took (static and inertial take the
    # fix as it is): the lever arm through the aligned attitude; with the heading unknown its horizontal
    # part points anywhere (variance |l_h|^2 / 2 per axis)
    arm = np.asarray(fopts.lever_arm if fopts.lever_arm is not None else cfg.gnss.lever_arm, float)
    st = res.state
    lat = math.radians(float(np.interp(st.time, gnss.time, gnss.lat)))
    lon = float(np.interp(st.time, gnss.time, np.unwrap(np.radians(gnss.lon))))
    lon = (lon + math.pi) % (2.0 * math.pi) - math.pi
    h = float(np.interp(st.time, gnss.time, gnss.height))
    d = st.Cbn @ arm
    rm, rn = radii_py(math.sin(lat))
    st.lat, st.lon, st.height = lat - d[1] / (rm + h), lon - d[0] / ((rn + h) * math.cos(lat)), h - d[2]
    if not np.isfinite(head_sigma):
        sig["position"][:2] = np.hypot(sig["position"][:2], math.hypot(d[0], d[1]) / math.sqrt(2.0))
    bias = None
    if res.gyro_bias is not None:
        bias = {"gyro": res.gyro_bias, "accel": res.accel_bias}
    log.info("aligned (%s over %s): initial state at %.6f s", method, why, res.state.time)
    return res.state, sig, bias
