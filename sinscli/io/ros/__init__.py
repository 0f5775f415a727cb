"""ROS 1 bags, ROS 2 bags (.db3 / .mcap directories) and MCAP files: read IMU and GNSS, summarize, write.

One module per concern:

- :mod:`.containers`: the log back ends (rosbags, mcap, direct SQLite for ``.db3``), :func:`open_log`,
  :func:`is_log`, topic listing and choice;
- :mod:`.decode`: messages -> numpy (bulk ``sensor_msgs/Imu`` decoding, deserialized messages, time stamps);
- :mod:`.imu`: ``sensor_msgs/Imu`` -> :class:`~sinscli.types.ImuLog` with its time and gap rules;
- :mod:`.gnss`: ``sensor_msgs/NavSatFix`` (+ velocity topic) -> :class:`~sinscli.types.GnssLog`;
- :mod:`.odometry`: ``nav_msgs/Odometry`` (body velocity) -> :class:`~sinscli.types.BodyVelLog`;
- :mod:`.summary`: :func:`log_summary` (``sins info``);
- :mod:`.write`: :func:`write_log` (arrays -> a ROS log, for tests, benchmarks and simulated data).
"""
from .containers import choose_topic, is_log, log_topics, open_log
from .decode import BODY_VEL_TYPES, IMU_TYPE, NAVSAT_TYPE, ODOMETRY_TYPE, TIME_SOURCES, VEL_TYPES, ImuBlock
from .gnss import read_gnss
from .imu import read_imu, read_imu_block
from .summary import log_summary
from .write import write_log

__all__ = ["BODY_VEL_TYPES", "IMU_TYPE", "NAVSAT_TYPE", "ODOMETRY_TYPE", "TIME_SOURCES", "VEL_TYPES", "ImuBlock", "choose_topic", "is_log",
           "log_summary", "log_topics", "open_log", "read_gnss", "read_imu", "read_imu_block", "write_log"]
