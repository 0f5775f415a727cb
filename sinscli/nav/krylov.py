"""Attitude by extended (four) Krylov angles, and the classic three (seed 003).

Formulas and section numbers are those of ``docs/krylov.md``, which
rebuilds the patent's lost equations.  The navigation frame is ENU and the
body frame FLU (x forward, y left, z up); the caller turns other body
conventions into FLU before calling.

Four-angle state ``ang = (phi, psi, gamma, xi)`` in radians with

    Cbn = Rz(phi) Ry(psi) Rx(gamma) Ry(xi)                          (sec. 1.3)

and an active set ``kset``: ``SET_A`` (psi = 0 frozen, active phi, gamma, xi)
or ``SET_B`` (phi = phiB frozen, active psi, gamma, xi; ``ang[0] == phiB``).
Set A is singular at |gamma| = 90 deg, set B at gamma = 0 or 180 deg; the
transfer rule of sec. 3 keeps the active set at least 45 deg (less one step's
overshoot) away from its singularity.

The classic three Krylov angles ``ang3 = (phi, psi, gamma)`` are the same
sequence with xi = 0 (sec. 2.4), singular at cos psi = 0.

All kernels are numba ``njit`` functions with no I/O.  As in
``rotation.py``, the cores (``*_t``) work on tuples (angles as 4- or
3-tuples, vectors as 3-tuples, matrices as tuples of row tuples) so that the
navigation loop allocates nothing per sample; the array functions of the same
name without ``_t`` wrap them for other callers.
"""
import math

import numpy as np
from numba import njit

from .rotation import m_from_array, m_to_array

SET_A, SET_B = 0, 1
GAMMA_S = 0.25 * math.pi            # transfer threshold gamma_s = 45 deg (sec. 3.1)
COS_GAMMA_S = math.cos(GAMMA_S)
HALF_PI = 0.5 * math.pi
TWO_PI = 2.0 * math.pi
EULER3_FORWARD_EULER, EULER3_RK4 = 0, 1
# Taylor coefficients of sin and cos (used by _cs_shift)
_S3, _S5, _S7, _S9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
_C4, _C6, _C8, _C10 = 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0, -1.0 / 3628800.0
_CPSI_FLOOR = 1e-15                 # |cos psi| floor of the 3-angle rates (no division by zero)
# RK4 sub-steps (docs/krylov.md "Sub-steps under fast rotation"): one RK4 step of the angle
# equations that turns the body by theta rad errs by at most RK4_KAPPA theta^5 rad (worst case
# over attitudes within the 45 deg margin, measured); a sub-step may turn by at most
# (tol / RK4_KAPPA)^(1/4), so that the truncation stays under tol theta per interval.
RK4_KAPPA = 0.04
SUBSTEP_TOL = 1.0e-9                # default of navigation.krylov_substep_tol
MAX_SUBSTEPS = 64


def substep_angle(tol=SUBSTEP_TOL):
    """Largest rotation (rad) of one RK4 sub-step for the relative truncation ``tol`` per interval.

    RK4's error on an interval that turns by theta in m sub-steps is about
    ``m RK4_KAPPA (theta/m)^5 = RK4_KAPPA (theta/m)^4 theta``; keeping it under
    ``tol theta`` gives ``theta/m <= (tol / RK4_KAPPA)^(1/4)``.
    """
    return (tol / RK4_KAPPA) ** 0.25


SUBSTEP_ANGLE = substep_angle()


@njit(cache=True, error_model="numpy")
def wrap_pi(a):
    """Angle ``a`` (rad) mapped to (-pi, pi] (``wrap`` of docs/krylov.md)."""
    if -math.pi < a <= math.pi:
        return a
    return a - TWO_PI * math.ceil((a - math.pi) / TWO_PI)


@njit(cache=True, error_model="numpy", inline="always")
def _dcm_from_trig(cf, sf, cp, sp, cg, sg, cx, sx):
    """Element form of sec. 1.3 from the cosines and sines of (phi, psi, gamma, xi)."""
    # rows E, N of B = Ry(psi) Rx(gamma) Ry(xi); row U of B is row U of Cbn
    be0 = cp * cx - sp * cg * sx
    be1 = sp * sg
    be2 = cp * sx + sp * cg * cx
    bn0 = sg * sx
    bn1 = cg
    bn2 = -sg * cx
    return ((cf * be0 - sf * bn0, cf * be1 - sf * bn1, cf * be2 - sf * bn2),
            (sf * be0 + cf * bn0, sf * be1 + cf * bn1, sf * be2 + cf * bn2),
            (-sp * cx - cp * cg * sx, cp * sg, -sp * sx + cp * cg * cx))


@njit(cache=True, error_model="numpy")
def krylov4_dcm_t(phi, psi, gamma, xi):
    """``Cbn = Rz(phi) Ry(psi) Rx(gamma) Ry(xi)`` in element form (sec. 1.3), radians -> matrix tuple."""
    return _dcm_from_trig(math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi),
                          math.cos(gamma), math.sin(gamma), math.cos(xi), math.sin(xi))


@njit(cache=True, error_model="numpy")
def krylov4_dcm(phi, psi, gamma, xi):
    """Array form of :func:`krylov4_dcm_t` (3x3)."""
    return m_to_array(krylov4_dcm_t(phi, psi, gamma, xi))


@njit(cache=True, error_model="numpy")
def krylov_dcm_t(ang, kset, phiB):
    """``Cbn`` (matrix tuple) of the four-angle state (sec. 1.3, 4.6 step 4).

    ``ang = (phi, psi, gamma, xi)`` rad; in set A psi is 0, in set B the
    frozen yaw ``phiB`` is used for phi.
    """
    g, x = ang[2], ang[3]
    if kset == SET_A:
        f = ang[0]
        return _dcm_from_trig(math.cos(f), math.sin(f), 1.0, 0.0,
                              math.cos(g), math.sin(g), math.cos(x), math.sin(x))
    p = ang[1]
    return _dcm_from_trig(math.cos(phiB), math.sin(phiB), math.cos(p), math.sin(p),
                          math.cos(g), math.sin(g), math.cos(x), math.sin(x))


@njit(cache=True, error_model="numpy")
def krylov_dcm(ang, kset, phiB):
    """``Cbn`` (3x3 array) of the four-angle state ``ang`` (float64[4]); see :func:`krylov_dcm_t`."""
    return m_to_array(krylov_dcm_t((ang[0], ang[1], ang[2], ang[3]), kset, phiB))


@njit(cache=True, error_model="numpy")
def krylov_margin(ang, kset):
    """Distance (rad) of the active set from its singularity (sec. 2.5).

    Set A: ``90 deg - |gamma|``; set B: ``90 deg - |gamma - 90 deg|``.
    """
    if kset == SET_A:
        return HALF_PI - abs(ang[2])
    return HALF_PI - abs(ang[2] - HALF_PI)


@njit(cache=True, error_model="numpy")
def krylov_init_t(c):
    """Four-angle state ``(ang, kset, phiB)`` from any rotation (matrix tuple) ``c = Cbn`` (sec. 4.8).

    Set A when the elevation of Y' is at most 45 deg (margin >= 45 deg),
    otherwise set B with ``phiB`` the azimuth of Y', so that gamma = 90 deg
    (margin 90 deg).  Rows of ``Cbn`` are E, N, U; columns X', Y', Z'.
    ``ang`` is a 4-tuple (phi, psi, gamma, xi), radians.
    """
    gam_a = math.atan2(c[2][1], math.sqrt(c[0][1] * c[0][1] + c[1][1] * c[1][1]))
    if abs(gam_a) <= GAMMA_S:
        return ((math.atan2(-c[0][1], c[1][1]), 0.0, gam_a, math.atan2(-c[2][0], c[2][2])),
                SET_A, 0.0)
    phib = math.atan2(c[1][1], c[0][1])          # 0 when Y' is exactly vertical
    cb, sb = math.cos(phib), math.sin(phib)
    # rows E' = cb E + sb N, N' = -sb E + cb N
    ep_y = cb * c[0][1] + sb * c[1][1]
    np_x = -sb * c[0][0] + cb * c[1][0]
    np_y = -sb * c[0][1] + cb * c[1][1]
    np_z = -sb * c[0][2] + cb * c[1][2]
    return ((phib, math.atan2(ep_y, c[2][1]), math.atan2(math.sqrt(np_x * np_x + np_z * np_z), np_y),
             math.atan2(np_x, -np_z)), SET_B, phib)


@njit(cache=True, error_model="numpy")
def krylov_init(Cbn):
    """:func:`krylov_init_t` for a 3x3 array; returns ``(ang float64[4], kset, phiB)``."""
    ang, kset, phib = krylov_init_t(m_from_array(Cbn))
    return np.array(ang), kset, phib


@njit(cache=True, error_model="numpy")
def transfer_a_to_b(phi, gamma, xi):
    """Set A -> set B by the exact identity M1 (sec. 3.2).

    ``(phi, 0, gamma, xi) == (phi + 90, 90 - gamma, 90, xi - 90)`` (deg);
    returns ``(phiB, psi, gamma, xi)`` in radians.
    """
    return wrap_pi(phi + HALF_PI), wrap_pi(HALF_PI - gamma), HALF_PI, wrap_pi(xi - HALF_PI)


@njit(cache=True, error_model="numpy")
def transfer_b_to_a(psi, gamma, xi, phib):
    """Set B -> set A by DCM extraction, branch cos gamma_A >= 0 (sec. 3.3).

    Returns ``(phi, gamma, xi)`` of set A (psi = 0), radians.
    """
    cp, sp = math.cos(psi), math.sin(psi)
    cg, sg = math.cos(gamma), math.sin(gamma)
    cx, sx = math.cos(xi), math.sin(xi)
    gam_a = math.atan2(cp * sg, math.sqrt(cg * cg + sp * sp * sg * sg))
    phi_a = wrap_pi(phib + math.atan2(-sp * sg, cg))
    xi_a = math.atan2(sp * cx + cp * cg * sx, cp * cg * cx - sp * sx)
    return phi_a, gam_a, xi_a


@njit(cache=True, error_model="numpy", inline="always")
def _cs_shift(c, s, d):
    """``(cos(x + d), sin(x + d))`` from ``c = cos x``, ``s = sin x`` (angle addition).

    Below |d| = 0.1 rad the sine and cosine of ``d`` come from their Taylor
    series to d^10 (truncation < 0.3 ulp), which is cheaper than libm; the RK4
    stages of one step only move the angles by such small amounts.
    """
    if abs(d) < 0.1:
        d2 = d * d
        sd = d * (1.0 + d2 * (_S3 + d2 * (_S5 + d2 * (_S7 + d2 * _S9))))
        cd = 1.0 + d2 * (-0.5 + d2 * (_C4 + d2 * (_C6 + d2 * (_C8 + d2 * _C10))))
    else:
        sd, cd = math.sin(d), math.cos(d)
    return c * cd - s * sd, s * cd + c * sd


@njit(cache=True, error_model="numpy", inline="always")
def rate_model(dtheta_prev_b, dtheta_b):
    """Two-sample linear rate model of sec. 4.4: ``(W0, Wh, W1)`` as 3-tuples (rad).

    ``W0 = (dth_prev + dth)/2``, ``Wh = dth``, ``W1 = (3 dth - dth_prev)/2``: the
    rate times T at the start, middle and end of the interval;
    ``(W0 + 4 Wh + W1)/6 = dth`` exactly.
    """
    p0, p1, p2 = dtheta_prev_b[0], dtheta_prev_b[1], dtheta_prev_b[2]
    h0, h1, h2 = dtheta_b[0], dtheta_b[1], dtheta_b[2]
    return ((0.5 * (p0 + h0), 0.5 * (p1 + h1), 0.5 * (p2 + h2)), (h0, h1, h2),
            (1.5 * h0 - 0.5 * p0, 1.5 * h1 - 0.5 * p1, 1.5 * h2 - 0.5 * p2))


@njit(cache=True, error_model="numpy", inline="always")
def _f4(kset, ca, sa, cg, sg, cx, sx, wx, wy, wz, zx, zy, zz, nav):
    """Angle increments ``F_s(x, w)`` of sec. 4.3, from the cosines and sines of x.

    x = (a, gamma, xi), a = phi (set A) or psi (set B); ``w`` body increment
    (rad); ``z`` = zeta (rad, ENU, already turned by Rz(-phiB) in set B),
    used when ``nav``.  Returns (da, dgamma, dxi).
    """
    if nav:
        if kset == SET_A:        # Rz(-phi) zeta
            p1 = ca * zx + sa * zy
            p2 = -sa * zx + ca * zy
            p3 = zz
        else:                    # Ry(-psi) zeta
            p1 = ca * zx - sa * zz
            p2 = zy
            p3 = sa * zx + ca * zz
        q2 = cg * p2 + sg * p3   # Rx(-gamma)
        q3 = -sg * p2 + cg * p3
        wx -= cx * p1 - sx * q3  # Ry(-xi); w~ = w - C^T zeta
        wy -= q2
        wz -= sx * p1 + cx * q3
    u = cx * wx + sx * wz
    v = cx * wz - sx * wx
    if kset == SET_A:
        da = v / cg
        return da, u, wy - sg * da
    da = -v / sg
    return da, u, wy - cg * da


@njit(cache=True, error_model="numpy", inline="always")
def substep_count(w0, w1, max_angle):
    """Number of RK4 sub-steps ``m = ceil(|w| T / max_angle)`` of one attitude interval (1..MAX_SUBSTEPS).

    ``w0``, ``w1``: the rate model's rate times T at the start and the end of
    the interval (sec. 4.4, rad); being linear in time, its largest magnitude
    over the interval is at one of the ends.  ``max_angle``: the largest
    rotation (rad) of one sub-step (:func:`substep_angle`).  Below it (every
    vehicle and aircraft manoeuvre at 100 Hz) the answer is 1 and costs two
    dot products.  A NaN rate gives 1.
    """
    t2 = max(w0[0] * w0[0] + w0[1] * w0[1] + w0[2] * w0[2], w1[0] * w1[0] + w1[1] * w1[1] + w1[2] * w1[2])
    if not t2 > max_angle * max_angle:
        return 1
    return min(MAX_SUBSTEPS, int(math.ceil(math.sqrt(t2) / max_angle)))


@njit(cache=True, error_model="numpy")
def substep_counts(dtheta_b, max_angle):
    """RK4 sub-steps (int64[N]) that the intervals of ``dtheta_b`` (N, 3) rad take (:func:`substep_count`).

    Interval k uses the rate model of ``dtheta_b[k-1], dtheta_b[k]`` (the first
    one ``dtheta_b[0]`` twice), as :func:`krylov_propagate` and the navigation
    loop do.  For reports, tests and benchmarks.
    """
    n = dtheta_b.shape[0]
    out = np.empty(n, dtype=np.int64)
    for k in range(n):
        j = k - 1 if k > 0 else 0
        w0, _, w1 = rate_model((dtheta_b[j, 0], dtheta_b[j, 1], dtheta_b[j, 2]),
                               (dtheta_b[k, 0], dtheta_b[k, 1], dtheta_b[k, 2]))
        out[k] = substep_count(w0, w1, max_angle)
    return out


@njit(cache=True, error_model="numpy", inline="always")
def _rk4(kset, ca, sa, cg, sg, cx, sx, w0, wh, w1, zx, zy, zz, nav):
    """Classical RK4 (sec. 4.5) of the active angles over one (sub-)step: ``(da, dgamma, dxi)``.

    ``w0, wh, w1``: the body increments of the step's rate model at its start,
    middle and end (3-tuples, rad); the trig arguments are those of the
    angles at the start of the step; stage states by angle addition
    (:func:`_cs_shift`).  Other arguments as :func:`_f4`.
    """
    k1a, k1g, k1x = _f4(kset, ca, sa, cg, sg, cx, sx, w0[0], w0[1], w0[2], zx, zy, zz, nav)
    c2a, s2a = _cs_shift(ca, sa, 0.5 * k1a) if nav else (1.0, 0.0)
    c2g, s2g = _cs_shift(cg, sg, 0.5 * k1g)
    c2x, s2x = _cs_shift(cx, sx, 0.5 * k1x)
    k2a, k2g, k2x = _f4(kset, c2a, s2a, c2g, s2g, c2x, s2x, wh[0], wh[1], wh[2], zx, zy, zz, nav)
    c3a, s3a = _cs_shift(ca, sa, 0.5 * k2a) if nav else (1.0, 0.0)
    c3g, s3g = _cs_shift(cg, sg, 0.5 * k2g)
    c3x, s3x = _cs_shift(cx, sx, 0.5 * k2x)
    k3a, k3g, k3x = _f4(kset, c3a, s3a, c3g, s3g, c3x, s3x, wh[0], wh[1], wh[2], zx, zy, zz, nav)
    c4a, s4a = _cs_shift(ca, sa, k3a) if nav else (1.0, 0.0)
    c4g, s4g = _cs_shift(cg, sg, k3g)
    c4x, s4x = _cs_shift(cx, sx, k3x)
    k4a, k4g, k4x = _f4(kset, c4a, s4a, c4g, s4g, c4x, s4x, w1[0], w1[1], w1[2], zx, zy, zz, nav)
    return ((k1a + 2.0 * (k2a + k3a) + k4a) / 6.0, (k1g + 2.0 * (k2g + k3g) + k4g) / 6.0,
            (k1x + 2.0 * (k2x + k3x) + k4x) / 6.0)


@njit(cache=True, error_model="numpy", inline="always")
def _lerp_inc(w0, d, s, f):
    """``f (w0 + s d)``: the rate model's increment at the fraction ``s`` of the interval, times ``f``."""
    return (f * (w0[0] + s * d[0]), f * (w0[1] + s * d[1]), f * (w0[2] + s * d[2]))


@njit(cache=True, error_model="numpy")
def krylov_update_t(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle):
    """One four-angle attitude interval t_k -> t_k + dt in ``m`` RK4 sub-steps, with ``Cbn(t_k + dt)``.

    ang: 4-tuple (phi, psi, gamma, xi) rad at t_k; kset: SET_A / SET_B;
    phiB: frozen yaw of set B (rad); dtheta_prev_b, dtheta_b: body angle
    increments (rad, FLU) of the previous and current interval (on the first
    step pass dtheta_b twice, sec. 4.4); dt: interval (s); w_in_n: navigation
    frame rate (rad/s, ENU, constant over the interval, taken at mid-interval);
    max_angle: the largest rotation (rad) of one RK4 sub-step
    (:func:`substep_angle`; ``math.inf``: never sub-step).  Vectors are
    3-tuples or arrays.

    Each sub-step follows the patent's order (sec. 4.6, 4.11): (1) the
    state-transfer test and mapping (M1 for A->B, sec. 3.3 extraction for
    B->A); (2) RK4 (sec. 4.5) on the active angles, its stage rates taken
    from the interval's two-sample linear rate model (sec. 4.4) over the
    sub-step's share of the interval, with the nav-frame term inside F at
    every stage (sec. 4.3).  Then (3) ``Cbn`` of the new angles (sec. 1.3),
    equal to :func:`krylov_dcm_t` of them to rounding.  ``m =``
    :func:`substep_count`; with ``m = 1`` this is exactly the single RK4 step
    of sec. 4.11.  Sub-steps cut the RK4 truncation of the angle equations,
    which grows as (|w| T)^5 per step, by m^4 (docs/krylov.md).

    Returns ``(ang_new 4-tuple, kset, phiB, transferred, Cbn matrix tuple,
    m)``; ``transferred`` tells whether a transfer happened in this interval.
    The sines and cosines of the RK4 stage states and of the result come from
    those of the step's start by angle addition (:func:`_cs_shift`).
    """
    a = ang[0] if kset == SET_A else ang[1]
    g, x = ang[2], ang[3]
    cg, sg = math.cos(g), math.sin(g)
    w0, wh, w1 = rate_model(dtheta_prev_b, dtheta_b)
    m = substep_count(w0, w1, max_angle)
    if m > 1:
        inv_m = 1.0 / m
        dw = (w1[0] - w0[0], w1[1] - w0[1], w1[2] - w0[2])
    ex, ey, ez = w_in_n[0] * dt, w_in_n[1] * dt, w_in_n[2] * dt        # zeta, ENU
    nav = ex != 0.0 or ey != 0.0 or ez != 0.0
    transferred = False
    fresh = True                     # trig of a and xi (and zeta in set axes) to be taken
    ca = sa = cx = sx = zx = zy = zz = 0.0
    cb, sb = 1.0, 0.0
    for j in range(m):
        if kset == SET_A:
            if cg < COS_GAMMA_S:
                phiB, a, g, x = transfer_a_to_b(a, g, x)
                kset = SET_B
                transferred = True
                fresh = True
                cg, sg = 0.0, 1.0                    # gamma = 90 deg exactly
        elif sg < COS_GAMMA_S:
            a, g, x = transfer_b_to_a(a, g, x, phiB)
            phiB = 0.0
            kset = SET_A
            transferred = True
            fresh = True
            cg, sg = math.cos(g), math.sin(g)
        if fresh:
            fresh = False
            ca, sa = math.cos(a), math.sin(a)
            cx, sx = math.cos(x), math.sin(x)
            zx, zy, zz = ex, ey, ez
            if kset == SET_B:
                cb, sb = math.cos(phiB), math.sin(phiB)
                zx, zy = cb * ex + sb * ey, -sb * ex + cb * ey      # Rz(-phiB) zeta
            if m > 1:
                zx, zy, zz = zx * inv_m, zy * inv_m, zz * inv_m
        if m == 1:
            da, dg, dx = _rk4(kset, ca, sa, cg, sg, cx, sx, w0, wh, w1, zx, zy, zz, nav)
        else:                        # sub-step j: the rate model over [j/m, (j+1)/m] of the interval
            da, dg, dx = _rk4(kset, ca, sa, cg, sg, cx, sx, _lerp_inc(w0, dw, j * inv_m, inv_m),
                              _lerp_inc(w0, dw, (j + 0.5) * inv_m, inv_m),
                              _lerp_inc(w0, dw, (j + 1.0) * inv_m, inv_m), zx, zy, zz, nav)
        ca, sa = _cs_shift(ca, sa, da)
        cg, sg = _cs_shift(cg, sg, dg)
        cx, sx = _cs_shift(cx, sx, dx)
        a = wrap_pi(a + da)
        g = g + dg
        x = wrap_pi(x + dx)

    if kset == SET_A:
        return ((a, 0.0, g, x), kset, phiB, transferred,
                _dcm_from_trig(ca, sa, 1.0, 0.0, cg, sg, cx, sx), m)
    return ((phiB, a, g, x), kset, phiB, transferred,
            _dcm_from_trig(cb, sb, ca, sa, cg, sg, cx, sx), m)


@njit(cache=True, error_model="numpy")
def krylov_step_dcm_t(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle=SUBSTEP_ANGLE):
    """:func:`krylov_update_t` without the sub-step count: ``(ang_new, kset, phiB, transferred, Cbn)``.

    ``max_angle`` defaults to the sub-step rotation of the default
    ``navigation.krylov_substep_tol`` (:data:`SUBSTEP_ANGLE`).
    """
    a, kset, phiB, tr, c, _ = krylov_update_t(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle)
    return a, kset, phiB, tr, c


@njit(cache=True, error_model="numpy")
def krylov_step_t(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle=SUBSTEP_ANGLE):
    """:func:`krylov_step_dcm_t` without the DCM: ``(ang_new 4-tuple, kset, phiB, transferred)``."""
    a, kset, phiB, tr, _, _ = krylov_update_t(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle)
    return a, kset, phiB, tr


@njit(cache=True, error_model="numpy")
def krylov_step(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle=SUBSTEP_ANGLE):
    """Array form of :func:`krylov_step_t` (sec. 4.6): ``ang`` float64[4], vectors float64[3].

    Returns ``(ang_new float64[4], kset, phiB, transferred)``.
    """
    a, kset, phiB, tr = krylov_step_t((ang[0], ang[1], ang[2], ang[3]), kset, phiB,
                                      dtheta_prev_b, dtheta_b, dt, w_in_n, max_angle)
    return np.array(a), kset, phiB, tr


@njit(cache=True, error_model="numpy")
def krylov_propagate(Cbn0, dtheta_b, dt, w_in_n, max_angle=SUBSTEP_ANGLE):
    """Attitude-only run of :func:`krylov_step_dcm_t` over ``dtheta_b`` (N, 3) rad.

    Starts from ``Cbn0`` (sec. 4.8), first step with Δθ_{-1} := Δθ_0, a
    constant nav-frame rate ``w_in_n`` (rad/s ENU).  Returns ``(Cbn (N+1,3,3),
    ang (N+1,4), kset (N+1,), transfers)`` where row 0 is the initial state
    and ``transfers`` counts the set changes.  For tests, benchmarks and
    attitude-only checks; the navigation loop calls the step itself.
    """
    n = dtheta_b.shape[0]
    cbn = np.empty((n + 1, 3, 3))
    angs = np.empty((n + 1, 4))
    sets = np.empty(n + 1, dtype=np.int64)
    w = (w_in_n[0], w_in_n[1], w_in_n[2])
    ang, kset, phib = krylov_init_t(m_from_array(Cbn0))
    cbn[0] = m_to_array(krylov_dcm_t(ang, kset, phib))
    angs[0] = np.array(ang)
    sets[0] = kset
    transfers = 0
    prev = (dtheta_b[0, 0], dtheta_b[0, 1], dtheta_b[0, 2])
    for k in range(n):
        cur = (dtheta_b[k, 0], dtheta_b[k, 1], dtheta_b[k, 2])
        ang, kset, phib, tr, c, _ = krylov_update_t(ang, kset, phib, prev, cur, dt, w, max_angle)
        if tr:
            transfers += 1
        cbn[k + 1] = m_to_array(c)
        for j in range(4):
            angs[k + 1, j] = ang[j]
        sets[k + 1] = kset
        prev = cur
    return cbn, angs, sets, transfers


# ---------------------------------------------------------------- classic 3 angles


@njit(cache=True, error_model="numpy")
def euler3_dcm_t(ang3):
    """``Cbn = Rz(phi) Ry(psi) Rx(gamma)``: the classic Krylov angles (sec. 2.4, xi = 0), matrix tuple."""
    return krylov4_dcm_t(ang3[0], ang3[1], ang3[2], 0.0)


@njit(cache=True, error_model="numpy")
def euler3_dcm(ang3):
    """Array form of :func:`euler3_dcm_t` (3x3)."""
    return m_to_array(euler3_dcm_t(ang3))


@njit(cache=True, error_model="numpy")
def euler3_init_t(c):
    """Classic angles ``(phi, psi, gamma)`` (rad, 3-tuple) from ``Cbn`` (matrix tuple).

    Inverse of :func:`euler3_dcm_t`, psi in [-90, 90] deg.  At cos psi = 0
    (X' vertical) gamma is set to 0 and phi takes the whole rotation about
    the vertical.
    """
    horiz = math.sqrt(c[0][0] * c[0][0] + c[1][0] * c[1][0])
    psi = math.atan2(-c[2][0], horiz)
    if horiz > 1e-12:
        return (math.atan2(c[1][0], c[0][0]), psi, math.atan2(c[2][1], c[2][2]))
    return (math.atan2(-c[0][1], c[1][1]), psi, 0.0)


@njit(cache=True, error_model="numpy")
def euler3_init(Cbn):
    """:func:`euler3_init_t` for a 3x3 array -> float64[3]."""
    return np.array(euler3_init_t(m_from_array(Cbn)))


@njit(cache=True, error_model="numpy")
def _f3(f, p, g, wx, wy, wz, zx, zy, zz):
    """Angle increments of the classic angles (sec. 2.4) with w~ = w - C^T zeta.

    Returns (dphi, dpsi, dgamma, |cos psi|).  |cos psi| is floored at 1e-15
    so that the rates stay finite at the singularity itself.
    """
    cp, sp = math.cos(p), math.sin(p)
    cg, sg = math.cos(g), math.sin(g)
    if zx != 0.0 or zy != 0.0 or zz != 0.0:
        cf, sf = math.cos(f), math.sin(f)
        p1 = cf * zx + sf * zy               # Rz(-phi)
        p2 = -sf * zx + cf * zy
        r1 = cp * p1 - sp * zz               # Ry(-psi)
        r3 = sp * p1 + cp * zz
        wx -= r1                             # Rx(-gamma)
        wy -= cg * p2 + sg * r3
        wz -= -sg * p2 + cg * r3
    acp = abs(cp)
    if acp < _CPSI_FLOOR:
        cp = _CPSI_FLOOR if cp >= 0.0 else -_CPSI_FLOOR
    t = wy * sg + wz * cg
    dphi = t / cp
    return dphi, wy * cg - wz * sg, wx + sp * dphi, acp


@njit(cache=True, error_model="numpy")
def euler3_step_t(ang3, dtheta_prev_b, dtheta_b, dt, w_in_n, integrator):
    """One update of the classic three Krylov angles (sec. 2.4).

    integrator 0 (``EULER3_FORWARD_EULER``): the patent's baseline,
    ``x_{k+1} = x_k + F(x_k, dtheta_k)``; 1 (``EULER3_RK4``): RK4 with the
    same two-sample rate model as the four angles (sec. 4.4, 4.5).  Other
    arguments as :func:`krylov_step_t`.  Returns ``(ang3_new 3-tuple,
    cos_psi_min)``, the smallest |cos psi| met by the step (start, stages
    and end): the caller compares it with ``--singularity-threshold``.
    """
    f, p, g = ang3[0], ang3[1], ang3[2]
    zx, zy, zz = w_in_n[0] * dt, w_in_n[1] * dt, w_in_n[2] * dt
    h0, h1, h2 = dtheta_b[0], dtheta_b[1], dtheta_b[2]
    if integrator == EULER3_FORWARD_EULER:
        d1, d2, d3, c1 = _f3(f, p, g, h0, h1, h2, zx, zy, zz)
        f, p, g = f + d1, p + d2, g + d3
        cmin = c1
    else:
        (a0x, a0y, a0z), _, (a1x, a1y, a1z) = rate_model(dtheta_prev_b, dtheta_b)
        k1f, k1p, k1g, c1 = _f3(f, p, g, a0x, a0y, a0z, zx, zy, zz)
        k2f, k2p, k2g, c2 = _f3(f + 0.5 * k1f, p + 0.5 * k1p, g + 0.5 * k1g, h0, h1, h2, zx, zy, zz)
        k3f, k3p, k3g, c3 = _f3(f + 0.5 * k2f, p + 0.5 * k2p, g + 0.5 * k2g, h0, h1, h2, zx, zy, zz)
        k4f, k4p, k4g, c4 = _f3(f + k3f, p + k3p, g + k3g, a1x, a1y, a1z, zx, zy, zz)
        f = f + (k1f + 2.0 * (k2f + k3f) + k4f) / 6.0
        p = p + (k1p + 2.0 * (k2p + k3p) + k4p) / 6.0
        g = g + (k1g + 2.0 * (k2g + k3g) + k4g) / 6.0
        cmin = min(min(c1, c2), min(c3, c4))
    p = wrap_pi(p)
    return (wrap_pi(f), p, wrap_pi(g)), min(cmin, abs(math.cos(p)))


@njit(cache=True, error_model="numpy")
def euler3_step(ang3, dtheta_prev_b, dtheta_b, dt, w_in_n, integrator):
    """Array form of :func:`euler3_step_t`: returns ``(ang3_new float64[3], cos_psi_min)``."""
    a, cmin = euler3_step_t((ang3[0], ang3[1], ang3[2]), dtheta_prev_b, dtheta_b, dt, w_in_n,
                            integrator)
    return np.array(a), cmin


@njit(cache=True, error_model="numpy")
def euler3_propagate(Cbn0, dtheta_b, dt, w_in_n, integrator):
    """Attitude-only run of :func:`euler3_step_t` (as :func:`krylov_propagate`).

    Returns ``(Cbn (N+1,3,3), ang3 (N+1,3), cos_psi_min (N,))``.
    """
    n = dtheta_b.shape[0]
    cbn = np.empty((n + 1, 3, 3))
    angs = np.empty((n + 1, 3))
    cmin = np.empty(n)
    w = (w_in_n[0], w_in_n[1], w_in_n[2])
    ang = euler3_init_t(m_from_array(Cbn0))
    cbn[0] = m_to_array(euler3_dcm_t(ang))
    angs[0] = np.array(ang)
    prev = (dtheta_b[0, 0], dtheta_b[0, 1], dtheta_b[0, 2])
    for k in range(n):
        cur = (dtheta_b[k, 0], dtheta_b[k, 1], dtheta_b[k, 2])
        ang, cmin[k] = euler3_step_t(ang, prev, cur, dt, w, integrator)
        cbn[k + 1] = m_to_array(euler3_dcm_t(ang))
        for j in range(3):
            angs[k + 1, j] = ang[j]
        prev = cur
    return cbn, angs, cmin
