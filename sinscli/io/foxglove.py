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
from ..nav.earth import local_enu_to_lla
from ..nav.rotation import body_flu_in_enu, cbn_from_flu, quat_to_dcm_many
from ..types import Trajectory
from .atomic import atomic_path
from .local_frame import trajectory_enu_quat

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


_FIX_JSON = ('{"timestamp": {"sec": %d, "nsec": %d}, "frame_id": "' + FRAME_BODY + '", "latitude": %r, '
             '"longitude": %r, "altitude": %r, "position_covariance": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], '
             '"position_covariance_type": 0}')
_POSE_JSON = ('{"timestamp": {"sec": %d, "nsec": %d}, "frame_id": "' + FRAME_ENU + '", "pose": {"position": '
              '{"x": %r, "y": %r, "z": %r}, "orientation": {"x": %r, "y": %r, "z": %r, "w": %r}}}')


def odometry_message(ts, sec, nsec, pos, q_xyzw, v_body):
    """A ``nav_msgs/msg/Odometry`` object of typestore ``ts`` (frame ``enu``, child ``base_link``)."""
    t = ts.types
    vec = t["geometry_msgs/msg/Vector3"]
    return t["nav_msgs/msg/Odometry"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int(nsec)),
                                        frame_id=FRAME_ENU),
        child_frame_id=FRAME_BODY,
        pose=t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=float(pos[0]), y=float(pos[1]), z=float(pos[2])),
                orientation=t["geometry_msgs/msg/Quaternion"](x=float(q_xyzw[0]), y=float(q_xyzw[1]),
                                                              z=float(q_xyzw[2]), w=float(q_xyzw[3]))),
            covariance=np.zeros(36)),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=vec(x=float(v_body[0]), y=float(v_body[1]), z=float(v_body[2])),
                                               angular=vec(x=0.0, y=0.0, z=0.0)),
            covariance=np.zeros(36)))


def odometry_cdr_block(ts, sec, nsec, pos, q_xyzw, v_body) -> np.ndarray:
    """CDR bytes of many Odometry messages at once, (N, L) uint8.

    The library serializes one template message whose fields hold marker
    values; the markers' byte offsets are where numpy writes every message's
    stamp, position, orientation and body velocity.  Equal to the library's
    ``serialize_cdr`` of each message bit for bit (``tests/test_io_traj_writers.py``).
    """
    markers = [float.fromhex(f"0x1.{k:x}5a5a5a5a5a5ap+{600 + k}") for k in range(10)]
    sec_m, nsec_m = 0x2B3C4D5E, 0x1A2B3C4D
    tpl = bytes(ts.serialize_cdr(odometry_message(ts, sec_m, nsec_m, markers[0:3], markers[3:7], markers[7:10]),
                                 "nav_msgs/msg/Odometry"))

    def where(pattern: bytes) -> int:
        if tpl.count(pattern) != 1:
            raise RuntimeError("Odometry template marker is not unique")
        return tpl.index(pattern)

    n = len(sec)
    block = np.tile(np.frombuffer(tpl, dtype=np.uint8), (n, 1))
    cols = [(where(np.int32(sec_m).tobytes()), np.asarray(sec, dtype="<i4")),
            (where(np.uint32(nsec_m).tobytes()), np.asarray(nsec, dtype="<u4"))]
    vals = np.column_stack([pos, q_xyzw, v_body]).astype("<f8")
    for j, m in enumerate(markers):
        cols.append((where(np.float64(m).tobytes()), vals[:, j]))
    for off, arr in cols:
        block[:, off:off + arr.itemsize] = np.ascontiguousarray(arr).view(np.uint8).reshape(n, arr.itemsize)
    return block


def write_trajectory_mcap(path, traj: Trajectory, conv: int = 0) -> None:
    """Write the trajectory as MCAP (see module docstring), atomically."""
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    origin, enu, q = trajectory_enu_quat(traj, conv)
    t_ns = _stamps(traj)
    if t_ns.shape[0] and t_ns.max() >= 2**31 * 1_000_000_000:
        raise SinsError(f"{traj.source}: times beyond 2^31 s do not fit a ROS time stamp")
    c_flu = body_flu_in_enu(traj.Cbn, conv)
    v_body = np.einsum("nji,nj->ni", c_flu, np.asarray(traj.vel_n, dtype=np.float64))   # C_n^FLU v_n
    lat_deg, lon_deg = np.degrees(traj.lat), np.degrees(traj.lon)
    fields = np.column_stack([lat_deg, lon_deg, traj.height, enu, q, v_body])
    sec, nsec = t_ns // 1_000_000_000, t_ns % 1_000_000_000
    ts = get_typestore(Stores.ROS2_HUMBLE)
    odom_def, _ = ts.generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)
    odom = odometry_cdr_block(ts, sec, nsec, enu, q, v_body)
    rows = fields.tolist()
    sec_l, nsec_l, t_l = sec.tolist(), nsec.tolist(), t_ns.tolist()
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
                "enu_origin_height_m": repr(float(origin[2])), "body_axes": "FLU", "source": str(traj.source)})
            for k, r in enumerate(rows):
                tk, s_, ns_ = t_l[k], sec_l[k], nsec_l[k]
                w.add_message(c_fix, log_time=tk, publish_time=tk, sequence=k,
                              data=(_FIX_JSON % (s_, ns_, r[0], r[1], r[2])).encode())
                w.add_message(c_pose, log_time=tk, publish_time=tk, sequence=k,
                              data=(_POSE_JSON % (s_, ns_, r[3], r[4], r[5], r[6], r[7], r[8], r[9])).encode())
                w.add_message(c_odom, log_time=tk, publish_time=tk, sequence=k, data=odom[k].tobytes())
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
