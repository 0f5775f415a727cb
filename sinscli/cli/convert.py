"""``sins convert LOG -o DIR``: a ROS bag / MCAP log to ``imu.csv`` (increments), ``gnss.csv`` and ``odom.csv``; a
UBX log to RINEX (``obs.rnx``, ``nav.rnx``); ``sins convert FILE.nmea -o gnss.csv`` and ``sins convert LOG.ubx
--solution -o gnss.csv``: a receiver's fixes to the GNSS CSV."""
from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from ..errors import SinsError
from ..io.atomic import commit_outputs, prepare_output, staged_dir
from ..io.body_vel_csv import write_body_velocity_csv
from ..io.gnss_csv import write_gnss_csv
from ..io.imu_csv import write_imu_csv
from ..io import ros
from .base import log, main, progress, quiet_option


@main.command("convert")
@click.argument("log_path", metavar="LOG", type=click.Path(path_type=Path))
@click.option("-o", "--output", "outdir", required=True, type=click.Path(path_type=Path),
              help="Output directory (created): imu.csv, gnss.csv and odom.csv (a UBX log: obs.rnx, nav.rnx); for "
                   "an NMEA log or a UBX log with --solution the GNSS CSV file to write.")
@click.option("--solution", is_flag=True,
              help="UBX log: its receiver's own solutions (NAV-PVT, with NAV-HPPOSLLH) to the GNSS CSV -o FILE, "
                   "not its raw observations to RINEX.")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="NMEA / UBX solutions: the navigation config whose imu.time_system (utc | gps) the times are "
                   "written in, and gnss.date (the UTC date of an NMEA log without RMC).")
@click.option("--imu-topic", default=None, help="sensor_msgs/Imu topic (default: the only one).")
@click.option("--gnss-topic", default=None, help="sensor_msgs/NavSatFix topic (default: the only one).")
@click.option("--vel-topic", default=None,
              help="GNSS velocity topic (TwistStamped or TwistWithCovarianceStamped), ENU.")
@click.option("--odom-topic", default=None,
              help="Odometry (body velocity) topic: nav_msgs/Odometry (default: the only one) or a body-frame "
                   "Twist topic, written to odom.csv in the axes of its frame.")
@click.option("--time", "time_source", type=click.Choice(list(ros.TIME_SOURCES)), default="header",
              show_default=True, help="Sample times from the message header stamps or the log (receive) times.")
@click.option("--start", type=float, default=None, help="Keep IMU samples from this time (s).")
@click.option("--end", type=float, default=None, help="Keep IMU samples up to this time (s).")
@click.option("--allow-gaps", is_flag=True,
              help="Bridge IMU gaps longer than 5 sample intervals with one increment each (as sins navigate "
                   "--allow-gaps; without it such a gap is refused, naming it).")
@quiet_option
def convert_cmd(log_path, outdir, solution, config_path, imu_topic, gnss_topic, vel_topic, odom_topic, time_source, start,
                end, allow_gaps, quiet):
    """Convert a ROS 1 bag, ROS 2 bag (directory or .db3) or MCAP LOG into docs/formats.md CSV files:
    DIR/imu.csv (increments, axes as in the messages), DIR/gnss.csv (when the log has a NavSatFix
    topic) and DIR/odom.csv (body velocity, when it has one nav_msgs/Odometry topic or --odom-topic;
    docs/io_formats.md).  Everything is read and checked before anything is written.

    An NMEA log (GGA, RMC, VTG, GST, GSA) or, with --solution, a UBX log's NAV-PVT solutions go to the GNSS
    CSV of docs/formats.md at -o FILE (times in the config's imu.time_system).

    \b
    Examples:
      sins convert husky_imu_gps.bag -o husky/ --time header
      sins convert drive.nmea -o gnss.csv
      sins convert f9p.ubx --solution -o gnss.csv
    """
    from ..io.raw_summary import convert_ubx, raw_kind   # loaded when the command runs: --help stays light
    kind = raw_kind(log_path)
    if kind == "nmea" or (kind == "ubx" and solution):  # a receiver's fixes -> gnss.csv
        _convert_receiver(log_path, outdir, config_path, quiet)
        return
    if solution:
        raise SinsError(f"{log_path}: --solution is for a u-blox UBX log (its NAV-PVT solutions); this is not one")
    if config_path is not None:
        raise SinsError("--config is for an NMEA log or a UBX log with --solution (imu.time_system, gnss.date)")
    prepare_output(outdir, directory=True)
    if kind == "ubx":                 # u-blox log -> RINEX 3.04 obs/nav (docs/raw_gnss.md)
        paths, obs, nav = convert_ubx(log_path, outdir)
        click.echo(f"wrote {', '.join(str(p) for p in paths)}: {len(obs)} epochs, {len(nav)} ephemerides from "
                   f"{log_path} (RINEX 3.04, read back and checked)", err=True)
        return
    topics = ros.log_topics(log_path)
    types = set(topics.values())
    want_imu = imu_topic is not None or ros.IMU_TYPE in types
    want_gnss = gnss_topic is not None or vel_topic is not None or ros.NAVSAT_TYPE in types
    want_odom = odom_topic is not None or list(topics.values()).count(ros.ODOMETRY_TYPE) == 1
    listing = ", ".join(f"{n} ({t})" for n, t in sorted(topics.items())) or "none"
    if not (want_imu or want_gnss):
        raise SinsError(f"{log_path}: no sensor_msgs/Imu or sensor_msgs/NavSatFix topic; topics: {listing}")
    if not want_imu:
        only = "gnss.csv and odom.csv" if want_odom else "gnss.csv"
        log.warning("%s: no sensor_msgs/Imu topic (topics: %s): writing %s only", log_path, listing, only)
    steps = int(want_imu) + int(want_gnss) + int(want_odom)
    imu = gnss = odom = None
    with progress(steps * 2, "convert", quiet) as bar:
        if want_imu:
            imu = ros.read_imu(log_path, topic=imu_topic, time_source=time_source, start=start, end=end,
                               allow_gaps=allow_gaps)
            bar.update(1)
        if want_gnss:
            gnss = ros.read_gnss(log_path, topic=gnss_topic, vel_topic=vel_topic, time_source=time_source)
            bar.update(1)
        if want_odom:
            # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
            from ..io.ros.odometry import read_twist_topic
            from ..types import BodyVelLog
            where, t, v, cov, frame, imu_frame = read_twist_topic(log_path, odom_topic, time_source, imu_topic)
            std = None if cov is None else np.sqrt(np.einsum("nii->ni", cov))
            odom = BodyVelLog(time=t, vel_b=v, std=std, source=where)
            bar.update(1)
        with staged_dir(outdir) as tmp:          # every file, or none
            if imu is not None:
                write_imu_csv(tmp / "imu.csv", imu)
                bar.update(1)
            if gnss is not None:
                write_gnss_csv(tmp / "gnss.csv", gnss)
                bar.update(1)
            if odom is not None:
                write_body_velocity_csv(tmp / "odom.csv", odom)
                bar.update(1)
    commit_outputs()
    if quiet:
        return
    if imu is not None:
        log.info("%s: %d IMU increments from %s (first interval starts at %.9f s)",
                 outdir / "imu.csv", len(imu), imu.source, imu.t0)
        click.echo(f"wrote {outdir / 'imu.csv'}: {len(imu)} increments from {imu.source}; the first interval "
                   f"starts at t0 = {imu.t0!r} s (use it as the initial state's time)", err=True)
    if gnss is not None:
        click.echo(f"wrote {outdir / 'gnss.csv'}: {len(gnss)} fixes from {gnss.source}", err=True)
    if odom is not None:
        axes = ("the IMU's sensor axes (read it with odometry.frame: sensor)" if imu_frame is not None and frame.lstrip("/") == imu_frame.lstrip("/") else
                f"the axes of frame '{frame}' (a vehicle frame, x forward, y left, z up: odometry.frame: vehicle)")
        click.echo(f"wrote {outdir / 'odom.csv'}: {len(odom.time)} body velocities from {odom.source}, in {axes}",
                   err=True)


def _convert_receiver(log_path, output, config_path, quiet) -> None:
    """An NMEA log or a UBX log's NAV-PVT solutions to the GNSS CSV ``output``."""
    from ..config import load_config              # loaded when the command runs: --help stays light
    from ..io.receiver import read_receiver_log   # loaded when the command runs: --help stays light
    prepare_output(output)
    cfg = load_config(config_path)
    gnss = read_receiver_log(log_path, cfg.imu.time_system, cfg.gnss.date, cfg.limits)
    write_gnss_csv(output, gnss)
    commit_outputs()
    if not quiet:
        vel = ("no velocity" if gnss.vel_n is None else
               "horizontal velocity (vel_e, vel_n)" if np.isnan(gnss.vel_n[:, 2]).all() else "ENU velocity")
        click.echo(f"wrote {output}: {len(gnss)} fixes from {log_path} with {vel}; times in "
                   f"{cfg.imu.time_system.upper()} (imu.time_system)", err=True)
