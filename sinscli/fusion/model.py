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

Propagation: ``P <- (I + F T) P (I + F T)^T + Qd``, ``Qd = G Q G^T T``, formed on F's 3x3 blocks
(:func:`f_blocks`, tuples on the stack) by :func:`propagate`, which skips F's zero entries and keeps P
exactly symmetric; :func:`add_process_noise` adds Qd in place.  :func:`transition_step` accumulates the
product of the same ``I + F T`` between two smoother epochs (the smoother's Phi).
"""
import numpy as np
from numba import njit

from ..nav.earth import OMEGA_IE, radii

R, V, PHI, BG, BA, SG, SA = 0, 3, 6, 9, 12, 15, 18
NX15, NX21 = 15, 21


@njit(cache=True)
def dgravity_dh(sin_lat, h):
    """``d g / d h`` of the docs/formats.md normal gravity (1/s^2): the vertical gravity gradient."""
    return (-0.0000030876910891 + 0.0000000043977311 * sin_lat * sin_lat) + 2.0 * 0.0000000000007211 * h


@njit(cache=True)
def f_blocks(c, vel, lat, h, f_n, w_b, f_b):
    """The non-zero 3x3 blocks of F at the state (module docstring), as tuples (no allocation):
    ``(F_rr, F_vr, F_vv, F_vphi, F_phir, F_phiv, F_phiphi, Cbn, Cbn diag(f^b), -Cbn diag(w^b))``.

    ``c`` is Cbn and ``vel``/``f_n`` (ENU), ``w_b``/``f_b`` (body, compensated) 3-tuples.  F_rv = I,
    F_v,ba = Cbn, F_phi,bg = -Cbn; the last two blocks are the scale-factor columns of 21 states.
    """
    sl, cl = np.sin(lat), np.cos(lat)
    rm, rn = radii(sl)
    Rm, Rn = rm + h, rn + h
    tl = sl / cl
    vE, vN, vU = vel[0], vel[1], vel[2]
    wN, wU = OMEGA_IE * cl, OMEGA_IE * sl
    eE, eN, eU = -vN / Rm, vE / Rn, vE * tl / Rn         # w_en
    iN, iU = wN + eN, wU + eU                              # w_in (east: eE)
    # A = d w_en / d dv: A01 = -1/Rm, A10 = 1/Rn, A20 = tanL/Rn
    a01, a10, a20 = -1.0 / Rm, 1.0 / Rn, tl / Rn
    # B = d w_in / d dr: B02, B11, B12, B21, B22; B2 = 2 B_ie + B_en (Coriolis) differs in B11, B21
    b02 = vN / (Rm * Rm)
    b11 = -OMEGA_IE * sl / Rm
    b12 = -vE / (Rn * Rn)
    ben21 = vE / (cl * cl * Rn * Rm)
    b21 = OMEGA_IE * cl / Rm + ben21
    b22 = -vE * tl / (Rn * Rn)
    c11 = 2.0 * b11
    c21 = 2.0 * OMEGA_IE * cl / Rm + ben21
    frr = ((vU / Rn - vN * tl / Rm, vE * tl / Rm, -vE / Rn), (0.0, vU / Rm, -vN / Rm), (0.0, 0.0, 0.0))
    # F_vr = [v x] B2 (columns N, U) + gravity gradient; [v x] = [[0, -vU, vN], [vU, 0, -vE], [-vN, vE, 0]]
    fvr = ((0.0, -vU * c11 + vN * c21, -vU * b12 + vN * b22),
           (0.0, -vE * c21, vU * b02 - vE * b22),
           (0.0, vE * c11, -vN * b02 + vE * b12 - dgravity_dh(sl, h)))
    # F_vv = [v x] A - [(2 w_ie + w_en) x]
    cE, cN, cU = eE, 2.0 * wN + eN, 2.0 * wU + eU
    fvv = ((-vU * a10 + vN * a20, cU, -cN), (-vE * a20 - cU, vU * a01, cE), (vE * a10 + cN, -vN * a01 - cE, 0.0))
    fvp = ((0.0, -f_n[2], f_n[1]), (f_n[2], 0.0, -f_n[0]), (-f_n[1], f_n[0], 0.0))       # [f^n x]
    fpr = ((0.0, 0.0, b02), (0.0, b11, b12), (0.0, b21, b22))                            # B
    fpv = ((0.0, a01, 0.0), (a10, 0.0, 0.0), (a20, 0.0, 0.0))                            # A
    fpp = ((0.0, iU, -iN), (-iU, 0.0, eE), (iN, -eE, 0.0))                              # -[w_in x]
    csa = ((c[0][0] * f_b[0], c[0][1] * f_b[1], c[0][2] * f_b[2]), (c[1][0] * f_b[0], c[1][1] * f_b[1],
           c[1][2] * f_b[2]), (c[2][0] * f_b[0], c[2][1] * f_b[1], c[2][2] * f_b[2]))
    csg = ((-c[0][0] * w_b[0], -c[0][1] * w_b[1], -c[0][2] * w_b[2]), (-c[1][0] * w_b[0], -c[1][1] * w_b[1],
           -c[1][2] * w_b[2]), (-c[2][0] * w_b[0], -c[2][1] * w_b[1], -c[2][2] * w_b[2]))
    return frr, fvr, fvv, fvp, fpr, fpv, fpp, c, csa, csg


@njit(cache=True)
def write_F(F, nx, fb, inv_tau_g, inv_tau_a):
    """The dense F (nx, nx) from :func:`f_blocks` (entries outside the pattern stay zero); ``inv_tau_*``
    the bias rows' 1/tau (0: a random walk)."""
    frr, fvr, fvv, fvp, fpr, fpv, fpp, c, csa, csg = fb
    for i in range(3):
        F[R + i, V + i] = 1.0
        for j in range(3):
            F[R + i, R + j] = frr[i][j]
            F[V + i, R + j] = fvr[i][j]
            F[V + i, V + j] = fvv[i][j]
            F[V + i, PHI + j] = fvp[i][j]
            F[PHI + i, R + j] = fpr[i][j]
            F[PHI + i, V + j] = fpv[i][j]
            F[PHI + i, PHI + j] = fpp[i][j]
            F[V + i, BA + j] = c[i][j]
            F[PHI + i, BG + j] = -c[i][j]
            if nx > 15:
                F[V + i, SA + j] = csa[i][j]
                F[PHI + i, SG + j] = csg[i][j]
        F[BG + i, BG + i] = -inv_tau_g[i]
        F[BA + i, BA + i] = -inv_tau_a[i]


def build_F(F, nx, c, vel, lat, h, f_n, w_b, f_b, inv_tau_g, inv_tau_a):
    """Dense F at the state (for tests and the docs): :func:`write_F` of :func:`f_blocks`."""
    write_F(F, nx, f_blocks(c, vel, lat, h, f_n, w_b, f_b), inv_tau_g, inv_tau_a)


# ---- 3x3 block arithmetic on tuples (rows of 3-tuples) for the propagation ----
@njit(cache=True)
def _r(a, x):
    return (a * x[0], a * x[1], a * x[2])


@njit(cache=True)
def _r2(a, x, b, y):
    return (a * x[0] + b * y[0], a * x[1] + b * y[1], a * x[2] + b * y[2])


@njit(cache=True)
def _r3(a, x, b, y, c, z):
    return (a * x[0] + b * y[0] + c * z[0], a * x[1] + b * y[1] + c * z[1], a * x[2] + b * y[2] + c * z[2])


@njit(cache=True)
def _dense(f, m):
    """``f m`` (3x3 blocks)."""
    return (_r3(f[0][0], m[0], f[0][1], m[1], f[0][2], m[2]), _r3(f[1][0], m[0], f[1][1], m[1], f[1][2], m[2]),
            _r3(f[2][0], m[0], f[2][1], m[1], f[2][2], m[2]))


@njit(cache=True)
def _nocol0(f, m):
    """``f m`` for an ``f`` whose first column is zero (F_vr, F_phir)."""
    return (_r2(f[0][1], m[1], f[0][2], m[2]), _r2(f[1][1], m[1], f[1][2], m[2]), _r2(f[2][1], m[1], f[2][2], m[2]))


@njit(cache=True)
def _nodiag(f, m):
    """``f m`` for an ``f`` with a zero diagonal (the skew blocks)."""
    return (_r2(f[0][1], m[1], f[0][2], m[2]), _r2(f[1][0], m[0], f[1][2], m[2]), _r2(f[2][0], m[0], f[2][1], m[1]))


@njit(cache=True)
def _add_row(a, b, c, d, e, s, m):
    return (m[0] + s * (a[0] + b[0] + c[0] + d[0] + e[0]), m[1] + s * (a[1] + b[1] + c[1] + d[1] + e[1]),
            m[2] + s * (a[2] + b[2] + c[2] + d[2] + e[2]))


@njit(cache=True)
def _add(a, b, c, d, e, s, m):
    """``m + s (a + b + c + d + e)`` (3x3 blocks)."""
    return (_add_row(a[0], b[0], c[0], d[0], e[0], s, m[0]), _add_row(a[1], b[1], c[1], d[1], e[1], s, m[1]),
            _add_row(a[2], b[2], c[2], d[2], e[2], s, m[2]))


@njit(cache=True)
def _phi_r(fb, T, mr, mv):
    """Block row dr of ``Phi M``: ``M_r + T (F_rr M_r + M_v)``."""
    frr = fb[0]
    a = (_r3(frr[0][0], mr[0], frr[0][1], mr[1], frr[0][2], mr[2]), _r2(frr[1][1], mr[1], frr[1][2], mr[2]),
         (0.0, 0.0, 0.0))
    return (_r2(1.0, mr[0], T, _r2(1.0, a[0], 1.0, mv[0])), _r2(1.0, mr[1], T, _r2(1.0, a[1], 1.0, mv[1])),
            _r2(1.0, mr[2], T, mv[2]))


@njit(cache=True)
def _phi_v(fb, T, mr, mv, mp, ma, msa, sf):
    """Block row dv of ``Phi M``: ``M_v + T (F_vr M_r + F_vv M_v + [f x] M_phi + Cbn M_ba (+ Cbn f^b M_sa))``."""
    e = _dense(fb[8], msa) if sf else ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    return _add(_nocol0(fb[1], mr), _dense(fb[2], mv), _nodiag(fb[3], mp), _dense(fb[7], ma), e, T, mv)


@njit(cache=True)
def _phi_p(fb, T, mr, mv, mp, mg, msg, sf):
    """Block row phi of ``Phi M``: ``M_phi + T (F_phir M_r + A M_v - [w_in x] M_phi - Cbn M_bg (- ..))``."""
    fpv = fb[5]
    av = (_r(fpv[0][1], mv[1]), _r(fpv[1][0], mv[0]), _r(fpv[2][0], mv[0]))
    cg = _dense(fb[7], mg)
    ncg = ((-cg[0][0], -cg[0][1], -cg[0][2]), (-cg[1][0], -cg[1][1], -cg[1][2]), (-cg[2][0], -cg[2][1], -cg[2][2]))
    e = _dense(fb[9], msg) if sf else ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    return _add(_nocol0(fb[4], mr), av, _nodiag(fb[6], mp), ncg, e, T, mp)


@njit(cache=True)
def _blk(P, i0, j0, tr):
    """The 3x3 block of ``P`` at ``(i0, j0)``, transposed with ``tr``."""
    if tr:
        return ((P[i0, j0], P[i0 + 1, j0], P[i0 + 2, j0]), (P[i0, j0 + 1], P[i0 + 1, j0 + 1], P[i0 + 2, j0 + 1]),
                (P[i0, j0 + 2], P[i0 + 1, j0 + 2], P[i0 + 2, j0 + 2]))
    return ((P[i0, j0], P[i0, j0 + 1], P[i0, j0 + 2]), (P[i0 + 1, j0], P[i0 + 1, j0 + 1], P[i0 + 1, j0 + 2]),
            (P[i0 + 2, j0], P[i0 + 2, j0 + 1], P[i0 + 2, j0 + 2]))


@njit(cache=True)
def _put(P, i0, j0, b, sym):
    """Write block ``b`` at ``(i0, j0)``; with ``sym`` also its transpose at ``(j0, i0)`` (a diagonal
    block is symmetrized)."""
    for i in range(3):
        for j in range(3):
            if sym and i0 == j0:
                v = 0.5 * (b[i][j] + b[j][i])
                P[i0 + i, j0 + j] = v
            else:
                P[i0 + i, j0 + j] = b[i][j]
                if sym:
                    P[j0 + j, i0 + i] = b[i][j]


@njit(cache=True)
def _phi_apply(src, X, tr, fb, T, sf, out, sym, first):
    """The navigation block rows of block column ``X`` of ``Phi M`` into ``out``, with ``M_ZX`` the
    block (Z, X) of ``src`` or, with ``tr``, the transposed block (X, Z).  Rows ``dr, dv, phi`` are
    written from ``first, first + 1, first + 2`` on (with ``sym`` only the upper blocks, row <= X,
    each with its mirror)."""
    o = 3 * X
    z = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    mr = _blk(src, o, 0, True) if tr else _blk(src, 0, o, False)
    mv = _blk(src, o, V, True) if tr else _blk(src, V, o, False)
    mp = _blk(src, o, PHI, True) if tr else _blk(src, PHI, o, False)
    mg = _blk(src, o, BG, True) if tr else _blk(src, BG, o, False)
    ma = _blk(src, o, BA, True) if tr else _blk(src, BA, o, False)
    msg = (_blk(src, o, SG, True) if tr else _blk(src, SG, o, False)) if sf else z
    msa = (_blk(src, o, SA, True) if tr else _blk(src, SA, o, False)) if sf else z
    _put(out, R, o, _phi_r(fb, T, mr, mv), sym)
    if X >= first + 1:
        _put(out, V, o, _phi_v(fb, T, mr, mv, mp, ma, msa, sf), sym)
    if X >= first + 2:
        _put(out, PHI, o, _phi_p(fb, T, mr, mv, mp, mg, msg, sf), sym)


@njit(cache=True)
def _col3(M, i0, j):
    return (M[i0, j], M[i0 + 1, j], M[i0 + 2, j])


@njit(cache=True)
def _mv(f, x):
    """``f x`` (3x3 block times a 3-vector)."""
    return (f[0][0] * x[0] + f[0][1] * x[1] + f[0][2] * x[2], f[1][0] * x[0] + f[1][1] * x[1] + f[1][2] * x[2],
            f[2][0] * x[0] + f[2][1] * x[1] + f[2][2] * x[2])


@njit(cache=True)
def _phi_col(src, j, fb, T, sf, out):
    """The navigation rows (dr, dv, phi) of ``Phi m`` for the column ``m = src[:, j]`` into ``out[:9, j]``
    (the columns of the parameter states, lever arm and time offset, which F does not reach)."""
    z3 = (0.0, 0.0, 0.0)
    xr, xv, xp = _col3(src, R, j), _col3(src, V, j), _col3(src, PHI, j)
    xg, xa = _col3(src, BG, j), _col3(src, BA, j)
    xsg = _col3(src, SG, j) if sf else z3
    xsa = _col3(src, SA, j) if sf else z3
    frr, fvr, fvv, fvp, fpr, fpv, fpp, c, csa, csg = fb
    a = _mv(frr, xr)
    b = (_mv(fvr, xr), _mv(fvv, xv), _mv(fvp, xp), _mv(c, xa), _mv(csa, xsa) if sf else z3)
    cg = _mv(c, xg)
    e = (_mv(fpr, xr), _mv(fpv, xv), _mv(fpp, xp), _mv(csg, xsg) if sf else z3)
    for i in range(3):
        out[R + i, j] = xr[i] + T * (a[i] + xv[i])
        out[V + i, j] = xv[i] + T * (b[0][i] + b[1][i] + b[2][i] + b[3][i] + b[4][i])
        out[PHI + i, j] = xp[i] + T * (e[0][i] + e[1][i] + e[2][i] - cg[i] + e[3][i])


@njit(cache=True)
def propagate(P, W, fb, T, nx, ncore, inv_tau_g, inv_tau_a):
    """``P <- Phi P Phi^T`` with ``Phi = I + F T`` over F's 3x3 blocks (:func:`f_blocks`); ``W`` (nx, nx)
    scratch; ``ncore`` (15 or 21: with scale factors) the states F's blocks reach, the rest parameter
    states (lever arm, time offset: constant, F zero on their rows and columns).

    The sensor rows of F are zero (random walk, scale factors) or diagonal (gm-decay: ``D = 1 - T/tau``),
    so only the navigation rows (dr, dv, phi) of ``W = Phi P`` are formed, block column by block
    column; then ``P = Phi W^T`` (``= W Phi^T``, P being symmetric) for the upper navigation blocks,
    ``W D`` for the navigation-sensor blocks and ``D P D`` for the sensor blocks, mirrored.  Each block
    is a few 3x3 products on tuples (the zero entries of F_rr, F_vr, A, B and the skew blocks
    skipped): about 1,250 multiply-adds for 15 states, and P exactly symmetric.
    """
    sf = ncore > 15
    decay = False
    for i in range(3):
        if inv_tau_g[i] != 0.0 or inv_tau_a[i] != 0.0:
            decay = True
    # one compiled _phi_apply for the block columns (a loop index, not a literal per call: numba would
    # compile one specialization per literal column, 10 of them, for ~8 s of a first run)
    for X in range(ncore // 3):
        _phi_apply(P, X, False, fb, T, sf, W, False, -9)
    for j in range(ncore, nx):
        _phi_col(P, j, fb, T, sf, W)
    for X in range(3):
        _phi_apply(W, X, True, fb, T, sf, P, True, 0)
    for j in range(9, nx):
        d = 1.0
        if j < BA:
            d = 1.0 - T * inv_tau_g[j - BG]
        elif j < SG:
            d = 1.0 - T * inv_tau_a[j - BA]
        for i in range(9):
            v = W[i, j] * d
            P[i, j] = v
            P[j, i] = v
        if decay:
            for i in range(9, nx):
                P[i, j] *= d
                if i < BA:
                    P[i, j] *= 1.0 - T * inv_tau_g[i - BG]
                elif i < SG:
                    P[i, j] *= 1.0 - T * inv_tau_a[i - BA]


@njit(cache=True)
def transition_step(M, W, fb, T, ncore, inv_tau_g, inv_tau_a):
    """``M <- (I + F T) M`` on the core states (``ncore`` x ``ncore``): the product of the filter's own
    transition matrices between two smoother epochs, so that the smoother's ``Phi`` is exactly the one
    P was propagated with (``W`` scratch).  Only the navigation rows change (the sensor rows of F are
    zero, or a diagonal decay)."""
    sf = ncore > 15
    for X in range(ncore // 3):
        _phi_apply(M, X, False, fb, T, sf, W, False, -9)
    for i in range(9):
        for j in range(ncore):
            M[i, j] = W[i, j]
    for i in range(3):
        if inv_tau_g[i] != 0.0 or inv_tau_a[i] != 0.0:
            dg = 1.0 - T * inv_tau_g[i]
            da = 1.0 - T * inv_tau_a[i]
            for j in range(ncore):
                M[BG + i, j] *= dg
                M[BA + i, j] *= da


@njit(cache=True)
def add_process_noise(P, c, T, s_drift, arw2, vrw2, q_bg, q_ba, q_att_extra, q_vel_extra):
    """``P += Qd``, ``Qd = G Q G^T T``: ``Cbn diag(arw^2) Cbn^T`` on phi, ``Cbn diag(vrw^2) Cbn^T`` on dv; the
    drift terms times ``s_drift`` (the bounded, decaying scale that outage-exit innovations move,
    :mod:`sinscli.fusion.kernel`): ``q_bg``/``q_ba`` (3,) bias densities and the isotropic
    scale-factor/misalignment densities ``q_*_extra``; ``c`` is Cbn as a 3-tuple of rows."""
    s = T
    sd = T * s_drift
    for i in range(3):
        for j in range(3):
            a = 0.0
            b = 0.0
            for k in range(3):
                a += c[i][k] * arw2[k] * c[j][k]
                b += c[i][k] * vrw2[k] * c[j][k]
            P[PHI + i, PHI + j] += a * s
            P[V + i, V + j] += b * s
        P[PHI + i, PHI + i] += q_att_extra * sd
        P[V + i, V + i] += q_vel_extra * sd
        P[BG + i, BG + i] += q_bg[i] * sd
        P[BA + i, BA + i] += q_ba[i] * sd
