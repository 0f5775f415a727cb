"""Errors of a fused trajectory against an exact truth (for tests, benchmarks and the docs' figures).

``errors(traj, truth)`` returns, at the trajectory's rows, the position error (ENU m), velocity error
(m/s) and the attitude error ``phi`` (ENU rad, ``Cbn_est = (I - [phi x]) Cbn_true``), all "estimate
minus truth" as the filter's error state, and the per-row 3x3 covariance blocks rebuilt from the
sigma columns where needed for NEES.
"""
from __future__ import annotations

import numpy as np

from ..nav.earth import enu_offset
from ..types import Trajectory


def errors(traj: Trajectory, truth: Trajectory):
    """``(dr (n, 3), dv (n, 3), phi (n, 3))`` at the rows of ``traj`` whose times the truth has."""
    k = np.searchsorted(truth.time, traj.time)
    k = np.clip(k, 0, len(truth) - 1)
    if not np.allclose(truth.time[k], traj.time, rtol=0, atol=1e-6):
        raise ValueError("truth does not hold the trajectory's times")
    dr = -enu_offset(truth.lat[k], truth.lon[k], truth.height[k], traj.lat, traj.lon, traj.height)  # radii at truth
    dv = traj.vel_n - truth.vel_n[k]
    # (I - [phi x]) = Cbn_est Cbn_true^T  ->  [phi x] = I - C_est C_true^T (antisymmetric part)
    E = np.einsum("nij,nkj->nik", traj.Cbn, truth.Cbn[k])
    phi = 0.5 * np.column_stack([E[:, 1, 2] - E[:, 2, 1], E[:, 2, 0] - E[:, 0, 2], E[:, 0, 1] - E[:, 1, 0]])
    return dr, dv, phi


def truth_at(truth: Trajectory, t: np.ndarray) -> Trajectory:
    """The truth at the times ``t`` (inside its span): position and velocity interpolated linearly, the
    attitude by the linear interpolation of Cbn re-orthonormalized (exact to the square of the rotation
    between two truth rows: 1e-8 rad for 1 deg).  For logs whose stamps are not the truth's (jitter, a
    clock offset undone by the config)."""
    k = np.clip(np.searchsorted(truth.time, t) - 1, 0, len(truth) - 2)
    w = (t - truth.time[k]) / (truth.time[k + 1] - truth.time[k])

    def lin(a):
        return a[k] * (1 - w) + a[k + 1] * w if a.ndim == 1 else a[k] * (1 - w)[:, None] + a[k + 1] * w[:, None]
    C = truth.Cbn[k] * (1 - w)[:, None, None] + truth.Cbn[k + 1] * w[:, None, None]
    u, _, vt = np.linalg.svd(C)
    return Trajectory(np.asarray(t, dtype=float).copy(), lin(truth.lat), lin(truth.lon), lin(truth.height),
                      lin(truth.vel_n), u @ vt, source=truth.source)


def errors_at(traj: Trajectory, truth: Trajectory):
    """:func:`errors` of the rows of ``traj`` inside the truth's span against the truth interpolated there
    (:func:`truth_at`); returns ``(rows mask, dr, dv, phi)``."""
    m = (traj.time >= truth.time[0]) & (traj.time <= truth.time[-1])
    sub = Trajectory(traj.time[m], traj.lat[m], traj.lon[m], traj.height[m], traj.vel_n[m], traj.Cbn[m])
    return (m,) + errors(sub, truth_at(truth, sub.time))


def horizontal_rms(dr) -> float:
    return float(np.sqrt(np.mean(dr[:, 0] ** 2 + dr[:, 1] ** 2)))


def outage_mask(t_rel: np.ndarray, outages) -> np.ndarray:
    """Rows whose time since the start ``t_rel`` (s) lies inside one of the ``[start, end)`` windows."""
    inside = np.zeros(len(t_rel), bool)
    for a, b in outages:
        inside |= (t_rel >= a) & (t_rel < b)
    return inside


def outage_rms(traj: Trajectory, truth: Trajectory, outages) -> float:
    """Horizontal position RMS (m) of the rows of ``traj`` inside the GNSS outages ``[start, end)`` (s since
    the truth's first time), against the truth interpolated there (:func:`errors_at`)."""
    m, dr, _, _ = errors_at(traj, truth)
    return horizontal_rms(dr[outage_mask(traj.time[m] - truth.time[0], outages)])
