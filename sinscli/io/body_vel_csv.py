"""Body-velocity (odometry) CSV: ``time, vel_x, vel_y, vel_z[, std_x, std_y, std_z]`` -> :class:`BodyVelLog`.

The velocity of the vehicle in its body axes (m/s): x, y, z of the body
convention in force (``imu.body``: FLU by default, so vel_x is the forward
speed), with optional 1-sigma (m/s) of each component.  The config's
``odometry.frame`` says otherwise: ``sensor`` (the IMU's sensor axes, turned
into the body axes with ``imu.mounting``) or ``vehicle`` (REP-103 vehicle axes
x forward, y left, z up, as ``sins convert`` writes a ``base_link`` twist;
turned into the convention in force).  Other column names through
``odometry.columns``.  Checks: unknown or missing columns, values
that are not finite numbers, a sigma of 0 or below, time that repeats or goes
backwards (gaps are allowed: an odometer may stop publishing at rest), time
stamps and speeds beyond the config's physical ``limits``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..config import ODOMETRY_NAMES, ImuSection, Limits, OdometrySection, mounting_matrix
from ..nav.rotation import BODY_CONVENTIONS, conv_to_flu
from ..types import BodyVelLog
from .atomic import atomic_path
from . import limits as limits_mod
from .csvcore import read_mapped_columns, write_table_csv
from .imu_csv import check_time

VEL = ["vel_x", "vel_y", "vel_z"]
STD = ["std_x", "std_y", "std_z"]


def read_body_velocity_csv(path, odo: OdometrySection | None = None, imu: ImuSection | None = None,
                           limits: Limits | None = None) -> BodyVelLog:
    """Read a body-velocity CSV; ``odo``, ``imu`` and ``limits`` are the config's sections (None: the
    defaults)."""
    path = Path(path)
    lim = limits_mod.resolve(limits)
    odo = odo if odo is not None else OdometrySection()
    data, mapping = read_mapped_columns(
        path, odo, ODOMETRY_NAMES, ["time"] + VEL, [STD],
        "expected a body-velocity CSV: time, vel_x, vel_y, vel_z and optionally std_x, std_y, std_z (map other "
        "names with the config's odometry.columns)", "expected time, vel_x, vel_y, vel_z (m/s, body axes)")
    names = {c: mapping.get(c, c) for c in data}
    limits_mod.check_time(path, data["time"], lim, names["time"], 2)
    check_time(path, data["time"], allow_gaps=True, what=names["time"])
    vel = np.column_stack([data[c] for c in VEL])
    limits_mod.check_velocity(path, vel, lim, [names[c] for c in VEL], 2)
    for c in STD:
        if c in data:
            limits_mod.check_sigma(path, data[c], names[c], 2)
    std = np.column_stack([data[c] for c in STD]) if STD[0] in data else None
    kind = odo.frame
    if kind in ("sensor", "vehicle"):
        imu = imu if imu is not None else ImuSection()
        c_sb = mounting_matrix(imu.mounting)
        cov = None if std is None else np.einsum("ni,ij->nij", std ** 2, np.eye(3))
        vel, cov_b = to_body_axes(vel, cov, kind, c_sb, BODY_CONVENTIONS[imu.body])
        std = None if cov_b is None else np.sqrt(np.einsum("nii->ni", cov_b))
    return BodyVelLog(time=data["time"], vel_b=vel, std=std, source=str(path))


def to_body_axes(vel: np.ndarray, cov: np.ndarray | None, kind: str, mounting: np.ndarray, conv: int):
    """``(v_b (N,3), cov_b (N,3,3) or None)`` in the body axes of convention ``conv``.

    ``kind``: ``body`` (already there), ``vehicle`` (REP-103 axes, x forward, y left, z up:
    ``C = C_FLU^{conv}``) or ``sensor`` (the IMU's axes: ``C = mounting``, C_sensor^body).
    """
    if kind == "body":
        return vel, cov
    c = np.asarray(mounting, dtype=np.float64) if kind == "sensor" else conv_to_flu(conv).T
    v_b = vel @ c.T
    cov_b = None if cov is None else np.einsum("ij,njk,lk->nil", c, cov, c)
    return v_b, cov_b


def write_body_velocity_csv(path, bv: BodyVelLog) -> None:
    """Write a body-velocity CSV atomically with exact floats (std columns when present)."""
    data = {"time": bv.time, "vel_x": bv.vel_b[:, 0], "vel_y": bv.vel_b[:, 1], "vel_z": bv.vel_b[:, 2]}
    if bv.std is not None:
        data.update({"std_x": bv.std[:, 0], "std_y": bv.std[:, 1], "std_z": bv.std[:, 2]})
    with atomic_path(path) as tmp:
        write_table_csv(tmp, data, sigmas=STD)
