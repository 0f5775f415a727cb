"""Inertial-frame alignment by attitude determination (seed 001, Fang, Gao, Xue 2016): the kernels.

The attitude is split as (eq 4)

    Cbn(t) = C_n(0)^n(t) Cbn(0) C_b(t)^b(0)

and the velocity equation, integrated in the frames n(0) and b(0) frozen in
inertial space, gives ``Cbn(0) alpha_v(t) = beta_v(t)`` (eq 16) with

    alpha_v(t) = int_0^t C_b(tau)^b(0) f^b dtau                                   (eq 17)
    beta_v(t)  = C_n(t)^n(0) v^n(t) - v^n(0)
                 + int_0^t C_n(tau)^n(0) w_ie^n x v^n dtau - int_0^t C_n(tau)^n(0) g^n dtau   (eq 18)

:func:`body_side` accumulates ``C_b(t)^b(0)`` (eq 5) and ``alpha_v`` from the
IMU increments with the project's coning/sculling kernels: each step adds
``C_b(t_k)^b(0) dv^b``, where ``dv^b`` already carries the rotation term
``int (int w dtau) x f dt`` inside the step (eq 19) and sculling.
:func:`nav_side` accumulates ``C_n(t)^n(0)`` (eq 6, earth rate plus the
transport rate from the GNSS velocity) and ``beta_v`` with the gravity
integral of eqs 20-21 and the Coriolis integral of eqs 22-24 (velocity linear
over each step, eq 23).  No I/O here: plain arrays in, arrays out.
"""
import numpy as np
from numba import njit

from ..nav.coning import CONING_COEFFS, MAX_ORDER, body_increments, fast_step, push_sample
from ..nav.earth import OMEGA_IE, gravity, transport_rate_n
from ..nav.mechanization import gamma_delta
from ..nav.rotation import (m_mul, m_vec, orthonormalize_t, rotvec_to_dcm_t, v_add, v_cross, v_scale,
                            v_sub)

_ORTHO_EVERY = 1024        # steps between re-orthonormalizations of the running DCMs

_I3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@njit(cache=True, inline="always")
def _store_m(out, k, c):
    for i in range(3):
        for j in range(3):
            out[k, i, j] = c[i][j]


@njit(cache=True, inline="always")
def _store_v(out, k, v):
    out[k, 0], out[k, 1], out[k, 2] = v[0], v[1], v[2]


@njit(cache=True)
def body_side(dtheta_b, dvel_b, order, out_cbb0, out_alpha):
    """``C_b(t_k)^b(0)`` and ``alpha_v(t_k)`` (eqs 5, 17, 19) for k = 0..M.

    ``dtheta_b``/``dvel_b`` (M, 3): increments over (t_{k-1}, t_k], the first
    starting at the alignment start t_0.  ``order``: coning/sculling order K
    (1-4) of :mod:`sinscli.nav.coning`.  Row 0 of the outputs is the start
    (identity, zero).  Each step: ``phi, dv^b = body_increments(...)`` (rotation
    vector and velocity increment with rotation compensation and sculling, in
    b(t_{k-1})), ``alpha += C dv^b``, ``C <- C exp([phi x])``.
    """
    m = dtheta_b.shape[0]
    coeffs = CONING_COEFFS[order - 1]
    nprev_max = order - 1
    prev_dth = np.zeros((MAX_ORDER - 1, 3))
    prev_dv = np.zeros((MAX_ORDER - 1, 3))
    n_prev = 0
    zero = (0.0, 0.0, 0.0)
    c = _I3
    alpha = zero
    a_prev = zero
    u_prev = zero
    have_prev = False
    _store_m(out_cbb0, 0, c)
    _store_v(out_alpha, 0, alpha)
    for k in range(m):
        dth = (dtheta_b[k, 0], dtheta_b[k, 1], dtheta_b[k, 2])
        dv = (dvel_b[k, 0], dvel_b[k, 1], dvel_b[k, 2])
        a, u, b, s = fast_step(zero, zero, zero, zero, dth, dv, prev_dth, prev_dv,
                               min(n_prev, nprev_max), coeffs)
        phi, dv_b = body_increments(a, u, b, s, a_prev, u_prev, have_prev and order > 1)
        if order == 1:
            phi = a
        a_prev, u_prev, have_prev = a, u, True
        n_prev = push_sample(prev_dth, prev_dv, dth, dv, n_prev)
        alpha = v_add(alpha, m_vec(c, dv_b))
        c = m_mul(c, rotvec_to_dcm_t(phi))
        if (k + 1) % _ORTHO_EVERY == 0:
            c = orthonormalize_t(c)
        _store_m(out_cbb0, k + 1, c)
        _store_v(out_alpha, k + 1, alpha)


@njit(cache=True)
def nav_side(dt, lat, h, vel_n, out_cnn0, out_beta):
    """``C_n(t_k)^n(0)`` and ``beta_v(t_k)`` (eqs 6, 18, 20-24) for k = 0..M.

    ``dt`` (M,) step lengths, s; ``lat`` (M+1,) rad, ``h`` (M+1,) m and
    ``vel_n`` (M+1, 3) ENU m/s at t_0..t_M (zero velocity on a static or
    moored base).  Per step of length T, with ``w_in`` at the step midpoint and
    ``zeta = w_in T``:

        int C_n(t)^n(0) g dt        = C_k T Gamma(-zeta) g,  Gamma(-zeta) = I + [zeta x]/2 + [zeta x]^2/6
                                                            (eq 21 with its next term)
        int C_n(t)^n(0) w_ie x v dt = C_k [(T/2 + T/6 [zeta x]) w_ie x v_k
                                           + (T/2 + T/3 [zeta x]) w_ie x v_k+1]   (eq 24)
        C_{k+1} = C_k exp([zeta x])
    """
    m = dt.shape[0]
    c = _I3
    g_int = (0.0, 0.0, 0.0)
    cor_int = (0.0, 0.0, 0.0)
    v0 = (vel_n[0, 0], vel_n[0, 1], vel_n[0, 2])
    _store_m(out_cnn0, 0, c)
    _store_v(out_beta, 0, (0.0, 0.0, 0.0))
    for k in range(m):
        T = dt[k]
        vk = (vel_n[k, 0], vel_n[k, 1], vel_n[k, 2])
        vk1 = (vel_n[k + 1, 0], vel_n[k + 1, 1], vel_n[k + 1, 2])
        lat_m = 0.5 * (lat[k] + lat[k + 1])
        h_m = 0.5 * (h[k] + h[k + 1])
        w_ie = (0.0, OMEGA_IE * np.cos(lat_m), OMEGA_IE * np.sin(lat_m))
        w_en_a = transport_rate_n(lat_m, h_m, np.array([0.5 * (vk[0] + vk1[0]), 0.5 * (vk[1] + vk1[1]),
                                                        0.5 * (vk[2] + vk1[2])]))
        zeta = v_scale(v_add(w_ie, (w_en_a[0], w_en_a[1], w_en_a[2])), T)
        gT = (0.0, 0.0, -gravity(np.sin(lat_m), h_m) * T)
        g_int = v_add(g_int, m_vec(c, v_add(gT, gamma_delta(v_scale(zeta, -1.0), gT))))
        a0 = v_cross(w_ie, vk)
        a1 = v_cross(w_ie, vk1)
        step = v_add(v_add(v_scale(a0, 0.5 * T), v_scale(v_cross(zeta, a0), T / 6.0)),
                     v_add(v_scale(a1, 0.5 * T), v_scale(v_cross(zeta, a1), T / 3.0)))
        cor_int = v_add(cor_int, m_vec(c, step))
        c = m_mul(c, rotvec_to_dcm_t(zeta))
        if (k + 1) % _ORTHO_EVERY == 0:
            c = orthonormalize_t(c)
        beta = v_sub(v_add(v_sub(m_vec(c, vk1), v0), cor_int), g_int)
        _store_m(out_cnn0, k + 1, c)
        _store_v(out_beta, k + 1, beta)


def integrate(dtheta_b, dvel_b, dt, lat, h, vel_n, order: int = 2):
    """Both sides over one window: ``(Cbb0, alpha, Cnn0, beta)``, each with M+1 rows (row 0 = start)."""
    m = dtheta_b.shape[0]
    cbb0 = np.empty((m + 1, 3, 3))
    alpha = np.empty((m + 1, 3))
    cnn0 = np.empty((m + 1, 3, 3))
    beta = np.empty((m + 1, 3))
    body_side(np.ascontiguousarray(dtheta_b, dtype=np.float64), np.ascontiguousarray(dvel_b, dtype=np.float64),
              int(order), cbb0, alpha)
    nav_side(np.ascontiguousarray(dt, dtype=np.float64), np.ascontiguousarray(lat, dtype=np.float64),
             np.ascontiguousarray(h, dtype=np.float64), np.ascontiguousarray(vel_n, dtype=np.float64), cnn0, beta)
    return cbb0, alpha, cnn0, beta


def lever_arm_alpha(alpha, cbb0, w_ib_b, lever_b):
    """``alpha`` with the GNSS lever arm moved to the body side.

    With ``u(t) = w_ib^b(t) x l^b`` (the antenna's velocity relative to the IMU
    in body axes; the earth-rate part, ~1e-4 m/s, is left out) and
    ``beta`` formed from the antenna velocity:
    ``Cbn(0) [alpha(t) + C_b(t)^b(0) u(t) - u(0)] = beta_ant(t)``.
    ``alpha`` (n, 3), ``cbb0`` (n, 3, 3), ``w_ib_b`` (n, 3) at the same epochs
    (row 0 = the start).
    """
    lever_b = np.asarray(lever_b, dtype=float)
    u = np.cross(w_ib_b, lever_b[None, :])
    return alpha + np.einsum("nij,nj->ni", cbb0, u) - u[0][None, :]


def attitude_at(cbn0, cbb0, cnn0):
    """``Cbn(t) = C_n(0)^n(t) Cbn(0) C_b(t)^b(0)`` (eq 4) at each epoch; ``cbn0`` (3, 3) or (n, 3, 3)."""
    return np.matmul(np.matmul(np.swapaxes(cnn0, -1, -2), cbn0), cbb0)
