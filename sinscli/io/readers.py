"""Pick the reader for an IMU, GNSS or body-velocity log: CSV here, ROS bags and MCAP in :mod:`sinscli.io.ros`."""
from __future__ import annotations

from pathlib import Path

from ..config import Config, mounting_matrix
from ..errors import SinsError
from ..nav.rotation import BODY_CONVENTIONS
from ..types import BodyVelLog, GnssLog, ImuLog
from .body_vel_csv import read_body_velocity_csv
from .gnss_csv import read_gnss_csv
from .imu_csv import apply_mounting, concat_imu, iter_imu_csv
from .receiver import is_receiver_log, read_receiver_log


def _is_log(path) -> bool:
    try:
        from .ros import is_log  # the ROS back ends (rosbags, mcap) only for a bag or MCAP log
    except ImportError:
        return False
    return is_log(path)


def iter_imu(path, cfg: Config, allow_gaps: bool = False):
    """IMU blocks from a CSV file (the ``imu`` section) or a ROS/MCAP log (the ``ros`` section);
    ``imu.time_offset`` (s) is added to their times (the output is then on the GNSS clock)."""
    offset = cfg.imu.time_offset
    for block in _iter_imu(Path(path), cfg, allow_gaps):
        if offset:
            block.time = block.time + offset
            if block.t0 is not None:
                block.t0 = block.t0 + offset
        yield block


def _iter_imu(path: Path, cfg: Config, allow_gaps: bool):
    if not path.exists():
        raise SinsError(f"{path}: file not found")
    if _is_log(path):
        from .ros import read_imu as read_ros_imu  # the ROS back ends (rosbags, mcap) only for a bag or MCAP log
        ros = cfg.ros
        imu = read_ros_imu(path, topic=ros.imu_topic, time_source=ros.time, allow_gaps=allow_gaps,
                           limits=cfg.limits)
        yield apply_mounting(imu, mounting_matrix(cfg.imu.mounting))
        return
    yield from iter_imu_csv(path, cfg.imu, allow_gaps, limits=cfg.limits)


def read_imu(path, cfg: Config, allow_gaps: bool = False) -> ImuLog:
    """A whole IMU log in memory (for alignment and tests)."""
    return concat_imu(iter_imu(path, cfg, allow_gaps))


def read_gnss(path, cfg: Config) -> GnssLog:
    """A GNSS log from a CSV file, a ROS/MCAP log, or a receiver's log (u-blox UBX NAV-PVT, NMEA 0183; its times
    in the IMU's ``imu.time_system``); ``gnss.time_offset`` (s) is added to its times."""
    path = Path(path)
    if not path.exists():
        raise SinsError(f"{path}: file not found")
    if _is_log(path):
        from .ros import read_gnss as read_ros_gnss  # the ROS back ends (rosbags, mcap) only for a bag or MCAP log
        ros = cfg.ros
        gnss = read_ros_gnss(path, topic=ros.gnss_topic, vel_topic=ros.vel_topic, time_source=ros.time,
                             limits=cfg.limits)
    elif is_receiver_log(path):
        gnss = read_receiver_log(path, cfg.imu.time_system, cfg.gnss.date, cfg.limits)
    else:
        gnss = read_gnss_csv(path, cfg.gnss, limits=cfg.limits)
    offset = cfg.gnss.time_offset
    if offset:
        gnss.time = gnss.time + offset
    return gnss


def read_body_velocity(path, cfg: Config) -> BodyVelLog:
    """Body velocity (odometry) from a body-velocity CSV or a ROS/MCAP log's Odometry topic.

    ``cfg`` is the validated config: ``odometry`` (CSV columns, frame), ``imu`` (body convention,
    mounting) and ``ros`` (``odom_topic``, ``imu_topic``, ``time``) sections.  The result is in the body
    axes of the convention in force (``imu.body``), after the mounting where the velocity is given in the
    IMU's sensor axes (docs/io_formats.md).
    """
    path = Path(path)
    if not path.exists():
        raise SinsError(f"{path}: file not found")
    if _is_log(path):
        # the ROS back ends (rosbags, mcap) only for a bag or MCAP log
        from .ros.odometry import read_body_velocity as read_ros_body_velocity
        ros = cfg.ros
        return read_ros_body_velocity(path, topic=ros.odom_topic, time_source=ros.time,
                                      mounting=mounting_matrix(cfg.imu.mounting),
                                      conv=BODY_CONVENTIONS[cfg.imu.body], frame=cfg.odometry.frame,
                                      imu_topic=ros.imu_topic, limits=cfg.limits)
    return read_body_velocity_csv(path, cfg.odometry, cfg.imu, cfg.limits)
