"""Wiring of ``sins navigate --gnss``: readers -> alignment (``--align``) -> the fusion stage -> writers.

Kept apart from :mod:`sinscli.cli.navigate` so that plain navigation does not import the filter.
"""
from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np

from ..errors import SinsError
from ..io.gnss_csv import check_gnss_against_imu
from ..io.init_state import read_init
from ..io.innovations import write_innovations
from ..io.readers import read_body_velocity, read_gnss, read_imu
from ..io.trajectory import write_trajectory
from ..types import ImuLog, NavState
from .base import log, progress

def init_from_yaml(init: NavState) -> tuple[dict, dict | None]:
    """1-sigma (attitude, rad) and sensor estimates (SI) that a ``sins align`` YAML carries."""
    sig = {}
    x = init.extra
    if "sigma_roll" in x and "sigma_pitch" in x:
        head = x.get("sigma_heading")
        sig["attitude"] = np.radians([float(x["sigma_roll"]), float(x["sigma_pitch"]),
                                      float(head) if head is not None else np.inf])
        for k in ("sigma_roll", "sigma_pitch"):
            v = float(x[k])
            if not math.isfinite(v) or v <= 0:
                raise SinsError(f"init: {k}: expected a finite sigma > 0, got {x[k]!r}")
    bias = None
    if "gyro_bias" in x and "accel_bias" in x:
        bias = {"gyro": np.radians(np.asarray(x["gyro_bias"], float)) / 3600.0,
                "accel": np.asarray(x["accel_bias"], float) * 9.80665e-6}
    return sig, bias


def _span(t) -> str:
    return f"{float(t[0])!r} to {float(t[-1])!r} s" if len(t) else "no rows"


def run_fused(imu_path, gnss_path, init_path, align_method, smooth, innovations_path, sensor, cfg, config_path,
              opts, output, quiet, odom_path=None):
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
    suffix = output.suffix.lower()
    from ..io.trajectory import WRITERS
    if suffix not in (".csv", ".parquet", *WRITERS):
        raise SinsError(f"{output}: unknown output format '{suffix}'")
    imu = read_imu(imu_path, cfg, allow_gaps=cfg["navigation"]["allow_gaps"])
    if len(imu) == 0:
        raise SinsError(f"{imu_path}: no IMU samples")
    gnss = read_gnss(gnss_path, cfg)
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0] - (imu.time[1] - imu.time[0]))
    check_gnss_against_imu(gnss, t0, float(imu.time[-1]))
    body_vel = None
    if odom_path is not None:
        body_vel = read_body_velocity(odom_path, cfg)
        if len(body_vel.time) == 0 or body_vel.time[-1] < t0 or body_vel.time[0] > imu.time[-1]:
            raise SinsError(f"{body_vel.source}: the body velocity ({_span(body_vel.time)}) does not overlap the "
                            f"IMU log ({t0!r} to {float(imu.time[-1])!r} s)")
    init_bias = None
    if align_method is not None:
        init, init_sigma, init_bias = _align(imu, gnss, align_method, cfg, config_path, opts.conv, fopts.gnss_pos_sigma)
    else:
        init = read_init(init_path, t0, opts.conv)
        init_sigma, init_bias = init_from_yaml(init)
    fusion = Fusion(init, opts, fopts, gnss, init_sigma=init_sigma, smooth=smooth, src=src, init_bias=init_bias,
                    body_vel=body_vel)
    step = 1 << 16
    blocks = (ImuLog(imu.time[a:a + step], imu.dtheta_b[a:a + step], imu.dvel_b[a:a + step],
                     t0=imu.t0 if a == 0 else None, source=imu.source) for a in range(0, len(imu), step))
    with progress(len(imu), "fusing", quiet or len(imu) < 200_000) as bar:
        traj = concat(list(fuse_blocks(blocks, fusion, progress=bar.update)))
    if smooth:
        traj = fusion.smoothed()
    summary = fusion.summary(traj)
    records = fusion.innovations()
    for r in records[~records["accepted"]]:
        log.debug("rejected %s %s at %.6f s: innovation %.4g, sigma %.4g, NIS %.3g", r["type"], r["axis"],
                  r["time"], r["innovation"], r["sigma"], r["nis"])
    for name in traj.extra:
        a = traj.extra[name]
        if not np.all(np.isfinite(a)):
            raise SinsError(f"internal: column {name} is not finite; nothing written")
    if innovations_path is not None:
        write_innovations(innovations_path, records)
    write_trajectory(output, traj, opts.conv)
    click.echo(f"sins: {summary.text()}", err=True)
    log.info("wrote %s", output)


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
