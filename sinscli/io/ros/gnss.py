"""``sensor_msgs/NavSatFix`` topics, with an optional velocity topic, as a :class:`GnssLog`."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ...errors import SinsError
from .. import limits as limits_mod
from ...types import GnssLog
from .containers import _Log, choose_topic, guard, open_log
from .decode import NAVSAT_TYPE, VEL_TYPES, check_increasing, check_time_source, message_times

log = logging.getLogger("sins")


def _quat_xyzw_to_dcm(q: np.ndarray) -> np.ndarray:
    from ...nav.rotation import quat_to_dcm_many
    wxyz = np.ascontiguousarray(q[:, [3, 0, 1, 2]], dtype=np.float64)
    n = np.linalg.norm(wxyz, axis=1)
    if np.any(~np.isfinite(n) | (n < 1e-6)):
        raise ValueError("invalid orientation quaternion")
    return quat_to_dcm_many(wxyz / n[:, None])


def _velocity(lg: _Log, topic: str, time_source: str, lim: dict):
    """(time s, vel (N,3), std (N,3) or None) from a TwistStamped / TwistWithCovarianceStamped / Odometry topic.

    Odometry twist is in the child (body) frame: it is turned into the parent frame with the pose
    orientation, and the parent frame is taken as ENU.
    """
    info = lg.topics[topic]
    where = f"{lg.path}: topic {topic}"
    log_ns, msgs = lg.decode_all(topic)
    if not msgs:
        raise SinsError(f"{where}: topic has no messages")
    t = message_times(where, log_ns, msgs, time_source)
    std = None
    if info.msgtype == "geometry_msgs/msg/TwistStamped":
        v = np.array([(m.twist.linear.x, m.twist.linear.y, m.twist.linear.z) for m in msgs], dtype=np.float64)
    else:
        v = np.array([(m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z) for m in msgs],
                     dtype=np.float64)
        cov = np.array([np.asarray(m.twist.covariance, dtype=np.float64).reshape(6, 6)[:3, :3] for m in msgs])
        if info.msgtype == "nav_msgs/msg/Odometry":
            q = np.array([(m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                           m.pose.pose.orientation.w) for m in msgs], dtype=np.float64)
            try:
                c = _quat_xyzw_to_dcm(q)
            except ValueError:
                raise SinsError(f"{where}: an Odometry pose orientation is not a valid quaternion") from None
            v = np.einsum("nij,nj->ni", c, v)
            cov = np.einsum("nij,njk,nlk->nil", c, cov, c)
        var = np.einsum("nii->ni", cov)
        if np.all(var == 0):
            std = None
        else:
            bad = ~np.isfinite(var).all(axis=1) | (var <= 0).any(axis=1)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise SinsError(f"{where}: message {k} has a zero, negative or NaN velocity variance "
                                f"({var[k].tolist()})")
            std = np.sqrt(var)
    if not np.isfinite(v).all():
        k = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise SinsError(f"{where}: message {k} has a non-finite velocity")
    limits_mod.check_velocity(where, v, lim, ("x", "y", "z"), 0, "message")
    check_increasing(t, where, f"{time_source} stamp")
    return t, v, std


def _interp_rows(t_out, t_in, y):
    """Linear interpolation of the rows of ``y`` at ``t_out``; NaN outside ``[t_in[0], t_in[-1]]``."""
    out = np.empty((t_out.shape[0], y.shape[1]))
    for j in range(y.shape[1]):
        out[:, j] = np.interp(t_out, t_in, y[:, j], left=np.nan, right=np.nan)
    return out


def read_gnss(path, topic=None, vel_topic=None, time_source="header", limits=None) -> GnssLog:
    """Read a ``sensor_msgs/NavSatFix`` topic (and optionally a velocity topic) as a :class:`GnssLog`.

    Fixes with status "no fix" (-1) are dropped (count logged).  The ENU position
    covariance diagonal gives ``std_pos`` (absent when every fix says
    COVARIANCE_TYPE_UNKNOWN).  Velocity (``vel_topic``: TwistStamped,
    TwistWithCovarianceStamped or Odometry, ENU) is interpolated linearly at the
    fix times; fixes outside the velocity topic's time span are dropped (count logged).
    Positions and velocities beyond ``limits`` (the config's section) are refused naming the message.
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
    check_increasing(t, where, f"{time_source} stamp")
    ctype = np.array([int(m.position_covariance_type) for m in msgs])
    cov = np.array([np.asarray(m.position_covariance, dtype=np.float64) for m in msgs]).reshape(-1, 9)
    std = None
    known = ctype != 0
    if known.any():
        var = cov[:, [0, 4, 8]]
        bad = known & (~np.isfinite(var).all(axis=1) | (var <= 0).any(axis=1))
        if bad.any():
            k = int(keep[np.flatnonzero(bad)[0]])
            raise SinsError(f"{where}: message {k} has a zero, negative or NaN position covariance "
                            f"({var[np.flatnonzero(bad)[0]].tolist()}) with covariance type "
                            f"{ctype[np.flatnonzero(bad)[0]]}")
        if known.all():
            std = np.sqrt(var)
        else:
            log.warning("%s: %d fixes have unknown covariance; std columns left out",
                        where, int((~known).sum()))
    vel = std_vel = None
    if vel_topic is not None:
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
