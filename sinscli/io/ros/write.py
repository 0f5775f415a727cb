"""Arrays -> ROS logs (ROS 1 bag, MCAP, rosbag2 .db3 or bag directory), serialized by the libraries.

Used by tests and benchmarks, and by anyone who wants simulated data as a bag.
"""
from __future__ import annotations

import heapq
import shutil
import tempfile
from pathlib import Path

import numpy as np


def _typestore(ros1: bool):
    from rosbags.typesys import Stores, get_typestore  # rosbags only when a log is written
    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _ns(t) -> np.ndarray:
    """Seconds (float64) -> integer nanoseconds, rounded."""
    return np.round(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


def _header(ts, ros1: bool, t_ns: int, frame_id: str, seq: int):
    time_cls = ts.types["builtin_interfaces/msg/Time"]
    stamp = time_cls(sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000))
    hdr = ts.types["std_msgs/msg/Header"]
    if ros1:
        return hdr(seq=seq, stamp=stamp, frame_id=frame_id)
    return hdr(stamp=stamp, frame_id=frame_id)


def _imu_messages(ts, ros1, imu, frame_id):
    """sensor_msgs/Imu objects from ``time`` (s), ``gyro`` (rad/s), ``accel`` (m/s^2), optional ``orientation`` xyzw."""
    t_ns = _ns(imu["time"])
    gyro = np.asarray(imu["gyro"], dtype=np.float64)
    accel = np.asarray(imu["accel"], dtype=np.float64)
    ori = np.asarray(imu.get("orientation", np.tile([0.0, 0.0, 0.0, 1.0], (len(t_ns), 1))), dtype=np.float64)
    cov = np.asarray(imu.get("covariance", np.zeros(9)), dtype=np.float64)
    cls = ts.types["sensor_msgs/msg/Imu"]
    q_cls, v_cls = ts.types["geometry_msgs/msg/Quaternion"], ts.types["geometry_msgs/msg/Vector3"]
    for k in range(len(t_ns)):
        g, a, o = gyro[k], accel[k], ori[k]
        yield cls(header=_header(ts, ros1, int(t_ns[k]), frame_id, k),
                  orientation=q_cls(x=float(o[0]), y=float(o[1]), z=float(o[2]), w=float(o[3])),
                  orientation_covariance=cov,
                  angular_velocity=v_cls(x=float(g[0]), y=float(g[1]), z=float(g[2])),
                  angular_velocity_covariance=cov,
                  linear_acceleration=v_cls(x=float(a[0]), y=float(a[1]), z=float(a[2])),
                  linear_acceleration_covariance=cov)


def _navsat_messages(ts, ros1, gnss, frame_id="gps"):
    """NavSatFix objects from ``time, lat, lon, height``, optional ``status``, ``cov`` (N,9), ``cov_type``."""
    t_ns = _ns(gnss["time"])
    n = len(t_ns)
    status = np.asarray(gnss.get("status", np.zeros(n)), dtype=np.int64)
    cov = np.asarray(gnss.get("cov", np.zeros((n, 9))), dtype=np.float64).reshape(n, 9)
    ctype = np.asarray(gnss.get("cov_type", np.where(cov.any(axis=1), 2, 0)), dtype=np.int64)
    cls, st_cls = ts.types["sensor_msgs/msg/NavSatFix"], ts.types["sensor_msgs/msg/NavSatStatus"]
    for k in range(n):
        yield cls(header=_header(ts, ros1, int(t_ns[k]), frame_id, k),
                  status=st_cls(status=int(status[k]), service=1),
                  latitude=float(gnss["lat"][k]), longitude=float(gnss["lon"][k]), altitude=float(gnss["height"][k]),
                  position_covariance=cov[k].copy(), position_covariance_type=int(ctype[k]))


def _twist_messages(ts, ros1, vel, frame_id="gps"):
    """geometry_msgs/TwistWithCovarianceStamped objects from ``time``, ``vel`` (N,3 ENU) and optional ``std`` (N,3).
    A NaN vertical velocity (horizontal only) is written as 0 with the vertical variance -1 (ROS: unknown)."""
    t_ns = _ns(vel["time"])
    v = np.asarray(vel["vel"], dtype=np.float64)
    std = vel.get("std")
    cls = ts.types["geometry_msgs/msg/TwistWithCovarianceStamped"]
    twc, tw = ts.types["geometry_msgs/msg/TwistWithCovariance"], ts.types["geometry_msgs/msg/Twist"]
    v_cls = ts.types["geometry_msgs/msg/Vector3"]
    for k in range(len(t_ns)):
        cov = np.zeros(36)
        if std is not None:
            cov[[0, 7, 14]] = np.asarray(std[k], dtype=np.float64) ** 2
        up = float(v[k, 2])
        if np.isnan(up):
            up, cov[14] = 0.0, -1.0
        yield cls(header=_header(ts, ros1, int(t_ns[k]), frame_id, k),
                  twist=twc(twist=tw(linear=v_cls(x=float(v[k, 0]), y=float(v[k, 1]), z=up),
                                     angular=v_cls(x=0.0, y=0.0, z=0.0)), covariance=cov))


def _odometry_messages(ts, ros1, odom):
    """nav_msgs/Odometry objects from ``time``, ``vel`` (N,3, in the child frame), optional ``std`` (N,3),
    ``frame_id`` (default odom), ``child_frame_id`` (default base_link), ``orientation`` (N,4 xyzw)."""
    t_ns = _ns(odom["time"])
    n = len(t_ns)
    v = np.asarray(odom["vel"], dtype=np.float64)
    std = odom.get("std")
    ori = np.asarray(odom.get("orientation", np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))), dtype=np.float64)
    t = ts.types
    vec = t["geometry_msgs/msg/Vector3"]
    for k in range(n):
        cov = np.zeros(36)
        if std is not None:
            cov[[0, 7, 14]] = np.asarray(std[k], dtype=np.float64) ** 2
        yield t["nav_msgs/msg/Odometry"](
            header=_header(ts, ros1, int(t_ns[k]), odom.get("frame_id", "odom"), k),
            child_frame_id=odom.get("child_frame_id", "base_link"),
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                    orientation=t["geometry_msgs/msg/Quaternion"](x=float(ori[k, 0]), y=float(ori[k, 1]),
                                                                  z=float(ori[k, 2]), w=float(ori[k, 3]))),
                covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=vec(x=float(v[k, 0]), y=float(v[k, 1]), z=float(v[k, 2])),
                                                   angular=vec(x=0.0, y=0.0, z=0.0)),
                covariance=cov))


def write_log(path, imu=None, gnss=None, vel=None, odom=None, *, imu_topic="/imu/data", gnss_topic="/fix",
              vel_topic="/fix_velocity", odom_topic="/odom", frame_id="imu_link", mcap_encoding="cdr",
              storage="sqlite3", log_delay=0.0, bag_compression=None) -> None:
    """Write IMU (and GNSS, GNSS velocity, odometry) arrays as a ROS log, serialized by the libraries.

    ``path`` suffix: ``.bag`` (ROS 1, rosbags), ``.mcap`` (``mcap`` writer,
    ``mcap_encoding`` "cdr" or "ros1"), ``.db3`` (a bare rosbag2 sqlite3 file)
    or no suffix (a ROS 2 bag directory with ``storage`` "sqlite3" or "mcap").
    Log times are each dict's ``log_time`` (default: its ``time``, the header
    stamps) plus ``log_delay`` seconds.  Used by tests and
    benchmarks, and by anyone who wants simulated data as a bag.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    ros1 = suffix == ".bag" or (suffix == ".mcap" and mcap_encoding == "ros1")
    ts = _typestore(ros1)
    streams = []
    if imu is not None:
        streams.append((imu_topic, "sensor_msgs/msg/Imu",
                        _ns(np.asarray(imu.get("log_time", imu["time"])) + log_delay),
                        _imu_messages(ts, ros1, imu, frame_id)))
    if gnss is not None:
        streams.append((gnss_topic, "sensor_msgs/msg/NavSatFix",
                        _ns(np.asarray(gnss.get("log_time", gnss["time"])) + log_delay),
                        _navsat_messages(ts, ros1, gnss)))
    if vel is not None:
        streams.append((vel_topic, "geometry_msgs/msg/TwistWithCovarianceStamped",
                        _ns(np.asarray(vel.get("log_time", vel["time"])) + log_delay),
                        _twist_messages(ts, ros1, vel, vel.get("frame_id", "gps"))))
    if odom is not None:
        streams.append((odom_topic, "nav_msgs/msg/Odometry",
                        _ns(np.asarray(odom.get("log_time", odom["time"])) + log_delay),
                        _odometry_messages(ts, ros1, odom)))
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr

    def one(i, typ, times, msgs):
        for t, m in zip(times, msgs):
            yield int(t), i, serialize(m, typ)

    def merged():
        """(log ns, stream index, serialized bytes) in log-time order."""
        iters = [one(i, typ, times, msgs) for i, (_top, typ, times, msgs) in enumerate(streams)]
        return heapq.merge(*iters, key=lambda x: (x[0], x[1]))

    if suffix == ".bag":
        from rosbags.rosbag1 import Writer as Writer1  # rosbags only for a bag
        path.unlink(missing_ok=True)
        w = Writer1(path)
        if bag_compression:
            w.set_compression(getattr(Writer1.CompressionFormat, bag_compression.upper()))
        with w:
            conns = [w.add_connection(top, typ, typestore=ts) for top, typ, _t, _m in streams]
            for t, i, raw in merged():
                w.write(conns[i], t, raw)
    elif suffix == ".mcap":
        from mcap.writer import Writer as McapWriter  # mcap only for an MCAP log
        with open(path, "wb") as f:
            w = McapWriter(f)
            w.start(profile="ros1" if ros1 else "ros2", library="sinscli")
            chans = []
            for top, typ, _t, _m in streams:
                text, _ = ts.generate_msgdef(typ, ros_version=1 if ros1 else 2)
                name = typ.replace("/msg/", "/") if ros1 else typ
                sid = w.register_schema(name=name, encoding="ros1msg" if ros1 else "ros2msg", data=text.encode())
                chans.append(w.register_channel(topic=top, message_encoding="ros1" if ros1 else "cdr",
                                                schema_id=sid))
            seqs = [0] * len(streams)
            for t, i, raw in merged():
                w.add_message(channel_id=chans[i], log_time=t, data=bytes(raw), publish_time=t, sequence=seqs[i])
                seqs[i] += 1
            w.finish()
    else:
        from rosbags.rosbag2 import StoragePlugin  # rosbags only for a db3 log
        from rosbags.rosbag2 import Writer as Writer2  # rosbags only for a db3 log
        bare = suffix == ".db3"
        target = Path(tempfile.mkdtemp(dir=path.parent)) / "bag" if bare else path
        if not bare and target.exists():
            shutil.rmtree(target)
        plugin = StoragePlugin.SQLITE3 if (bare or storage == "sqlite3") else StoragePlugin.MCAP
        with Writer2(target, version=9, storage_plugin=plugin) as w:
            conns = [w.add_connection(top, typ, typestore=ts) for top, typ, _t, _m in streams]
            for t, i, raw in merged():
                w.write(conns[i], t, raw)
        if bare:
            path.unlink(missing_ok=True)
            shutil.move(str(target / "bag.db3"), str(path))
            shutil.rmtree(target.parent)
