"""The strapdown navigation loop: a numba kernel over plain arrays (no I/O).

:func:`run` consumes IMU increments sample by sample (the fast rate l), closes
an attitude interval every N samples (the moderate rate m of Savage's
two-speed design, seed 004), and writes every K-th state into output arrays.
Its whole state lives in one float64 vector (:func:`new_state`), so a long log
runs in chunks with identical results, and no per-sample Python objects exist.

Attitude methods (``ATT_*``):
  * ``ATT_DCM``: ``Cbn <- exp(-[zeta x]) Cbn exp([phi x])`` with the exact closed
    form (Savage eq 26 for the body, eq 49 for the navigation frame), then
    orthonormalization (4.1.3);
  * ``ATT_DCM_SEED000``: the element recursion of seed 000 eqs 12-14 (series
    a1, a2, a3 to theta^6) for the body update, no orthonormalization, as the
    paper; the navigation-frame update as above;
  * ``ATT_QUAT``: ``q <- q(-zeta) o q o q(phi)`` (seed 000 eqs 3-4, Savage eqs
    57-62), normalized (4.2.3);
  * ``ATT_KRYLOV`` / ``ATT_EULER``: the angle methods of seed 003 (see
    :mod:`sinscli.nav.krylov`).
"""
import numpy as np
from numba import njit

from ..layout import Layout
from .coning import (
    CONING_COEFFS,
    body_increments,
    fast_step,
    load_memory,
    push_sample,
    save_memory,
)
from .krylov import (
    SUBSTEP_TOL,
    euler3_dcm_t,
    euler3_init,
    euler3_step_t,
    krylov_init,
    krylov_update_t,
    substep_angle,
)
from .mechanization import (
    displacement,
    first_guess_displacement,
    frame_rotation,
    midpoint,
    position_update,
    velocity_update,
)
from .rotation import (
    conv_to_flu,
    dcm_to_quat,
    m_mul,
    m_trans,
    m_vec,
    quat_mul_t,
    quat_to_dcm_t,
    rotvec_to_dcm_delta_t,
    rotvec_to_quat_delta_t,
    v_add,
    v_scale,
)

ATT_DCM, ATT_DCM_SEED000, ATT_QUAT, ATT_KRYLOV, ATT_EULER = 0, 1, 2, 3, 4

# --- state vector layout (sinscli/layout.py: offsets generated from the fields, tests/test_layout.py) ---
STATE = Layout("strapdown state", [
    ("S_T", 1), ("S_LAT", 1), ("S_LON", 1), ("S_H", 1),   # s, rad, rad, m
    ("S_VEL", 3),              # m/s, ENU
    ("S_CBN", 9),              # Cbn, row-major
    ("S_Q", 4),                # q_b^n, scalar first
    ("S_PDTH", 9),             # MAX_ORDER-1 previous dtheta, 3 each
    ("S_PDV", 9),              # MAX_ORDER-1 previous dvel, 3 each
    ("S_NPREV", 1),            # previous samples held
    ("S_VMM2", 3),             # velocity at t_{m-2}
    ("S_TMM2", 1),
    ("S_HAVE_MM2", 1),         # older velocities available (0, 1, 2)
    ("S_ALPHA", 3), ("S_UPS", 3), ("S_BETA", 3), ("S_SCUL", 3),   # the interval's sums (rad, m/s)
    ("S_NSUB", 1),             # fast samples in the current interval
    ("S_TSTART", 1),           # start time of the current interval
    ("S_NOUT", 1),             # attitude updates since the last output
    ("S_ANG", 4),              # 4 angles (krylov / 3-angle methods)
    ("S_KSET", 1), ("S_PHIB", 1),   # krylov: angle set (0 A, 1 B) and its transfer reference
    ("S_COSMIN", 1),           # smallest |cos| of the 3-angle method so far
    ("S_TCOSMIN", 1),          # and its time
    ("S_QLO", 4),              # compensated-summation residues (see _acc) of q,
    ("S_CLO", 9),              # Cbn,
    ("S_VLO", 3),              # velocity,
    ("S_PLO", 3),              # lat, lon, h
    ("S_PALPHA", 3),           # previous interval's alpha (rate model of the velocity increment)
    ("S_PUPS", 3),             # previous interval's upsilon
    ("S_HAVE_PREV", 1),
    ("S_VMM3", 3),             # velocity at t_{m-3}
    ("S_TMM3", 1),
    ("S_STOPPED", 1),          # 1 when the 3-angle method stopped at its singularity
    ("S_KSUB_ANGLE", 1),       # krylov: largest rotation (rad) of one RK4 sub-step (krylov.substep_angle)
    ("S_KSUB_MAX", 1),         # krylov: most sub-steps in one interval, since the counters were reset
    ("S_KSUB_SUM", 1),         # krylov: sub-steps summed over the intervals counted in S_KSUB_N
    ("S_KSUB_N", 1),           # krylov: intervals counted
], total=102)
(S_T, S_LAT, S_LON, S_H, S_VEL, S_CBN, S_Q, S_PDTH, S_PDV, S_NPREV, S_VMM2, S_TMM2, S_HAVE_MM2, S_ALPHA, S_UPS,
 S_BETA, S_SCUL, S_NSUB, S_TSTART, S_NOUT, S_ANG, S_KSET, S_PHIB, S_COSMIN, S_TCOSMIN, S_QLO, S_CLO, S_VLO, S_PLO,
 S_PALPHA, S_PUPS, S_HAVE_PREV, S_VMM3, S_TMM3, S_STOPPED, S_KSUB_ANGLE, S_KSUB_MAX, S_KSUB_SUM,
 S_KSUB_N) = STATE.offsets(*(name for name, _ in STATE.fields))
STATE_SIZE = STATE.total

N_EVENT = 10           # transfer events: time, old 4 angles, new 4 angles, new set


def new_state(time, lat, lon, h, vel_n, cbn, method=ATT_QUAT, conv=0, krylov_substep_tol=SUBSTEP_TOL):
    """A fresh state vector at the initial time (radians, metres, ENU).

    For the angle methods the angles are initialized from ``Cbn`` in FLU axes
    (docs/krylov.md 4.8; the 3-angle extraction of 2.4); ``krylov_substep_tol`` is the
    relative RK4 truncation allowed per interval (``navigation.krylov_substep_tol``).
    """
    st = np.zeros(STATE_SIZE)
    st[S_T], st[S_LAT], st[S_LON], st[S_H] = time, lat, lon, h
    st[S_VEL:S_VEL + 3] = vel_n
    st[S_CBN:S_CBN + 9] = np.asarray(cbn, dtype=np.float64).ravel()
    st[S_Q:S_Q + 4] = dcm_to_quat(np.ascontiguousarray(cbn, dtype=np.float64))
    st[S_TSTART] = time
    st[S_COSMIN] = 1.0
    st[S_KSUB_ANGLE] = substep_angle(krylov_substep_tol)
    if method in (ATT_KRYLOV, ATT_EULER):
        c_flu = np.asarray(cbn, dtype=np.float64) @ conv_to_flu(conv).T
        if method == ATT_KRYLOV:
            ang, kset, phib = krylov_init(np.ascontiguousarray(c_flu))
            st[S_ANG:S_ANG + 4] = ang
            st[S_KSET], st[S_PHIB] = kset, phib
        else:
            st[S_ANG:S_ANG + 3] = euler3_init(np.ascontiguousarray(c_flu))
    return st


@njit(cache=True, inline="always")
def _vec(st, i):
    return (st[i], st[i + 1], st[i + 2])


@njit(cache=True, inline="always")
def _set_vec(st, i, v):
    st[i], st[i + 1], st[i + 2] = v[0], v[1], v[2]


@njit(cache=True, inline="always")
def _cbn(st):
    return ((st[S_CBN], st[S_CBN + 1], st[S_CBN + 2]),
            (st[S_CBN + 3], st[S_CBN + 4], st[S_CBN + 5]),
            (st[S_CBN + 6], st[S_CBN + 7], st[S_CBN + 8]))


@njit(cache=True, inline="always")
def _set_cbn(st, c):
    for i in range(3):
        for j in range(3):
            st[S_CBN + 3 * i + j] = c[i][j]


@njit(cache=True, inline="always")
def load_fast(st):
    """The fast-rate state of a block's start: sample memory, its count, the interval sums, samples so far."""
    prev_dth, prev_dv = load_memory(st, S_PDTH, S_PDV)
    sums = (_vec(st, S_ALPHA), _vec(st, S_UPS), _vec(st, S_BETA), _vec(st, S_SCUL))
    return prev_dth, prev_dv, int(st[S_NPREV]), sums, int(st[S_NSUB])


@njit(cache=True, inline="always")
def fast_sample(dtheta_b, dvel_b, k, sums, prev_dth, prev_dv, n_prev, order):
    """Sample k at the fast rate: coning/sculling sums (eqs 41-47), then the sample memory."""
    dth = (dtheta_b[k, 0], dtheta_b[k, 1], dtheta_b[k, 2])
    dv = (dvel_b[k, 0], dvel_b[k, 1], dvel_b[k, 2])
    sums = fast_step(sums[0], sums[1], sums[2], sums[3], dth, dv, prev_dth, prev_dv,
                     min(n_prev, order - 1), CONING_COEFFS[order - 1])
    return sums, push_sample(prev_dth, prev_dv, dth, dv, n_prev)


@njit(cache=True, inline="always")
def close_interval(st, sums, order):
    """Body rotation vector and velocity increment of the closing attitude interval (eq 35 and
    :func:`sinscli.nav.coning.body_increments`); keeps its sums for the next interval's rate model.

    Order 1 is seed 000's fixed axis: ``phi = alpha``.  Returns ``(phi, dv_b, alpha_prev)``,
    ``alpha_prev`` being the previous interval's angle sum (this one's at the start).
    """
    alpha, ups, beta, scul = sums
    have = st[S_HAVE_PREV] > 0.0
    alpha_prev = _vec(st, S_PALPHA) if have else alpha
    phi, dv_b = body_increments(alpha, ups, beta, scul, _vec(st, S_PALPHA), _vec(st, S_PUPS), have and order > 1)
    _set_vec(st, S_PALPHA, alpha)
    _set_vec(st, S_PUPS, ups)
    st[S_HAVE_PREV] = 1.0
    if order == 1:
        phi = alpha
    return phi, dv_b, alpha_prev


@njit(cache=True, inline="always")
def save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now):
    """Store the fast-rate state for the next block (inverse of :func:`load_fast`)."""
    save_memory(st, S_PDTH, S_PDV, prev_dth, prev_dv)
    st[S_NPREV] = n_prev
    _set_vec(st, S_ALPHA, sums[0])
    _set_vec(st, S_UPS, sums[1])
    _set_vec(st, S_BETA, sums[2])
    _set_vec(st, S_SCUL, sums[3])
    st[S_NSUB] = nsub_now


@njit(cache=True)
def _seed000_row_delta(ci, th, a1m1, a2, a3):
    b = ci[0] * th[0] + ci[1] * th[1] + ci[2] * th[2]
    return (a1m1 * ci[0] + a2 * (ci[1] * th[2] - ci[2] * th[1]) + a3 * b * th[0],
            a1m1 * ci[1] + a2 * (ci[2] * th[0] - ci[0] * th[2]) + a3 * b * th[1],
            a1m1 * ci[2] + a2 * (ci[0] * th[1] - ci[1] * th[0]) + a3 * b * th[2])


@njit(cache=True)
def _seed000_body_delta(c, th):
    """Seed 000 eqs 12-14 as a change ``C' - C``:
    ``C'_ij = a1 C_ij + a2 (C_i,j+1 th_j+2 - C_i,j+2 th_j+1) + a3 b_i th_j`` with
    ``a2 = 1 - D/6 + D^2/120``, ``a3 = 1/2 - D/24 + D^2/720``, ``a1 = 1 - D a3``,
    ``D = |th|^2``, ``b_i = sum_j C_ij th_j`` (so ``a1 - 1 = -D a3``).
    """
    d = th[0] * th[0] + th[1] * th[1] + th[2] * th[2]
    a2 = 1.0 - d / 6.0 + d * d / 120.0
    a3 = 0.5 - d / 24.0 + d * d / 720.0
    a1m1 = -d * a3
    return (_seed000_row_delta(c[0], th, a1m1, a2, a3), _seed000_row_delta(c[1], th, a1m1, a2, a3),
            _seed000_row_delta(c[2], th, a1m1, a2, a3))


@njit(cache=True, inline="always")
def _acc(st, i, lo, x):
    """``st[i] += x`` with a compensated (TwoSum) residue kept in ``st[lo]``.

    Every integrated state accumulates this way: increments below half an ulp
    of the state (time-stamp rounding, slow drifts) are carried instead of
    being rounded away with a bias that would turn noise into drift.
    """
    a = st[i]
    b = x + st[lo]
    s = a + b
    bb = s - a
    st[lo] = (a - (s - bb)) + (b - bb)
    st[i] = s


@njit(cache=True)
def _m_add(a, b):
    return ((a[0][0] + b[0][0], a[0][1] + b[0][1], a[0][2] + b[0][2]),
            (a[1][0] + b[1][0], a[1][1] + b[1][1], a[1][2] + b[1][2]),
            (a[2][0] + b[2][0], a[2][1] + b[2][1], a[2][2] + b[2][2]))


@njit(cache=True)
def _q_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


@njit(cache=True, inline="always")
def _attitude_update(st, method, phi, zeta):
    """Body and navigation-frame attitude update of one interval; keeps Cbn and q in step.

    The products are expanded around the old attitude, ``C' = C + (E_n C + C E_b
    + E_n C E_b)`` with ``E = exp([. x]) - I`` (and likewise for the
    quaternion), so that at rest, where the body and frame rotations cancel,
    the state is not rounded step after step in the same direction.
    """
    if method == ATT_QUAT:
        _att_quat(st, phi, zeta)
    elif method == ATT_DCM_SEED000:
        _att_dcm_seed000(st, phi, zeta)
    else:
        _att_dcm(st, phi, zeta)


@njit(cache=True)
def _att_quat(st, phi, zeta):
    """Quaternion update (seed 000 eqs 3-4, Savage eqs 57-62) of :func:`_attitude_update`."""
    zm = v_scale(zeta, -1.0)
    q = (st[S_Q], st[S_Q + 1], st[S_Q + 2], st[S_Q + 3])
    en = rotvec_to_quat_delta_t(zm)
    eb = rotvec_to_quat_delta_t(phi)
    en_q = quat_mul_t(en, q)
    dq = _q_add(_q_add(en_q, quat_mul_t(q, eb)), quat_mul_t(en_q, eb))
    for i in range(4):
        _acc(st, S_Q + i, S_QLO + i, dq[i])
    # normalization (4.2.3) as a small correction: q (1/|q| - 1)
    n2 = 0.0
    for i in range(4):
        n2 += st[S_Q + i] * st[S_Q + i]
    f = 1.0 / np.sqrt(n2) - 1.0
    for i in range(4):
        _acc(st, S_Q + i, S_QLO + i, st[S_Q + i] * f)
    _set_cbn(st, quat_to_dcm_t((st[S_Q], st[S_Q + 1], st[S_Q + 2], st[S_Q + 3])))


@njit(cache=True)
def _att_dcm_seed000(st, phi, zeta):
    """Seed 000 eqs 12-14 body update with the exact navigation-frame update, of :func:`_attitude_update`."""
    zm = v_scale(zeta, -1.0)
    c = _cbn(st)
    db = _seed000_body_delta(c, phi)
    dc = _m_add(db, m_mul(rotvec_to_dcm_delta_t(zm), _m_add(c, db)))
    for i in range(3):
        for j in range(3):
            _acc(st, S_CBN + 3 * i + j, S_CLO + 3 * i + j, dc[i][j])


@njit(cache=True)
def _att_dcm(st, phi, zeta):
    """Exact closed-form DCM update (Savage eqs 26, 49) and orthonormalization, of :func:`_attitude_update`."""
    zm = v_scale(zeta, -1.0)
    c = _cbn(st)
    en_c = m_mul(rotvec_to_dcm_delta_t(zm), c)
    eb = rotvec_to_dcm_delta_t(phi)
    dc = _m_add(_m_add(en_c, m_mul(c, eb)), m_mul(en_c, eb))
    for i in range(3):
        for j in range(3):
            _acc(st, S_CBN + 3 * i + j, S_CLO + 3 * i + j, dc[i][j])
    # orthonormalization (4.1.3) as a small symmetric correction -1/2 C (C^T C - I)
    c = _cbn(st)
    e = m_mul(m_trans(c), c)
    e = ((e[0][0] - 1.0, e[0][1], e[0][2]), (e[1][0], e[1][1] - 1.0, e[1][2]),
         (e[2][0], e[2][1], e[2][2] - 1.0))
    ce = m_mul(c, e)
    for i in range(3):
        for j in range(3):
            _acc(st, S_CBN + 3 * i + j, S_CLO + 3 * i + j, -0.5 * ce[i][j])


@njit(cache=True, inline="always")
def _angle_update(st, method, alpha, alpha_prev, zeta, cflu, integrator, t_start, events, n_ev):
    """Seed 003 angle methods over one interval (docs/krylov.md 4.6, 2.4), in FLU axes.

    ``alpha``/``alpha_prev`` are the raw summed body increments of this and the
    previous interval (the two-sample rate model does the coning part, so the
    coning-compensated ``phi`` is not used); ``zeta`` enters as the navigation-
    frame rate over a unit interval.  Writes Cbn (body convention) to the state;
    records a transfer in ``events`` and returns the new event count.  The
    four-angle update takes as many RK4 sub-steps as ``st[S_KSUB_ANGLE]`` asks
    for (:func:`sinscli.nav.krylov.substep_count`) and counts them in
    ``S_KSUB_MAX/SUM/N`` (the caller reads and resets them per block).
    """
    if method == ATT_KRYLOV:
        return _angle_krylov(st, alpha, alpha_prev, zeta, cflu, t_start, events, n_ev)
    _angle_euler(st, alpha, alpha_prev, zeta, cflu, integrator, t_start)
    return n_ev


@njit(cache=True)
def _angle_krylov(st, alpha, alpha_prev, zeta, cflu, t_start, events, n_ev):
    """The four-angle update of :func:`_angle_update` (docs/krylov.md 4.6); returns the event count."""
    a_f = m_vec(cflu, alpha)
    p_f = m_vec(cflu, alpha_prev)
    ang = (st[S_ANG], st[S_ANG + 1], st[S_ANG + 2], st[S_ANG + 3])
    new, kset, phib, moved, c_flu, nrk = krylov_update_t(ang, int(st[S_KSET]), st[S_PHIB], p_f, a_f, 1.0,
                                                         zeta, st[S_KSUB_ANGLE])
    st[S_KSUB_MAX] = max(st[S_KSUB_MAX], nrk)
    st[S_KSUB_SUM] += nrk
    st[S_KSUB_N] += 1.0
    if moved:
        if n_ev < events.shape[0]:
            events[n_ev, 0] = t_start
            for i in range(4):
                events[n_ev, 1 + i] = ang[i]
                events[n_ev, 5 + i] = new[i]
            events[n_ev, 9] = kset
        n_ev += 1
    for i in range(4):
        st[S_ANG + i] = new[i]
    st[S_KSET], st[S_PHIB] = kset, phib
    # C_conv^n = C_flu^n C_conv^flu
    _set_cbn(st, m_mul(c_flu, cflu))
    return n_ev


@njit(cache=True)
def _angle_euler(st, alpha, alpha_prev, zeta, cflu, integrator, t_start):
    """The three-angle update of :func:`_angle_update` (docs/krylov.md 2.4)."""
    a_f = m_vec(cflu, alpha)
    p_f = m_vec(cflu, alpha_prev)
    ang3 = (st[S_ANG], st[S_ANG + 1], st[S_ANG + 2])
    new3, cmin = euler3_step_t(ang3, p_f, a_f, 1.0, zeta, integrator)
    if cmin < st[S_COSMIN]:
        st[S_COSMIN] = cmin
        st[S_TCOSMIN] = t_start
    for i in range(3):
        st[S_ANG + i] = new3[i]
    c_flu = euler3_dcm_t(new3)
    # C_conv^n = C_flu^n C_conv^flu
    _set_cbn(st, m_mul(c_flu, cflu))


@njit(cache=True, inline="always")
def interval_update(st, sums, order, method, t_end, cflu, integrator, events, n_ev):
    """One attitude interval closes at ``t_end``: the moderate-rate update of the state ``st``.

    Body increments (:func:`close_interval`), displacement and velocity with the midpoint
    navigation-frame rotation (:mod:`sinscli.nav.mechanization`), attitude (or the angle methods),
    position, then the compensated accumulation of every integrated state and the interval's
    bookkeeping (``S_T = S_TSTART = t_end``).  The one mechanization step shared by :func:`run` and
    the fusion kernel (:mod:`sinscli.fusion.kernel`); returns the event count ``n_ev``.
    """
    T = t_end - st[S_TSTART]
    phi, dv_b, alpha_prev = close_interval(st, sums, order)
    cbn = _cbn(st)
    dv_n0 = m_vec(cbn, dv_b)
    vel = _vec(st, S_VEL)
    lat, h = st[S_LAT], st[S_H]
    v_mm2 = _vec(st, S_VMM2)
    v_mm3 = _vec(st, S_VMM3)
    nhist = int(st[S_HAVE_MM2])
    h1 = st[S_TSTART] - st[S_TMM2]
    h2 = st[S_TMM2] - st[S_TMM3]
    dR = first_guess_displacement(vel, dv_n0, lat, h, T)
    for _ in range(2):
        lat_mid, h_mid = midpoint(lat, h, dR)
        zeta = frame_rotation(lat_mid, h_mid, dR, T)
        dvel = velocity_update(vel, dv_n0, zeta, lat_mid, h_mid, dR, T)
        v_new = v_add(vel, dvel)
        dR = displacement(v_mm3, v_mm2, vel, v_new, h2, h1, T, nhist)
    lat_mid, h_mid = midpoint(lat, h, dR)
    zeta = frame_rotation(lat_mid, h_mid, dR, T)
    if method == ATT_KRYLOV or method == ATT_EULER:
        n_ev = _angle_update(st, method, sums[0], alpha_prev, zeta, cflu, integrator, st[S_TSTART], events, n_ev)
    else:
        _attitude_update(st, method, phi, zeta)
    dlat, dlon, dh = position_update(lat, h, dR)
    store_interval(st, vel, dvel, nhist, t_end)
    _acc(st, S_LAT, S_PLO, dlat)
    _acc(st, S_LON, S_PLO + 1, dlon)
    _acc(st, S_H, S_PLO + 2, dh)
    return n_ev


@njit(cache=True)
def store_interval(st, vel, dvel, nhist, t_end):
    """The store step of an attitude interval, shared by both frames (:func:`interval_update` and the
    launch-inertial loop, :mod:`sinscli.nav.inertial`): the velocity history moves one interval back
    (``v_{m-3} <- v_{m-2} <- v_{m-1} = vel``, for the Adams-Moulton displacement), ``dvel`` is added to the
    velocity with its compensated residue (:func:`_acc`), and the interval closes at ``t_end``
    (``S_T = S_TSTART = t_end``).  The caller adds its own position increment.
    """
    _set_vec(st, S_VMM3, _vec(st, S_VMM2))
    st[S_TMM3] = st[S_TMM2]
    _set_vec(st, S_VMM2, vel)
    st[S_TMM2] = st[S_TSTART]
    st[S_HAVE_MM2] = min(nhist + 1, 2)
    for i in range(3):
        _acc(st, S_VEL + i, S_VLO + i, dvel[i])
    st[S_T] = t_end
    st[S_TSTART] = t_end


def run(time, dtheta_b, dvel_b, st, method, order, nsub, every, cflu_arr, integrator, cos_stop,
        out_t, out_pos, out_vel, out_cbn, out_ang, events):
    """Navigate the samples ``time[k]`` (end of each increment interval) from state ``st``.

    ``order`` is the coning/sculling order K (1-4), ``nsub`` the fast samples per
    attitude update N, ``every`` the output decimation in attitude updates.
    ``cflu_arr`` is ``C_conv^FLU`` of the body convention (angle methods work in
    FLU); ``integrator`` the 3-angle integrator (0 Euler, 1 RK4); the 3-angle
    method stops (``st[S_STOPPED] = 1``) when |cos psi| falls under ``cos_stop``
    (pass 0 to carry on).  Writes states into the ``out_*`` arrays (capacity
    ``len(time) // (nsub*every) + 1``; ``out_ang`` gets the raw angles and set),
    transfer events into ``events``; returns ``(rows written, events seen)``.
    Runs the compiled entry point of the attitude method, :data:`RUN` ``[method]``.
    """
    return RUN[method](time, dtheta_b, dvel_b, st, order, nsub, every, cflu_arr, integrator, cos_stop,
                       out_t, out_pos, out_vel, out_cbn, out_ang, events)


def _entry(method):
    """The compiled loop of :func:`run` for one attitude method.

    ``method`` is a constant (a closure cell) inside it, so numba prunes the other methods' branches
    before typing: a quat run compiles neither the Krylov nor the 3-angle update.  The loop is written
    here, not inlined from a shared function: numba's inliner copies a callee's IR at a cost that grows
    with its size squared, and the whole loop was the largest callee (docs/engine.md, first run).
    """
    @njit(cache=True)
    def entry(time, dtheta_b, dvel_b, st, order, nsub, every, cflu_arr, integrator, cos_stop,
              out_t, out_pos, out_vel, out_cbn, out_ang, events):
        cflu = ((cflu_arr[0, 0], cflu_arr[0, 1], cflu_arr[0, 2]), (cflu_arr[1, 0], cflu_arr[1, 1], cflu_arr[1, 2]),
                (cflu_arr[2, 0], cflu_arr[2, 1], cflu_arr[2, 2]))
        n_ev = 0
        n_out = 0
        prev_dth, prev_dv, n_prev, sums, nsub_now = load_fast(st)
        for k in range(time.shape[0]):
            sums, n_prev = fast_sample(dtheta_b, dvel_b, k, sums, prev_dth, prev_dv, n_prev, order)
            nsub_now += 1
            if nsub_now < nsub:
                continue
            # ---- attitude interval closes: moderate-rate update ----
            t_end = time[k]
            n_ev = interval_update(st, sums, order, method, t_end, cflu, integrator, events, n_ev)
            lat, lon, h = st[S_LAT], st[S_LON], st[S_H]
            v_new = _vec(st, S_VEL)
            z = (0.0, 0.0, 0.0)
            sums = (z, z, z, z)
            nsub_now = 0
            st[S_NOUT] += 1.0
            if st[S_NOUT] >= every:
                st[S_NOUT] = 0.0
                out_t[n_out] = t_end
                out_pos[n_out, 0], out_pos[n_out, 1], out_pos[n_out, 2] = lat, lon, h
                out_vel[n_out, 0], out_vel[n_out, 1], out_vel[n_out, 2] = v_new[0], v_new[1], v_new[2]
                for i in range(3):
                    for j in range(3):
                        out_cbn[n_out, i, j] = st[S_CBN + 3 * i + j]
                for i in range(4):
                    out_ang[n_out, i] = st[S_ANG + i]
                out_ang[n_out, 4] = st[S_KSET]
                n_out += 1
            if method == ATT_EULER and st[S_COSMIN] < cos_stop:
                st[S_STOPPED] = 1.0
                break
        save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now)
        return n_out, n_ev
    return entry


#: attitude method code -> its compiled entry point (:func:`run` dispatches through it)
RUN = {m: _entry(m) for m in (ATT_DCM, ATT_DCM_SEED000, ATT_QUAT, ATT_KRYLOV, ATT_EULER)}
