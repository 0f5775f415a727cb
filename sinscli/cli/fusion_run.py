"""Wiring of ``sins navigate --gnss``: readers -> alignment (``--align``) -> the fusion stage -> writers.

Kept apart from :mod:`sinscli.cli.navigate` so that plain navigation does not import the filter.
"""
from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from ..errors import SinsError
from ..io.gnss_csv import check_gnss_against_imu
from ..io.atomic import prepare_output
from ..io.init_state import align_estimates, read_init
from ..io.innovations import write_innovations
from ..io.readers import read_body_velocity, read_gnss, read_imu
from ..io.trajectory import check_trajectory_output, guard_trajectory, write_trajectory
from ..types import ImuLog
from .base import log, progress, summary_line


def _span(t) -> str:
    return f"{float(t[0])!r} to {float(t[-1])!r} s" if len(t) else "no rows"


def run_fused(imu_path, gnss_path, init_path, align_method, smooth, innovations_path, sensor, cfg, config_path,
              opts, output, quiet, window=None, odom_path=None, force=False):
    from ..fusion.options import build_fusion_options
    from ..fusion.pipeline import Fusion, fuse_blocks
    from ..nav.pipeline import concat

    src = str(config_path) if config_path else "config"
    base = Path(config_path).parent if config_path else Path.cwd()
    fopts = build_fusion_options(cfg.get("fusion"), src, base_dir=base)
    if sensor is not None:
        fopts.sensor, fopts.base_dir = sensor, Path.cwd()
    if fopts.lever_arm is None:
        fopts.lever_arm = np.asarray(cfg["gnss"]["lever_arm"], dtype=float)
    check_trajectory_output(output)
    if innovations_path is not None:
        prepare_output(innovations_path)
    imu = read_imu(imu_path, cfg, allow_gaps=cfg["navigation"]["allow_gaps"])
    if len(imu) == 0:
        raise SinsError(f"{imu_path}: no IMU samples")
    gnss = read_gnss(gnss_path, cfg)
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    from ..nav.window import Window, check_in_log, check_init, clip_imu, from_start, trim
    window = (window or Window()).resolve(t0)
    check_in_log(window, t0, float(imu.time[-1]), str(imu_path))
    imu = clip_imu(imu, window.end)
    if align_method is not None and window.start is not None:     # aligned on the window's first seconds
        imu = from_start(imu, window.start)
        t0 = float(imu.t0)
    try:
        check_gnss_against_imu(gnss, t0, float(imu.time[-1]))
    except SinsError as exc:
        offset = float(cfg["gnss"]["time_offset"])
        if not offset:
            raise
        raise SinsError(f"{exc} (after the GNSS time offset of {offset:g} s, --time-offset or gnss.time_offset)") \
            from None
    if not force:                              # a constant offset the spans cannot show (nav/timesync.py)
        from ..nav.timesync import estimate_offset, offset_refusal
        est = estimate_offset(imu.time, imu.dtheta_b, imu.dvel_b, t0, gnss.time, gnss.lat, gnss.lon, gnss.height,
                              gnss.vel_n)
        text = offset_refusal(est, str(gnss.source), float(cfg["gnss"]["time_offset"]))
        if text:
            raise SinsError(text)
    body_vel = None
    if odom_path is not None:
        body_vel = read_body_velocity(odom_path, cfg)
        if len(body_vel.time) == 0 or body_vel.time[-1] < t0 or body_vel.time[0] > imu.time[-1]:
            raise SinsError(f"{body_vel.source}: the body velocity ({_span(body_vel.time)}) does not overlap the "
                            f"IMU log ({t0!r} to {float(imu.time[-1])!r} s)")
    from ..nav.earth import gravity
    from ..nav.sanity import mounting_warning
    init_bias = None
    if align_method is not None:             # the attitude comes from the log: check its up axis
        note = mounting_warning(imu, t0, gravity(np.sin(np.radians(gnss.lat[0])), float(gnss.height[0])), opts.conv,
                                None, cfg["imu"])
        if note:
            log.warning(note)
        init, init_sigma, init_bias = _align(imu, gnss, align_method, cfg, config_path, opts.conv, fopts.gnss_pos_sigma)
    else:
        init = read_init(init_path, t0 if window.start is None else window.start, opts.conv, cfg["limits"],
                         cfg["init"])
        check_init(init.time, window, str(init_path))
        init_sigma, init_bias = align_estimates(init, init_path, cfg["limits"])
        note = mounting_warning(imu, max(t0, init.time), gravity(np.sin(init.lat), init.height), opts.conv,
                                init.Cbn, cfg["imu"])
        if note:
            log.warning(note)
    from ..io.readers import _is_log
    from ..nav.sanity import gyro_unit_check
    from ..sensors import load_sensor
    lat0 = float(init.lat) if align_method is None else float(np.radians(gnss.lat[0]))
    h0 = float(init.height) if align_method is None else float(gnss.height[0])
    gyro_unit_check(imu, t0 if align_method is not None else max(t0, init.time), gravity(np.sin(lat0), h0), lat0,
                    cfg["imu"], load_sensor(fopts.sensor or "mems", None, src, fopts.base_dir or base), force,
                    ros=_is_log(imu_path))
    fusion = Fusion(init, opts, fopts, gnss, init_sigma=init_sigma, smooth=smooth, src=src, init_bias=init_bias,
                    body_vel=body_vel)
    step = 1 << 16
    blocks = (ImuLog(imu.time[a:a + step], imu.dtheta_b[a:a + step], imu.dvel_b[a:a + step],
                     t0=imu.t0 if a == 0 else None, source=imu.source) for a in range(0, len(imu), step))
    with progress(len(imu), "fusing", quiet or len(imu) < 200_000) as bar:
        traj = concat(list(fuse_blocks(blocks, fusion, progress=bar.update)))
    if smooth:
        traj = fusion.smoothed()
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
    click.echo(f"sins: {summary.text()}", err=True)
    if not quiet:
        summary_line(imu_path, len(traj), float(traj.time[0]), float(traj.time[-1]), output)


def _align(imu, gnss, method, cfg, config_path, conv, gnss_pos_sigma):
    """``sins align --method METHOD`` on the log's first window (the align section of the same config)."""
    from ..align.options import build_options, merge_section
    from ..align.pipeline import align
    src = str(config_path) if config_path else "config"
    al = merge_section(cfg.get("align"), src)
    al["method"] = method
    aopts = build_options(al, src, conv=conv, lever_arm=cfg["gnss"]["lever_arm"])
    res = align(imu, aopts, gnss)
    for note in res.notes:
        click.echo(f"sins: note: {note}", err=True)
    sig = {"attitude": np.array([res.sigma[0], res.sigma[1],
                                 res.sigma[2] if np.isfinite(res.sigma[2]) else np.inf])}
    k = int(np.clip(np.searchsorted(gnss.time, res.state.time), 0, len(gnss) - 1))
    sig["position"] = np.maximum(gnss.position_sigma(gnss_pos_sigma)[k], 0.01) * 2.0
    bias = None
    if res.gyro_bias is not None:
        bias = {"gyro": res.gyro_bias, "accel": res.accel_bias}
    log.info("aligned (%s): initial state at %.6f s", method, res.state.time)
    return res.state, sig, bias
