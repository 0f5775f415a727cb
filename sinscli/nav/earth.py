"""Earth model: WGS-84 ellipsoid, the docs/formats.md normal gravity, earth and transport rates.

Each formula is written once, as a plain function of its arguments using only
arithmetic and ``np.sqrt`` / ``np.sin`` / ``np.cos``; the ``*_py`` names are
those plain functions (usable on numpy arrays, or on the Taylor "jets" of the
simulator), and the unsuffixed names are the same functions compiled with
``numba.njit(cache=True)`` for the navigation kernels.  Angles in radians,
lengths in metres, ENU navigation frame.
"""
import numpy as np
from numba import njit

A = 6378137.0                      # semi-major axis, m
F = 1.0 / 298.257223563            # flattening
E2 = F * (2.0 - F)                 # first eccentricity squared
B = A * (1.0 - F)                  # semi-minor axis, m
OMEGA_IE = 7.292115e-5             # earth rate, rad/s
GM = 3.986004418e14                # m^3/s^2 (gravitation, launch-inertial frame)
J2 = 1.08262982131e-3              # second zonal harmonic (WGS-84)


def radii_py(sin_lat):
    """Meridian and prime-vertical radii of curvature ``(RM, RN)`` in metres."""
    w = 1.0 - E2 * sin_lat * sin_lat
    rn = A / np.sqrt(w)
    rm = rn * (1.0 - E2) / w
    return rm, rn


def gravity_py(sin_lat, h):
    """Normal gravity magnitude of docs/formats.md, m/s^2, acting along -Up.

    ``g = 9.7803267715 (1 + 0.0052790414 s^2 + 0.0000232718 s^4)
         + (-3.0876910891e-6 + 4.3977311e-9 s^2) h + 7.211e-13 h^2``
    """
    s2 = sin_lat * sin_lat
    return (9.7803267715 * (1.0 + 0.0052790414 * s2 + 0.0000232718 * s2 * s2)
            + (-0.0000030876910891 + 0.0000000043977311 * s2) * h
            + 0.0000000000007211 * h * h)


def wrap_lon(lon, half=np.pi):
    """Longitude wrapped into ``[-half, half)`` (``half`` = pi for radians, 180 for degrees): values already
    there are returned unchanged, bit for bit; arrays or scalars.  Every writer and every reported
    longitude goes through it (the antimeridian, RFC 7946, KML)."""
    x = np.asarray(lon, dtype=np.float64)
    inside = (x >= -half) & (x < half)
    if np.all(inside):
        return lon if np.ndim(lon) else float(x)
    w = np.mod(x + half, 2.0 * half) - half
    out = np.where(inside, x, np.where(w >= half, -half, w))
    return out if np.ndim(lon) else float(out)


def dlon(a, b, half=np.pi):
    """``a - b`` of two longitudes taken modulo a full turn, into ``[-half, half]``: the east offset across
    the antimeridian (179.9999 to -179.9999 deg is 0.0002 deg, not -359.9998).  The plain difference when it
    is already within a half turn (the rounded count of turns is 0), so nothing changes away from the
    antimeridian.  Arrays or scalars; :data:`dlon_nb` is the same function compiled for the kernels.
    Residuals, ENU offsets, velocities from positions and comparisons use it."""
    d = a - b
    return d - 2.0 * half * np.round(d / (2.0 * half))


radii = njit(cache=True)(radii_py)
dlon_nb = njit(cache=True)(dlon)
gravity = njit(cache=True)(gravity_py)


@njit(cache=True)
def earth_rate_sc(sin_lat, cos_lat):
    """``w_ie^n = (0, W cos L, W sin L)`` in ENU, rad/s, from ``sin L`` and ``cos L``."""
    out = np.empty(3)
    out[0] = 0.0
    out[1] = OMEGA_IE * cos_lat
    out[2] = OMEGA_IE * sin_lat
    return out


@njit(cache=True)
def earth_rate_n(lat):
    """``w_ie^n`` (:func:`earth_rate_sc`) at latitude ``lat`` (rad)."""
    return earth_rate_sc(np.sin(lat), np.cos(lat))


@njit(cache=True)
def transport_rate_sc(sin_lat, tan_lat, h, vel_n):
    """``w_en^n = (-vN/(RM+h), vE/(RN+h), vE tan L/(RN+h))`` in ENU, rad/s, from ``sin L`` and ``tan L``
    (the simulator passes its own, CPU-independent values: sinscli/sim/pinned.py)."""
    rm, rn = radii(sin_lat)
    out = np.empty(3)
    out[0] = -vel_n[1] / (rm + h)
    out[1] = vel_n[0] / (rn + h)
    out[2] = vel_n[0] * tan_lat / (rn + h)
    return out


@njit(cache=True)
def transport_rate_n(lat, h, vel_n):
    """``w_en^n`` (:func:`transport_rate_sc`) at latitude ``lat`` (rad)."""
    return transport_rate_sc(np.sin(lat), np.tan(lat), h, vel_n)


def lla_to_ecef(lat, lon, h, m=np):
    """Geodetic (radians, metres) to ECEF metres; arrays broadcast.  Returns (..., 3).  ``m``: the module of
    the trigonometric functions (numpy; the simulator's CPU-independent :mod:`sinscli.sim.pinned`)."""
    s = m.sin(lat)
    _, rn = radii_py(s)
    c = m.cos(lat)
    return np.stack([(rn + h) * c * m.cos(lon),
                     (rn + h) * c * m.sin(lon),
                     (rn * (1.0 - E2) + h) * s], axis=-1)


@njit(cache=True)
def geodetic_to_ecef(lat, lon, h):
    """ECEF position ``(x, y, z)`` (m) of one geodetic point (radians, metres), for kernels: the formula of
    :func:`lla_to_ecef` on scalars (a tuple, nothing allocated)."""
    s = np.sin(lat)
    _, rn = radii(s)
    c = np.cos(lat)
    return (rn + h) * c * np.cos(lon), (rn + h) * c * np.sin(lon), (rn * (1.0 - E2) + h) * s


@njit(cache=True)
def enu_axes(lat, lon):
    """The ENU axes at (lat, lon) (radians) in ECEF, as three row tuples ``(east, north, up)``: the rows of
    ``C_e^n`` (:func:`enu_rotation` on scalars, for kernels)."""
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    return (-so, co, 0.0), (-sl * co, -sl * so, cl), (cl * co, cl * so, sl)


def ecef_to_lla(xyz, m=np):
    """ECEF metres (..., 3) to geodetic ``(lat, lon, h)`` (radians, metres); ``m`` as for :func:`lla_to_ecef`.

    Bowring's start and three Newton-type refinements: below 1e-9 m for any
    terrestrial or near-space point.
    """
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = m.hypot(x, y)
    lon = m.arctan2(y, x)
    lat = m.arctan2(z, p * (1.0 - E2))
    for _ in range(5):
        s = m.sin(lat)
        _, rn = radii_py(s)
        c = m.cos(lat)
        h = np.where(np.abs(c) > 1e-8, p / np.maximum(c, 1e-300) - rn, np.abs(z) - B)
        lat = m.arctan2(z, p * (1.0 - E2 * rn / (rn + h)))
    s = m.sin(lat)
    _, rn = radii_py(s)
    c = m.cos(lat)
    h = p * c + z * s - A * A / rn
    return lat, lon, h


def enu_rotation(lat, lon, m=np):
    """``C_e^n`` rows (E, N, U) of the ENU frame at (lat, lon) in ECEF axes; (..., 3, 3); ``m`` as for
    :func:`lla_to_ecef`."""
    sl, cl = m.sin(lat), m.cos(lat)
    so, co = m.sin(lon), m.cos(lon)
    z = np.zeros_like(sl)
    e = np.stack([-so, co, z], axis=-1)
    n = np.stack([-sl * co, -sl * so, cl], axis=-1)
    u = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([e, n, u], axis=-2)


def lla_to_local_enu(lat, lon, h, lat0: float, lon0: float, h0: float) -> np.ndarray:
    """ENU coordinates (N, 3) in metres of geodetic points (radians, metres) about an origin point."""
    d = lla_to_ecef(np.asarray(lat), np.asarray(lon), np.asarray(h)) - lla_to_ecef(lat0, lon0, h0)
    return d @ enu_rotation(lat0, lon0).T


def enu_offset(lat, lon, h, lat0, lon0, h0) -> np.ndarray:
    """Small-angle offset (m, E N U; (..., 3)) of the point ``(lat, lon, h)`` from ``(lat0, lon0, h0)`` (rad, m):
    ``E = dlon (RN + h) cos lat``, ``N = dlat (RM + h)``, ``U = h - h0``, with the WGS-84 radii at the point
    and the longitude difference taken by :func:`dlon`.  Exact to first order in the offset (the error is
    ~offset^2 / R: 1.6e-7 m at 1 m, 1.6 mm at 100 m); :func:`lla_to_local_enu` is the exact form."""
    lat = np.asarray(lat, dtype=float)
    rm, rn = radii_py(np.sin(lat))
    east = dlon(np.asarray(lon, dtype=float), lon0)       # across the antimeridian
    return np.stack(np.broadcast_arrays(east * (rn + h) * np.cos(lat), (lat - lat0) * (rm + h), np.asarray(h) - h0),
                    axis=-1)


def local_en(lat_deg, lon_deg, h):
    """East and north offsets (m) of points (deg, deg, m) from the first one (:func:`enu_offset`)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    off = enu_offset(lat, lon, h, lat[0], lon[0], h[0])
    return off[..., 0], off[..., 1]


def local_enu_to_lla(enu, lat0: float, lon0: float, h0: float):
    """Inverse of :func:`lla_to_local_enu`: ``(lat, lon, h)`` in radians and metres."""
    xyz = lla_to_ecef(lat0, lon0, h0) + np.asarray(enu) @ enu_rotation(lat0, lon0)
    return ecef_to_lla(xyz)


# --- WGS-84 gravitation with J2 and the launch-centred inertial frame ----------------------------
#
# The launch-inertial frame ``i`` (docs/inertial.md): origin at the launch point at the launch
# time t_L; x_i horizontal along the launch azimuth A (clockwise from north), y_i up along the
# ellipsoid normal, z_i = x_i x y_i (horizontal, to the right of x_i); frozen in inertial space at
# t_L.  ``C_e^i`` at launch is :func:`launch_axes`; at t = t_L + dt the earth has turned by
# W dt about its polar axis, so ``C_e(t)^i = C_e(tL)^i Rz(W dt)`` with ``Rz`` the rotation of
# :func:`ecef_to_launch_axes_py`.

def gravitation_py(x, y, z):
    """WGS-84 gravitation (attraction only, no centrifugal term) with J2, ECEF components, m/s^2.

    ``G = -GM/r^3 (x (1 + c (1 - 5 z^2/r^2)), y (1 + c (1 - 5 z^2/r^2)), z (1 + c (3 - 5 z^2/r^2)))``
    with ``c = 3/2 J2 (a/r)^2``: the gradient of ``U = GM/r (1 - J2 (a/r)^2 P2(z/r))``.
    The field is symmetric about the polar axis, so the same formula holds in any
    frame whose third axis is the polar axis (e.g. ECEF frozen at the launch time).
    """
    r2 = x * x + y * y + z * z
    r = np.sqrt(r2)
    k = -GM / (r2 * r)
    c = 1.5 * J2 * A * A / r2
    q = 5.0 * z * z / r2
    f = k * (1.0 + c * (1.0 - q))
    return f * x, f * y, k * z * (1.0 + c * (3.0 - q))


def plumb_gravity_py(x, y, z):
    """J2 gravity of the rotating earth in ECEF: ``g = G - W x (W x r)`` (gravitation + centrifugal), m/s^2.

    numpy only (the simulator's ``j2`` model); the navigation kernels use :func:`gravitation`.
    """
    gx, gy, gz = gravitation_py(x, y, z)
    w2 = OMEGA_IE * OMEGA_IE
    return gx + w2 * x, gy + w2 * y, gz


def ecef_to_launch_axes_py(x, y, z, dt, c_ei):
    """An ECEF vector at time ``t_L + dt`` (s) in launch-inertial axes: ``C_e(tL)^i Rz(W dt) x``.

    ``c_ei`` is ``C_e^i`` at launch (:func:`launch_axes`, indexable ``c_ei[i][j]``).
    Axes only: a position needs the launch point subtracted (``r^i = R^i - R_0^i``).
    """
    th = OMEGA_IE * dt
    ct, st = np.cos(th), np.sin(th)
    x0 = ct * x - st * y
    y0 = st * x + ct * y
    return (c_ei[0][0] * x0 + c_ei[0][1] * y0 + c_ei[0][2] * z,
            c_ei[1][0] * x0 + c_ei[1][1] * y0 + c_ei[1][2] * z,
            c_ei[2][0] * x0 + c_ei[2][1] * y0 + c_ei[2][2] * z)


def launch_to_ecef_axes_py(x, y, z, dt, c_ei):
    """The inverse of :func:`ecef_to_launch_axes_py`: ``Rz(-W dt) C_i^e(tL) x``."""
    x0 = c_ei[0][0] * x + c_ei[1][0] * y + c_ei[2][0] * z
    y0 = c_ei[0][1] * x + c_ei[1][1] * y + c_ei[2][1] * z
    z0 = c_ei[0][2] * x + c_ei[1][2] * y + c_ei[2][2] * z
    th = OMEGA_IE * dt
    ct, st = np.cos(th), np.sin(th)
    return ct * x0 + st * y0, -st * x0 + ct * y0, z0


gravitation = njit(cache=True)(gravitation_py)
ecef_to_launch_axes = njit(cache=True)(ecef_to_launch_axes_py)
launch_to_ecef_axes = njit(cache=True)(launch_to_ecef_axes_py)


def launch_axes(lat, lon, azimuth):
    """``C_e^i`` (3, 3) at launch: rows x_i, y_i, z_i in ECEF axes (radians).

    ``x_i = sin A E + cos A N``, ``y_i = U``, ``z_i = x_i x y_i = cos A E - sin A N``
    with E, N, U the rows of :func:`enu_rotation` at the launch point.
    """
    e, n, u = enu_rotation(lat, lon)
    sa, ca = np.sin(azimuth), np.cos(azimuth)
    return np.stack([sa * e + ca * n, u, ca * e - sa * n])
