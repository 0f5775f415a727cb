"""Propagation corrections (numba kernels, no I/O): Klobuchar ionosphere, Saastamoinen troposphere with the
RTCA DO-229 mapping function."""
from __future__ import annotations

import math

from numba import njit

from .signals import C_LIGHT

PI = math.pi
F_L1 = 1575.42e6


@njit(cache=True)
def klobuchar(ion, lat, lon, az, el, tow):
    """Ionospheric group delay (m) on GPS L1 by the broadcast Klobuchar model (IS-GPS-200 20.3.3.5.2.5,
    figure 20-4).  ``ion`` = alpha0..3, beta0..3 (semicircle units as broadcast); receiver ``lat``, ``lon``,
    satellite ``az``, ``el`` in radians; ``tow`` GPS seconds of week.  Other frequencies f: times
    (f_L1/f)^2."""
    if ion[0] == 0.0 and ion[1] == 0.0 and ion[2] == 0.0 and ion[3] == 0.0:
        return 0.0
    e = el / PI                                           # semicircles
    psi = 0.0137 / (e + 0.11) - 0.022                     # earth-centred angle
    phi_i = lat / PI + psi * math.cos(az)
    if phi_i > 0.416:
        phi_i = 0.416
    elif phi_i < -0.416:
        phi_i = -0.416
    lam_i = lon / PI + psi * math.sin(az) / math.cos(phi_i * PI)
    phi_m = phi_i + 0.064 * math.cos((lam_i - 1.617) * PI)
    t = 43200.0 * lam_i + tow
    t -= math.floor(t / 86400.0) * 86400.0
    f = 1.0 + 16.0 * (0.53 - e) ** 3                      # obliquity factor
    amp = ion[0] + phi_m * (ion[1] + phi_m * (ion[2] + phi_m * ion[3]))
    per = ion[4] + phi_m * (ion[5] + phi_m * (ion[6] + phi_m * ion[7]))
    if amp < 0.0:
        amp = 0.0
    if per < 72000.0:
        per = 72000.0
    x = 2.0 * PI * (t - 50400.0) / per
    if abs(x) < 1.57:
        delay = f * (5e-9 + amp * (1.0 - x * x / 2.0 + x * x * x * x / 24.0))
    else:
        delay = f * 5e-9
    return C_LIGHT * delay


@njit(cache=True)
def tropo_zenith(lat, h):
    """Zenith hydrostatic and wet delays (m) by Saastamoinen (1972) with a standard atmosphere at ellipsoidal
    height ``h`` (m): P = 1013.25 (1 - 2.2557e-5 h)^5.2568 hPa, T = 15 - 6.5e-3 h deg C, 70 % humidity (the
    values RTKLIB's ``tropmodel`` uses).  Returns ``(zhd, zwd)``; zero outside -100 m .. 1e4 m."""
    if h < -100.0 or h > 1e4:
        return 0.0, 0.0
    hh = h if h > 0.0 else 0.0
    pres = 1013.25 * (1.0 - 2.2557e-5 * hh) ** 5.2568
    temp = 15.0 - 6.5e-3 * hh + 273.16
    e = 6.108 * 0.7 * math.exp((17.15 * temp - 4684.0) / (temp - 38.45))
    zhd = 0.0022768 * pres / (1.0 - 0.00266 * math.cos(2.0 * lat) - 0.00028 * hh / 1e3)
    zwd = 0.002277 * (1255.0 / temp + 0.05) * e
    return zhd, zwd


@njit(cache=True)
def mapping_mops(el):
    """Tropospheric mapping function of RTCA DO-229 (A.4.2.4): 1.001 / sqrt(0.002001 + sin^2 el)."""
    s = math.sin(el)
    return 1.001 / math.sqrt(0.002001 + s * s)


@njit(cache=True)
def tropo_delay(lat, h, el):
    """Slant tropospheric delay (m): Saastamoinen zenith delays times the DO-229 mapping function."""
    if el <= 0.0:
        return 0.0
    zhd, zwd = tropo_zenith(lat, h)
    return (zhd + zwd) * mapping_mops(el)
