"""Trajectory -> MCAP that Foxglove opens, plus ``nav_msgs/Odometry`` for ROS users.

Channels (one message per trajectory row, log time = the row's time):

- ``/sins/fix``: ``foxglove.LocationFix`` (JSON): latitude, longitude (deg), altitude (m) for the Map panel;
- ``/sins/pose``: ``foxglove.PoseInFrame`` (JSON) in frame ``enu``: a local ENU frame whose origin is the
  first point (m), orientation of the FLU body axes (REP-103) for the 3D panel;
- ``/sins/odom``: ``nav_msgs/msg/Odometry`` (CDR, ros2msg schema): the same pose, and the velocity in the
  ``base_link`` (FLU body) frame as ROS wants;
- ``/sins/imu_bias``: ``sins.ImuBias`` (JSON), only for an aided trajectory: the sensor error estimates
  (``gyro_bias_x..z`` deg/h, ``accel_bias_x..z`` micro-g, body axes of the file; ``gyro_sf_*``,
  ``accel_sf_*`` ppm), named like the trajectory columns.

The 1-sigma columns of an aided trajectory (:mod:`sinscli.io.aided_columns`) go into the messages'
covariances: ``LocationFix.position_covariance`` (ENU, diagonal, type DIAGONAL_KNOWN); the Odometry pose
covariance (position ENU; orientation as rotations about the ENU axes, from the roll, pitch and heading
sigmas taken as independent small rotations about the level forward, right and down axes:
``M diag(s_r^2, s_p^2, s_h^2) M`` with :func:`sinscli.nav.rotation.level_heading_frame`); the Odometry twist
covariance (the ENU velocity covariance turned into ``base_link``: ``C_n^b diag(s_v^2) C_b^n``).  Zero
blocks mean "not given".

An MCAP metadata record ``sins`` holds the ENU origin and the body convention, so
:func:`read_trajectory_mcap` gives the trajectory back, its sigma and bias columns included.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import SinsError, printable
from ..nav.earth import local_enu_to_lla
from ..nav.rotation import body_flu_in_enu, cbn_from_flu, dcm_to_euler_many, level_heading_frame, quat_to_dcm_many
from ..types import Trajectory
from . import aided_columns as ac
from .atomic import atomic_path, output_lon_lat
from .local_frame import trajectory_enu_quat

TOPIC_FIX, TOPIC_POSE, TOPIC_ODOM, TOPIC_BIAS = "/sins/fix", "/sins/pose", "/sins/odom", "/sins/imu_bias"
COV_DIAGONAL_KNOWN = 2
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


IMU_BIAS_SCHEMA = {
    "title": "sins.ImuBias", "type": "object",
    "description": "IMU error estimates of an aided trajectory, body axes of the file",
    "properties": {"timestamp": _TIME, **{c: {"type": "number", "description": ac.UNITS[c]} for c in ac.BIAS_COLUMNS}},
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
_FIX_COV_JSON = ('{"timestamp": {"sec": %d, "nsec": %d}, "frame_id": "' + FRAME_BODY + '", "latitude": %r, '
                 '"longitude": %r, "altitude": %r, "position_covariance": [%r, 0.0, 0.0, 0.0, %r, 0.0, 0.0, 0.0, %r], '
                 '"position_covariance_type": ' + str(COV_DIAGONAL_KNOWN) + '}')
_POSE_JSON = ('{"timestamp": {"sec": %d, "nsec": %d}, "frame_id": "' + FRAME_ENU + '", "pose": {"position": '
              '{"x": %r, "y": %r, "z": %r}, "orientation": {"x": %r, "y": %r, "z": %r, "w": %r}}}')


def odometry_message(ts, sec, nsec, pos, q_xyzw, v_body, pose_cov=None, twist_cov=None):
    """A ``nav_msgs/msg/Odometry`` object of typestore ``ts`` (frame ``enu``, child ``base_link``).

    ``pose_cov``, ``twist_cov``: the 36 covariance values (row-major 6x6), zeros when None.
    """
    pose_cov = np.zeros(36) if pose_cov is None else np.asarray(pose_cov, dtype=np.float64).reshape(36)
    twist_cov = np.zeros(36) if twist_cov is None else np.asarray(twist_cov, dtype=np.float64).reshape(36)
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
            covariance=pose_cov.copy()),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=vec(x=float(v_body[0]), y=float(v_body[1]), z=float(v_body[2])),
                                               angular=vec(x=0.0, y=0.0, z=0.0)),
            covariance=twist_cov.copy()))


def odometry_cdr_block(ts, sec, nsec, pos, q_xyzw, v_body, pose_cov=None, twist_cov=None) -> np.ndarray:
    """CDR bytes of many Odometry messages at once, (N, L) uint8.

    The library serializes one template message whose fields hold marker
    values; the markers' byte offsets are where numpy writes every message's
    stamp, position, orientation, body velocity and (when given, (N, 36) each)
    covariances.  Equal to the library's ``serialize_cdr`` of each message bit
    for bit (``tests/test_io_traj_writers.py``).
    """
    n = len(sec)
    with_cov = pose_cov is not None or twist_cov is not None
    n_float = 10 + (72 if with_cov else 0)
    markers = [float.fromhex(f"0x1.{k:03x}5a5a5a5a5ap+{600 + k}") for k in range(n_float)]
    sec_m, nsec_m = 0x2B3C4D5E, 0x1A2B3C4D
    tpl_msg = odometry_message(ts, sec_m, nsec_m, markers[0:3], markers[3:7], markers[7:10],
                               markers[10:46] if with_cov else None, markers[46:82] if with_cov else None)
    tpl = bytes(ts.serialize_cdr(tpl_msg, "nav_msgs/msg/Odometry"))

    def where(pattern: bytes) -> int:
        if tpl.count(pattern) != 1:
            raise RuntimeError("Odometry template marker is not unique")
        return tpl.index(pattern)

    block = np.tile(np.frombuffer(tpl, dtype=np.uint8), (n, 1))
    cols = [(where(np.int32(sec_m).tobytes()), np.asarray(sec, dtype="<i4")),
            (where(np.uint32(nsec_m).tobytes()), np.asarray(nsec, dtype="<u4"))]
    parts = [pos, q_xyzw, v_body]
    if with_cov:
        parts += [np.zeros((n, 36)) if pose_cov is None else pose_cov,
                  np.zeros((n, 36)) if twist_cov is None else twist_cov]
    vals = np.column_stack(parts).astype("<f8")
    for j, m in enumerate(markers):
        cols.append((where(np.float64(m).tobytes()), vals[:, j]))
    for off, arr in cols:
        block[:, off:off + arr.itemsize] = np.ascontiguousarray(arr).view(np.uint8).reshape(n, arr.itemsize)
    return block


def _covariances(traj: Trajectory, c_flu: np.ndarray, heading: np.ndarray):
    """``(pos var (N,3) or None, pose cov (N,36) or None, twist cov (N,36) or None)`` from the sigma columns."""
    x = traj.extra
    pos_s, vel_s, att_s = ac.group(x, ac.POS_STD), ac.group(x, ac.VEL_STD), ac.group(x, ac.ATT_STD)
    n = len(traj)
    pos_var = pos_s ** 2 if pos_s is not None else None
    pose = twist = None
    if pos_s is not None or att_s is not None:
        pose = np.zeros((n, 6, 6))
        if pos_s is not None:
            pose[:, [0, 1, 2], [0, 1, 2]] = pos_var
        if att_s is not None:
            m = level_heading_frame(heading)
            d = np.radians(att_s) ** 2
            pose[:, 3:, 3:] = np.einsum("nij,nj,nkj->nik", m, d, m)
        pose = pose.reshape(n, 36)
    if vel_s is not None:
        twist = np.zeros((n, 6, 6))
        twist[:, :3, :3] = np.einsum("nji,nj,njk->nik", c_flu, vel_s ** 2, c_flu)   # C_n^b diag C_b^n
        twist = twist.reshape(n, 36)
    return pos_var, pose, twist


def write_trajectory_mcap(path, traj: Trajectory, conv: int = 0) -> None:
    """Write the trajectory as MCAP (see module docstring), atomically.  Called through
    :func:`sinscli.io.trajectory.write_trajectory`, whose guard has refused non-finite values and sigmas."""
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    origin, enu, q = trajectory_enu_quat(traj, conv)
    t_ns = _stamps(traj)
    if t_ns.shape[0] and t_ns.max() >= 2**31 * 1_000_000_000:
        raise SinsError(f"{traj.source}: times beyond 2^31 s do not fit a ROS time stamp")
    c_flu = body_flu_in_enu(traj.Cbn, conv)
    v_body = np.einsum("nji,nj->ni", c_flu, np.asarray(traj.vel_n, dtype=np.float64))   # C_n^FLU v_n
    lat_deg, lon_deg = output_lon_lat(path, np.degrees(traj.lat), np.degrees(traj.lon), traj.time)
    fields = np.column_stack([lat_deg, lon_deg, traj.height, enu, q, v_body])
    heading = dcm_to_euler_many(np.ascontiguousarray(traj.Cbn, dtype=np.float64), conv)[:, 2]
    pos_var, pose_cov, twist_cov = _covariances(traj, c_flu, heading)
    bias_cols = [c for c in ac.BIAS_COLUMNS if c in traj.extra]
    bias = np.column_stack([np.asarray(traj.extra[c], dtype=np.float64) for c in bias_cols]) if bias_cols else None
    sec, nsec = t_ns // 1_000_000_000, t_ns % 1_000_000_000
    ts = get_typestore(Stores.ROS2_HUMBLE)
    odom_def, _ = ts.generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)
    odom = odometry_cdr_block(ts, sec, nsec, enu, q, v_body, pose_cov, twist_cov)
    rows = fields.tolist()
    fix_fmt = _FIX_JSON if pos_var is None else _FIX_COV_JSON
    fix_rows = fields[:, :3] if pos_var is None else np.column_stack([fields[:, :3], pos_var])
    fix_rows = fix_rows.tolist()
    bias_fmt = ('{"timestamp": {"sec": %d, "nsec": %d}, ' + ", ".join(f'"{c}": %r' for c in bias_cols) + "}"
                if bias is not None else None)
    bias_rows = bias.tolist() if bias is not None else None
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
            c_bias = None
            if bias is not None:
                s_bias = w.register_schema("sins.ImuBias", "jsonschema", json.dumps(IMU_BIAS_SCHEMA).encode())
                c_bias = w.register_channel(TOPIC_BIAS, "json", s_bias)
            w.add_metadata("sins", {
                "enu_origin_lat_deg": repr(float(np.degrees(origin[0]))),
                "enu_origin_lon_deg": repr(float(lon_deg[0])),
                "enu_origin_height_m": repr(float(origin[2])), "body_axes": "FLU", "source": printable(traj.source)})
            for k, r in enumerate(rows):
                tk, s_, ns_ = t_l[k], sec_l[k], nsec_l[k]
                w.add_message(c_fix, log_time=tk, publish_time=tk, sequence=k,
                              data=(fix_fmt % (s_, ns_, *fix_rows[k])).encode())
                w.add_message(c_pose, log_time=tk, publish_time=tk, sequence=k,
                              data=(_POSE_JSON % (s_, ns_, r[3], r[4], r[5], r[6], r[7], r[8], r[9])).encode())
                w.add_message(c_odom, log_time=tk, publish_time=tk, sequence=k, data=odom[k].tobytes())
                if c_bias is not None:
                    w.add_message(c_bias, log_time=tk, publish_time=tk, sequence=k,
                                  data=(bias_fmt % (s_, ns_, *bias_rows[k])).encode())
            w.finish()


def read_trajectory_mcap(path, conv: int = 0) -> Trajectory:
    """Read back a trajectory written by :func:`write_trajectory_mcap` (position from LocationFix,
    attitude from PoseInFrame, velocity from Odometry), with ``Cbn`` in body convention ``conv``.

    Sigma columns come back from the covariances (position exactly; velocity and attitude through
    the rotations, to rounding), bias columns from ``/sins/imu_bias``.
    """
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    path = Path(path)
    fixes, poses, odoms, biases, meta = [], [], [], [], {}
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
            for m in reader.iter_metadata():
                if m.name == "sins":
                    meta = dict(m.metadata)
            lists = {TOPIC_FIX: fixes, TOPIC_POSE: poses, TOPIC_BIAS: biases}
            for _schema, channel, msg in reader.iter_messages(topics=[TOPIC_FIX, TOPIC_POSE, TOPIC_BIAS]):
                lists[channel.topic].append(json.loads(msg.data))
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
    if biases and len(biases) != len(fixes):
        raise SinsError(f"{path}: expected as many {TOPIC_BIAS} messages as {TOPIC_FIX} messages")
    cbn = cbn_from_flu(c_flu, conv)
    extra = _read_sigmas(fixes, odoms, c_flu, dcm_to_euler_many(np.ascontiguousarray(cbn), conv)[:, 2])
    for c in ac.BIAS_COLUMNS:
        if biases and c in biases[0]:
            extra[c] = np.array([b[c] for b in biases], dtype=np.float64)
    return Trajectory(time=t, lat=lat, lon=lon, height=h, vel_n=vel, Cbn=cbn, extra=extra, source=str(path))


def _read_sigmas(fixes, odoms, c_flu, heading) -> dict:
    """Sigma columns from the LocationFix and Odometry covariances (inverse of :func:`_covariances`)."""
    out = {}
    if fixes[0].get("position_covariance_type") == COV_DIAGONAL_KNOWN:
        cov = np.array([fx["position_covariance"] for fx in fixes], dtype=np.float64)
        for i, c in enumerate(ac.POS_STD):
            out[c] = np.sqrt(cov[:, 4 * i])
    pose = np.array([np.asarray(o.pose.covariance, dtype=np.float64) for o in odoms]).reshape(-1, 6, 6)
    twist = np.array([np.asarray(o.twist.covariance, dtype=np.float64) for o in odoms]).reshape(-1, 6, 6)
    if np.any(pose[:, 3:, 3:] != 0):
        m = level_heading_frame(heading)
        lev = np.einsum("nij,njk,nkl->nil", m, pose[:, 3:, 3:], m)
        for i, c in enumerate(ac.ATT_STD):
            out[c] = np.degrees(np.sqrt(lev[:, i, i]))
    if np.any(twist[:, :3, :3] != 0):
        enu = np.einsum("nij,njk,nlk->nil", c_flu, twist[:, :3, :3], c_flu)   # C_b^n P_b C_n^b
        for i, c in enumerate(ac.VEL_STD):
            out[c] = np.sqrt(enu[:, i, i])
    return out
