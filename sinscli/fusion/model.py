"""Error-state model of the ENU strapdown equations: F, the discrete process noise, propagation of P.

State (15, or 21 with scale factors), every error "computed minus true":

    x = [dr (E, N, U m), dv (E, N, U m/s), phi (E, N, U rad), b_g (body rad/s), b_a (body m/s^2),
         s_g (body, 1), s_a (body, 1)]

with the computed attitude ``Cbn_c = (I - [phi x]) Cbn`` and the bias errors ``b_true - b_est`` (the
increments are compensated as ``(dtheta - b_g dt) / (1 + s_g)``, so the residual rate error is
``dw = x_bg + diag(w^b) x_sg``).  The phi-angle model of the mechanization of
:mod:`sinscli.nav.mechanization` (Groves ch. 14.2, Shin's thesis ch. 2.4, Yan's PSINS in ENU with the
position error in metres, R_m = RM + h, R_n = RN + h):

    dr'  = F_rr dr + dv
    dv'  = F_vr dr + F_vv dv + [f^n x] phi + Cbn (b_a + diag(f^b) s_a) + Cbn w_a
    phi' = F_pr dr + F_pv dv - [w_in^n x] phi - Cbn (b_g + diag(w^b) s_g) - Cbn w_g
    b'   = -b / tau + w_b              (first-order Gauss-Markov density 2 sigma^2/tau; the pipeline
                                        passes 1/tau = 0, a random walk: see filter_model)
    s'   = 0

    F_rr = [[vU/Rn - vN tanL/Rm, vE tanL/Rm, -vE/Rn], [0, vU/Rm, -vN/Rm], [0, 0, 0]]
    F_pv = A = [[0, -1/Rm, 0], [1/Rn, 0, 0], [tanL/Rn, 0, 0]]             (d w_en / d dv)
    F_pr = B = B_ie + B_en                                                  (d w_in / d dr)
    B_ie = [[0, 0, 0], [0, -W sinL/Rm, 0], [0, W cosL/Rm, 0]]
    B_en = [[0, 0, vN/Rm^2], [0, 0, -vE/Rn^2], [0, vE sec^2 L/(Rn Rm), -vE tanL/Rn^2]]
    F_vv = -[(2 w_ie + w_en) x] + [v x] A
    F_vr = [v x] (2 B_ie + B_en) + diag(0, 0, -dg/dh)                      (Coriolis, gravity gradient)

Process noise densities (rad^2/s, (m/s)^2/s): ARW^2 and VRW^2 rotated to ENU, ``2 sigma^2 / tau`` on
the biases, times ``q_scale`` (>= 1, raised when the innovations show the model too optimistic, see
:mod:`sinscli.fusion.kernel`).  Scale-factor and misalignment errors that a 15-state filter does not
estimate enter as white noise of density ``(sigma_sf^2 + sigma_mis^2) |w|^2 tau_c`` on phi and
``(..) |f^n - g^n|^2 tau_c`` on dv: a constant error ``sigma |w|`` over a manoeuvre of length tau_c
has the same variance; the part under gravity alone is a constant bias and is added to the initial
accelerometer bias variance instead.

Propagation: ``P <- (I + F T) P (I + F T)^T + Qd``, ``Qd = G Q G^T T``, with ``F P`` formed over
the non-zero entries of F only (a compressed-row pattern) and P kept exactly symmetric.
"""
import numpy as np
from numba import njit

from ..nav.earth import OMEGA_IE, radii

R, V, PHI, BG, BA, SG, SA = 0, 3, 6, 9, 12, 15, 18
NX15, NX21 = 15, 21


def sparsity(nx: int):
    """Compressed-row pattern ``(ptr, col)`` of F's possibly non-zero entries for ``nx`` states."""
    rows = []
    for i in range(nx):
        cols = set()
        if i < 3:                               # dr
            cols |= {0, 1, 2, V + i}
        elif i < 6:                             # dv
            cols |= set(range(0, 9)) | {BA, BA + 1, BA + 2}
            if nx == NX21:
                cols |= {SA, SA + 1, SA + 2}
        elif i < 9:                             # phi
            cols |= set(range(0, 9)) | {BG, BG + 1, BG + 2}
            if nx == NX21:
                cols |= {SG, SG + 1, SG + 2}
        elif i < 15:                            # biases: Gauss-Markov
            cols |= {i}
        rows.append(sorted(cols))
    ptr = np.zeros(nx + 1, dtype=np.int64)
    for i, c in enumerate(rows):
        ptr[i + 1] = ptr[i] + len(c)
    col = np.array([c for r in rows for c in r], dtype=np.int64)
    return ptr, col


@njit(cache=True)
def dgravity_dh(sin_lat, h):
    """``d g / d h`` of the FORMATS.md normal gravity (1/s^2): the vertical gravity gradient."""
    return (-0.0000030876910891 + 0.0000000043977311 * sin_lat * sin_lat) + 2.0 * 0.0000000000007211 * h


@njit(cache=True)
def build_F(F, nx, cbn, vel, lat, h, f_n, w_b, f_b, inv_tau_g, inv_tau_a):
    """Fill the non-zero entries of ``F`` (nx, nx) at the state (module docstring).

    ``cbn`` (3, 3) array, ``vel``/``f_n`` ENU, ``w_b``/``f_b`` body (compensated), ``inv_tau_*``
    (3,) arrays of 1/tau (0 for a random constant).
    """
    sl, cl = np.sin(lat), np.cos(lat)
    rm, rn = radii(sl)
    Rm, Rn = rm + h, rn + h
    tl = sl / cl
    vE, vN, vU = vel[0], vel[1], vel[2]
    wN, wU = OMEGA_IE * cl, OMEGA_IE * sl
    # w_en and w_in
    eE, eN, eU = -vN / Rm, vE / Rn, vE * tl / Rn
    iE, iN, iU = eE, wN + eN, wU + eU
    # A = d w_en / d dv, B = d w_in / d dr
    A = np.zeros((3, 3))
    A[0, 1] = -1.0 / Rm
    A[1, 0] = 1.0 / Rn
    A[2, 0] = tl / Rn
    B = np.zeros((3, 3))
    B[0, 2] = vN / (Rm * Rm)
    B[1, 1] = -OMEGA_IE * sl / Rm
    B[1, 2] = -vE / (Rn * Rn)
    B[2, 1] = OMEGA_IE * cl / Rm + vE / (cl * cl * Rn * Rm)
    B[2, 2] = -vE * tl / (Rn * Rn)
    B2 = B.copy()                               # 2 B_ie + B_en
    B2[1, 1] = 2.0 * B[1, 1]
    B2[2, 1] = 2.0 * OMEGA_IE * cl / Rm + vE / (cl * cl * Rn * Rm)
    # [v x]
    vx = np.array([[0.0, -vU, vN], [vU, 0.0, -vE], [-vN, vE, 0.0]])
    # F_rr
    F[0, 0] = vU / Rn - vN * tl / Rm
    F[0, 1] = vE * tl / Rm
    F[0, 2] = -vE / Rn
    F[1, 1] = vU / Rm
    F[1, 2] = -vN / Rm
    for i in range(3):
        F[i, V + i] = 1.0
    # F_vv = -[(2 w_ie + w_en) x] + [v x] A
    cE, cN, cU = eE, 2.0 * wN + eN, 2.0 * wU + eU
    for i in range(3):
        for j in range(3):
            s_vv = 0.0
            s_vr = 0.0
            for k in range(3):
                s_vv += vx[i, k] * A[k, j]
                s_vr += vx[i, k] * B2[k, j]
            F[V + i, V + j] = s_vv
            F[V + i, R + j] = s_vr
            F[PHI + i, V + j] = A[i, j]
            F[PHI + i, R + j] = B[i, j]
            F[V + i, BA + j] = cbn[i, j]
            F[PHI + i, BG + j] = -cbn[i, j]
            if nx > 15:
                F[V + i, SA + j] = cbn[i, j] * f_b[j]
                F[PHI + i, SG + j] = -cbn[i, j] * w_b[j]
    F[V + 0, V + 1] += cU
    F[V + 0, V + 2] -= cN
    F[V + 1, V + 0] -= cU
    F[V + 1, V + 2] += cE
    F[V + 2, V + 0] += cN
    F[V + 2, V + 1] -= cE
    F[V + 2, R + 2] += -dgravity_dh(sl, h)
    # F_v,phi = [f^n x]
    F[V + 0, PHI + 0] = 0.0
    F[V + 0, PHI + 1] = -f_n[2]
    F[V + 0, PHI + 2] = f_n[1]
    F[V + 1, PHI + 0] = f_n[2]
    F[V + 1, PHI + 1] = 0.0
    F[V + 1, PHI + 2] = -f_n[0]
    F[V + 2, PHI + 0] = -f_n[1]
    F[V + 2, PHI + 1] = f_n[0]
    F[V + 2, PHI + 2] = 0.0
    # F_phi,phi = -[w_in x]
    F[PHI + 0, PHI + 0] = 0.0
    F[PHI + 0, PHI + 1] = iU
    F[PHI + 0, PHI + 2] = -iN
    F[PHI + 1, PHI + 0] = -iU
    F[PHI + 1, PHI + 1] = 0.0
    F[PHI + 1, PHI + 2] = iE
    F[PHI + 2, PHI + 0] = iN
    F[PHI + 2, PHI + 1] = -iE
    F[PHI + 2, PHI + 2] = 0.0
    for i in range(3):
        F[BG + i, BG + i] = -inv_tau_g[i]
        F[BA + i, BA + i] = -inv_tau_a[i]


@njit(cache=True)
def propagate(P, F, ptr, col, nx, T, qd, M):
    """``P <- (I + F T) P (I + F T)^T + Qd`` over F's pattern; ``qd`` (nx, nx) is Qd, ``M`` scratch.

    ``M = F P`` costs (non-zeros of F) x nx; the result is formed on the upper triangle and
    mirrored, so P stays exactly symmetric.
    """
    for i in range(nx):
        for j in range(nx):
            M[i, j] = 0.0
        for p in range(ptr[i], ptr[i + 1]):
            c = col[p]
            f = F[i, c]
            if f != 0.0:
                for j in range(nx):
                    M[i, j] += f * P[c, j]
    T2 = T * T
    for i in range(nx):
        for j in range(i, nx):
            # (F P F^T)_ij = sum_c F[i, c] M[j, c]
            fpf = 0.0
            for p in range(ptr[i], ptr[i + 1]):
                c = col[p]
                fpf += F[i, c] * M[j, c]
            v = P[i, j] + T * (M[i, j] + M[j, i]) + T2 * fpf + qd[i, j]
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def process_noise(qd, nx, cbn, T, q_scale, arw2, vrw2, q_bg, q_ba, q_att_extra, q_vel_extra):
    """Qd = G Q G^T T into ``qd`` (nx, nx): ``Cbn diag(arw^2) Cbn^T`` on phi, ``Cbn diag(vrw^2) Cbn^T``
    on dv (plus the isotropic scale-factor/misalignment densities ``q_*_extra``), ``q_bg``/``q_ba``
    (3,) Gauss-Markov densities on the biases; all times ``q_scale``."""
    s = T * q_scale
    for i in range(3):
        for j in range(3):
            a = 0.0
            b = 0.0
            for k in range(3):
                a += cbn[i, k] * arw2[k] * cbn[j, k]
                b += cbn[i, k] * vrw2[k] * cbn[j, k]
            qd[PHI + i, PHI + j] = a * s
            qd[V + i, V + j] = b * s
        qd[PHI + i, PHI + i] += q_att_extra * s
        qd[V + i, V + i] += q_vel_extra * s
        qd[BG + i, BG + i] = q_bg[i] * s
        qd[BA + i, BA + i] = q_ba[i] * s
