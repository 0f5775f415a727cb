"""The fused GNSS/INS loop: one numba kernel over plain arrays (no I/O).

:func:`fuse` runs the strapdown mechanization of :mod:`sinscli.nav.strapdown` (its fast-rate
``load_fast/fast_sample/save_fast`` and the per-interval :func:`~sinscli.nav.strapdown.interval_update`,
no second mechanization) on increments compensated by the filter's bias and scale-factor estimates
(``(dtheta - b_g dt) / (1 + s_g)``, likewise ``dvel``), propagates the error covariance
(:mod:`sinscli.fusion.model`) and applies the measurements (:mod:`sinscli.fusion.updates`) at their own
times: a measurement inside an IMU interval splits that interval's increments at its time (as KF-GINS
does), closes the attitude interval there and propagates P to it.  Every estimate is fed back into
the mechanization's state (position, velocity, ``Cbn`` and ``q`` together, compensated-summation
residues cleared) and the error state is zero again (closed loop).

Nothing is allocated per sample or per update: the matrices the filter works in are the slices of one
workspace (:func:`workspace`), 3-vectors and Cbn are tuples on the stack.

Measurement rows (``meas``, float64, sorted by time then kind) are ``[time, kind, z0, z1, z2, s0, s1,
s2, aux0, aux1]`` with ``kind`` one of the ``MT_*`` codes and ``s`` 1-sigmas (see
:mod:`sinscli.fusion.pipeline` for what each kind carries).

Consistency guard (:func:`_adapt`, docs/fusion.md): the normalized innovations of the GNSS fixes tell
whether the covariance is as large as the errors are; a run of ``rejection_run`` consecutive rejected
GNSS fixes adds each axis' squared innovation to the position variance and accepts the fix (a
diverged filter, or a GNSS jump that stays), reported as an event.
"""
import numpy as np
from numba import njit

from ..nav import strapdown as sd
from ..nav.earth import OMEGA_IE, dlon_nb, gravity, radii
from ..nav.rotation import (dcm_to_euler, dcm_to_quat, euler_to_dcm, m_mul, m_trans, m_tvec, m_vec, orthonormalize_t,
                            quat_mul_t, quat_normalize_t, quat_to_dcm_t, rotvec_to_dcm_t, rotvec_to_quat_t)
from .linalg import cholesky
from .model import BA, BG, PHI, R, SA, SG, V, add_process_noise, f_blocks, propagate, write_F
from .updates import kalman_update, skew_into

# measurement kinds (also the innovation record's type code)
MT_GNSS_POS, MT_GNSS_VEL, MT_ZUPT, MT_ZARU, MT_NHC, MT_ODOM, MT_COURSE = 0, 1, 2, 3, 4, 5, 6
MEAS_NAMES = ("gnss_pos", "gnss_vel", "zupt", "zaru", "nhc", "odom", "course")
MW = 10

# config vector
(C_NX, C_METHOD, C_ORDER, C_NSUB, C_EVERY, C_CONV, C_PROP_DT, C_GATE1, C_GATE2, C_GATE3) = range(10)
C_ARW2 = 10          # 3
C_VRW2 = 13          # 3
C_QBG = 16           # 3
C_QBA = 19           # 3
C_ITG = 22           # 3
C_ITA = 25           # 3
C_SFG = 28           # sigma^2 tau_c of gyro scale factor + misalignment
C_SFA = 29
C_LEVER = 30         # 3
C_REJ_RUN = 33
C_ADAPT_THR = 34     # 0: off
C_ADAPT_N = 35
C_SMOOTH_DT = 36     # > 0: store smoother epochs at least this often
C_ZUPT_MAXV = 37
C_NHC_AX0 = 38
C_NHC_AX1 = 39
C_HEAD_MINSPEED = 40
C_QMAX = 41
C_FWD = 42           # the body's forward axis (0 x, 1 y): roll/pitch sigma
C_ZARU_Q = 43        # 1: the ZARU sigma derives from the ARW (its variance follows the process-noise scale)
CV_SIZE = 45

# filter scalars
F_BG, F_BA, F_SG, F_SA = 0, 3, 6, 9
F_QSCALE = 12
F_ACC_T = 13
F_ACC_DV = 14        # 3
F_ACC_DTH = 17       # 3
F_W = 20             # 3: last compensated body rate
F_HEAD_KNOWN = 23
F_NREJ = 24
F_TREJ0 = 25
F_T_EPOCH = 28
F_ERR = 29
F_ERR_T = 30
F_RESET = 31
F_TPREV = 32
F_NSAMP_OUT = 33
F_HAVE_W = 34
F_ADAPT = 35         # 3 x 3: per kind (GNSS position, velocity, ZARU) the adaptation window's sums of
                     # the clipped NIS per dof, of measurements, of the P share of S (see _adapt)
F_XACC = 44          # nx: correction fed back since the last stored epoch
FS_SIZE = 72

ERR_NONFINITE, ERR_NOT_PD = 1.0, 2.0
EV_REJECTION_RUN, EV_HEADING_INIT, EV_ADAPT = 1.0, 2.0, 3.0

# workspace: matrices (nx, nx) and rows (nx,)
W_F, W_W, W_PM, W_A, W_L = range(5)
NW_MAT = 5
V_X, V_H, V_HP, V_KT, V_Z, V_R = 0, 1, 4, 7, 10, 11
NW_VEC = 12
# per-row variances written with every output row
NVAR = 9             # pos E N U, vel E N U, roll, pitch, heading (heading < 0: not yet known)
NBIAS = 12           # b_g, b_a, s_g, s_a (SI)


def workspace(nx):
    """The kernel's scratch: ``(mats (NW_MAT, nx, nx), vecs (NW_VEC, nx), s3 (2, 3, 3))``."""
    return np.zeros((NW_MAT, nx, nx)), np.zeros((NW_VEC, nx)), np.zeros((2, 3, 3))


@njit(cache=True)
def _set_attitude(st, c):
    """Write an attitude (tuple matrix) into Cbn and q together; clears their summation residues."""
    ca = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            st[sd.S_CBN + 3 * i + j] = c[i][j]
            ca[i, j] = c[i][j]
    q = dcm_to_quat(ca)
    for i in range(4):
        st[sd.S_Q + i] = q[i]
        st[sd.S_QLO + i] = 0.0
    for i in range(9):
        st[sd.S_CLO + i] = 0.0


@njit(cache=True)
def feedback(st, fs, x, nx, method):
    """Closed loop: remove the estimated errors ``x`` from the mechanization state and the sensor
    estimates; the error state is zero afterwards."""
    lat, h = st[sd.S_LAT], st[sd.S_H]
    rm, rn = radii(np.sin(lat))
    st[sd.S_LAT] = lat - x[R + 1] / (rm + h)
    st[sd.S_LON] = st[sd.S_LON] - x[R] / ((rn + h) * np.cos(lat))
    st[sd.S_H] = h - x[R + 2]
    for i in range(3):
        st[sd.S_PLO + i] = 0.0
        st[sd.S_VEL + i] -= x[V + i]
        st[sd.S_VMM2 + i] -= x[V + i]       # the velocity history of the position rule moves with it
        st[sd.S_VMM3 + i] -= x[V + i]
        st[sd.S_VLO + i] = 0.0
    phi = (x[PHI], x[PHI + 1], x[PHI + 2])
    if method == sd.ATT_QUAT:
        q = (st[sd.S_Q], st[sd.S_Q + 1], st[sd.S_Q + 2], st[sd.S_Q + 3])
        q = quat_normalize_t(quat_mul_t(rotvec_to_quat_t(phi), q))
        _set_attitude(st, quat_to_dcm_t(q))
        for i in range(4):
            st[sd.S_Q + i] = q[i]
    else:
        _set_attitude(st, orthonormalize_t(m_mul(rotvec_to_dcm_t(phi), sd._cbn(st))))
    for i in range(3):
        fs[F_BG + i] += x[BG + i]
        fs[F_BA + i] += x[BA + i]
    if nx > 15:
        for i in range(3):
            fs[F_SG + i] += x[SG + i]
            fs[F_SA + i] += x[SA + i]
    for i in range(nx):
        fs[F_XACC + i] += x[i]


@njit(cache=True)
def _fail(fs, t, code):
    fs[F_ERR] = code
    fs[F_ERR_T] = t
    return False


@njit(cache=True)
def _health(P, nx, fs, t, L, full):
    """A finite positive diagonal (after each propagation: a non-finite entry reaches the diagonal
    within one propagation); with ``full``, every entry finite and P positive definite (a Cholesky
    factorization succeeds: after each measurement group).  While the heading is held out of the filter
    its zero row and column are left out of the test."""
    held = fs[F_HEAD_KNOWN] == 0.0             # heading held out: its row and column of P are zero
    for i in range(nx):
        d = P[i, i]
        if not np.isfinite(d):
            return _fail(fs, t, ERR_NONFINITE)
        if not d > 0.0 and not (held and i == PHI + 2 and d == 0.0):
            return _fail(fs, t, ERR_NOT_PD)
    if full:
        s = 0.0
        for i in range(nx):
            for j in range(nx):
                s += P[i, j]
        if not np.isfinite(s):
            return _fail(fs, t, ERR_NONFINITE)
        if held:                                # the zero row/column: a unit variance for the check
            P[PHI + 2, PHI + 2] = 1.0
        ok = cholesky(P, nx, L)
        if held:
            P[PHI + 2, PHI + 2] = 0.0
        if not ok:
            return _fail(fs, t, ERR_NOT_PD)
    return True


@njit(cache=True)
def _do_propagate(st, fs, cv, P, F, W, ptr, col, ftv, store, itg, ita, arw2, vrw2, qbg, qba):
    """Propagate P over the accumulated time with F at the current state and the mean f, w (``F``, ``W``
    scratch; the model's (3,) arrays 1/tau, ARW^2, VRW^2 and bias densities passed once per block)."""
    T = fs[F_ACC_T]
    if T <= 0.0:
        return
    nx = int(cv[C_NX])
    c = sd._cbn(st)
    f_n = (fs[F_ACC_DV] / T, fs[F_ACC_DV + 1] / T, fs[F_ACC_DV + 2] / T)
    w_b = (fs[F_ACC_DTH] / T, fs[F_ACC_DTH + 1] / T, fs[F_ACC_DTH + 2] / T)
    for i in range(3):
        fs[F_W + i] = w_b[i]
    fs[F_HAVE_W] = 1.0
    f_b = m_tvec(c, f_n)
    vel = (st[sd.S_VEL], st[sd.S_VEL + 1], st[sd.S_VEL + 2])
    lat, h = st[sd.S_LAT], st[sd.S_H]
    fb = f_blocks(c, vel, lat, h, f_n, w_b, f_b)
    propagate(P, W, fb, T, nx, itg, ita)
    g = gravity(np.sin(lat), h)
    w2 = w_b[0] * w_b[0] + w_b[1] * w_b[1] + w_b[2] * w_b[2]
    fd2 = f_n[0] * f_n[0] + f_n[1] * f_n[1] + (f_n[2] - g) * (f_n[2] - g)
    add_process_noise(P, nx, c, T, fs[F_QSCALE], arw2, vrw2, qbg, qba, cv[C_SFG] * w2, cv[C_SFA] * fd2)
    if store:
        write_F(F, nx, fb, itg, ita)
        for i in range(nx):
            for p in range(ptr[i], ptr[i + 1]):
                ftv[p] += F[i, col[p]] * T
    fs[F_ACC_T] = 0.0
    for i in range(3):
        fs[F_ACC_DV + i] = 0.0
        fs[F_ACC_DTH + i] = 0.0


@njit(cache=True)
def _close(st, fs, sums, order, method, t_end, cflu, events, n_ev):
    """Close the attitude interval at ``t_end`` with the shared mechanization step; accumulate f, w."""
    T = t_end - st[sd.S_TSTART]
    n_ev = sd.interval_update(st, sums, order, method, t_end, cflu, 0, events, n_ev)
    dv_n = m_vec(sd._cbn(st), sums[1])
    alpha = sums[0]
    for i in range(3):
        fs[F_ACC_DV + i] += dv_n[i]
        fs[F_ACC_DTH + i] += alpha[i]
    fs[F_ACC_T] += T
    return n_ev


@njit(cache=True)
def _record(inn, n_inn, t, kind, axis, z, var, nis, acc):
    if n_inn < inn.shape[0]:
        inn[n_inn, 0] = t
        inn[n_inn, 1] = kind
        inn[n_inn, 2] = axis
        inn[n_inn, 3] = z
        inn[n_inn, 4] = np.sqrt(var) if var > 0.0 else 0.0
        inn[n_inn, 5] = nis
        inn[n_inn, 6] = 1.0 if acc else 0.0
    return n_inn + 1


@njit(cache=True)
def _event(evs, n_evs, t, kind, a, b):
    if n_evs < evs.shape[0]:
        evs[n_evs, 0] = t
        evs[n_evs, 1] = kind
        evs[n_evs, 2] = a
        evs[n_evs, 3] = b
    return n_evs + 1


@njit(cache=True)
def _heading_from_course(row, st, fs, cv, P, nx, evs, n_evs):
    """Set heading and horizontal velocity from the GNSS course (the heading was unknown)."""
    if fs[F_HEAD_KNOWN] > 0.0 or row[3] * row[3] + row[4] * row[4] < cv[C_HEAD_MINSPEED] ** 2:
        return n_evs
    conv = int(cv[C_CONV])
    ca = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            ca[i, j] = st[sd.S_CBN + 3 * i + j]
    rpy = dcm_to_euler(ca, conv)
    c_new = euler_to_dcm(rpy[0], rpy[1], row[2], conv)
    _set_attitude(st, ((c_new[0, 0], c_new[0, 1], c_new[0, 2]), (c_new[1, 0], c_new[1, 1], c_new[1, 2]),
                       (c_new[2, 0], c_new[2, 1], c_new[2, 2])))
    st[sd.S_VEL] = row[3]
    st[sd.S_VEL + 1] = row[4]
    for i in range(3):
        st[sd.S_VLO + i] = 0.0
    for j in (PHI + 2, V, V + 1):
        for i in range(nx):
            P[i, j] = 0.0
            P[j, i] = 0.0
    P[PHI + 2, PHI + 2] = row[5] * row[5]
    P[V, V] = row[6] * row[6]
    P[V + 1, V + 1] = row[6] * row[6]
    fs[F_HEAD_KNOWN] = 1.0
    fs[F_RESET] = 1.0
    return _event(evs, n_evs, row[0], EV_HEADING_INIT, (rpy[2] - row[2]), row[5])


@njit(cache=True)
def _model(row, kind, st, fs, cv, nx, H, z, r):
    """Innovation ``z``, its Jacobian ``H`` (rows zeroed here) and noise ``r`` of one measurement row.

    Returns ``(m, axis0, ax0, ax1, ax2)``: the number of components (0: not applicable now), the
    axis code of the first (0 e, 1 n, 2 u, 3 x, 4 y, 5 z) and the axes used.
    """
    for a in range(3):
        for j in range(nx):
            H[a, j] = 0.0
    c = sd._cbn(st)
    lat, lon, h = st[sd.S_LAT], st[sd.S_LON], st[sd.S_H]
    vel = (st[sd.S_VEL], st[sd.S_VEL + 1], st[sd.S_VEL + 2])
    head_known = fs[F_HEAD_KNOWN] > 0.0
    lever = (cv[C_LEVER], cv[C_LEVER + 1], cv[C_LEVER + 2])
    m = 3
    axis0 = 0
    ax = (0, 1, 2)
    if kind == MT_GNSS_POS:
        rm, rn = radii(np.sin(lat))
        l_n = m_vec(c, lever)
        z[0] = dlon_nb(lon, row[3]) * (rn + h) * np.cos(lat) + l_n[0]      # across the antimeridian too
        z[1] = (lat - row[2]) * (rm + h) + l_n[1]
        z[2] = h - row[4] + l_n[2]
        for i in range(3):
            H[i, R + i] = 1.0
        skew_into(H, 0, PHI, l_n, 1.0)
    elif kind == MT_GNSS_VEL:
        if not head_known or fs[F_HAVE_W] == 0.0:
            return 0, 0, 0, 1, 2
        w = (fs[F_W], fs[F_W + 1], fs[F_W + 2])
        wxl = (w[1] * lever[2] - w[2] * lever[1], w[2] * lever[0] - w[0] * lever[2],
               w[0] * lever[1] - w[1] * lever[0])
        cw = m_vec(c, wxl)
        l_n = m_vec(c, lever)
        rm, rn = radii(np.sin(lat))
        w_in = (-vel[1] / (rm + h), OMEGA_IE * np.cos(lat) + vel[0] / (rn + h),
                OMEGA_IE * np.sin(lat) + vel[0] * np.tan(lat) / (rn + h))
        wl = (w_in[1] * l_n[2] - w_in[2] * l_n[1], w_in[2] * l_n[0] - w_in[0] * l_n[2],
              w_in[0] * l_n[1] - w_in[1] * l_n[0])
        for i in range(3):
            z[i] = vel[i] + cw[i] - wl[i] - row[2 + i]
            H[i, V + i] = 1.0
        skew_into(H, 0, PHI, cw, 1.0)
        lx = ((0.0, -lever[2], lever[1]), (lever[2], 0.0, -lever[0]), (-lever[1], lever[0], 0.0))
        clx = m_mul(c, lx)                      # -Cbn [l x] on b_g
        for i in range(3):
            for j in range(3):
                H[i, BG + j] = -clx[i][j]
    elif kind == MT_ZUPT or kind == MT_ZARU:
        speed2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]
        if speed2 > cv[C_ZUPT_MAXV] ** 2:
            return 0, 0, 0, 1, 2
        if kind == MT_ZUPT:
            for i in range(3):
                z[i] = vel[i]
                H[i, V + i] = 1.0
        else:
            w_exp = m_tvec(c, (0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)))
            axis0 = 3
            for i in range(3):
                wc = (row[2 + i] - fs[F_BG + i]) / (1.0 + fs[F_SG + i])
                z[i] = wc - w_exp[i]
                H[i, BG + i] = 1.0
                if nx > 15:
                    H[i, SG + i] = row[2 + i]
    elif kind == MT_NHC or kind == MT_ODOM:
        if not head_known:
            return 0, 0, 0, 1, 2
        v_b = m_tvec(c, vel)
        vx = ((0.0, -vel[2], vel[1]), (vel[2], 0.0, -vel[0]), (-vel[1], vel[0], 0.0))
        cvx = m_mul(m_trans(c), vx)                         # Cbn^T [v x]
        axis0 = 3
        if kind == MT_NHC:
            m = 2
            ax = (int(cv[C_NHC_AX0]), int(cv[C_NHC_AX1]), 0)
        for a in range(m):
            i = ax[a]
            z[a] = v_b[i] - (row[2 + i] if kind == MT_ODOM else 0.0)
            for j in range(3):
                H[a, V + j] = c[j][i]
                H[a, PHI + j] = -cvx[i][j]
    else:
        return 0, 0, 0, 1, 2
    for a in range(m):
        s = row[5 + ax[a]] if kind == MT_NHC else row[5 + a]
        r[a] = s * s
        if kind == MT_ZARU and cv[C_ZARU_Q] > 0.0:
            r[a] *= fs[F_QSCALE]
    return m, axis0, ax[0], ax[1], ax[2]


@njit(cache=True)
def _apply(row, st, fs, cv, P, mats, vecs, s3, inn, n_inn, evs, n_evs):
    """Apply one measurement row at the current time (the state is at its time).  Returns counters."""
    nx = int(cv[C_NX])
    kind = int(row[1])
    t = row[0]
    if kind == MT_COURSE:
        return n_inn, _heading_from_course(row, st, fs, cv, P, nx, evs, n_evs)
    H = vecs[V_H:V_H + 3]
    z = vecs[V_Z]
    r = vecs[V_R]
    x = vecs[V_X]
    m, axis0, a0, a1, a2 = _model(row, kind, st, fs, cv, nx, H, z, r)
    if m == 0:
        return n_inn, n_evs
    head_known = fs[F_HEAD_KNOWN] > 0.0
    if not head_known:
        for i in range(nx):
            P[i, PHI + 2] = 0.0
            P[PHI + 2, i] = 0.0
    gate = cv[C_GATE1 + m - 1]
    HP = vecs[V_HP:V_HP + 3]
    KT = vecs[V_KT:V_KT + 3]
    A = mats[W_A]
    S = s3[0]
    nis, acc = kalman_update(P, nx, H, z, r, m, gate, x, False, HP, KT, A, S, s3[1])
    if kind == MT_GNSS_POS:
        if acc:
            fs[F_NREJ] = 0.0
        else:
            if fs[F_NREJ] == 0.0:
                fs[F_TREJ0] = t
            fs[F_NREJ] += 1.0
            if fs[F_NREJ] >= cv[C_REJ_RUN]:
                n_evs = _event(evs, n_evs, t, EV_REJECTION_RUN, fs[F_TREJ0], fs[F_NREJ])
                for i in range(3):
                    P[R + i, R + i] += z[i] * z[i]
                nis, acc = kalman_update(P, nx, H, z, r, m, gate, x, True, HP, KT, A, S, s3[1])
                fs[F_NREJ] = 0.0
                fs[F_RESET] = 1.0
    axes = (a0, a1, a2)
    for a in range(m):
        n_inn = _record(inn, n_inn, t, kind, axis0 + axes[a], z[a], S[a, a], nis, acc)
    if acc:
        if not head_known:
            x[PHI + 2] = 0.0
        feedback(st, fs, x, nx, int(cv[C_METHOD]))
    if kind == MT_GNSS_POS or kind == MT_GNSS_VEL or (kind == MT_ZARU and cv[C_ZARU_Q] > 0.0):
        rho = 0.0
        for a in range(m):
            rho += (S[a, a] - r[a]) / (S[a, a] * m)
        n_evs = _adapt(t, kind, nis, m, gate, rho, fs, cv, P, nx, evs, n_evs)
    return n_inn, n_evs


@njit(cache=True)
def _adapt(t, kind, nis, m, gate, rho, fs, cv, P, nx, evs, n_evs):
    """Consistency guard: covariance matching on a scale of Q (docs/fusion.md).

    Per kind (GNSS position, GNSS velocity, and ZARU when its sigma derives from the sensor's ARW, so
    that Q's scale is its scale too), over consecutive windows of ``adapt.window`` measurements:
    the mean ``mu`` of the NIS per dof, each clipped at the gate (``min(NIS, gate) / m``: a rejected
    outlier counts, but no more than a measurement at the gate), and the mean share ``rho`` of the
    filter's own ``H P H^T`` in the innovation variance ``S = H P H^T + R``.  A consistent filter has
    ``mu`` = 1 (std ``sqrt(2 / (m N))``); ``mu`` over ``adapt.threshold`` is the test.  Were the
    filter's part of S too small by ``lam``, ``mu = 1 + rho (lam - 1)``: P and the process-noise scale
    ``q_scale`` (and with it the ZARU variance derived from the ARW) are multiplied by
    ``lam = 1 + (mu - 1) / rho``, at most 10x per window and ``adapt.max_scale`` in all.  Never below 1:
    it only widens; each widening is an event (logged, summarized).
    """
    if cv[C_ADAPT_THR] <= 0.0 or not np.isfinite(nis):
        return n_evs
    b = F_ADAPT + 3 * min(kind, 2)
    fs[b] += min(nis, gate) / m
    fs[b + 1] += 1.0
    fs[b + 2] += rho
    if fs[b + 1] < cv[C_ADAPT_N]:
        return n_evs
    mu = fs[b] / fs[b + 1]
    rho_m = max(fs[b + 2] / fs[b + 1], 0.01)
    fs[b] = 0.0
    fs[b + 1] = 0.0
    fs[b + 2] = 0.0
    if mu > cv[C_ADAPT_THR]:
        f = min(mu if kind == MT_GNSS_POS else 1.0 + (mu - 1.0) / rho_m, 10.0)
        if fs[F_QSCALE] * f > cv[C_QMAX]:
            f = max(cv[C_QMAX] / fs[F_QSCALE], 1.0)
        if f > 1.0:
            fs[F_QSCALE] *= f
            for i in range(nx):
                for j in range(nx):
                    P[i, j] *= f
            n_evs = _event(evs, n_evs, t, EV_ADAPT, f, fs[F_QSCALE])
            fs[F_RESET] = 1.0
    return n_evs


@njit(cache=True)
def _store_epoch(t, P, Pm, nx, fs, ftv, ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset, n_ep):
    """One smoother epoch: P- and P+ (upper triangles, row by row), the integral of F over its
    pattern, the correction fed back since the previous epoch, the reset flag."""
    if n_ep < ep_t.shape[0]:
        ep_t[n_ep] = t
        u = 0
        for i in range(nx):
            ep_x[n_ep, i] = fs[F_XACC + i]
            fs[F_XACC + i] = 0.0
            for j in range(i, nx):
                ep_pm[n_ep, u] = Pm[i, j]
                ep_pp[n_ep, u] = P[i, j]
                u += 1
        for p in range(ftv.shape[0]):
            ep_ft[n_ep, p] = ftv[p]
            ftv[p] = 0.0
        ep_reset[n_ep] = fs[F_RESET]
    fs[F_RESET] = 0.0
    fs[F_T_EPOCH] = t
    return n_ep + 1


@njit(cache=True)
def _measure_group(tm, meas, im, nm, st, fs, cv, P, mats, vecs, s3, ptr, col, ftv, inn, n_inn, evs, n_evs,
                   ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset, n_ep, tol):
    """Propagate P to ``tm`` and apply every row at that time; store the smoother epoch."""
    store = cv[C_SMOOTH_DT] > 0.0
    _do_propagate(st, fs, cv, P, mats[W_F], mats[W_W], ptr, col, ftv, store, cv[C_ITG:C_ITG + 3],
                  cv[C_ITA:C_ITA + 3], cv[C_ARW2:C_ARW2 + 3], cv[C_VRW2:C_VRW2 + 3], cv[C_QBG:C_QBG + 3],
                  cv[C_QBA:C_QBA + 3])
    nx = int(cv[C_NX])
    Pm = mats[W_PM]
    if store:
        for i in range(nx):
            for j in range(nx):
                Pm[i, j] = P[i, j]
    while im < nm and meas[im, 0] <= tm + tol:
        n_inn, n_evs = _apply(meas[im], st, fs, cv, P, mats, vecs, s3, inn, n_inn, evs, n_evs)
        im += 1
    if not _health(P, nx, fs, tm, mats[W_L], True):
        return im, n_inn, n_evs, n_ep
    if store:
        n_ep = _store_epoch(tm, P, Pm, nx, fs, ftv, ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset, n_ep)
    return im, n_inn, n_evs, n_ep


@njit(cache=True, inline="always")
def row_variances(out, n, c, fwd, pe, pn, pu, ve, vn, vu, aee, ann, auu, aen, head_known):
    """The variances of an output row: position, velocity, then roll, pitch (the phi block about the
    body's forward and right axes, levelled) and heading (-1 while the heading is unknown)."""
    ue, un = c[0][fwd], c[1][fwd]
    nrm = np.sqrt(ue * ue + un * un)
    if nrm > 1e-12:
        ue /= nrm
        un /= nrm
    else:
        ue, un = 0.0, 1.0
    out[n, 0] = pe
    out[n, 1] = pn
    out[n, 2] = pu
    out[n, 3] = ve
    out[n, 4] = vn
    out[n, 5] = vu
    out[n, 6] = ue * ue * aee + un * un * ann + 2.0 * ue * un * aen        # about the forward axis
    out[n, 7] = un * un * aee + ue * ue * ann - 2.0 * ue * un * aen        # about the right axis
    out[n, 8] = auu if head_known else -1.0


@njit(cache=True)
def fuse(time, dtheta_b, dvel_b, st, fs, cv, P, meas, ptr, col, ftv, cflu_arr, mats, vecs, s3,
         out_t, out_pos, out_vel, out_cbn, out_var, out_bias, inn, evs,
         ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset, n_ep):
    """Fused navigation of the samples ``time[k]`` with the measurement rows ``meas`` (module docstring).

    ``st`` is the strapdown state (:func:`sinscli.nav.strapdown.new_state`), ``fs`` the filter scalars,
    ``cv`` the configuration vector, ``P`` the covariance (nx, nx), ``ftv`` the integral of F since the
    last smoother epoch over F's pattern ``ptr/col`` (carried between blocks), ``mats/vecs/s3`` the
    :func:`workspace`.  Writes output rows every ``nsub * every`` samples (position, velocity, Cbn, the
    variances of :func:`row_variances`, the sensor estimates), innovation records, events and smoother
    epochs from index ``n_ep``.  Returns ``(rows, measurement rows consumed, innovation records,
    events, n_ep)``; stops early with ``fs[F_ERR]`` set when the covariance turns non-finite or loses
    positive definiteness.
    """
    nx = int(cv[C_NX])
    method = int(cv[C_METHOD])
    order = int(cv[C_ORDER])
    nsub = int(cv[C_NSUB])
    per_out = nsub * int(cv[C_EVERY])
    fwd = int(cv[C_FWD])
    smooth_dt = cv[C_SMOOTH_DT]
    store = smooth_dt > 0.0
    cflu = ((cflu_arr[0, 0], cflu_arr[0, 1], cflu_arr[0, 2]), (cflu_arr[1, 0], cflu_arr[1, 1], cflu_arr[1, 2]),
            (cflu_arr[2, 0], cflu_arr[2, 1], cflu_arr[2, 2]))
    Pm = mats[W_PM]
    Fw, Ww, Lw = mats[W_F], mats[W_W], mats[W_L]
    itg, ita, arw2, vrw2 = cv[C_ITG:C_ITG + 3], cv[C_ITA:C_ITA + 3], cv[C_ARW2:C_ARW2 + 3], cv[C_VRW2:C_VRW2 + 3]
    qbg, qba = cv[C_QBG:C_QBG + 3], cv[C_QBA:C_QBA + 3]
    events = np.empty((1, sd.N_EVENT))
    buf_th = np.empty((1, 3))
    buf_dv = np.empty((1, 3))
    n_ev = 0
    n_out = 0
    n_inn = 0
    n_evs = 0
    im = 0
    nm = meas.shape[0]
    prev_dth, prev_dv, n_prev, sums, nsub_now = sd.load_fast(st)
    z3 = (0.0, 0.0, 0.0)
    for k in range(time.shape[0]):
        tk = time[k]
        t0s = fs[F_TPREV]
        dt = tk - t0s
        tol = 1e-6 * dt
        for i in range(3):
            buf_th[0, i] = (dtheta_b[k, i] - fs[F_BG + i] * dt) / (1.0 + fs[F_SG + i])
            buf_dv[0, i] = (dvel_b[k, i] - fs[F_BA + i] * dt) / (1.0 + fs[F_SA + i])
        th_full = (buf_th[0, 0], buf_th[0, 1], buf_th[0, 2])
        dv_full = (buf_dv[0, 0], buf_dv[0, 1], buf_dv[0, 2])
        frac = 0.0
        # measurements strictly inside the interval: split the increments at their time
        while im < nm and meas[im, 0] < tk - tol:
            tm = meas[im, 0]
            if tm <= t0s + tol:          # before the navigation start: not used
                im += 1
                continue
            a = (tm - t0s) / dt
            for i in range(3):
                buf_th[0, i] = th_full[i] * (a - frac)
                buf_dv[0, i] = dv_full[i] * (a - frac)
            sums, n_prev = sd.fast_sample(buf_th, buf_dv, 0, sums, prev_dth, prev_dv, n_prev, order)
            n_ev = _close(st, fs, sums, order, method, tm, cflu, events, n_ev)
            sums = (z3, z3, z3, z3)
            nsub_now = 0
            frac = a
            im, n_inn, n_evs, n_ep = _measure_group(tm, meas, im, nm, st, fs, cv, P, mats, vecs, s3, ptr, col, ftv,
                                                    inn, n_inn, evs, n_evs, ep_t, ep_pm, ep_pp, ep_ft, ep_x,
                                                    ep_reset, n_ep, tol)
            if fs[F_ERR] != 0.0:
                sd.save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now)
                return n_out, im, n_inn, n_evs, n_ep
        for i in range(3):
            buf_th[0, i] = th_full[i] * (1.0 - frac)
            buf_dv[0, i] = dv_full[i] * (1.0 - frac)
        sums, n_prev = sd.fast_sample(buf_th, buf_dv, 0, sums, prev_dth, prev_dv, n_prev, order)
        nsub_now += 1
        fs[F_TPREV] = tk
        fs[F_NSAMP_OUT] += 1.0
        due = im < nm and meas[im, 0] <= tk + tol
        if nsub_now < nsub and not due:
            continue
        n_ev = _close(st, fs, sums, order, method, tk, cflu, events, n_ev)
        sums = (z3, z3, z3, z3)
        nsub_now = 0
        if due:
            im, n_inn, n_evs, n_ep = _measure_group(tk, meas, im, nm, st, fs, cv, P, mats, vecs, s3, ptr, col, ftv,
                                                    inn, n_inn, evs, n_evs, ep_t, ep_pm, ep_pp, ep_ft, ep_x,
                                                    ep_reset, n_ep, tol)
            if fs[F_ERR] != 0.0:
                break
        elif fs[F_ACC_T] >= cv[C_PROP_DT] * (1.0 - 1e-9):
            _do_propagate(st, fs, cv, P, Fw, Ww, ptr, col, ftv, store, itg, ita, arw2, vrw2, qbg, qba)
            if not _health(P, nx, fs, tk, Lw, False):
                break
            if store and tk - fs[F_T_EPOCH] >= smooth_dt * (1.0 - 1e-9):
                for i in range(nx):
                    for j in range(nx):
                        Pm[i, j] = P[i, j]
                n_ep = _store_epoch(tk, P, Pm, nx, fs, ftv, ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset, n_ep)
        if fs[F_NSAMP_OUT] >= per_out and n_out < out_t.shape[0]:
            fs[F_NSAMP_OUT] = 0.0
            out_t[n_out] = tk
            out_pos[n_out, 0] = st[sd.S_LAT]
            out_pos[n_out, 1] = st[sd.S_LON]
            out_pos[n_out, 2] = st[sd.S_H]
            for i in range(3):
                out_vel[n_out, i] = st[sd.S_VEL + i]
                for j in range(3):
                    out_cbn[n_out, i, j] = st[sd.S_CBN + 3 * i + j]
            row_variances(out_var, n_out, sd._cbn(st), fwd, P[R, R], P[R + 1, R + 1], P[R + 2, R + 2],
                          P[V, V], P[V + 1, V + 1], P[V + 2, V + 2], P[PHI, PHI], P[PHI + 1, PHI + 1],
                          P[PHI + 2, PHI + 2], P[PHI, PHI + 1], fs[F_HEAD_KNOWN] > 0.0)
            for i in range(NBIAS):
                out_bias[n_out, i] = fs[i]
            n_out += 1
    sd.save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now)
    return n_out, im, n_inn, n_evs, n_ep
