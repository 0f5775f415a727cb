"""Rauch-Tung-Striebel smoother over the closed-loop filter's stored epochs.

The forward filter stores, at each measurement epoch and at least every ``smoother_interval`` s
(pseudo-epochs without a measurement), the covariance before (P-) and after (P+) its updates, the
integral of F since the previous epoch (``Phi = exp(int F dt)``, to third order) and the correction
``x`` it fed back into the nominal state.  Errors are "nominal minus true"; the nominal runs
continuously from the corrected state after epoch k to the uncorrected one at epoch k+1, whose
smoothed error is therefore ``d_{k+1}^s + x_{k+1}``.  Backwards (Rauch, Tung, Striebel 1965; Groves
eq. 3.76 in error-state form):

    C_k   = P_k^+ Phi_k^T (P_{k+1}^-)^-1
    d_k^s = C_k (d_{k+1}^s + x_{k+1})            (the forward error estimate after feedback is 0)
    P_k^s = P_k^+ + C_k (P_{k+1}^s - P_{k+1}^-) C_k^T

starting from ``d^s = 0``, ``P^s = P^+`` at the last epoch, and restarting there after a reset
(heading initialization, rejection-run inflation, adaptive widening), where the filter's chain is
broken.  Between two epochs (at most ``smoother_interval`` apart, not across an outage) the smoothed
error of each output row goes linearly from ``d_k^s`` to ``d_{k+1}^s + x_{k+1}``; it is removed from
the forward nominal row like a filter correction.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..nav.earth import radii
from ..nav.rotation import mm3, rotvec_to_dcm
from ..types import Trajectory
from .linalg import matmul, matvec, spd_solve
from .model import BA, BG, PHI, R, SA, SG, V


@njit(cache=True)
def rts_backward(ep_pm, ep_pp, ep_ft, ep_x, ep_reset):
    """Smoothed errors ``d (E, nx)`` (of the corrected nominal at each epoch) and covariances ``Ps``."""
    E, nx = ep_x.shape
    d = np.zeros((E, nx))
    Ps = np.empty((E, nx, nx))
    if E == 0:
        return d, Ps
    Ps[E - 1] = ep_pp[E - 1]
    I = np.eye(nx)
    for k in range(E - 2, -1, -1):
        if ep_reset[k + 1] > 0.0:
            Ps[k] = ep_pp[k]
            continue
        A = ep_ft[k + 1]
        A2 = matmul(A, A)
        Phi = I + A + 0.5 * A2 + matmul(A2, A) / 6.0
        Ct = spd_solve(ep_pm[k + 1], matmul(Phi, ep_pp[k]))    # C^T (P- and P+ symmetric)
        C = Ct.T.copy()
        dm = d[k + 1] + ep_x[k + 1]
        d[k] = matvec(C, dm)
        Pk = ep_pp[k] + matmul(matmul(C, Ps[k + 1] - ep_pm[k + 1]), Ct)
        Ps[k] = 0.5 * (Pk + Pk.T)
    return d, Ps


@njit(cache=True)
def apply_corrections(t_rows, lat, lon, h, vel, cbn, cov, bias, ep_t, d, Ps, ep_x, nx):
    """Remove the interpolated smoothed error from each output row (in place); smoothed covariance."""
    E = ep_t.shape[0]
    k = 0
    dm = np.zeros(nx)
    for n in range(t_rows.shape[0]):
        t = t_rows[n]
        while k < E and ep_t[k] <= t:
            k += 1
        # epochs k-1 <= t < k
        if k == 0:
            w = 1.0
            for i in range(nx):
                dm[i] = d[0, i] + ep_x[0, i]
            da = dm
            db = dm
            Pa = Ps[0]
            Pb = Ps[0]
        elif k >= E:
            continue                      # after the last epoch: the forward solution
        else:
            t0, t1 = ep_t[k - 1], ep_t[k]
            w = (t - t0) / (t1 - t0)
            for i in range(nx):
                dm[i] = d[k, i] + ep_x[k, i]
            da = d[k - 1]
            db = dm
            Pa = Ps[k - 1]
            Pb = Ps[k]
        x = (1.0 - w) * da + w * db
        P = (1.0 - w) * Pa + w * Pb
        rm, rn = radii(np.sin(lat[n]))
        lat0 = lat[n]
        lat[n] = lat0 - x[R + 1] / (rm + h[n])
        lon[n] = lon[n] - x[R] / ((rn + h[n]) * np.cos(lat0))
        h[n] = h[n] - x[R + 2]
        for i in range(3):
            vel[n, i] -= x[V + i]
        phi = np.array([x[PHI], x[PHI + 1], x[PHI + 2]])
        cbn[n] = mm3(rotvec_to_dcm(phi), np.ascontiguousarray(cbn[n]))
        for i in range(3):
            bias[n, i] += x[BG + i]
            bias[n, 3 + i] += x[BA + i]
            if nx > 15:
                bias[n, 6 + i] += x[SG + i]
                bias[n, 9 + i] += x[SA + i]
            cov[n, i] = P[R + i, R + i]
            cov[n, 3 + i] = P[V + i, V + i]
            if cov[n, 6 + 2] >= 0.0 or i < 2:
                cov[n, 6 + i] = P[PHI + i, PHI + i]
            bias[n, 12 + i] = P[BG + i, BG + i]
            bias[n, 15 + i] = P[BA + i, BA + i]
        cov[n, 9] = P[PHI, PHI + 1]
        cov[n, 10] = P[PHI, PHI + 2]
        cov[n, 11] = P[PHI + 1, PHI + 2]


def smooth_trajectory(traj: Trajectory, cov, bias, epochs, nx, conv):
    """The smoothed trajectory, covariance columns and sensor estimates at the forward rows."""
    if epochs is None or len(epochs[0]) == 0:
        return traj, cov, bias
    ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset = epochs
    d, Ps = rts_backward(ep_pm, ep_pp, ep_ft, ep_x, ep_reset)
    out = Trajectory(traj.time, traj.lat.copy(), traj.lon.copy(), traj.height.copy(), traj.vel_n.copy(),
                     np.ascontiguousarray(traj.Cbn).copy(), source=traj.source)
    cov = cov.copy()
    bias = bias.copy()
    apply_corrections(out.time, out.lat, out.lon, out.height, out.vel_n, out.Cbn, cov, bias, ep_t, d, Ps, ep_x, nx)
    return out, cov, bias
