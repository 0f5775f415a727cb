"""Earth model: WGS-84 ellipsoid, the FORMATS.md normal gravity, earth and transport rates.

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
    """Normal gravity magnitude of FORMATS.md, m/s^2, acting along -Up.

    ``g = 9.7803267715 (1 + 0.0052790414 s^2 + 0.0000232718 s^4)
         + (-3.0876910891e-6 + 4.3977311e-9 s^2) h + 7.211e-13 h^2``
    """
    s2 = sin_lat * sin_lat
    return (9.7803267715 * (1.0 + 0.0052790414 * s2 + 0.0000232718 * s2 * s2)
            + (-0.0000030876910891 + 0.0000000043977311 * s2) * h
            + 0.0000000000007211 * h * h)


radii = njit(cache=True)(radii_py)
gravity = njit(cache=True)(gravity_py)


@njit(cache=True)
def earth_rate_n(lat):
    """``w_ie^n = (0, W cos L, W sin L)`` in ENU, rad/s."""
    out = np.empty(3)
    out[0] = 0.0
    out[1] = OMEGA_IE * np.cos(lat)
    out[2] = OMEGA_IE * np.sin(lat)
    return out


@njit(cache=True)
def transport_rate_n(lat, h, vel_n):
    """``w_en^n = (-vN/(RM+h), vE/(RN+h), vE tan L/(RN+h))`` in ENU, rad/s."""
    rm, rn = radii(np.sin(lat))
    out = np.empty(3)
    out[0] = -vel_n[1] / (rm + h)
    out[1] = vel_n[0] / (rn + h)
    out[2] = vel_n[0] * np.tan(lat) / (rn + h)
    return out


def lla_to_ecef(lat, lon, h):
    """Geodetic (radians, metres) to ECEF metres; arrays broadcast.  Returns (..., 3)."""
    s = np.sin(lat)
    _, rn = radii_py(s)
    c = np.cos(lat)
    return np.stack([(rn + h) * c * np.cos(lon),
                     (rn + h) * c * np.sin(lon),
                     (rn * (1.0 - E2) + h) * s], axis=-1)


def ecef_to_lla(xyz):
    """ECEF metres (..., 3) to geodetic ``(lat, lon, h)`` (radians, metres).

    Bowring's start and three Newton-type refinements: below 1e-9 m for any
    terrestrial or near-space point.
    """
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    lat = np.arctan2(z, p * (1.0 - E2))
    for _ in range(5):
        s = np.sin(lat)
        _, rn = radii_py(s)
        h = np.where(np.abs(np.cos(lat)) > 1e-8, p / np.maximum(np.cos(lat), 1e-300) - rn,
                     np.abs(z) - B)
        lat = np.arctan2(z, p * (1.0 - E2 * rn / (rn + h)))
    s = np.sin(lat)
    _, rn = radii_py(s)
    c = np.cos(lat)
    h = p * c + z * s - A * A / rn
    return lat, lon, h


def enu_rotation(lat, lon):
    """``C_e^n`` rows (E, N, U) of the ENU frame at (lat, lon) in ECEF axes; (..., 3, 3)."""
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    z = np.zeros_like(sl)
    e = np.stack([-so, co, z], axis=-1)
    n = np.stack([-sl * co, -sl * so, cl], axis=-1)
    u = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([e, n, u], axis=-2)
