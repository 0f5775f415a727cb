"""``sins navigate``: IMU log + initial state -> trajectory file."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import click

from .. import conventions as cv
from ..conventions import BODY_CONVENTIONS
from ..errors import SinsError
from .base import finish_progress, log, main, progress, quiet_option, summary_line

# the readers, the kernels (numpy, numba) and the writers are imported when the command runs, so
# that `sins navigate --help` does not load them


def _extra_columns(opts):
    """Extra trajectory columns the options add (``--angles``, ``--frame launch-inertial``)."""
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..nav.inertial import COLUMNS as INERTIAL_COLUMNS
    cols = ("k_phi", "k_psi", "k_gamma", "k_xi", "k_set") if opts.angles else ()
    return cols + (INERTIAL_COLUMNS if opts.frame == "launch-inertial" else ())


def _count_rows(path: Path) -> int:
    """Rough row count for the progress bar (file size / first line length)."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            fh.readline()
            line = fh.readline()
        return max(1, size // max(len(line), 1))
    except OSError:
        return 1


@main.command("navigate")
@click.argument("imu", type=click.Path(path_type=Path))
@click.option("--init", "init_path", default=None, type=click.Path(path_type=Path),
              help="Initial state: init YAML or trajectory CSV/Parquet (the row at the IMU start).")
@click.option("--gnss", "gnss_path", default=None, type=click.Path(path_type=Path),
              help="GNSS log (CSV or ROS bag/MCAP): fused navigation with the error-state Kalman filter.")
@click.option("--gnss-raw", "raw_path", default=None, type=click.Path(path_type=Path),
              help="Raw GNSS observations (RINEX 2.11/3.x, or a u-blox UBX log) with --nav: tightly coupled fusion, "
                   "every satellite's pseudorange and Doppler in the filter (docs/raw_gnss.md).")
@click.option("--nav", "nav_paths", multiple=True, type=click.Path(path_type=Path),
              help="With --gnss-raw: RINEX navigation file(s) (repeat for several); optional for a UBX log.")
@click.option("--tdcp", is_flag=True,
              help="With --gnss-raw: also the carrier phase, differenced between consecutive epochs (TDCP), with "
                   "cycle-slip tests against the INS (fusion.raw.tdcp; docs/raw_gnss.md).")
@click.option("--align", "align_method", default=None,
              type=click.Choice(cv.ALIGN_METHODS),
              help="With --gnss: initial state from `sins align --method METHOD` on the log's first window.")
@click.option("--smooth", is_flag=True, help="With --gnss: Rauch-Tung-Striebel smoothed trajectory.")
@click.option("--innovations", "innovations_path", default=None, type=click.Path(path_type=Path),
              help="With --gnss: CSV of every measurement's innovation, sigma, NIS and acceptance.")
@click.option("--odom", "odom_path", default=None, type=click.Path(path_type=Path),
              help="With --gnss: body velocity (odometry): a body-velocity CSV, or a bag/MCAP with an Odometry "
                   "topic (ros.odom_topic, else auto-detected).")
@click.option("--vehicle", default=None, type=click.Choice(cv.VEHICLES),
              help="With --gnss: the platform, for its constraints: car and robot NHC + ZUPT/ZARU at rest, pedestrian "
                   "ZUPT/ZARU at rest and heading from motion, aircraft and none (default) no constraint "
                   "(config fusion.vehicle).")
@click.option("--sensor", default=None,
              help="With --gnss: sensor description (preset mems|tactical|navigation or a sensor YAML).")
@click.option("--attitude", type=click.Choice(cv.ATTITUDES), default=None,
              help="Attitude algorithm (default from config: quat).")
@click.option("--dcm-variant", type=click.Choice(cv.DCM_VARIANTS), default=None,
              help="dcm: exact closed form (Savage eq 26) or the series recursion of seed 000 eqs 12-14.")
@click.option("--coning", type=click.IntRange(1, 4), default=None,
              help="Coning/sculling order: 1 (none, fixed axis), 2, 3 or 4 samples.")
@click.option("--subsamples", type=click.IntRange(1), default=None,
              help="Fast IMU samples per attitude update (1 = one-speed).")
@click.option("--every", type=click.IntRange(1), default=None, help="Write every K-th attitude update.")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="Navigation config YAML (see configs/navigation.yaml).")
@click.option("--body", type=click.Choice(sorted(cv.BODY_NAMES)), default=None,
              help="Body axes convention of the IMU after mounting.")
@click.option("--allow-gaps", is_flag=True, default=None, help="Bridge gaps > 5 intervals with a warning.")
@click.option("--static-start", is_flag=True, default=None,
              help="The log starts at rest: check the specific force against gravity.")
@click.option("--angles", is_flag=True, help="Add the raw angles (krylov/euler) to the output.")
@click.option("--euler-integrator", type=click.Choice(cv.EULER_INTEGRATORS), default=None,
              help="3-angle baseline integrator: forward Euler (the patent's) or RK4.")
@click.option("--singularity-threshold", type=float, default=None,
              help="|cos psi| under which the 3-angle method reports its singularity (default 0.01).")
@click.option("--on-singularity", type=click.Choice(cv.ON_SINGULARITY), default=None,
              help="3-angle method at its singularity: carry on (warn) or stop the run there.")
@click.option("--frame", type=click.Choice(cv.NAV_FRAMES), default=None,
              help="Navigation frame: local ENU, or the launch-centred inertial frame (WGS-84 J2 "
                   "gravitation; launch point from navigation.launch or the init YAML's launch:).")
@click.option("--imu-topic", default=None, help="IMU topic in a ROS bag / MCAP log.")
@click.option("--start", default=None, metavar="T",
              help="Window start: time in the IMU log's clock, or +S seconds after its first epoch. The init must "
                   "be at or before it (a trajectory file as --init gives its row at T); rows from T are written.")
@click.option("--end", default=None, metavar="T", help="Window end (time, or +S after the log's first epoch).")
@click.option("--duration", type=float, default=None, help="Window length in seconds (instead of --end).")
@click.option("--time-offset", type=float, default=None,
              help="With --gnss: seconds added to every GNSS time (config gnss.time_offset).")
@click.option("-o", "--output", type=click.Path(path_type=Path), default=Path("trajectory.csv"),
              show_default=True, help="Trajectory output: .csv, .parquet, .mcap, .tum, .geojson, .kml.")
@click.option("--force", is_flag=True,
              help="Navigate data that a plausibility check refuses (gyro rates or specific forces impossible in "
                   "their declared unit, a GNSS time offset found by cross-correlation): for the rare real case.")
@quiet_option
def navigate_cmd(imu, init_path, gnss_path, raw_path, nav_paths, tdcp, align_method, smooth, innovations_path, odom_path, vehicle, sensor, attitude, dcm_variant, coning, subsamples, every, config_path, body,
                 allow_gaps, static_start, angles, euler_integrator, singularity_threshold, on_singularity,
                 frame, imu_topic, start, end, duration, time_offset, output, force, quiet):
    """Navigate IMU increments from an initial state and write the trajectory.

    \b
    With --gnss, fused GNSS/INS navigation (closed-loop error-state Kalman filter), e.g.
      sins navigate imu.csv --gnss gnss.csv --init init.yaml --smooth -o fused.csv
      sins navigate log.bag --gnss log.bag --config configs/fusion/husky.yaml --align gnss-inertial -o f.mcap

    \b
    With --gnss-raw, tightly coupled (every satellite's pseudorange and Doppler, down to one satellite), e.g.
      sins navigate imu.csv --gnss-raw obs.rnx --nav nav.rnx --init init.yaml --smooth -o fused.csv
    and with the carrier phase between epochs (TDCP): --gnss-raw obs.rnx --nav nav.rnx --tdcp
    """
    if gnss_path is not None and raw_path is not None:
        raise SinsError("give either --gnss (fixes, loosely coupled) or --gnss-raw (raw observations, tightly "
                        "coupled), not both")
    if nav_paths and raw_path is None:
        raise SinsError("--nav needs --gnss-raw (the raw observations' broadcast ephemerides)")
    if tdcp and raw_path is None:
        raise SinsError("--tdcp needs --gnss-raw OBS (raw observations with carrier phase); "
                        f"{'--gnss gives fixes, which have none' if gnss_path is not None else 'none given'}")
    fused = gnss_path is not None or raw_path is not None
    if not fused:
        for name, value in (("--align", align_method), ("--smooth", smooth or None),
                            ("--innovations", innovations_path), ("--odom", odom_path), ("--sensor", sensor),
                            ("--vehicle", vehicle)):
            if value is not None:
                raise SinsError(f"{name} needs --gnss or --gnss-raw (fused navigation)")
        if init_path is None:
            raise SinsError("give the initial state: --init FILE (or, with --gnss, --align METHOD)")
        if time_offset is not None:
            raise SinsError("--time-offset needs --gnss or --gnss-raw (it shifts the GNSS times)")
    elif (init_path is None) == (align_method is None):
        raise SinsError(f"with {'--gnss' if gnss_path is not None else '--gnss-raw'} give exactly one of --init FILE "
                        f"and --align METHOD")
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from .. import config as config_mod
    from ..io.imu_csv import check_static_start
    from ..io.init_state import read_init
    from ..io.readers import iter_imu
    from ..io.trajectory import TrajectoryWriter, check_trajectory_output, write_trajectory
    from ..nav.earth import gravity
    from ..nav.inertial import launch_frame
    from ..nav.pipeline import NavOptions, concat, navigate_blocks
    from ..nav.window import check_in_log, check_init, clip_blocks, make_window, windowed

    check_trajectory_output(output)            # before any work: a directory, no format, no permission
    window = make_window(start, end, duration)
    cfg = config_mod.load_config(config_path)           # once per run; the options below replace its keys
    cfg = config_mod.override(cfg, "navigation", attitude=attitude, dcm_variant=dcm_variant, coning=coning,
                              subsamples=subsamples, every=every, allow_gaps=allow_gaps,
                              euler_integrator=euler_integrator, singularity_threshold=singularity_threshold,
                              on_singularity=on_singularity, frame=frame)
    cfg = config_mod.override(cfg, "imu", body=body, static_start=static_start)
    cfg = config_mod.override(cfg, "ros", imu_topic=imu_topic)
    cfg = config_mod.override(cfg, "gnss", time_offset=time_offset)
    nav = cfg.navigation
    conv = BODY_CONVENTIONS[cfg.imu.body]
    opts = NavOptions(attitude=nav.attitude, dcm_variant=nav.dcm_variant, coning=nav.coning,
                      subsamples=nav.subsamples, every=nav.every, conv=conv, frame=nav.frame,
                      angles=angles, euler_integrator=nav.euler_integrator,
                      singularity_threshold=nav.singularity_threshold, on_singularity=nav.on_singularity,
                      launch=None if nav.launch is None else dict(nav.launch),
                      krylov_substep_tol=nav.krylov_substep_tol)
    opts.check()
    if fused:
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from .fusion_run import run_fused
        run_fused(imu, gnss_path, init_path, align_method, smooth, innovations_path, sensor, cfg, config_path,
                  opts, output, quiet, window, odom_path=odom_path, vehicle=vehicle, force=force,
                  raw=(raw_path, nav_paths) if raw_path is not None else None, tdcp=tdcp)
        return
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from .._numba_cache import set_compile_note
    from ..nav.pipeline import first_run_seconds
    seconds = first_run_seconds(opts)
    set_compile_note(f"sins: compiling navigation kernels (first run only, about {seconds} s)", seconds)
    blocks = iter_imu(imu, cfg, allow_gaps=nav.allow_gaps)
    first = next(blocks, None)
    if first is None or len(first) == 0:
        raise SinsError(f"{imu}: no IMU samples")
    t_start = first.t0 if first.t0 is not None else float(first.time[0] - (
        first.time[1] - first.time[0] if len(first) > 1 else 0.0))
    window = window.resolve(t_start)
    check_in_log(window, t_start, None, str(imu))
    init = read_init(init_path, t_start if window.start is None else window.start, conv, cfg.limits, cfg.init)
    check_init(init.time, window, str(init_path))
    if opts.frame == "launch-inertial" and opts.launch is None and "launch" in init.extra:
        launch_frame(init.extra["launch"], init.time, f"{init_path}: launch")   # checked naming the file
        opts = replace(opts, launch=init.extra["launch"])
    if cfg.imu.static_start:
        check_static_start(first, gravity(math.sin(init.lat), init.height), conv)
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..nav.sanity import mounting_warning
    note = mounting_warning(first, max(t_start, init.time), gravity(math.sin(init.lat), init.height), conv, init.Cbn,
                            cfg.imu)
    if note:
        log.warning(note)
    # the readers (pyarrow, rosbags) and the checks load when the command runs: --help stays light
    from ..io.readers import _is_log
    from ..nav.sanity import accel_unit_check, gyro_unit_check
    accel_unit_check(first, max(t_start, init.time), cfg.imu, force, ros=_is_log(imu))
    gyro_unit_check(first, max(t_start, init.time), gravity(math.sin(init.lat), init.height), init.lat, cfg.imu,
                    _sensor_description(cfg, config_path), force, ros=_is_log(imu))

    def all_blocks():
        yield first
        yield from blocks

    total = _count_rows(Path(imu)) if Path(imu).is_file() else len(first)
    streaming = output.suffix.lower() in (".csv", ".parquet")
    written = [0, None, None]                  # rows, first and last time written
    with progress(total, "navigating", quiet or total < 200_000) as bar:
        chunks = navigate_blocks(clip_blocks(all_blocks(), window.end), init, opts, progress=bar.update)
        if window.active:
            chunks = windowed(chunks, window, str(imu))
        if streaming:
            extra = list(_extra_columns(opts))
            with TrajectoryWriter(output, conv, extra_columns=extra) as writer:
                for chunk in chunks:
                    writer.write(chunk)
                    _count(written, chunk)
        else:
            traj = concat(list(chunks))
            write_trajectory(output, traj, conv)
            _count(written, traj)
        finish_progress(bar)
    if quiet:
        return
    summary_line(imu, written[0], written[1] or 0.0, written[2] or 0.0, output)


def _sensor_description(cfg, config_path) -> dict | None:
    """The IMU's error description of the config (``fusion.sensor``), SI units, or None."""
    spec = cfg.fusion.get("sensor") if isinstance(cfg.fusion, dict) else None
    if spec is None:
        return None
    from ..sensors import load_sensor   # PyYAML: only with a sensor description
    base = Path(config_path).parent if config_path else Path.cwd()
    return load_sensor(spec, None, str(config_path or "config"), base, key="fusion.sensor")


def _count(written: list, chunk) -> None:
    """Add a written chunk to ``[rows, first time, last time]`` (the run's summary line)."""
    if len(chunk):
        written[0] += len(chunk)
        written[1] = float(chunk.time[0]) if written[1] is None else written[1]
        written[2] = float(chunk.time[-1])
