"""Rauch-Tung-Striebel smoother over the closed-loop filter's stored epochs.

The forward filter stores, at each measurement epoch and at least every ``smoother_interval`` s
(pseudo-epochs without a measurement), the covariance before (P-) and after (P+) its updates (upper
triangles), the integral of F since the previous epoch over F's sparsity pattern
(``Phi = exp(int F dt)``, to third order: the chain dr <- dv <- phi <- b_g is nilpotent of that
length) and the correction ``x`` it fed back into the nominal state.  Errors are "nominal minus true";
the nominal runs continuously from the corrected state after epoch k to the uncorrected one at epoch
k+1, whose smoothed error is therefore ``d_{k+1}^s + x_{k+1}``.  Backwards (Rauch, Tung, Striebel 1965;
Groves eq. 3.76 in error-state form):

    C_k   = P_k^+ Phi_k^T (P_{k+1}^-)^-1
    d_k^s = C_k (d_{k+1}^s + x_{k+1})            (the forward error estimate after feedback is 0)
    P_k^s = P_k^+ + C_k (P_{k+1}^s - P_{k+1}^-) C_k^T

starting from ``d^s = 0``, ``P^s = P^+`` at the last epoch, and restarting there after a reset
(heading initialization, rejection-run inflation, adaptive widening), where the filter's chain is
broken.  Between two epochs (at most ``smoother_interval`` apart, not across an outage) the smoothed
error of each output row goes linearly from ``d_k^s`` to ``d_{k+1}^s + x_{k+1}``; it is removed from
the forward nominal row like a filter correction.  Only the 12 covariance entries an output row needs
are kept per epoch (:func:`sinscli.fusion.kernel.row_variances`); nothing is allocated per epoch.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..nav.earth import radii
from ..nav.rotation import m_from_array, m_mul, rotvec_to_dcm_t
from .kernel import NVAR, row_variances
from .linalg import chol_solve_into, cholesky, rows_times
from .model import BA, BG, PHI, R, SA, SG, V

NPS = 12         # smoothed covariance entries kept per epoch: pos, vel diag, phi ee nn uu en


@njit(cache=True)
def _unpack(packed, k, nx, M):
    """Symmetric ``M`` from the upper triangle ``packed[k]`` (row by row)."""
    u = 0
    for i in range(nx):
        for j in range(i, nx):
            v = packed[k, u]
            M[i, j] = v
            M[j, i] = v
            u += 1


@njit(cache=True)
def _phi(ftk, ptr, col, nx, A, A2, Phi):
    """``Phi = I + A + A^2/2 + A^3/6`` of ``A = int F dt`` given over F's pattern (row operations)."""
    for i in range(nx):
        for j in range(nx):
            A[i, j] = 0.0
            A2[i, j] = 0.0
        for p in range(ptr[i], ptr[i + 1]):
            A[i, col[p]] = ftk[p]
    for i in range(nx):                       # A2 = A A
        for p in range(ptr[i], ptr[i + 1]):
            a = A[i, col[p]]
            c = col[p]
            for j in range(nx):
                A2[i, j] += a * A[c, j]
    for i in range(nx):                       # Phi = I + A + A2/2 + (A2 A)/6
        for j in range(nx):
            Phi[i, j] = A[i, j] + 0.5 * A2[i, j]
        Phi[i, i] += 1.0
        for c in range(nx):
            a = A2[i, c] / 6.0
            if a != 0.0:
                for p in range(ptr[c], ptr[c + 1]):
                    Phi[i, col[p]] += a * A[c, col[p]]


@njit(cache=True)
def rts_backward(ep_pm, ep_pp, ep_ft, ep_x, ep_reset, ptr, col, nx):
    """Smoothed errors ``d (E, nx)`` (of the corrected nominal at each epoch) and the ``NPS`` smoothed
    covariance entries of each epoch ``ps (E, NPS)``."""
    E = ep_x.shape[0]
    d = np.zeros((E, nx))
    ps = np.zeros((E, NPS))
    if E == 0:
        return d, ps
    Ps = np.empty((nx, nx))          # P^s_{k+1}
    Pp = np.empty((nx, nx))
    Pm = np.empty((nx, nx))
    A = np.empty((nx, nx))
    A2 = np.empty((nx, nx))
    Phi = np.empty((nx, nx))
    B = np.empty((nx, nx))
    C = np.empty((nx, nx))
    L = np.zeros((nx, nx))
    dm = np.empty(nx)
    _unpack(ep_pp, E - 1, nx, Ps)
    _keep(ps, E - 1, Ps)
    for k in range(E - 2, -1, -1):
        _unpack(ep_pp, k, nx, Pp)
        if ep_reset[k + 1] > 0.0:
            for i in range(nx):
                for j in range(nx):
                    Ps[i, j] = Pp[i, j]
            _keep(ps, k, Ps)
            continue
        _unpack(ep_pm, k + 1, nx, Pm)
        _phi(ep_ft[k + 1], ptr, col, nx, A, A2, Phi)
        # B = Phi P+; C^T = (P-)^-1 B
        rows_times(Phi, nx, Pp, nx, B)
        if not cholesky(Pm, nx, L):
            for i in range(nx):
                for j in range(nx):
                    Ps[i, j] = Pp[i, j]
            _keep(ps, k, Ps)
            continue
        chol_solve_into(L, nx, B)             # B <- (P-)^-1 Phi P+ = C^T
        for i in range(nx):
            for j in range(nx):
                C[i, j] = B[j, i]
        for i in range(nx):
            dm[i] = d[k + 1, i] + ep_x[k + 1, i]
        for i in range(nx):
            s = 0.0
            for j in range(nx):
                s += C[i, j] * dm[j]
            d[k, i] = s
        # P^s_k = P+ + C (P^s_{k+1} - P-) C^T
        for i in range(nx):
            for j in range(nx):
                Ps[i, j] -= Pm[i, j]
        rows_times(C, nx, Ps, nx, B)          # B = C D
        for i in range(nx):
            for j in range(i, nx):
                s = 0.0
                for c in range(nx):
                    s += B[i, c] * C[j, c]
                v = Pp[i, j] + s
                Ps[i, j] = v
                Ps[j, i] = v
        _keep(ps, k, Ps)
    return d, ps


@njit(cache=True)
def _keep(ps, k, P):
    for i in range(3):
        ps[k, i] = P[R + i, R + i]
        ps[k, 3 + i] = P[V + i, V + i]
        ps[k, 6 + i] = P[PHI + i, PHI + i]
    ps[k, 9] = P[PHI, PHI + 1]
    ps[k, 10] = P[PHI, PHI + 2]
    ps[k, 11] = P[PHI + 1, PHI + 2]


@njit(cache=True)
def apply_corrections(t_rows, lat, lon, h, vel, cbn, var, bias, ep_t, d, ps, ep_x, nx, fwd):
    """Remove the interpolated smoothed error from each output row (in place) and write its smoothed
    variances (:func:`sinscli.fusion.kernel.row_variances`)."""
    E = ep_t.shape[0]
    k = 0
    x = np.empty(nx)
    q = np.empty(NPS)
    for n in range(t_rows.shape[0]):
        t = t_rows[n]
        while k < E and ep_t[k] <= t:
            k += 1
        # epochs k-1 <= t < k
        if k >= E:
            continue                      # after the last epoch: the forward solution
        if k == 0:
            w = 1.0
            ka = 0
        else:
            w = (t - ep_t[k - 1]) / (ep_t[k] - ep_t[k - 1])
            ka = k - 1
        for i in range(nx):
            da = d[ka, i] if k > 0 else d[0, i] + ep_x[0, i]
            x[i] = (1.0 - w) * da + w * (d[k, i] + ep_x[k, i])
        for i in range(NPS):
            q[i] = (1.0 - w) * ps[ka, i] + w * ps[k, i]
        rm, rn = radii(np.sin(lat[n]))
        lat0 = lat[n]
        lat[n] = lat0 - x[R + 1] / (rm + h[n])
        lon[n] = lon[n] - x[R] / ((rn + h[n]) * np.cos(lat0))
        h[n] = h[n] - x[R + 2]
        for i in range(3):
            vel[n, i] -= x[V + i]
        c = m_mul(rotvec_to_dcm_t((x[PHI], x[PHI + 1], x[PHI + 2])), m_from_array(cbn[n]))
        for i in range(3):
            for j in range(3):
                cbn[n, i, j] = c[i][j]
            bias[n, i] += x[BG + i]
            bias[n, 3 + i] += x[BA + i]
            if nx > 15:
                bias[n, 6 + i] += x[SG + i]
                bias[n, 9 + i] += x[SA + i]
        row_variances(var, n, c, fwd, q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9],
                      var[n, NVAR - 1] >= 0.0)


def smooth_rows(time, lat, lon, h, vel, cbn, var, bias, epochs, ptr, col, nx, fwd):
    """Smooth the forward output rows in place (``epochs``: the stored arrays, in time order)."""
    if epochs is None or len(epochs[0]) == 0:
        return
    ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset = epochs
    d, ps = rts_backward(ep_pm, ep_pp, ep_ft, ep_x, ep_reset, ptr, col, nx)
    apply_corrections(time, lat, lon, h, vel, cbn, var, bias, ep_t, d, ps, ep_x, nx, fwd)
