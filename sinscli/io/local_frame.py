"""A trajectory in a local ENU frame with the attitude of its FLU body axes.

The common form of the local-frame trajectory formats (TUM for ``evo``, MCAP
for Foxglove and ROS): position in metres in an ENU frame whose origin is the
trajectory's first point, attitude of the FLU body axes (x forward, y left,
z up, REP-103) in that frame.  Not a writer: the writers take it from here.
"""
from __future__ import annotations

import numpy as np

from ..errors import SinsError
from ..nav.earth import lla_to_local_enu
from ..nav.rotation import body_flu_in_enu, dcm_to_quat_many
from ..types import Trajectory


def trajectory_enu_quat(traj: Trajectory, conv: int):
    """``(origin (lat, lon, h), enu (N, 3), q_xyzw (N, 4))`` of a trajectory for local-frame formats."""
    if len(traj) == 0:
        raise SinsError(f"{traj.source}: trajectory is empty; nothing to write")
    fields = np.column_stack([traj.time, traj.lat, traj.lon, traj.height,
                              np.asarray(traj.Cbn, dtype=np.float64).reshape(-1, 9)])
    if not np.isfinite(fields).all():
        k = int(np.flatnonzero(~np.isfinite(fields).all(axis=1))[0])
        raise SinsError(f"{traj.source}: row {k} (time {float(traj.time[k])!r}) has a non-finite time, position "
                        "or attitude; cannot write a local-frame trajectory")
    origin = (float(traj.lat[0]), float(traj.lon[0]), float(traj.height[0]))
    enu = lla_to_local_enu(traj.lat, traj.lon, traj.height, *origin)
    q = dcm_to_quat_many(np.ascontiguousarray(body_flu_in_enu(traj.Cbn, conv)))
    return origin, enu, q[:, [1, 2, 3, 0]]
