"""Measurement models of pseudorange and range rate (numba kernels, no I/O), shared by single-point
positioning and the tightly coupled filter.

* time of transmission and the satellite state then (IS-GPS-200 20.3.3.3.3.1: ``t_sv = t_rx - P/c``, the
  satellite clock removed);
* geometric range with the Earth's rotation during the flight (Sagnac) in closed form, and its rate;
* group delays of the signal used (TGD, BGD, TGD1/TGD2: IS-GPS-200 20.3.3.3.3.2, OS-SIS-ICD 5.1.5,
  BDS-SIS-ICD 5.2.4.10);
* geodetic latitude, longitude, height of the receiver and the satellite's azimuth and elevation.
"""
from __future__ import annotations

import math

from numba import njit

from .ephemeris import SOURCE, SYS, TGD1, TGD2
from .orbits import clock_poly, earth_rate, sat_state
from .signals import C_LIGHT, SYS_BDS, SYS_GAL

A_WGS = 6378137.0
E2_WGS = 6.69437999014e-3
F_L1 = 1575.42e6


@njit(cache=True)
def transmit_state(eph, k, t_rx, pr):
    """Satellite state at the time of transmission of a signal received at GPS time ``t_rx`` (receiver clock
    time, s) with pseudorange ``pr`` (m): ``t_tx = t_rx - pr/c - dt_s(t_tx)`` (clock polynomial), then
    :func:`sinscli.gnss.orbits.sat_state` at ``t_tx``.  Returns ``(t_tx, x, y, z, vx, vy, vz, dts, ddts)``."""
    t = t_rx - pr / C_LIGHT
    dt = clock_poly(eph, k, t)
    dt = clock_poly(eph, k, t - dt)
    t_tx = t - dt
    x, y, z, vx, vy, vz, dts, ddts = sat_state(eph, k, t_tx)
    return t_tx, x, y, z, vx, vy, vz, dts, ddts


@njit(cache=True)
def to_reception_frame(sx, sy, sz, rx, ry, rz, omge):
    """Satellite position (ECEF of the time of transmission) in the ECEF frame of the time of reception:
    ``R_z(w_e tau) r_s`` with the flight time ``tau = |r_s - r_r| / c`` (the Earth's rotation during the flight,
    the Sagnac effect, in closed form).  Returns ``(x, y, z, cos, sin)`` of the rotation."""
    dx = sx - rx
    dy = sy - ry
    dz = sz - rz
    tau = math.sqrt(dx * dx + dy * dy + dz * dz) / C_LIGHT
    c = math.cos(omge * tau)
    s = math.sin(omge * tau)
    return c * sx + s * sy, -s * sx + c * sy, sz, c, s


@njit(cache=True)
def geo_range(sx, sy, sz, rx, ry, rz, omge):
    """Geometric range (m) from receiver ``r`` to satellite ``s`` (ECEF at transmission) with the Earth's rotation
    during the flight (:func:`to_reception_frame`; to first order the usual ``w_e (x_s y_r - y_s x_r) / c``), and
    the unit line of sight from the receiver to the satellite.  Returns ``(rho, ex, ey, ez)``."""
    x, y, z, c, s = to_reception_frame(sx, sy, sz, rx, ry, rz, omge)
    dx = x - rx
    dy = y - ry
    dz = z - rz
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    return r, dx / r, dy / r, dz / r


@njit(cache=True)
def range_rate(sx, sy, sz, svx, svy, svz, rx, ry, rz, rvx, rvy, rvz, ex, ey, ez, omge):
    """Rate (m/s) of the range of :func:`geo_range` (``e`` its line of sight), exact to first order in the flight
    time's rate: ``d rho/dt = e.(R v_s - v_r) / (1 - e.(w_e R' r_s - R v_s)/c)`` with ``R = R_z(w_e tau)`` and
    ``R'`` its derivative by the angle (the rotation's own rate and the transmission time moving with the
    range).  The first-order Sagnac form leaves ~3 cm/s (the satellite's velocity across a line of sight turned
    by ``w_e tau``)."""
    x, y, z, c, s = to_reception_frame(sx, sy, sz, rx, ry, rz, omge)
    vx = c * svx + s * svy
    vy = -s * svx + c * svy
    wx = omge * (-s * sx + c * sy)
    wy = omge * (-c * sx - s * sy)
    num = ex * (vx - rvx) + ey * (vy - rvy) + ez * (svz - rvz)
    den = 1.0 - (ex * (wx - vx) + ey * (wy - vy) - ez * svz) / C_LIGHT
    return num / den


@njit(cache=True)
def sat_earth_rate(eph, k):
    return earth_rate(int(eph[k, SYS]))


@njit(cache=True)
def group_delay(eph, k, band, freq):
    """Group delay (s) of the signal in RINEX ``band`` at ``freq`` (Hz) relative to the broadcast clock's
    reference, to be added to the satellite clock term: GPS/QZSS ``(f_L1/f)^2 TGD`` (L1: TGD, L2: gamma TGD); Galileo ``(f_E1/f)^2 BGD`` with BGD(E1,E5a) for an F/NAV ephemeris or E5a and
    BGD(E1,E5b) otherwise; BeiDou B1I TGD1, B2I TGD2, B3I 0.  GPS/QZSS L5: TGD (IS-GPS-705 20.3.3.3.1.2:
    the L5 clock correction is ``dt_sv - TGD + ISC_L5``; the ISC is not in LNAV and is taken as 0)."""
    sys = int(eph[k, SYS])
    if sys == SYS_BDS:
        if band == 2:
            return eph[k, TGD1]
        if band == 7:
            return eph[k, TGD2]
        return 0.0
    g = (F_L1 / freq) ** 2
    if sys == SYS_GAL:
        fnav_only = (int(eph[k, SOURCE]) & 0b101) == 0
        if band == 5 or fnav_only:
            return g * eph[k, TGD1]
        return g * eph[k, TGD2]
    if band == 5:
        return eph[k, TGD1]
    return g * eph[k, TGD1]


@njit(cache=True)
def ecef_to_geodetic(x, y, z):
    """Geodetic latitude, longitude (rad) and ellipsoidal height (m) of an ECEF point (WGS-84), by fixed-point
    iteration on the prime-vertical radius (converges to < 1e-9 m in a few steps for points above 1 km from
    the centre)."""
    p = math.sqrt(x * x + y * y)
    lon = math.atan2(y, x)
    lat = math.atan2(z, p * (1.0 - E2_WGS))
    h = 0.0
    for _ in range(10):
        s = math.sin(lat)
        rn = A_WGS / math.sqrt(1.0 - E2_WGS * s * s)
        h_new = p * math.cos(lat) + z * s - A_WGS * A_WGS / rn
        lat_new = math.atan2(z, p * (1.0 - E2_WGS * rn / (rn + h_new)))
        done = abs(lat_new - lat) < 1e-14 and abs(h_new - h) < 1e-6
        lat = lat_new
        h = h_new
        if done:
            break
    s = math.sin(lat)
    rn = A_WGS / math.sqrt(1.0 - E2_WGS * s * s)
    h = p * math.cos(lat) + z * s - A_WGS * A_WGS / rn
    return lat, lon, h


@njit(cache=True)
def azel(lat, lon, ex, ey, ez):
    """Azimuth (rad, clockwise from north) and elevation (rad) of the line of sight ``e`` (ECEF unit vector)
    at geodetic ``lat``, ``lon``."""
    sl = math.sin(lat)
    cl = math.cos(lat)
    so = math.sin(lon)
    co = math.cos(lon)
    east = -so * ex + co * ey
    north = -sl * co * ex - sl * so * ey + cl * ez
    up = cl * co * ex + cl * so * ey + sl * ez
    az = math.atan2(east, north)
    if az < 0.0:
        az += 2.0 * math.pi
    return az, math.asin(max(-1.0, min(1.0, up)))
