"""Time-differenced carrier phase (TDCP) in the tightly coupled filter: the measurement model, the stochastic
cloning of the antenna position and the clock bias, and the INS-aided cycle-slip test (numba kernels called by
:mod:`sinscli.fusion.kernel`; docs/raw_gnss.md, "Carrier phase in the filter").

A TDCP row of satellite s between raw epochs k-1 and k carries the corrected delta range ``Delta Phi_c``
(:mod:`sinscli.gnss.phase`), which measures

    Delta Phi_c = rho_k(r_a,k) - rho_k-1(r_a,k-1) + b_k - b_k-1 + noise

(``r_a`` the antenna, ``rho`` the geometric range with the Earth's rotation during the flight to the satellite's
position at transmission, ``b`` the receiver clock bias, m; an inter-system bias cancels).  The terms of epoch
k-1 are not states of the filter at k: stochastic cloning (Roumeliotis & Burdick 2002, "Stochastic cloning: a
generalized framework for processing relative state measurements", ICRA, eq. 6-12) keeps them.  After the
updates of each raw epoch the filter appends (replaces) four clone states: the antenna position error then
(ENU, m) and the clock bias error then (m),

    x_c = J x,   J = [d r_a / d x ; e_clk^T],   P_cc = J P J^T,   P_cx = J P,

(``J`` the antenna position's Jacobian, :func:`antenna_jacobian`), and keeps their nominal values: the antenna's
ECEF position and the clock bias estimate then (``F_TDCP``).  A TDCP row at k then predicts
``rho_k(r_a) - rho_k-1(r_c) + b - b_c`` with Jacobian

    H = -e_k^T J_r(x) + 1 (b) + e_k-1^T (x_c,r) - 1 (x_c,b)

(``e`` the unit lines of sight, ENU), exactly, whatever the filter corrected between the two epochs: the
clones' estimates are fed back into their nominal values like every other state.  The clones do not move
between epochs (no process noise; the transition's clone rows are ``J`` at a clone, the identity after); a
floor of ``CLONE_FLOOR`` on their variance keeps P numerically positive definite (the clone is an exact linear
function of the other states).

Cycle slips the receiver did not flag are found against the INS-predicted displacement: before the epoch's TDCP
rows are applied (after its pseudoranges and range rates), their innovations ``z`` and covariance
``S = H P H^T + R`` are formed together and Baarda's data snooping is run (Baarda 1968, "A testing procedure
for use in geodetic networks"; Teunissen 2006, "Testing theory", sec. 4.6): the standardized
``w_i = (S^-1 z)_i / sqrt((S^-1)_ii)``, N(0, 1) without a slip, the one with the largest ``|w|`` over the
threshold is a slip and is left out, and the test repeats on the rest.  The common clock change, to which every
row is equally sensitive, is thereby estimated from the other satellites, not taken from the clock's prior;
a slip of one cycle in one satellite stands out at the carrier's noise.  A slipped satellite's pair is left out
(its innovation record says rejected); its next pair, from the slipped epoch on, is used again.
"""
import numpy as np
from numba import njit

from ..gnss.model import geo_range
from ..gnss.orbits import earth_rate
from ..nav.earth import enu_axes
from ..nav.linalg import chol_solve_into, cholesky
from ..nav import strapdown as sd
from ..nav.rotation import m_mul
from .antenna import _antenna_velocity, _dvant_dlever, antenna_ecef
from .model import BG, PHI, R, V
from .updates import innovation_covariance

# the kernel's layout slots these kernels read, passed as the tuple ``sl`` (kernel.TDCP_SLOTS, in this order): the
# kernel imports this module, not the reverse
SLOT_NAMES = ("F_LEVER", "F_TD", "F_W", "F_HEAD_KNOWN", "F_HAVE_W", "F_CLK", "F_TDCP", "C_LA", "C_TD", "C_CLK", "C_TDCP",
              "RW_T", "RW_KIND", "RW_Z", "RW_S", "RW_AUX", "SAT_POS", "SAT_SYS", "MT_TDCP", "AX_LOS", "W_F", "W_W",
              "W_A", "W_L", "W_PHI", "V_KT", "V_H", "V_Z", "V_R", "V_HP")
(I_F_LEVER, I_F_TD, I_F_W, I_F_HEAD_KNOWN, I_F_HAVE_W, I_F_CLK, I_F_TDCP, I_C_LA, I_C_TD, I_C_CLK, I_C_TDCP, I_RW_T,
 I_RW_KIND, I_RW_Z, I_RW_S, I_RW_AUX, I_SAT_POS, I_SAT_SYS, I_MT_TDCP, I_AX_LOS, I_W_F, I_W_W, I_W_A, I_W_L, I_W_PHI,
 I_V_KT, I_V_H, I_V_Z, I_V_R, I_V_HP) = range(len(SLOT_NAMES))
MAJORITY_MIN = 4                # with this many rows or more, slips found on most of them are the prediction's fault
CLONE_FLOOR = 1.0e-8            # m^2: the clones' own variance (0.1 mm): P stays numerically positive definite
# the slots of F_TDCP (kernel.FS): the clones' nominal values
TD_ANT, TD_B, TD_T = 0, 3, 4    # antenna ECEF at the cloned epoch (m, 3), clock bias then (m), its time (s)
# the slots of C_TDCP (kernel.CV)
TC_CLONE, TC_SLIP_W = 0, 1      # the first of the 4 clone states (-1: no TDCP), the slip test's threshold on |w|


@njit(cache=True)
def antenna_jacobian(st, fs, cv, nx, J, sl):
    """The antenna's ECEF position at the stamp plus the time offset, ``r(lat, lon, h) + C_n^e (Cbn l + tau
    v_ant)`` (the pseudorange model's antenna, :func:`sinscli.fusion.kernel._raw_model`), and its Jacobian in ENU
    into rows 0-2 of ``J`` (``nx`` columns; the rest zero):

        d r_a = dr + tau dv + ([l_n x] + tau ([Cbn (w x l) x] - [w_in x][l_n x])) phi - tau Cbn [l x] db_g
                + (Cbn + tau d v_ant / d l) dl + v_ant dtau.

    Returns ``(x, y, z)`` and the ENU axes ``(east, north, up)``."""
    c = sd._cbn(st)
    lat, lon, h = st[sd.S_LAT], st[sd.S_LON], st[sd.S_H]
    vel = (st[sd.S_VEL], st[sd.S_VEL + 1], st[sd.S_VEL + 2])
    lever = (fs[sl[I_F_LEVER]], fs[sl[I_F_LEVER] + 1], fs[sl[I_F_LEVER] + 2])
    tau = fs[sl[I_F_TD]]
    w = (fs[sl[I_F_W]], fs[sl[I_F_W] + 1], fs[sl[I_F_W] + 2])
    v_ant, cw, l_n, w_in = _antenna_velocity(c, vel, lat, h, w, lever)
    rx, ry, rz, ue, un, uu = antenna_ecef(lat, lon, h, l_n, v_ant, tau)
    for a in range(3):
        for j in range(nx):
            J[a, j] = 0.0
        J[a, R + a] = 1.0
        J[a, V + a] = tau
    wl = w_in[0] * l_n[0] + w_in[1] * l_n[1] + w_in[2] * l_n[2]
    for a in range(3):
        for b in range(3):
            # [w_in x][l_n x] = l_n w_in^T - (w_in . l_n) I
            m = l_n[a] * w_in[b] - (wl if a == b else 0.0)
            J[a, PHI + b] = -tau * m
    # [l_n x] + tau [cw x]
    for v, s in ((l_n, 1.0), (cw, tau)):
        J[0, PHI + 1] -= s * v[2]
        J[0, PHI + 2] += s * v[1]
        J[1, PHI + 0] += s * v[2]
        J[1, PHI + 2] -= s * v[0]
        J[2, PHI + 0] -= s * v[1]
        J[2, PHI + 1] += s * v[0]
    if tau != 0.0:                              # -tau Cbn [l x] on the gyro bias (through the antenna's rate)
        lx = ((0.0, -lever[2], lever[1]), (lever[2], 0.0, -lever[0]), (-lever[1], lever[0], 0.0))
        clx = m_mul(c, lx)
        for a in range(3):
            for b in range(3):
                J[a, BG + b] = -tau * clx[a][b]
    la, td = int(cv[sl[I_C_LA]]), int(cv[sl[I_C_TD]])
    if la >= 0:
        dl = _dvant_dlever(c, w, w_in)
        for a in range(3):
            for b in range(3):
                J[a, la + b] = c[a][b] + tau * dl[a][b]
    if td >= 0:
        for a in range(3):
            J[a, td] = v_ant[a]
    return rx, ry, rz, ue, un, uu


@njit(cache=True)
def model(row, st, fs, cv, nx, H, z, r, sat, sl):
    """Innovation (computed minus measured), Jacobian (row 0 of ``H``; rows 1-2 scratch, left zero) and variance
    of one TDCP row (module docstring): ``z = rho_k(r_a) - rho_k-1(r_c) + b - b_c - Delta Phi_c``.  The row:
    ``z = (Delta Phi_c, satellite-table row of epoch k-1, time of epoch k-1)``, ``s[0]`` its sigma, ``aux =
    (satellite-table row of epoch k, system)``.  Returns as :func:`sinscli.fusion.kernel._model`: 0 components
    while there is no clone of epoch k-1 (the filter had no raw epoch there), while the heading is unknown (the
    lever arm's direction) or before the first propagation (the antenna's rate)."""
    q = int(cv[sl[I_C_TDCP] + TC_CLONE])
    clk = int(cv[sl[I_C_CLK]])
    if q < 0 or clk < 0 or fs[sl[I_F_HEAD_KNOWN]] == 0.0 or fs[sl[I_F_HAVE_W]] == 0.0:
        return 0, 0, 0, 1, 2
    if fs[sl[I_F_TDCP] + TD_T] != row[sl[I_RW_Z] + 2]:
        return 0, 0, 0, 1, 2
    k = int(row[sl[I_RW_AUX]])
    kp = int(row[sl[I_RW_Z] + 1])
    omge = earth_rate(int(sat[k, sl[I_SAT_SYS]]))
    rx, ry, rz, ue, un, uu = antenna_jacobian(st, fs, cv, nx, H, sl)
    rho, ex, ey, ez = geo_range(sat[k, sl[I_SAT_POS]], sat[k, sl[I_SAT_POS] + 1], sat[k, sl[I_SAT_POS] + 2], rx, ry, rz, omge)
    a0 = sl[I_F_TDCP] + TD_ANT
    rho_p, px, py, pz = geo_range(sat[kp, sl[I_SAT_POS]], sat[kp, sl[I_SAT_POS] + 1], sat[kp, sl[I_SAT_POS] + 2], fs[a0],
                                  fs[a0 + 1], fs[a0 + 2], omge)
    e = (ue[0] * ex + ue[1] * ey + ue[2] * ez, un[0] * ex + un[1] * ey + un[2] * ez,
         uu[0] * ex + uu[1] * ey + uu[2] * ez)
    ep = (ue[0] * px + ue[1] * py + ue[2] * pz, un[0] * px + un[1] * py + un[2] * pz,
          uu[0] * px + uu[1] * py + uu[2] * pz)
    for j in range(nx):                         # row 0 <- -e^T J (rows 1, 2 of J cleared)
        v = -(e[0] * H[0, j] + e[1] * H[1, j] + e[2] * H[2, j])
        H[0, j] = v
        H[1, j] = 0.0
        H[2, j] = 0.0
    for i in range(3):
        H[0, q + i] = ep[i]
    H[0, clk] = 1.0
    H[0, q + 3] = -1.0
    z[0] = rho - rho_p + fs[sl[I_F_CLK]] - fs[sl[I_F_TDCP] + TD_B] - row[sl[I_RW_Z]]
    s0 = row[sl[I_RW_S]]
    r[0] = s0 * s0
    return 1, sl[I_AX_LOS], 0, 1, 2


@njit(cache=True)
def clone(st, fs, cv, P, nx, t, mats, store, sl):
    """After the updates of the raw epoch at ``t`` (module docstring): the clone states take the antenna position
    error and the clock bias error, ``x_c = J x`` (their rows and columns of P ``J P``, their block ``J P J^T``,
    plus :data:`CLONE_FLOOR`), and ``F_TDCP`` the antenna's ECEF position, the clock bias estimate and ``t``.
    With ``store`` (smoothing) the transition since the smoother's last epoch (the identity: this runs right after
    :func:`sinscli.fusion.kernel._store_epoch`) gets the clone rows ``J``.  ``mats``: the kernel's workspace
    (its ``W_F``, ``W_W``, ``W_A`` matrices as scratch)."""
    q = int(cv[sl[I_C_TDCP] + TC_CLONE])
    clk = int(cv[sl[I_C_CLK]])
    J = mats[sl[I_W_F]]
    A = mats[sl[I_W_W]]
    C = mats[sl[I_W_A]]
    rx, ry, rz, ue, un, uu = antenna_jacobian(st, fs, cv, nx, J, sl)
    for a in range(3):
        J[3, a] = CLONE_FLOOR
    innovation_covariance(P, nx, J, J[3], 3, A, C)       # A = J P, C = J P J^T + floor (J is 0 on the clones)
    for j in range(nx):
        if q <= j < q + 4:
            continue
        for a in range(3):
            P[q + a, j] = A[a, j]
            P[j, q + a] = A[a, j]
        P[q + 3, j] = P[clk, j]
        P[j, q + 3] = P[clk, j]
    for a in range(3):
        for b in range(3):
            P[q + a, q + b] = 0.5 * (C[a, b] + C[b, a])
        P[q + a, q + 3] = A[a, clk]
        P[q + 3, q + a] = A[a, clk]
    P[q + 3, q + 3] = P[clk, clk] + CLONE_FLOOR
    fs[sl[I_F_TDCP] + TD_ANT] = rx
    fs[sl[I_F_TDCP] + TD_ANT + 1] = ry
    fs[sl[I_F_TDCP] + TD_ANT + 2] = rz
    fs[sl[I_F_TDCP] + TD_B] = fs[sl[I_F_CLK]]
    fs[sl[I_F_TDCP] + TD_T] = t
    if store:
        Phi = mats[sl[I_W_PHI]]
        for a in range(4):
            for j in range(nx):
                Phi[q + a, j] = J[a, j] if a < 3 else 0.0
        Phi[q + 3, clk] = 1.0


@njit(cache=True)
def feedback(fs, cv, x, lat, lon, sl):
    """The clones' error estimates removed from their nominal values (closed loop): the antenna then by the ENU
    estimate (the axes at ``lat``, ``lon``: the clone is of the previous epoch, a second away), the clock bias
    then."""
    q = int(cv[sl[I_C_TDCP] + TC_CLONE])
    ue, un, uu = enu_axes(lat, lon)
    for i in range(3):
        fs[sl[I_F_TDCP] + TD_ANT + i] -= ue[i] * x[q] + un[i] * x[q + 1] + uu[i] * x[q + 2]
    fs[sl[I_F_TDCP] + TD_B] -= x[q + 3]


@njit(cache=True)
def screen(meas, i0, st, fs, cv, P, nx, sat, mats, vecs, sl):
    """The INS-aided cycle-slip test of the TDCP rows of the raw epoch whose first row is ``meas[i0]`` (module
    docstring: data snooping with the rows' joint innovation covariance), run before any row of the epoch is
    applied: the carrier changes against the INS-predicted displacement and clock, not against a state that the
    epoch's pseudoranges have already moved (a pseudorange noisier than stated would pass for slips).  A row found
    slipped gets its ``w`` in the slot after its sigma (``kernel.TDCP_SLIP``; 0 otherwise): :func:`sinscli.fusion.kernel._apply` then
    records it as rejected and leaves it out.  Returns the number of slips found; or, when they would be most of
    :data:`MAJORITY_MIN` rows or more (the carriers agree with one another and not with the prediction: the filter
    is too sure of itself, as after pseudoranges noisier than stated), minus the epoch's NIS per row (at least 1),
    no row marked: the caller widens the navigation covariance by it.  Scratch: the workspace's
    ``W_W`` (rows' H, then S^-1), ``W_L`` (H P, then the Cholesky factor), ``W_A`` (S), ``V_KT`` (z, r, active),
    ``V_HP`` (row indices)."""
    thr = cv[sl[I_C_TDCP] + TC_SLIP_W]
    t0 = meas[i0, sl[I_RW_T]]
    nm = meas.shape[0]
    Hs = mats[sl[I_W_W]]
    A = mats[sl[I_W_A]]
    L = mats[sl[I_W_L]]
    kt = vecs[sl[I_V_KT]:sl[I_V_KT] + 3]
    zs, rs, act = kt[0], kt[1], kt[2]
    H3 = vecs[sl[I_V_H]:sl[I_V_H] + 3]
    z1 = vecs[sl[I_V_Z]]
    r1 = vecs[sl[I_V_R]]
    rows = vecs[sl[I_V_HP]]
    idx = vecs[sl[I_V_HP] + 1]
    n = 0
    while i0 < nm and meas[i0, sl[I_RW_T]] == t0 and int(meas[i0, sl[I_RW_KIND]]) != sl[I_MT_TDCP]:
        i0 += 1
    i = i0
    while i < nm and meas[i, sl[I_RW_T]] == t0 and int(meas[i, sl[I_RW_KIND]]) == sl[I_MT_TDCP]:
        meas[i, sl[I_RW_S] + 1] = 0.0
        i += 1
    i1 = i
    cap = nx
    for i in range(i0, i1):
        if n >= cap:
            break
        for a in range(3):
            for j in range(nx):
                H3[a, j] = 0.0
        m = model(meas[i], st, fs, cv, nx, H3, z1, r1, sat, sl)[0]
        if m == 0:
            continue
        for j in range(nx):
            Hs[n, j] = H3[0, j]
        zs[n] = z1[0]
        rs[n] = r1[0]
        act[n] = 1.0
        rows[n] = i
        n += 1
    if n == 0:
        return 0
    innovation_covariance(P, nx, Hs, rs, n, L, A)       # L = Hs P, A = S = Hs P Hs^T + R
    found = 0
    nis_all = 0.0
    while True:
        m = 0
        for a in range(n):
            if act[a] > 0.0:
                idx[m] = a
                m += 1
        if m == 0:
            break
        # S of the active rows into Hs' rows (S^-1 after the solve); L its Cholesky factor
        for a in range(m):
            for b in range(m):
                Hs[a, b] = A[int(idx[a]), int(idx[b])]
        if not cholesky(Hs, m, L):
            break
        for a in range(m):
            for b in range(m):
                Hs[a, b] = 1.0 if a == b else 0.0
        chol_solve_into(L, m, Hs[:m, :m])
        worst, w_worst = -1, 0.0
        for a in range(m):
            s = 0.0
            for b in range(m):
                s += Hs[a, b] * zs[int(idx[b])]
            if m == n:
                nis_all += zs[int(idx[a])] * s
            w = s / np.sqrt(Hs[a, a])
            if abs(w) > abs(w_worst):
                worst, w_worst = a, w
        if worst < 0 or abs(w_worst) <= thr:
            break
        j = int(idx[worst])
        act[j] = 0.0
        meas[int(rows[j]), sl[I_RW_S] + 1] = w_worst
        found += 1
    if n >= MAJORITY_MIN and 2 * found > n:
        # most of the epoch's carriers disagree with the prediction: the prediction is wrong (a filter too sure
        # of itself), not the carriers; no slip marked, the caller widens the covariance by the epoch's NIS per row
        for a in range(n):
            meas[int(rows[a]), sl[I_RW_S] + 1] = 0.0
        return -max(nis_all / n, 1.0)
    return found


__all__ = ["antenna_jacobian", "model", "clone", "feedback", "screen", "CLONE_FLOOR", "SLOT_NAMES"]
