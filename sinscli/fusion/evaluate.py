"""Errors of a fused trajectory against an exact truth (for tests, benchmarks and the docs' figures).

``errors(traj, truth)`` returns, at the trajectory's rows, the position error (ENU m), velocity error
(m/s) and the attitude error ``phi`` (ENU rad, ``Cbn_est = (I - [phi x]) Cbn_true``), all "estimate
minus truth" as the filter's error state, and the per-row 3x3 covariance blocks rebuilt from the
sigma columns where needed for NEES.
"""
from __future__ import annotations

import numpy as np

from ..nav.earth import dlon, radii_py
from ..types import Trajectory


def errors(traj: Trajectory, truth: Trajectory):
    """``(dr (n, 3), dv (n, 3), phi (n, 3))`` at the rows of ``traj`` whose times the truth has."""
    k = np.searchsorted(truth.time, traj.time)
    k = np.clip(k, 0, len(truth) - 1)
    if not np.allclose(truth.time[k], traj.time, rtol=0, atol=1e-6):
        raise ValueError("truth does not hold the trajectory's times")
    rm, rn = radii_py(np.sin(truth.lat[k]))
    h = truth.height[k]
    dr = np.column_stack([dlon(traj.lon, truth.lon[k]) * (rn + h) * np.cos(truth.lat[k]),
                          (traj.lat - truth.lat[k]) * (rm + h), traj.height - h])
    dv = traj.vel_n - truth.vel_n[k]
    # (I - [phi x]) = Cbn_est Cbn_true^T  ->  [phi x] = I - C_est C_true^T (antisymmetric part)
    E = np.einsum("nij,nkj->nik", traj.Cbn, truth.Cbn[k])
    phi = 0.5 * np.column_stack([E[:, 1, 2] - E[:, 2, 1], E[:, 2, 0] - E[:, 0, 2], E[:, 0, 1] - E[:, 1, 0]])
    return dr, dv, phi


def horizontal_rms(dr) -> float:
    return float(np.sqrt(np.mean(dr[:, 0] ** 2 + dr[:, 1] ** 2)))
