"""Velocity, position and attitude updates of one attitude interval (ENU frame).

KF-GINS style: each update is a short function; the loop that calls them is
:mod:`sinscli.nav.strapdown`.  Notation: interval from t_{m-1} to t_m of
length T; ``n0``/``b0`` are the navigation and body frames at t_{m-1} frozen in
inertial space; ``zeta = int w_in^n dt`` is the navigation-frame rotation over
the interval (Savage eqs 50-56) and ``phi`` the body rotation vector (eq 35).

Velocity (Savage part 2, in its exact frozen-frame form):

    v_m = C_{n0}^{n_m} (v_{m-1} + C_{b0}^{n0} dv^{b0})
          + Gamma(zeta) (g^n - w_ie^n x v) T,    C_{n0}^{n_m} = exp(-[zeta x])

with ``Gamma(zeta) = int_0^1 exp(-(1-s)[zeta x]) ds = I - 1/2 [zeta x]
+ 1/6 [zeta x]^2`` and the Coriolis integral taken as ``w_ie^n x dR`` with
``dR = int v dt``.  This form keeps a vehicle at rest exactly at rest:
the body and navigation-frame rotations cancel to third order.

Position: ``dR = int v^n dt`` by the cubic (fourth-order Adams-Moulton)
rule through the velocities at t_{m-3} .. t_m (actual spacings): a trapezoid
with curvature corrections that carry the rotation/scrolling effects of the
interval to fourth order; then latitude, longitude and height with the radii
of curvature at the interval midpoint.
"""
import numpy as np
from numba import njit

from .earth import OMEGA_IE, gravity, radii
from .rotation import rotvec_coeffs, v_add, v_cross, v_scale, v_sub


@njit(cache=True, inline="always")
def rotate_delta(phi, x):
    """``exp([phi x]) x - x`` (Rodrigues, Savage eq 26 applied to a vector, without x)."""
    a, b = rotvec_coeffs(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    px = v_cross(phi, x)
    return v_add(v_scale(px, a), v_scale(v_cross(phi, px), b))


@njit(cache=True, inline="always")
def gamma_delta(zeta, x):
    """``Gamma(zeta) x - x = -1/2 zeta x x + 1/6 zeta x (zeta x x)`` (|zeta| ~ 1e-6 rad)."""
    zx = v_cross(zeta, x)
    return v_add(v_scale(zx, -0.5), v_scale(v_cross(zeta, zx), 1.0 / 6.0))


@njit(cache=True, inline="always")
def midpoint(lat, h, dR):
    """Latitude and height at the middle of the interval from the displacement ``dR`` (ENU, m)."""
    rm, _ = radii(np.sin(lat))
    lat_mid = lat + 0.5 * dR[1] / (rm + h)
    return lat_mid, h + 0.5 * dR[2]


@njit(cache=True, inline="always")
def frame_rotation(lat_mid, h_mid, dR, T):
    """``zeta = w_ie^n T + int w_en^n dt`` with the transport rate integrated as ``dR / R`` (eqs 53-56)."""
    rm, rn = radii(np.sin(lat_mid))
    c, s = np.cos(lat_mid), np.sin(lat_mid)
    return (-dR[1] / (rm + h_mid),
            OMEGA_IE * c * T + dR[0] / (rn + h_mid),
            OMEGA_IE * s * T + dR[0] * (s / c) / (rn + h_mid))


@njit(cache=True, inline="always")
def velocity_update(vel, dv_sf_n0, zeta, lat_mid, h_mid, dR, T):
    """Velocity change ``v_m - v_{m-1}`` from the specific-force increment in n0, gravity, Coriolis.

    Formed as ``(dv + gc) + (exp(-zeta x) - I)(v + dv) + (Gamma - I) gc``: the terms
    of order g T cancel first (the sum vanishes at rest), so rounding cannot
    bias a vehicle at rest; the caller adds it to the state.
    """
    g = gravity(np.sin(lat_mid), h_mid)
    w_ie = (0.0, OMEGA_IE * np.cos(lat_mid), OMEGA_IE * np.sin(lat_mid))
    cor = v_cross(w_ie, dR)                       # int w_ie x v dt
    gc = (-cor[0], -cor[1], -g * T - cor[2])      # int (g^n - w_ie x v) dt
    small = v_add(rotate_delta(v_scale(zeta, -1.0), v_add(vel, dv_sf_n0)), gamma_delta(zeta, gc))
    return v_add(v_add(dv_sf_n0, gc), small)


@njit(cache=True, inline="always")
def _lagrange_weight(xi, xa, xb, xc, h):
    """``int_0^h L(x) dx`` for the cubic Lagrange basis of node ``xi`` with other nodes xa, xb, xc."""
    s1 = xa + xb + xc
    s2 = xa * xb + xa * xc + xb * xc
    s3 = xa * xb * xc
    num = h * h * h * h / 4.0 - s1 * h * h * h / 3.0 + s2 * h * h / 2.0 - s3 * h
    return num / ((xi - xa) * (xi - xb) * (xi - xc))


@njit(cache=True, inline="always")
def displacement(v3, v2, v1, v0, h2, h1, T, nhist):
    """``int v dt`` over (t_{m-1}, t_m] from the velocities at t_{m-3}, t_{m-2}, t_{m-1}, t_m.

    ``v3, v2, v1, v0`` are those velocities, ``h2 = t_{m-2} - t_{m-3}``,
    ``h1 = t_{m-1} - t_{m-2}``, ``T = t_m - t_{m-1}``; ``nhist`` how many of the
    older velocities exist (0: trapezoid, 1: quadratic, 2: cubic).  The cubic is
    the fourth-order Adams-Moulton rule ((9, 19, -5, 1)/24 at equal spacing), with
    weights from the actual spacings.
    """
    if nhist == 0:
        return v_scale(v_add(v1, v0), 0.5 * T)
    if nhist == 1:
        w0 = T * (2.0 * T + 3.0 * h1) / (6.0 * (T + h1))
        w2 = -T * T * T / (6.0 * h1 * (T + h1))
        w1 = T - w0 - w2
        return v_add(v_add(v_scale(v2, w2), v_scale(v1, w1)), v_scale(v0, w0))
    x3, x2, x1, x0 = -(h1 + h2), -h1, 0.0, T
    w3 = _lagrange_weight(x3, x2, x1, x0, T)
    w2 = _lagrange_weight(x2, x3, x1, x0, T)
    w0 = _lagrange_weight(x0, x3, x2, x1, T)
    w1 = T - w0 - w2 - w3
    return v_add(v_add(v_scale(v3, w3), v_scale(v2, w2)), v_add(v_scale(v1, w1), v_scale(v0, w0)))


@njit(cache=True, inline="always")
def position_update(lat, h, dR):
    """Increments (dlat, dlon, dh) from the displacement with midpoint radii (rates of Savage eqs 21-22)."""
    lat_mid, h_mid = midpoint(lat, h, dR)
    rm, rn = radii(np.sin(lat_mid))
    dlat = dR[1] / (rm + h_mid)
    lat_mid = lat + 0.5 * dlat
    rm, rn = radii(np.sin(lat_mid))
    dlat = dR[1] / (rm + h_mid)
    dlon = dR[0] / ((rn + h_mid) * np.cos(lat + 0.5 * dlat))
    return dlat, dlon, dR[2]


@njit(cache=True, inline="always")
def first_guess_displacement(vel, dv_sf_n0, lat, h, T):
    """A first displacement estimate to place the midpoint before the velocity is known."""
    g = gravity(np.sin(lat), h)
    return v_scale(v_add(vel, v_scale(v_sub(dv_sf_n0, (0.0, 0.0, g * T)), 0.5)), T)
