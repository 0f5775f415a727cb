"""``sins align``: IMU (+GNSS) log -> initial state YAML; ``--monte-carlo N --scenario S``: seed 001 Figs. 1-3."""
from __future__ import annotations

import logging
import sys
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from .. import conventions as cv
from ..errors import SinsError
from ..io.atomic import atomic_path, commit_outputs, prepare_output
from ..io.init_state import write_init_yaml
from ..nav.rotation import BODY_CONVENTIONS, dcm_to_euler_many
from .base import log, main, progress, quiet_option
from .batch_options import info_echo, interrupted_exit, scheduler_options


def _parse_heading(value):
    try:
        return float(value)
    except ValueError:
        raise SinsError(f"--heading: expected degrees, got {value!r}") from None


@main.command("align")
@click.argument("imu", required=False, type=click.Path(path_type=Path))
@click.option("--gnss", "gnss_path", type=click.Path(path_type=Path), default=None,
              help="GNSS log (CSV or ROS bag/MCAP): position, and velocity for gnss-inertial / kf on the move.")
@click.option("--method", type=click.Choice(cv.ALIGN_METHODS), default=None,
              help="static (analytic, at rest) | inertial (seed 001, static or swaying base) | gnss-inertial "
                   "(moving, GNSS velocity) | kf (Kalman fine alignment after a coarse stage). Default: config.")
@click.option("--start", type=float, default=None, help="Alignment start, log time (s). Default: the log's start.")
@click.option("--duration", type=float, default=None, help="Alignment interval (s). Default: the rest of the log.")
@click.option("--position", default=None, help="LAT,LON,H (deg, deg, m) when there is no GNSS log.")
@click.option("--roll-window", type=float, default=None,
              help="Roll from the first S seconds, pitch and heading from the whole interval (seed 001).")
@click.option("--heading", default=None, help="Heading (deg) to use instead of the estimated one.")
@click.option("--epoch", type=click.Choice(cv.ALIGN_EPOCHS), default=None,
              help="State written for the interval's end (default) or start (Cbn(0)).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="Config YAML: imu/gnss/ros sections of the navigation config plus an 'align' section.")
@click.option("--body", type=click.Choice(sorted(cv.BODY_NAMES)), default=None, help="Body axes convention.")
@click.option("--imu-topic", default=None, help="IMU topic in a ROS bag / MCAP log.")
@click.option("--gnss-topic", default=None, help="NavSatFix topic in a ROS bag / MCAP log.")
@click.option("--vel-topic", default=None,
              help="GNSS velocity topic (TwistStamped or TwistWithCovarianceStamped, ENU) in a ROS bag / MCAP log. "
                   "nav_msgs/Odometry is refused: its twist is a body velocity, not ENU.")
@click.option("--series", type=click.Path(path_type=Path), default=None,
              help="CSV of the attitude estimate against alignment time.")
@click.option("--plot", type=click.Path(path_type=Path), default=None, help="PNG of the attitude against time.")
@click.option("--monte-carlo", "mc_runs", type=click.IntRange(min=2), default=None,
              help="Run N seeded simulations of --scenario and write the error statistics and figures to -o DIR.")
@click.option("--scenario", type=click.Path(path_type=Path), default=None,
              help="Alignment scenario (simulator scenario + align + monte_carlo sections), for --monte-carlo.")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="First seed of the Monte Carlo runs.")
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="Initial-state YAML (or, with --monte-carlo, the output directory).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="--monte-carlo: worker processes of the local pool (default: all cores).")
@scheduler_options
@click.option("--force", is_flag=True,
              help="Align data that the unit checks refuse (rates or specific forces impossible in their declared "
                   "unit).")
@quiet_option
def align_cmd(imu, gnss_path, method, start, duration, position, roll_window, heading, epoch, config_path, body,
              imu_topic, gnss_topic, vel_topic, series, plot, mc_runs, scenario, seed, output, jobs, scheduler, resume,
              figures, force, quiet):
    """Initial alignment: the attitude (and state) where navigation starts, with its 1-sigma.

    \b
    Examples:
      sins align imu.csv --method static --position 30,114,50 -o init.yaml
      sins align imu.csv --method inertial --roll-window 10 --position 30,114,50 -o init.yaml
      sins align imu.csv --gnss gnss.csv --method gnss-inertial --duration 100 -o init.yaml
      sins align log.bag --gnss log.bag --config configs/align/husky.yaml -o init.yaml
      sins align --monte-carlo 100 --scenario configs/align/seed001_static.yaml -o mc
      sins align --monte-carlo 10000 --scenario S.yaml -o mc --scheduler tcp://10.0.0.5:8786 --resume
    """
    if mc_runs is not None or scenario is not None:
        if mc_runs is None or scenario is None:
            raise SinsError("--monte-carlo N and --scenario FILE go together")
        _monte_carlo(scenario, mc_runs, seed, output, quiet, jobs, scheduler, resume, figures)
        return
    for opt, val in (("--jobs", jobs), ("--scheduler", scheduler), ("--resume", resume),
                     ("--figures", figures != "auto")):
        if val:
            raise SinsError(f"{opt}: only used with --monte-carlo")
    if imu is None:
        raise SinsError("give an IMU log (or --monte-carlo N --scenario FILE)")
    for out in (output, series, plot):         # before any work: a directory, no permission, an input
        if out is not None:
            prepare_output(out)
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..align.options import build_options, load_align_config, parse_position
    from ..align.pipeline import align
    from ..config import override
    from ..io.readers import read_gnss, read_imu

    cfg, al = load_align_config(config_path)
    cfg = override(cfg, "imu", body=body)
    cfg = override(cfg, "ros", imu_topic=imu_topic, gnss_topic=gnss_topic, vel_topic=vel_topic)
    for key, value in (("method", method), ("start", start), ("duration", duration),
                       ("roll_window", roll_window), ("epoch", epoch)):
        if value is not None:
            al[key] = value
    if heading is not None:
        al["heading"] = _parse_heading(heading)
    conv_name = cfg.imu.body
    conv = BODY_CONVENTIONS[conv_name]
    opts = build_options(al, str(config_path) if config_path else "command line", conv=conv,
                         lever_arm=cfg.gnss.lever_arm,
                         base_dir=config_path.parent if config_path is not None else None)
    if position is not None:
        opts = replace(opts, position=parse_position(position, "--position"))
    imu_log = read_imu(imu, cfg)
    gnss = read_gnss(gnss_path, cfg) if gnss_path is not None else None
    if gnss is not None:
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..io.gnss_csv import check_gnss_against_imu
        check_gnss_against_imu(gnss, imu_log.t0 if imu_log.t0 is not None else float(imu_log.time[0]),
                               float(imu_log.time[-1]))
    # the readers (pyarrow, rosbags) and the unit checks load when the command runs: --help stays light
    from ..io.readers import _is_log
    from ..nav.earth import gravity
    from ..nav.sanity import accel_unit_check, gyro_unit_check
    t_first = imu_log.t0 if imu_log.t0 is not None else float(imu_log.time[0])
    accel_unit_check(imu_log, t_first, cfg.imu, force, ros=_is_log(imu))     # g read as m/s^2 (nav/sanity.py)
    lat = opts.position[0] if opts.position is not None else (
        float(np.radians(gnss.lat[0])) if gnss is not None and len(gnss) else None)
    if lat is not None:                       # gyros in deg/s read as rad/s (nav/sanity.py)
        spec = opts.sensor
        sensor = {"gyro": {"bias_sigma": spec.gyro_bias}} if spec is not None and spec.gyro_bias else None
        gyro_unit_check(imu_log, t_first, gravity(np.sin(lat), 0.0), lat, cfg.imu, sensor, force,
                        ros=_is_log(imu))
    res = align(imu_log, opts, gnss)          # well under a second for minutes of data: no progress bar
    for note in res.notes:
        click.echo(f"sins: note: {note}", err=True)
    # every output is written after the alignment succeeded, each atomically
    write_init_yaml(output, res.state, conv, res.yaml_extra(conv_name))
    eul = None
    if series is not None or plot is not None:
        eul = np.degrees(dcm_to_euler_many(np.ascontiguousarray(res.series.cbn), conv))
    if series is not None:
        _write_series(series, res, eul, conv)
    if plot is not None:
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..report.align_figures import plot_series
        final = np.degrees(dcm_to_euler_many(res.state.Cbn[None], conv)[0])
        plot_series(plot, res.series.time - res.t0, eul,
                    title=f"Alignment of {Path(imu).name} (--method {res.method}), heading from {res.heading_source}",
                    sigma_deg=np.degrees(res.sigma), final_deg=final, heading_supplied=res.heading_source == "user")
    commit_outputs()                          # every output in place before the line that names them
    r, p, h = np.degrees(dcm_to_euler_many(res.state.Cbn[None], conv)[0])
    s = np.degrees(res.sigma)
    hs = f"{s[2]:.3g}" if np.isfinite(s[2]) else "unknown"
    if not quiet:
        click.echo(f"aligned ({res.method}, {res.duration:.4g} s, heading from {res.heading_source}): roll {r:.4f}, "
                   f"pitch {p:.4f}, heading {h:.4f} deg; 1-sigma {s[0]:.3g}, {s[1]:.3g}, {hs} deg -> {output}",
                   err=True)
    log.info("wrote %s", output)


def _write_series(path, res, eul, conv):
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..io.csvcore import write_table_csv
    data = {"time": res.series.time, "roll": eul[:, 0], "pitch": eul[:, 1], "heading": eul[:, 2]}
    if res.series.cbn0 is not None:
        e0 = np.degrees(dcm_to_euler_many(np.ascontiguousarray(res.series.cbn0), conv))
        data.update({"roll_start": e0[:, 0], "pitch_start": e0[:, 1], "heading_start": e0[:, 2]})
    with atomic_path(path, suffix=".csv") as tmp:
        write_table_csv(tmp, data)


def _monte_carlo(scenario, runs, seed, outdir, quiet, jobs, scheduler, resume, figures):
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..batch.mc_study import run_mc_study

    def on_error(msg):
        click.echo(f"\nsins: error: {msg}", err=True)

    with interrupted_exit(), progress(runs, "monte carlo", quiet) as bar:
        study = run_mc_study(scenario, outdir, runs, seed, jobs=jobs, scheduler=scheduler, resume=resume,
                             figures=figures, on_progress=bar.update, on_error=on_error, on_info=info_echo(quiet),
                             verbose=log.getEffectiveLevel() <= logging.INFO)
    mc = study.mc
    commit_outputs()
    if not quiet:
        resumed = f" ({study.resumed} resumed from {outdir}/jobs, {study.ran} run)" if study.resumed else ""
        failed = f", {len(study.failed)} failed" if study.failed else ""
        click.echo(f"monte carlo {mc.scenario}: {mc.runs} runs{resumed}{failed} -> {outdir} "
                   f"({', '.join(study.files)})", err=True)
    for r in mc.summary_rows():
        if r["attitude"] == "current" and r["theory_deg"] is not None:
            log.info("%s %s: std %.3g deg, theory %.3g deg", r["variant"], r["angle"], r["std_deg"], r["theory_deg"])
    if study.failed:
        sys.exit(1)
