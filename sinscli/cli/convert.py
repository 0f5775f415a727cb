"""``sins convert LOG -o DIR``: a ROS bag / MCAP log to ``imu.csv`` (increments) and ``gnss.csv``."""
from __future__ import annotations

from pathlib import Path

import click

from ..errors import SinsError
from ..io.atomic import prepare_output, staged_dir
from ..io.gnss_csv import write_gnss_csv
from ..io.imu_csv import write_imu_csv
from ..io import ros
from .base import log, main, progress, quiet_option


@main.command("convert")
@click.argument("log_path", metavar="LOG", type=click.Path(path_type=Path))
@click.option("-o", "--output", "outdir", required=True, type=click.Path(path_type=Path, file_okay=False),
              help="Output directory (created): imu.csv and gnss.csv.")
@click.option("--imu-topic", default=None, help="sensor_msgs/Imu topic (default: the only one).")
@click.option("--gnss-topic", default=None, help="sensor_msgs/NavSatFix topic (default: the only one).")
@click.option("--vel-topic", default=None,
              help="GNSS velocity topic (TwistStamped, TwistWithCovarianceStamped or Odometry), ENU.")
@click.option("--time", "time_source", type=click.Choice(list(ros.TIME_SOURCES)), default="header",
              show_default=True, help="Sample times from the message header stamps or the log (receive) times.")
@click.option("--start", type=float, default=None, help="Keep IMU samples from this time (s).")
@click.option("--end", type=float, default=None, help="Keep IMU samples up to this time (s).")
@quiet_option
def convert_cmd(log_path, outdir, imu_topic, gnss_topic, vel_topic, time_source, start, end, quiet):
    """Convert a ROS 1 bag, ROS 2 bag (directory or .db3) or MCAP LOG into FORMATS.md CSV files:
    DIR/imu.csv (increments, axes as in the messages) and DIR/gnss.csv (when the log has a NavSatFix
    topic).  Everything is read and checked before anything is written.

    \b
    Example:
      sins convert husky_imu_gps.bag -o husky/ --time header
    """
    prepare_output(outdir, directory=True)
    topics = ros.log_topics(log_path)
    types = set(topics.values())
    want_imu = imu_topic is not None or ros.IMU_TYPE in types
    want_gnss = gnss_topic is not None or vel_topic is not None or ros.NAVSAT_TYPE in types
    listing = ", ".join(f"{n} ({t})" for n, t in sorted(topics.items())) or "none"
    if not (want_imu or want_gnss):
        raise SinsError(f"{log_path}: no sensor_msgs/Imu or sensor_msgs/NavSatFix topic; topics: {listing}")
    if not want_imu:
        log.warning("%s: no sensor_msgs/Imu topic (topics: %s): writing gnss.csv only", log_path, listing)
    steps = int(want_imu) + int(want_gnss)
    imu = gnss = None
    with progress(steps * 2, "convert", quiet) as bar:
        if want_imu:
            imu = ros.read_imu(log_path, topic=imu_topic, time_source=time_source, start=start, end=end)
            bar.update(1)
        if want_gnss:
            gnss = ros.read_gnss(log_path, topic=gnss_topic, vel_topic=vel_topic, time_source=time_source)
            bar.update(1)
        with staged_dir(outdir) as tmp:          # both files, or neither
            if imu is not None:
                write_imu_csv(tmp / "imu.csv", imu)
                bar.update(1)
            if gnss is not None:
                write_gnss_csv(tmp / "gnss.csv", gnss)
                bar.update(1)
    if imu is not None:
        log.info("%s: %d IMU increments from %s (first interval starts at %.9f s)",
                 outdir / "imu.csv", len(imu), imu.source, imu.t0)
        click.echo(f"wrote {outdir / 'imu.csv'}: {len(imu)} increments from {imu.source}; the first interval "
                   f"starts at t0 = {imu.t0!r} s (use it as the initial state's time)", err=True)
    if gnss is not None:
        click.echo(f"wrote {outdir / 'gnss.csv'}: {len(gnss)} fixes from {gnss.source}", err=True)
