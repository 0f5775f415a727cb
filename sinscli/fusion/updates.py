"""Measurement updates of the error-state filter: the models (H, innovation) and one safe update.

Innovations are "computed minus measured", so that ``z = H x + noise`` with ``x`` the error state of
:mod:`sinscli.fusion.model` (computed minus true).  Models (Groves 14.3, KF-GINS):

* GNSS position of the antenna at the lever arm ``l^b``: ``z = r_c + Cbn l - r_gnss`` (ENU metres,
  the latitude/longitude difference scaled by the radii), ``H = [I, 0, [(Cbn l) x], 0 ...]``;
* GNSS velocity of the antenna: ``v_ant = v + Cbn (w_ib^b x l) - w_in^n x (Cbn l)``,
  ``H = [0, I, [(Cbn (w x l)) x], -Cbn [l x], 0 ...]``;
* ZUPT: ``z = v_c``, ``H = [0, I, 0 ...]``; ZARU: ``z = w_c - Cbn^T w_ie^n``, ``H = [.., I (b_g), ..]``;
* body velocity (odometry, NHC on the lateral and vertical axes): ``v^b = Cbn^T v``,
  ``z = v^b_c - v^b_meas``, ``H = [0, Cbn^T, -Cbn^T [v x], 0 ...]`` (rows of the constrained axes).

:func:`innovation_covariance` and :func:`nis_of` give the innovation covariance and the normalized
innovation squared of the whole vector (the kernel gates, weights and adapts on them,
:mod:`sinscli.fusion.kernel`); :func:`kalman_apply` updates in Joseph form
``P = (I - K H) P (I - K H)^T + K R K^T`` (kept symmetric).
"""
from numba import njit

from ..nav.linalg import inv_small, rows_times


@njit(cache=True)
def innovation_covariance(P, nx, H, r, m, HP, S):
    """``S = H P H^T + diag(r)`` of ``m`` components (an update's: <= 3; the TDCP slip test and clone, more);
    ``HP`` (>= m, nx) keeps ``H P``."""
    rows_times(H, m, P, nx, HP)                 # HP = H P  (= (P H^T)^T, P symmetric)
    for a in range(m):
        for b in range(m):
            s = 0.0
            for j in range(nx):
                s += HP[a, j] * H[b, j]
            S[a, b] = s
        S[a, a] += r[a]


@njit(cache=True)
def nis_of(S, z, m, Si):
    """The normalized innovation squared ``z^T S^-1 z`` (``Si`` receives ``S^-1``)."""
    inv_small(S, m, Si)
    nis = 0.0
    for a in range(m):
        for b in range(m):
            nis += z[a] * Si[a, b] * z[b]
    return nis


@njit(cache=True)
def kalman_apply(P, nx, H, z, r, m, x, HP, KT, A, Si):
    """The update with ``HP = H P`` and ``Si = S^-1`` of :func:`innovation_covariance`/:func:`nis_of`:
    ``x = K z`` and P in Joseph form ``(I - K H) P (I - K H)^T + K R K^T`` (kept symmetric).  ``KT``
    (3, nx), ``A`` (nx, nx) scratch; ``HP`` is overwritten."""
    for a in range(m):                          # K^T = S^-1 H P
        for j in range(nx):
            s = 0.0
            for b in range(m):
                s += Si[a, b] * HP[b, j]
            KT[a, j] = s
    for i in range(nx):
        s = 0.0
        for a in range(m):
            s += KT[a, i] * z[a]
        x[i] = s
    # Joseph form: A = (I - K H) P = P - K (H P); P' = A - (A H^T) K^T + K R K^T
    for i in range(nx):
        for j in range(nx):
            s = P[i, j]
            for a in range(m):
                s -= KT[a, i] * HP[a, j]
            A[i, j] = s
    for a in range(m):                          # HP <- (A H^T)^T, no longer needed as H P
        for i in range(nx):
            s = 0.0
            for j in range(nx):
                s += A[i, j] * H[a, j]
            HP[a, i] = s
    for i in range(nx):
        for j in range(i, nx):
            s = A[i, j]
            s2 = A[j, i]
            for a in range(m):
                s += -HP[a, i] * KT[a, j] + KT[a, i] * r[a] * KT[a, j]
                s2 += -HP[a, j] * KT[a, i] + KT[a, j] * r[a] * KT[a, i]
            v = 0.5 * (s + s2)
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def skew_into(H, row0, col0, v, sign):
    """Write ``sign [v x]`` into ``H[row0:row0+3, col0:col0+3]``."""
    H[row0 + 0, col0 + 1] = -sign * v[2]
    H[row0 + 0, col0 + 2] = sign * v[1]
    H[row0 + 1, col0 + 0] = sign * v[2]
    H[row0 + 1, col0 + 2] = -sign * v[0]
    H[row0 + 2, col0 + 0] = -sign * v[1]
    H[row0 + 2, col0 + 1] = sign * v[0]
