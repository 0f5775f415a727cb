"""Trajectory -> MCAP that Foxglove opens, plus ``nav_msgs/Odometry`` for ROS users.

Channels (one message per trajectory row, log time = the row's time):

- ``/sins/fix``: ``foxglove.LocationFix`` (JSON): latitude, longitude (deg), altitude (m) for the Map panel;
- ``/sins/pose``: ``foxglove.PoseInFrame`` (JSON) in frame ``enu``: a local ENU frame whose origin is the
  first point (m), orientation of the FLU body axes (REP-103) for the 3D panel;
- ``/sins/odom``: ``nav_msgs/msg/Odometry`` (CDR, ros2msg schema): the same pose, and the velocity in the
  ``base_link`` (FLU body) frame as ROS wants.

An MCAP metadata record ``sins`` holds the ENU origin and the body convention, so
:func:`read_trajectory_mcap` gives the trajectory back.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..types import Trajectory
from .atomic import atomic_path
from .tum import body_flu_in_enu, cbn_from_flu, local_enu_to_lla, trajectory_enu_quat

TOPIC_FIX, TOPIC_POSE, TOPIC_ODOM = "/sins/fix", "/sins/pose", "/sins/odom"
FRAME_ENU, FRAME_BODY = "enu", "base_link"

_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_XYZ = {k: {"type": "number"} for k in ("x", "y", "z")}
LOCATION_FIX_SCHEMA = {
    "title": "foxglove.LocationFix", "type": "object",
    "properties": {
        "timestamp": _TIME, "frame_id": {"type": "string"},
        "latitude": {"type": "number"}, "longitude": {"type": "number"}, "altitude": {"type": "number"},
        "position_covariance": {"type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9},
        "position_covariance_type": {"title": "foxglove.PositionCovarianceType",
                                     "oneOf": [{"title": t, "const": i} for i, t in
                                               enumerate(["UNKNOWN", "APPROXIMATED", "DIAGONAL_KNOWN", "KNOWN"])]},
    },
}
POSE_IN_FRAME_SCHEMA = {
    "title": "foxglove.PoseInFrame", "type": "object",
    "properties": {
        "timestamp": _TIME, "frame_id": {"type": "string"},
        "pose": {"title": "foxglove.Pose", "type": "object", "properties": {
            "position": {"title": "foxglove.Vector3", "type": "object", "properties": _XYZ},
            "orientation": {"title": "foxglove.Quaternion", "type": "object",
                            "properties": {**_XYZ, "w": {"type": "number"}}}}},
    },
}


def _stamps(traj: Trajectory) -> np.ndarray:
    t = np.asarray(traj.time, dtype=np.float64)
    if not np.isfinite(t).all():
        raise SinsError(f"{traj.source}: trajectory has non-finite times; cannot write MCAP")
    if t.shape[0] and t.min() < 0:
        raise SinsError(f"{traj.source}: MCAP needs times >= 0 s (first negative time {t.min()!r})")
    return np.round(t * 1e9).astype(np.int64)


def write_trajectory_mcap(path, traj: Trajectory, conv: int = 0) -> None:
    """Write the trajectory as MCAP (see module docstring), atomically."""
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    origin, enu, q = trajectory_enu_quat(traj, conv)
    t_ns = _stamps(traj)
    c_flu = body_flu_in_enu(traj.Cbn, conv)
    v_body = np.einsum("nji,nj->ni", c_flu, np.asarray(traj.vel_n, dtype=np.float64))   # C_n^FLU v_n
    lat_deg, lon_deg = np.degrees(traj.lat), np.degrees(traj.lon)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    odom_def, _ = ts.generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)
    types = ts.types
    zeros36 = np.zeros(36)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            w = Writer(f)
            w.start(profile="", library="sinscli")
            s_fix = w.register_schema("foxglove.LocationFix", "jsonschema", json.dumps(LOCATION_FIX_SCHEMA).encode())
            s_pose = w.register_schema("foxglove.PoseInFrame", "jsonschema", json.dumps(POSE_IN_FRAME_SCHEMA).encode())
            s_odom = w.register_schema("nav_msgs/msg/Odometry", "ros2msg", odom_def.encode())
            c_fix = w.register_channel(TOPIC_FIX, "json", s_fix)
            c_pose = w.register_channel(TOPIC_POSE, "json", s_pose)
            c_odom = w.register_channel(TOPIC_ODOM, "cdr", s_odom)
            w.add_metadata("sins", {
                "enu_origin_lat_deg": repr(float(np.degrees(origin[0]))),
                "enu_origin_lon_deg": repr(float(np.degrees(origin[1]))),
                "enu_origin_height_m": repr(origin[2]), "body_axes": "FLU", "source": str(traj.source)})
            for k in range(t_ns.shape[0]):
                tk = int(t_ns[k])
                sec, nsec = tk // 1_000_000_000, tk % 1_000_000_000
                stamp = {"sec": sec, "nsec": nsec}
                fix = {"timestamp": stamp, "frame_id": FRAME_BODY, "latitude": float(lat_deg[k]),
                       "longitude": float(lon_deg[k]), "altitude": float(traj.height[k]),
                       "position_covariance": [0.0] * 9, "position_covariance_type": 0}
                x, y, z = (float(v) for v in enu[k])
                qx, qy, qz, qw = (float(v) for v in q[k])
                pose = {"timestamp": stamp, "frame_id": FRAME_ENU,
                        "pose": {"position": {"x": x, "y": y, "z": z},
                                 "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}}
                w.add_message(c_fix, log_time=tk, publish_time=tk, sequence=k, data=json.dumps(fix).encode())
                w.add_message(c_pose, log_time=tk, publish_time=tk, sequence=k, data=json.dumps(pose).encode())
                vb = v_body[k]
                odom = types["nav_msgs/msg/Odometry"](
                    header=types["std_msgs/msg/Header"](
                        stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=FRAME_ENU),
                    child_frame_id=FRAME_BODY,
                    pose=types["geometry_msgs/msg/PoseWithCovariance"](
                        pose=types["geometry_msgs/msg/Pose"](
                            position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z),
                            orientation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)),
                        covariance=zeros36),
                    twist=types["geometry_msgs/msg/TwistWithCovariance"](
                        twist=types["geometry_msgs/msg/Twist"](
                            linear=types["geometry_msgs/msg/Vector3"](x=float(vb[0]), y=float(vb[1]), z=float(vb[2])),
                            angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
                        covariance=zeros36))
                w.add_message(c_odom, log_time=tk, publish_time=tk, sequence=k,
                              data=bytes(ts.serialize_cdr(odom, "nav_msgs/msg/Odometry")))
            w.finish()


def read_trajectory_mcap(path, conv: int = 0) -> Trajectory:
    """Read back a trajectory written by :func:`write_trajectory_mcap` (position from LocationFix,
    attitude from PoseInFrame, velocity from Odometry), with ``Cbn`` in body convention ``conv``."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    path = Path(path)
    fixes, poses, odoms, meta = [], [], [], {}
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
            for m in reader.iter_metadata():
                if m.name == "sins":
                    meta = dict(m.metadata)
            for _schema, channel, msg in reader.iter_messages(topics=[TOPIC_FIX, TOPIC_POSE]):
                (fixes if channel.topic == TOPIC_FIX else poses).append(json.loads(msg.data))
            for _s, _c, _m, odom in reader.iter_decoded_messages(topics=[TOPIC_ODOM]):
                odoms.append(odom)
    except SinsError:
        raise
    except Exception as exc:  # noqa: BLE001 - library failure on a user file
        raise SinsError(f"{path}: cannot read as a sins MCAP trajectory ({type(exc).__name__}: {exc})") from None
    if not fixes or len(fixes) != len(poses) or len(poses) != len(odoms):
        raise SinsError(f"{path}: expected equal numbers of {TOPIC_FIX}, {TOPIC_POSE} and {TOPIC_ODOM} messages")
    t = np.array([fx["timestamp"]["sec"] + fx["timestamp"]["nsec"] * 1e-9 for fx in fixes])
    lat = np.radians([fx["latitude"] for fx in fixes])
    lon = np.radians([fx["longitude"] for fx in fixes])
    h = np.array([fx["altitude"] for fx in fixes], dtype=np.float64)
    q = np.array([[p["pose"]["orientation"][k] for k in ("w", "x", "y", "z")] for p in poses])
    from ..nav.rotation import quat_to_dcm_many
    c_flu = quat_to_dcm_many(np.ascontiguousarray(q))
    vb = np.array([(o.twist.twist.linear.x, o.twist.twist.linear.y, o.twist.twist.linear.z) for o in odoms])
    vel = np.einsum("nij,nj->ni", c_flu, vb)
    if meta:
        enu = np.array([[p["pose"]["position"][k] for k in "xyz"] for p in poses])
        origin = (np.radians(float(meta["enu_origin_lat_deg"])), np.radians(float(meta["enu_origin_lon_deg"])),
                  float(meta["enu_origin_height_m"]))
        # the pose positions must agree with the fixes (a check on the file, metres)
        lat2, lon2, _h2 = local_enu_to_lla(enu, *origin)
        if np.max(np.abs(lat2 - lat)) > 1e-6:
            raise SinsError(f"{path}: {TOPIC_POSE} positions disagree with {TOPIC_FIX}")
    return Trajectory(time=t, lat=lat, lon=lon, height=h, vel_n=vel, Cbn=cbn_from_flu(c_flu, conv),
                      source=str(path))
