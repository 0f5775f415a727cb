"""``sensor_msgs/NavSatFix`` topics, with an optional velocity topic, as a :class:`GnssLog`."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ...errors import SinsError
from ...types import GnssLog
from .. import limits as limits_mod
from ..gnss_csv import POLE_USE
from .containers import _Log, choose_topic, guard, open_log
from .decode import NAVSAT_TYPE, ODOMETRY_TYPE, VEL_TYPES, check_increasing, check_time_source, message_times

log = logging.getLogger("sins")


BODY_FRAME_NAMES = ("base_link", "base_footprint", "body", "vehicle")
UNKNOWN_VARIANCE = 1.0e6     # (m/s)^2: a vertical velocity variance this large (or negative, ROS's "unknown") says
                             # the receiver gives no vertical velocity (speed and course): horizontal only


def refuse_odometry(lg: _Log, topic: str | None, role: str = "GNSS velocity") -> None:
    """SinsError when ``topic`` is a ``nav_msgs/Odometry`` topic given where an ENU velocity is required.

    Its twist is the vehicle's velocity in its child (body) frame, and its parent frame (``odom``) is a
    local frame of arbitrary heading, not ENU: it is body-velocity aiding, read by
    :func:`sinscli.io.ros.odometry.read_body_velocity`.
    """
    if topic is not None and topic in lg.topics and lg.topics[topic].msgtype == ODOMETRY_TYPE:
        raise SinsError(f"{lg.path}: topic {topic} is nav_msgs/msg/Odometry: its twist is the vehicle's velocity "
                        f"in its own body frame (child_frame_id), not an ENU velocity, so it cannot serve as "
                        f"{role}; give it as body-velocity (odometry) input instead (ros.odom_topic, --odom-topic)")


def _velocity(lg: _Log, topic: str, time_source: str, lim: dict):
    """(time s, vel (N,3), std (N,3) or None) from a TwistStamped / TwistWithCovarianceStamped topic, ENU.

    GNSS receiver drivers (nmea_navsat_driver, ublox, septentrio) publish these with the antenna's frame
    in ``header.frame_id`` and the velocity components east, north, up: the values are taken as ENU.
    A ``frame_id`` that names a vehicle body frame (``base_link`` ...) gets a warning: such a twist is
    more likely a body velocity.  A TwistWithCovarianceStamped whose vertical variance is negative or at
    least :data:`UNKNOWN_VARIANCE` has no vertical velocity: its up component (and sigma) is NaN.
    """
    info = lg.topics[topic]
    where = f"{lg.path}: topic {topic}"
    log_ns, msgs = lg.decode_all(topic)
    if not msgs:
        raise SinsError(f"{where}: topic has no messages")
    t = message_times(where, log_ns, msgs, time_source)
    frames = sorted({m.header.frame_id for m in msgs} & set(BODY_FRAME_NAMES))
    if frames:
        log.warning("%s: frame_id %s names a vehicle body frame, but the twist is read as an ENU (east, north, up) "
                    "GNSS velocity; if it is a body velocity, give it as odometry instead", where, frames[0])
    std = None
    up_unknown = np.zeros(len(msgs), dtype=bool)
    if info.msgtype == "geometry_msgs/msg/TwistStamped":
        v = np.array([(m.twist.linear.x, m.twist.linear.y, m.twist.linear.z) for m in msgs], dtype=np.float64)
    else:
        v = np.array([(m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z) for m in msgs],
                     dtype=np.float64)
        cov = np.array([np.asarray(m.twist.covariance, dtype=np.float64).reshape(6, 6)[:3, :3] for m in msgs])
        var = np.einsum("nii->ni", cov).copy()
        up_unknown = (var[:, 2] < 0) | (var[:, 2] >= UNKNOWN_VARIANCE)
        var[up_unknown, 2] = 0.0
        if up_unknown.any() and not np.all(var == 0):
            var[up_unknown, 2] = 1.0            # checked as a placeholder, then NaN
        std = variance_to_std(where, var, "velocity")
    if not np.isfinite(v).all():
        k = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise SinsError(f"{where}: message {k} has a non-finite velocity")
    limits_mod.check_velocity(where, v, lim, ("x", "y", "z"), 0, "message")
    check_increasing(t, where, f"{time_source} stamp")
    if up_unknown.any():
        v[up_unknown, 2] = np.nan
        if std is not None:
            std[up_unknown, 2] = np.nan
    return t, v, std


def variance_to_std(where: str, var: np.ndarray, what: str, messages=0) -> np.ndarray | None:
    """1-sigma from (N, 3) covariance diagonals; None when all are zero (not given); SinsError at a
    variance among given ones that is not positive and finite (:func:`limits.check_sigma`), naming the
    message (``messages``: index of row 0, or the message index of every row)."""
    if np.all(var == 0):
        return None
    for j in range(3):
        limits_mod.check_sigma(where, var[:, j], f"{what} variance [{j}]", messages, "message", variance=True)
    return np.sqrt(var)


def _interp_rows(t_out, t_in, y):
    """Linear interpolation of the rows of ``y`` at ``t_out``; NaN outside ``[t_in[0], t_in[-1]]``."""
    out = np.empty((t_out.shape[0], y.shape[1]))
    for j in range(y.shape[1]):
        out[:, j] = np.interp(t_out, t_in, y[:, j], left=np.nan, right=np.nan)
    return out


def read_gnss(path, topic=None, vel_topic=None, time_source="header", limits=None) -> GnssLog:
    """Read a ``sensor_msgs/NavSatFix`` topic (and optionally a velocity topic) as a :class:`GnssLog`.

    Fixes with status "no fix" (-1) are dropped (count logged).  The ENU position
    covariance diagonal (REP-145) gives ``std_pos``: None when every fix says
    COVARIANCE_TYPE_UNKNOWN, NaN rows for the UNKNOWN fixes among known ones (the
    filter then uses its configured sigma).  Velocity (``vel_topic``: TwistStamped or
    TwistWithCovarianceStamped, ENU; an Odometry topic is refused: its twist is a
    body velocity) is interpolated linearly at the fix times; fixes outside the
    velocity topic's time span are dropped (count logged).
    Positions, velocities and variances beyond ``limits`` (the config's section) are refused naming the
    message.
    """
    check_time_source(time_source)
    path = Path(path)
    with open_log(path) as lg:
        topic = choose_topic(lg, topic, NAVSAT_TYPE, "GNSS", "--gnss-topic")
        where = f"{path}: topic {topic}"
        with guard(path, topic, "cannot decode sensor_msgs/NavSatFix messages"):
            return _read_navsat(lg, topic, where, vel_topic, time_source, limits_mod.resolve(limits))


def _read_navsat(lg: _Log, topic: str, where: str, vel_topic, time_source, lim: dict) -> GnssLog:
    """The body of :func:`read_gnss` on an open log."""
    path = lg.path
    log_ns, msgs = lg.decode_all(topic)
    if not msgs:
        raise SinsError(f"{where}: topic has no messages")
    status = np.array([int(m.status.status) for m in msgs])
    fix = status >= 0
    n_drop = int((~fix).sum())
    if n_drop:
        log.warning("%s: dropped %d of %d NavSatFix messages with status 'no fix'", where, n_drop, len(msgs))
    if not fix.any():
        raise SinsError(f"{where}: no NavSatFix message has a fix (all {len(msgs)} have status 'no fix')")
    t_all = message_times(where, log_ns, msgs, time_source)
    keep = np.flatnonzero(fix)
    msgs = [msgs[i] for i in keep]
    t = t_all[keep]
    lla = np.array([(m.latitude, m.longitude, m.altitude) for m in msgs], dtype=np.float64)
    bad = ~np.isfinite(lla).all(axis=1)
    if bad.any():
        k = int(keep[np.flatnonzero(bad)[0]])
        raise SinsError(f"{where}: message {k} has a fix with NaN or infinite latitude/longitude/altitude")
    limits_mod.check_position(where, lla[:, 0], lla[:, 1], lla[:, 2], lim, ("latitude", "longitude", "altitude"),
                              keep, "message")
    limits_mod.check_near_pole(where, lla[:, 0], "latitude", keep, "message", use=POLE_USE)
    check_increasing(t, where, f"{time_source} stamp")
    ctype = np.array([int(m.position_covariance_type) for m in msgs])
    cov = np.array([np.asarray(m.position_covariance, dtype=np.float64) for m in msgs]).reshape(-1, 9)
    std = None
    known = ctype != 0
    if known.any():
        std = np.full((len(msgs), 3), np.nan)    # NaN: unknown for this fix, the user's configured sigma
        var = cov[known][:, [0, 4, 8]]
        for j in range(3):
            limits_mod.check_sigma(where, var[:, j], f"position variance [{j}] (covariance type known)", keep[known],
                                   "message", variance=True)
        std[known] = np.sqrt(var)
        if not known.all():
            log.warning("%s: %d of %d fixes have covariance type UNKNOWN; their sigma is left to the config",
                        where, int((~known).sum()), len(msgs))
    vel = std_vel = None
    if vel_topic is not None:
        refuse_odometry(lg, vel_topic)
        vtopic = choose_topic(lg, vel_topic, VEL_TYPES, "GNSS velocity", "--vel-topic")
        tv, v, sv = _velocity(lg, vtopic, time_source, lim)
        vel = _interp_rows(t, tv, v)
        std_vel = _interp_rows(t, tv, sv) if sv is not None else None
        covered = ~np.isnan(vel[:, 0])
        if not covered.any():
            raise SinsError(f"{path}: topic {vtopic}: velocity times do not overlap the fixes of {topic}")
        if not covered.all():
            log.warning("%s: dropped %d fixes outside the time span of the velocity topic %s",
                        where, int((~covered).sum()), vtopic)
            t, lla, vel = t[covered], lla[covered], vel[covered]
            std = std[covered] if std is not None else None
            std_vel = std_vel[covered] if std_vel is not None else None
    return GnssLog(time=t, lat=lla[:, 0].copy(), lon=lla[:, 1].copy(), height=lla[:, 2].copy(),
                   vel_n=vel, std_pos=std, std_vel=std_vel, source=f"{path}:{topic}")
