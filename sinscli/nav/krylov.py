"""Attitude by extended (four) Krylov angles, and the classic three (seed 003).

Formulas and section numbers are those of ``shared/docs/KRYLOV.md``, which
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

All kernels are numba ``njit`` functions over float64 arrays and scalars,
with no I/O.  Stage functions work on scalars (no array allocation), so one
four-angle RK4 step costs a few tenths of a microsecond.
"""
import math

import numpy as np
from numba import njit

from .rotation import mm3

SET_A, SET_B = 0, 1
GAMMA_S = 0.25 * math.pi            # transfer threshold gamma_s = 45 deg (sec. 3.1)
COS_GAMMA_S = math.cos(GAMMA_S)
HALF_PI = 0.5 * math.pi
TWO_PI = 2.0 * math.pi
EULER3_FORWARD_EULER, EULER3_RK4 = 0, 1
_CPSI_FLOOR = 1e-15                 # |cos psi| floor of the 3-angle rates (no division by zero)


@njit(cache=True, error_model="numpy")
def wrap_pi(a):
    """Angle ``a`` (rad) mapped to (-pi, pi] (``wrap`` of KRYLOV.md)."""
    if -math.pi < a <= math.pi:
        return a
    return a - TWO_PI * math.ceil((a - math.pi) / TWO_PI)


@njit(cache=True, error_model="numpy")
def krylov4_dcm(phi, psi, gamma, xi):
    """``Cbn = Rz(phi) Ry(psi) Rx(gamma) Ry(xi)`` in element form (sec. 1.3), radians."""
    cf, sf = math.cos(phi), math.sin(phi)
    cp, sp = math.cos(psi), math.sin(psi)
    cg, sg = math.cos(gamma), math.sin(gamma)
    cx, sx = math.cos(xi), math.sin(xi)
    # rows of B = Ry(psi) Rx(gamma) Ry(xi)
    be0 = cp * cx - sp * cg * sx
    be1 = sp * sg
    be2 = cp * sx + sp * cg * cx
    bn0 = sg * sx
    bn1 = cg
    bn2 = -sg * cx
    c = np.empty((3, 3))
    c[0, 0] = cf * be0 - sf * bn0
    c[0, 1] = cf * be1 - sf * bn1
    c[0, 2] = cf * be2 - sf * bn2
    c[1, 0] = sf * be0 + cf * bn0
    c[1, 1] = sf * be1 + cf * bn1
    c[1, 2] = sf * be2 + cf * bn2
    c[2, 0] = -sp * cx - cp * cg * sx
    c[2, 1] = cp * sg
    c[2, 2] = -sp * sx + cp * cg * cx
    return c


@njit(cache=True, error_model="numpy")
def krylov_dcm(ang, kset, phiB):
    """``Cbn`` (3x3) of the four-angle state (sec. 1.3, 4.6 step 4).

    ``ang = (phi, psi, gamma, xi)`` rad; in set A psi is 0, in set B the
    frozen yaw ``phiB`` is used for phi.
    """
    if kset == SET_A:
        return krylov4_dcm(ang[0], 0.0, ang[2], ang[3])
    return krylov4_dcm(phiB, ang[1], ang[2], ang[3])


@njit(cache=True, error_model="numpy")
def krylov_margin(ang, kset):
    """Distance (rad) of the active set from its singularity (sec. 2.5).

    Set A: ``90 deg - |gamma|``; set B: ``90 deg - |gamma - 90 deg|``.
    """
    if kset == SET_A:
        return HALF_PI - abs(ang[2])
    return HALF_PI - abs(ang[2] - HALF_PI)


@njit(cache=True, error_model="numpy")
def krylov_init(Cbn):
    """Four-angle state ``(ang, kset, phiB)`` from any rotation ``Cbn`` (sec. 4.8).

    Set A when the elevation of Y' is at most 45 deg (margin >= 45 deg),
    otherwise set B with ``phiB`` the azimuth of Y', so that gamma = 90 deg
    (margin 90 deg).  Rows of ``Cbn`` are E, N, U; columns X', Y', Z'.
    """
    c = Cbn
    ang = np.zeros(4)
    gam_a = math.atan2(c[2, 1], math.sqrt(c[0, 1] * c[0, 1] + c[1, 1] * c[1, 1]))
    if abs(gam_a) <= GAMMA_S:
        ang[0] = math.atan2(-c[0, 1], c[1, 1])
        ang[1] = 0.0
        ang[2] = gam_a
        ang[3] = math.atan2(-c[2, 0], c[2, 2])
        return ang, SET_A, 0.0
    phib = math.atan2(c[1, 1], c[0, 1])          # 0 when Y' is exactly vertical
    cb, sb = math.cos(phib), math.sin(phib)
    # rows E' = cb E + sb N, N' = -sb E + cb N
    ep_y = cb * c[0, 1] + sb * c[1, 1]
    np_x = -sb * c[0, 0] + cb * c[1, 0]
    np_y = -sb * c[0, 1] + cb * c[1, 1]
    np_z = -sb * c[0, 2] + cb * c[1, 2]
    ang[0] = phib
    ang[1] = math.atan2(ep_y, c[2, 1])
    ang[2] = math.atan2(math.sqrt(np_x * np_x + np_z * np_z), np_y)
    ang[3] = math.atan2(np_x, -np_z)
    return ang, SET_B, phib


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


@njit(cache=True, error_model="numpy")
def _f4(kset, a, g, x, wx, wy, wz, zx, zy, zz):
    """Angle increments ``F_s(x, w)`` of sec. 4.3 (scalars).

    ``(a, g, x)`` = (phi or psi, gamma, xi); ``w`` body increment (rad);
    ``z`` = zeta (rad, ENU, already turned by Rz(-phiB) in set B).  Returns
    (da, dgamma, dxi).
    """
    cg, sg = math.cos(g), math.sin(g)
    cx, sx = math.cos(x), math.sin(x)
    if zx != 0.0 or zy != 0.0 or zz != 0.0:
        ca, sa = math.cos(a), math.sin(a)
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


@njit(cache=True, error_model="numpy")
def krylov_step(ang, kset, phiB, dtheta_prev_b, dtheta_b, dt, w_in_n):
    """One four-angle attitude update t_k -> t_k + dt (sec. 4.6, 4.11).

    ang: float64[4] (phi, psi, gamma, xi) rad at t_k; kset: SET_A / SET_B;
    phiB: frozen yaw of set B (rad); dtheta_prev_b, dtheta_b: body angle
    increments (rad, FLU) of the previous and current interval (on the first
    step pass dtheta_b twice, sec. 4.4); dt: interval (s); w_in_n: navigation
    frame rate (rad/s, ENU, constant over the interval, taken at mid-interval).

    Order as in the patent: state-transfer test and mapping (M1 for A->B,
    sec. 3.3 extraction for B->A), then RK4 (sec. 4.5) on the active angles
    with the two-sample linear rate model (sec. 4.4) and the nav-frame term
    inside F at every stage (sec. 4.3).  Returns ``(ang_new, kset, phiB,
    transferred)``; ``transferred`` tells whether a transfer happened at the
    start of this step (at t_k).
    """
    phi, psi, g, x = ang[0], ang[1], ang[2], ang[3]
    transferred = False
    if kset == SET_A:
        if math.cos(g) < COS_GAMMA_S:
            phiB, psi, g, x = transfer_a_to_b(phi, g, x)
            phi = phiB
            kset = SET_B
            transferred = True
    elif math.sin(g) < COS_GAMMA_S:
        phi, g, x = transfer_b_to_a(psi, g, x, phiB)
        psi = 0.0
        phiB = 0.0
        kset = SET_A
        transferred = True

    zx, zy, zz = w_in_n[0] * dt, w_in_n[1] * dt, w_in_n[2] * dt
    if kset == SET_B and (zx != 0.0 or zy != 0.0):
        cb, sb = math.cos(phiB), math.sin(phiB)
        zx, zy = cb * zx + sb * zy, -sb * zx + cb * zy
    # two-sample linear rate model (sec. 4.4)
    p0, p1, p2 = dtheta_prev_b[0], dtheta_prev_b[1], dtheta_prev_b[2]
    h0, h1, h2 = dtheta_b[0], dtheta_b[1], dtheta_b[2]
    a0x, a0y, a0z = 0.5 * (p0 + h0), 0.5 * (p1 + h1), 0.5 * (p2 + h2)
    a1x, a1y, a1z = 1.5 * h0 - 0.5 * p0, 1.5 * h1 - 0.5 * p1, 1.5 * h2 - 0.5 * p2

    a = phi if kset == SET_A else psi
    k1a, k1g, k1x = _f4(kset, a, g, x, a0x, a0y, a0z, zx, zy, zz)
    k2a, k2g, k2x = _f4(kset, a + 0.5 * k1a, g + 0.5 * k1g, x + 0.5 * k1x, h0, h1, h2, zx, zy, zz)
    k3a, k3g, k3x = _f4(kset, a + 0.5 * k2a, g + 0.5 * k2g, x + 0.5 * k2x, h0, h1, h2, zx, zy, zz)
    k4a, k4g, k4x = _f4(kset, a + k3a, g + k3g, x + k3x, a1x, a1y, a1z, zx, zy, zz)
    a = wrap_pi(a + (k1a + 2.0 * (k2a + k3a) + k4a) / 6.0)
    g = g + (k1g + 2.0 * (k2g + k3g) + k4g) / 6.0
    x = wrap_pi(x + (k1x + 2.0 * (k2x + k3x) + k4x) / 6.0)

    out = np.empty(4)
    if kset == SET_A:
        out[0] = a
        out[1] = 0.0
    else:
        out[0] = phiB
        out[1] = a
    out[2] = g
    out[3] = x
    return out, kset, phiB, transferred


@njit(cache=True, error_model="numpy")
def krylov_propagate(Cbn0, dtheta_b, dt, w_in_n):
    """Attitude-only run of :func:`krylov_step` over ``dtheta_b`` (N, 3).

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
    ang, kset, phib = krylov_init(Cbn0)
    cbn[0] = krylov_dcm(ang, kset, phib)
    angs[0] = ang
    sets[0] = kset
    transfers = 0
    for k in range(n):
        prev = dtheta_b[k - 1] if k > 0 else dtheta_b[0]
        ang, kset, phib, tr = krylov_step(ang, kset, phib, prev, dtheta_b[k], dt, w_in_n)
        if tr:
            transfers += 1
        cbn[k + 1] = krylov_dcm(ang, kset, phib)
        angs[k + 1] = ang
        sets[k + 1] = kset
    return cbn, angs, sets, transfers


# ---------------------------------------------------------------- classic 3 angles


@njit(cache=True, error_model="numpy")
def euler3_dcm(ang3):
    """``Cbn = Rz(phi) Ry(psi) Rx(gamma)``: the classic Krylov angles (sec. 2.4, xi = 0)."""
    return krylov4_dcm(ang3[0], ang3[1], ang3[2], 0.0)


@njit(cache=True, error_model="numpy")
def euler3_init(Cbn):
    """Classic angles ``(phi, psi, gamma)`` (rad) from ``Cbn`` (inverse of :func:`euler3_dcm`).

    psi in [-90, 90] deg.  At cos psi = 0 (X' vertical) gamma is set to 0
    and phi takes the whole rotation about the vertical.
    """
    c = Cbn
    ang = np.empty(3)
    horiz = math.sqrt(c[0, 0] * c[0, 0] + c[1, 0] * c[1, 0])
    ang[1] = math.atan2(-c[2, 0], horiz)
    if horiz > 1e-12:
        ang[0] = math.atan2(c[1, 0], c[0, 0])
        ang[2] = math.atan2(c[2, 1], c[2, 2])
    else:
        ang[0] = math.atan2(-c[0, 1], c[1, 1])
        ang[2] = 0.0
    return ang


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
def euler3_step(ang3, dtheta_prev_b, dtheta_b, dt, w_in_n, integrator):
    """One update of the classic three Krylov angles (sec. 2.4).

    integrator 0 (``EULER3_FORWARD_EULER``): the patent's baseline,
    ``x_{k+1} = x_k + F(x_k, dtheta_k)``; 1 (``EULER3_RK4``): RK4 with the
    same two-sample rate model as the four angles (sec. 4.4, 4.5).  Arguments
    as :func:`krylov_step`.  Returns ``(ang3_new, cos_psi_min)``, the
    smallest |cos psi| met by the step (start, stages and end): the caller
    compares it with ``--singularity-threshold``.
    """
    f, p, g = ang3[0], ang3[1], ang3[2]
    zx, zy, zz = w_in_n[0] * dt, w_in_n[1] * dt, w_in_n[2] * dt
    h0, h1, h2 = dtheta_b[0], dtheta_b[1], dtheta_b[2]
    out = np.empty(3)
    if integrator == EULER3_FORWARD_EULER:
        d1, d2, d3, c1 = _f3(f, p, g, h0, h1, h2, zx, zy, zz)
        f, p, g = f + d1, p + d2, g + d3
        cmin = c1
    else:
        p0, p1, p2 = dtheta_prev_b[0], dtheta_prev_b[1], dtheta_prev_b[2]
        a0x, a0y, a0z = 0.5 * (p0 + h0), 0.5 * (p1 + h1), 0.5 * (p2 + h2)
        a1x, a1y, a1z = 1.5 * h0 - 0.5 * p0, 1.5 * h1 - 0.5 * p1, 1.5 * h2 - 0.5 * p2
        k1f, k1p, k1g, c1 = _f3(f, p, g, a0x, a0y, a0z, zx, zy, zz)
        k2f, k2p, k2g, c2 = _f3(f + 0.5 * k1f, p + 0.5 * k1p, g + 0.5 * k1g, h0, h1, h2, zx, zy, zz)
        k3f, k3p, k3g, c3 = _f3(f + 0.5 * k2f, p + 0.5 * k2p, g + 0.5 * k2g, h0, h1, h2, zx, zy, zz)
        k4f, k4p, k4g, c4 = _f3(f + k3f, p + k3p, g + k3g, a1x, a1y, a1z, zx, zy, zz)
        f = f + (k1f + 2.0 * (k2f + k3f) + k4f) / 6.0
        p = p + (k1p + 2.0 * (k2p + k3p) + k4p) / 6.0
        g = g + (k1g + 2.0 * (k2g + k3g) + k4g) / 6.0
        cmin = min(min(c1, c2), min(c3, c4))
    out[0] = wrap_pi(f)
    out[1] = wrap_pi(p)
    out[2] = wrap_pi(g)
    cmin = min(cmin, abs(math.cos(out[1])))
    return out, cmin


@njit(cache=True, error_model="numpy")
def euler3_propagate(Cbn0, dtheta_b, dt, w_in_n, integrator):
    """Attitude-only run of :func:`euler3_step` (as :func:`krylov_propagate`).

    Returns ``(Cbn (N+1,3,3), ang3 (N+1,3), cos_psi_min (N,))``.
    """
    n = dtheta_b.shape[0]
    cbn = np.empty((n + 1, 3, 3))
    angs = np.empty((n + 1, 3))
    cmin = np.empty(n)
    ang = euler3_init(Cbn0)
    cbn[0] = euler3_dcm(ang)
    angs[0] = ang
    for k in range(n):
        prev = dtheta_b[k - 1] if k > 0 else dtheta_b[0]
        ang, cmin[k] = euler3_step(ang, prev, dtheta_b[k], dt, w_in_n, integrator)
        cbn[k + 1] = euler3_dcm(ang)
        angs[k + 1] = ang
    return cbn, angs, cmin


# ---------------------------------------------------------------- checks


@njit(cache=True, error_model="numpy")
def check_orthonormal(C):
    """Orthonormality error of a would-be rotation: ``max(max|C^T C - I|, |det C - 1|)``.

    Raises nothing; the caller compares with 1e-6 and raises SinsError
    ``initial attitude DCM is not orthonormal (error X > 1e-6)``.  A
    reflection (det = -1) gives an error of 2.
    """
    e = mm3(C.T.copy(), C)
    err = 0.0
    for i in range(3):
        for j in range(3):
            d = abs(e[i, j] - (1.0 if i == j else 0.0))
            if d > err:
                err = d
    det = (C[0, 0] * (C[1, 1] * C[2, 2] - C[1, 2] * C[2, 1])
           - C[0, 1] * (C[1, 0] * C[2, 2] - C[1, 2] * C[2, 0])
           + C[0, 2] * (C[1, 0] * C[2, 1] - C[1, 1] * C[2, 0]))
    d = abs(det - 1.0)
    if d > err:
        err = d
    if not (err == err):      # NaN in C
        err = math.inf
    return err
