"""Rauch-Tung-Striebel smoother over the closed-loop filter's stored epochs.

The forward filter stores, at each measurement epoch and at least every ``smoother_interval`` s
(pseudo-epochs without a measurement), the covariance before (P-) and after (P+) its updates (upper
triangles), the transition matrix since the previous epoch (the product of the very ``I + F T`` P was
propagated with, :func:`sinscli.fusion.model.transition_step`, so that ``P^- = Phi P^+ Phi^T + Q`` holds
with a positive semi-definite Q up to rounding) and the correction ``x`` it fed back into the nominal
state.  Errors are "nominal minus true";
the nominal runs continuously from the corrected state after epoch k to the uncorrected one at epoch
k+1, whose smoothed error is therefore ``d_{k+1}^s + x_{k+1}``.  Backwards (Rauch, Tung, Striebel 1965;
Groves eq. 3.76 in error-state form):

    C_k   = P_k^+ Phi_k^T (P_{k+1}^-)^-1
    d_k^s = C_k (d_{k+1}^s + x_{k+1})            (the forward error estimate after feedback is 0)
    P_k^s = P_k^+ + C_k (P_{k+1}^s - P_{k+1}^-) C_k^T
          = J_k P_k^+ J_k^T + C_k (Q_k + P_{k+1}^s) C_k^T,   J_k = I - C_k Phi_k,
            Q_k = P_{k+1}^- - Phi_k P_k^+ Phi_k^T

The second (Joseph) form is the one computed, from the LDL^T factors of ``P_k^+`` and of
``Q_k + P_{k+1}^s`` with their pivots kept non-negative: a sum of two Gram matrices, positive
semi-definite by construction, whatever the rounding of C (the first form subtracts two large
matrices and lost definiteness in long outages and with 21 states: NaN sigmas).  The gain is solved
through the Cholesky factor of the Jacobi-scaled ``P^-`` (a state held out of the filter, zero
variance, excluded).  The guard is measured and reported: pivots clipped (negative beyond 1e-12 of
their diagonal), the worst of them, gains that needed a ridge (:func:`rts_backward`).

The recursion starts from ``d^s = 0``, ``P^s = P^+`` at the last epoch, and restarting there after a reset
(heading initialization, rejection-run inflation), where the filter's chain is broken.  Between two epochs (at most ``smoother_interval`` apart, not across an outage) the smoothed
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
from ..nav.linalg import gram_add, ldl_psd, rows_times, scaled_solve, times_lower
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
def _phi(ftk, ncore, nx, Phi, clk=-1, clone=-1):
    """The transition matrix between two epochs from its stored form
    (:func:`sinscli.fusion.kernel._store_epoch`): the navigation rows over the core states, then the
    diagonal of the other rows, then with a receiver clock (bias state ``clk``) its bias-drift entry, then with
    TDCP clones (states ``clone`` ..) their 4 full rows (:mod:`sinscli.fusion.tdcp`)."""
    for i in range(nx):
        for j in range(nx):
            Phi[i, j] = 0.0
    u = 0
    for i in range(9):
        for j in range(ncore):
            Phi[i, j] = ftk[u]
            u += 1
    for i in range(9, nx):
        Phi[i, i] = ftk[u]
        u += 1
    if clk >= 0:
        Phi[clk, clk + 1] = ftk[u]
        u += 1
    if clone >= 0:
        for i in range(clone, clone + 4):
            for j in range(nx):
                Phi[i, j] = ftk[u]
                u += 1


@njit(cache=True)
def rts_backward(ep_pm, ep_pp, ep_ft, ep_x, ep_reset, ncore, nx, clk=-1, clone=-1):
    """Smoothed errors ``d (E, nx)`` (of the corrected nominal at each epoch), the ``NPS`` smoothed
    covariance entries of each epoch ``ps (E, NPS)`` and the guard's record ``guard (6,)``: pivots
    clipped (not PSD beyond rounding), the most negative pivot relative to its diagonal, gains solved
    with a ridge, epochs smoothed, the epochs of the first clipped pivot and of the worst (-1: none).

    The covariance in factored Joseph form (module docstring): with ``J = I - C Phi`` and
    ``N = Q + P^s_{k+1} = P^-_{k+1} + P^s_{k+1} - Phi P^+_k Phi^T``,

        P^s_k = J P^+_k J^T + C N C^T = (J L1) D1 (J L1)^T + (C L2) D2 (C L2)^T

    with ``P^+_k = L1 D1 L1^T`` and ``N = L2 D2 L2^T`` factored with non-negative pivots
    (:func:`~sinscli.nav.linalg.ldl_psd`): a sum of Gram matrices, positive semi-definite by
    construction and with a non-negative diagonal exactly, whatever the rounding of the gain ``C``.
    (Algebraically it is the textbook ``P^+ + C (P^s - P^-) C^T``, whose subtraction loses definiteness
    when P^- is large against P^s: a long outage, an ill-conditioned 21-state P.)"""
    E = ep_x.shape[0]
    d = np.zeros((E, nx))
    ps = np.zeros((E, NPS))
    guard = np.zeros(6)
    guard[4] = -1.0
    if E == 0:
        return d, ps, guard
    Ps = np.empty((nx, nx))          # P^s_{k+1}, then P^s_k
    Pp = np.empty((nx, nx))
    Pm = np.empty((nx, nx))
    A = np.empty((nx, nx))
    A2 = np.empty((nx, nx))
    Phi = np.empty((nx, nx))
    B = np.empty((nx, nx))
    CT = np.empty((nx, nx))
    N = np.empty((nx, nx))
    G = np.empty((nx, nx))
    L = np.zeros((nx, nx))
    Dg = np.empty(nx)
    sc = np.empty(nx)
    dm = np.empty(nx)
    diag_row = np.empty(nx, dtype=np.bool_)
    tol = 1e-12
    _unpack(ep_pp, E - 1, nx, Ps)
    _keep(ps, E - 1, Ps)
    for k in range(E - 2, -1, -1):
        _unpack(ep_pp, k, nx, Pp)
        if ep_reset[k + 1] > 0.0:    # the filter's chain is broken here: restart from the filtered state
            for i in range(nx):
                for j in range(nx):
                    Ps[i, j] = Pp[i, j]
            _keep(ps, k, Ps)
            continue
        guard[3] += 1.0
        _unpack(ep_pm, k + 1, nx, Pm)
        _phi(ep_ft[k + 1], ncore, nx, Phi, clk, clone)
        _hold_out(Pp, Pm, Ps, Phi, nx)
        for i in range(nx):                   # rows of Phi that are diagonal (sensor states)
            diag_row[i] = True
            for j in range(nx):
                if j != i and Phi[i, j] != 0.0:
                    diag_row[i] = False
                    break
        rows_times(Phi, nx, Pp, nx, B)        # B = Phi P+
        for i in range(nx):                   # A <- B^T = P+ Phi^T
            for j in range(nx):
                A[i, j] = B[j, i]
        rows_times(Phi, nx, A, nx, A2)        # A2 = Phi P+ Phi^T
        for i in range(nx):                   # N = P- + P^s_{k+1} - Phi P+ Phi^T
            for j in range(nx):
                N[i, j] = Pm[i, j] + Ps[i, j] - 0.5 * (A2[i, j] + A2[j, i])
        for i in range(nx):
            for j in range(nx):
                CT[i, j] = B[i, j]
        ridge = scaled_solve(Pm, nx, CT, A, L, sc)    # CT = (P-)^+ Phi P+ = C^T
        if ridge < 0.0:                       # not even with a ridge: no smoothing across this epoch
            guard[2] += 1.0
            for i in range(nx):
                for j in range(nx):
                    Ps[i, j] = Pp[i, j]
            _keep(ps, k, Ps)
            continue
        if ridge > 0.0:
            guard[2] += 1.0
        for i in range(nx):
            dm[i] = d[k + 1, i] + ep_x[k + 1, i]
        for i in range(nx):                   # d_k = C (d_{k+1} + x_{k+1})
            s = 0.0
            for j in range(nx):
                s += CT[j, i] * dm[j]
            d[k, i] = s
        for i in range(nx):                   # B <- J = I - C Phi
            for j in range(nx):
                B[i, j] = 0.0
            for kk in range(nx):
                c = CT[kk, i]
                if c == 0.0:
                    continue
                if diag_row[kk]:
                    B[i, kk] -= c * Phi[kk, kk]
                else:
                    for j in range(nx):
                        B[i, j] -= c * Phi[kk, j]
            B[i, i] += 1.0
        cl, worst = ldl_psd(Pp, nx, L, Dg, tol)
        _guard(guard, k, cl, worst)
        times_lower(B, L, nx, G)              # G = J L1
        gram_add(G, Dg, nx, Ps, True)
        cl, worst = ldl_psd(N, nx, L, Dg, tol)
        _guard(guard, k, cl, worst)
        for i in range(nx):                   # A <- C
            for j in range(nx):
                A[i, j] = CT[j, i]
        times_lower(A, L, nx, G)              # G = C L2
        gram_add(G, Dg, nx, Ps, False)
        _keep(ps, k, Ps)
    return d, ps, guard


@njit(cache=True)
def _guard(guard, k, clipped, worst):
    """Count the pivots clipped at epoch ``k``; keep the worst and the epochs of the first and the worst."""
    if clipped == 0:
        return
    guard[0] += clipped
    if worst < guard[1]:
        guard[1] = worst
        guard[5] = k
    guard[4] = k          # walking backwards: the last written is the first in time


@njit(cache=True)
def _hold_out(Pp, Pm, Ps, Phi, nx):
    """A state held out of the filter at these epochs (zero variance before or after the update: the
    heading before the GNSS course gives it) is left out of the smoothing step: its rows and columns are
    zero in the covariances and in the transition matrix, so that no factor sees the propagation's
    couplings of a state the filter does not carry."""
    for i in range(nx):
        if Pp[i, i] <= 0.0 or Pm[i, i] <= 0.0:
            for j in range(nx):
                Pp[i, j] = 0.0
                Pp[j, i] = 0.0
                Pm[i, j] = 0.0
                Pm[j, i] = 0.0
                Ps[i, j] = 0.0
                Ps[j, i] = 0.0
                Phi[i, j] = 0.0
                Phi[j, i] = 0.0


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
def apply_corrections(t_rows, lat, lon, h, vel, cbn, var, bias, ep_t, d, ps, ep_x, ncore, nx, fwd):
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
            if ncore > 15:
                bias[n, 6 + i] += x[SG + i]
                bias[n, 9 + i] += x[SA + i]
        row_variances(var, n, c, fwd, q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9],
                      var[n, NVAR - 1] >= 0.0)


def smooth_rows(time, lat, lon, h, vel, cbn, var, bias, epochs, ncore, nx, fwd, clk=-1, clone=-1):
    """Smooth the forward output rows in place (``epochs``: the stored arrays, in time order; ``clk`` the
    receiver clock's bias state, ``clone`` the first TDCP clone state, -1 none)."""
    if epochs is None or len(epochs[0]) == 0:
        g = np.zeros(6)
        g[4] = g[5] = -1.0
        return g
    ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset = epochs
    d, ps, guard = rts_backward(ep_pm, ep_pp, ep_ft, ep_x, ep_reset, ncore, nx, clk, clone)
    apply_corrections(time, lat, lon, h, vel, cbn, var, bias, ep_t, d, ps, ep_x, ncore, nx, fwd)
    return guard
