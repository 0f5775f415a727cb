"""``nav_msgs/Odometry`` (or a body-frame Twist topic) as body velocity: a :class:`BodyVelLog`.

The twist of an Odometry message is expressed in its ``child_frame_id``, the
moving vehicle (REP-105: ``base_link``), not in its parent frame: it is a body
velocity, and ``odom`` is a local frame of arbitrary heading, never ENU.  A
``TwistStamped`` / ``TwistWithCovarianceStamped`` read as odometry is taken in
its ``header.frame_id`` likewise.  Which body axes:

- the velocity frame equals the IMU messages' ``frame_id`` (the IMU's sensor
  axes): turned into the body axes with the config's mounting (``imu.mounting``,
  ``v_b = C_sensor^body v``);
- any other frame (``base_link``): the vehicle frame of REP-103 (x forward,
  y left, z up), turned into the body convention in force (``imu.body``);
- an empty frame name is refused (say which with ``odometry.frame``).

``odometry.frame: vehicle | sensor | body`` in the config overrides the choice
(``body``: already in the body axes of the convention in force).  The
covariance's linear block gives the 1-sigma (rotated the same way; all zero
means "not given"), and the IMU frame comes from the log's IMU topic when it
has one.  Velocity measured at the frame's origin, not at the IMU: a lever
arm between them is the filter's business.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ...errors import SinsError
from ...types import BodyVelLog
from .containers import _Log, choose_topic, guard, open_log
from .decode import BODY_VEL_TYPES, IMU_TYPE, ODOMETRY_TYPE, check_increasing, check_time_source, message_times
from ..body_vel_csv import to_body_axes
from .gnss import variance_to_std

log = logging.getLogger("sins")

FRAMES = ("auto", "body", "vehicle", "sensor")


def imu_frame_id(lg: _Log, topic: str | None = None) -> str | None:
    """``header.frame_id`` of the first message of the log's IMU topic (None when the log has none)."""
    cands = [n for n, i in lg.topics.items() if i.msgtype == IMU_TYPE]
    if topic is None:
        if len(cands) != 1:
            return None
        topic = cands[0]
    if topic not in lg.topics or lg.topics[topic].msgtype != IMU_TYPE:
        return None
    deser = lg.deserializer(topic)
    with guard(lg.path, topic, "cannot decode sensor_msgs/Imu messages"):
        for _t, raw in lg.iter_raw(topic):
            return str(deser(raw).header.frame_id)
    return None


def velocity_frame(where: str, child: str, imu_frame: str | None, frame: str) -> str:
    """``"sensor"``, ``"vehicle"`` or ``"body"``: which axes the twist is in (see the module docstring)."""
    if frame not in FRAMES:
        raise SinsError(f"{where}: odometry frame {frame!r} unknown (expected one of {', '.join(FRAMES)})")
    if frame != "auto":
        return frame
    if not child:
        raise SinsError(f"{where}: the velocity frame name (child_frame_id) is empty, so its axes are unknown; "
                        "say which with the config's odometry.frame: vehicle (x forward, y left, z up), sensor (the "
                        "IMU's axes) or body (the body axes in force)")
    same = imu_frame is not None and child.lstrip("/") == imu_frame.lstrip("/")    # ROS 1 names may lead with /
    return "sensor" if same else "vehicle"


def read_twist_topic(path, topic=None, time_source="header", imu_topic=None):
    """The raw twists of an Odometry topic (the single one when ``topic`` is None) or a named Twist topic.

    Returns ``(where, time (N,), vel (N,3), cov (N,3,3) or None, frame name, IMU frame_id or None)``,
    the velocity in the axes of its frame (child frame of an Odometry, header frame of a Twist).
    """
    check_time_source(time_source)
    path = Path(path)
    with open_log(path) as lg:
        if topic is None:
            topic = choose_topic(lg, None, ODOMETRY_TYPE, "odometry (body velocity)", "--odom-topic")
        else:
            topic = choose_topic(lg, topic, BODY_VEL_TYPES, "odometry (body velocity)", "--odom-topic")
        where = f"{path}: topic {topic}"
        msgtype = lg.topics[topic].msgtype
        with guard(path, topic, f"cannot decode {msgtype} messages"):
            log_ns, msgs = lg.decode_all(topic)
            if not msgs:
                raise SinsError(f"{where}: topic has no messages")
            t = message_times(where, log_ns, msgs, time_source)
            if msgtype == ODOMETRY_TYPE:
                frames = {str(m.child_frame_id) for m in msgs}
            else:
                frames = {str(m.header.frame_id) for m in msgs}
            if len(frames) != 1:
                raise SinsError(f"{where}: the velocity frame changes between messages ({', '.join(sorted(frames))}); "
                                "expected one frame")
            child = frames.pop()
            if msgtype == "geometry_msgs/msg/TwistStamped":
                v = np.array([(m.twist.linear.x, m.twist.linear.y, m.twist.linear.z) for m in msgs], dtype=np.float64)
                cov = None
            else:
                v = np.array([(m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z) for m in msgs],
                             dtype=np.float64)
                cov = np.array([np.asarray(m.twist.covariance, dtype=np.float64).reshape(6, 6)[:3, :3]
                                for m in msgs])
            imu_frame = imu_frame_id(lg, imu_topic)
    if not np.isfinite(v).all():
        k = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise SinsError(f"{where}: message {k} has a non-finite twist velocity")
    check_increasing(t, where, f"{time_source} stamp")
    if cov is not None and variance_to_std(where, np.einsum("nii->ni", cov), "twist velocity") is None:
        cov = None
    return where, t, v, cov, child, imu_frame


def read_body_velocity(path, topic=None, time_source="header", mounting=None, conv: int = 0, frame="auto",
                       imu_topic=None) -> BodyVelLog:
    """Body velocity from an Odometry topic (the single one when ``topic`` is None) or a named Twist topic.

    ``mounting``: ``C_sensor^body`` (identity when None); ``conv``: body convention code; ``frame``:
    auto | body | sensor (module docstring).  ``source`` is ``"file:topic"``.
    """
    mounting = np.eye(3) if mounting is None else np.asarray(mounting, dtype=np.float64)
    where, t, v, cov, child, imu_frame = read_twist_topic(path, topic, time_source, imu_topic)
    kind = velocity_frame(where, child, imu_frame, frame)
    v_b, cov_b = to_body_axes(v, cov, kind, mounting, conv)
    std = None if cov_b is None else np.sqrt(np.einsum("nii->ni", cov_b))
    log.info("%s: %d velocities in frame '%s', taken as %s axes", where, len(t), child,
             {"sensor": "the IMU's sensor (mounting applied)", "vehicle": "vehicle (REP-103)",
              "body": "body"}[kind])
    return BodyVelLog(time=t, vel_b=v_b, std=std, source=where.replace(": topic ", ":"))
