"""Satellite position, velocity and clock from a broadcast Keplerian ephemeris (numba kernels, no I/O).

IS-GPS-200 table 20-IV (GPS, QZSS), Galileo OS-SIS-ICD 5.1.1 (the same user algorithm with Galileo's GM),
BDS-SIS-ICD (B1I) 5.2.4.12 (MEO/IGSO as GPS; GEO with the -5 deg rotation), clock polynomial and the
relativistic term F e sqrt(A) sin E (IS-GPS-200 20.3.3.3.3.1).  Velocity is the analytic time derivative.
Positions are in the ECEF frame at the time of transmission (the Earth's rotation during the signal's flight,
the Sagnac term, is applied in :mod:`sinscli.gnss.model`).
"""
from __future__ import annotations

import math

from numba import njit

from .ephemeris import (AF0, AF1, AF2, CIC, CIS, CRC, CRS, CUC, CUS, DELTAN, ECC, I0, IDOT, M0, OMEGA, OMEGA0,
                        OMEGADOT, PRN, SQRTA, SYS, TOC, TOE)
from .signals import SYS_BDS, SYS_GAL
from .timesys import BDT_OFFSET, SECONDS_PER_WEEK

GM_GPS = 3.986005e14              # m^3/s^2, IS-GPS-200 table 20-IV
GM_GAL = 3.986004418e14           # OS-SIS-ICD 5.1.1
GM_BDS = 3.986004418e14           # BDS-SIS-ICD 5.2.4.10 (CGCS2000)
OMGE_GPS = 7.2921151467e-5        # rad/s, IS-GPS-200 and OS-SIS-ICD
OMGE_BDS = 7.292115e-5            # rad/s, CGCS2000
F_REL = -4.442807633e-10          # s/sqrt(m), -2 sqrt(GM)/c^2 (IS-GPS-200 20.3.3.3.3.1)
SIN5 = math.sin(math.radians(-5.0))
COS5 = math.cos(math.radians(-5.0))


@njit(cache=True)
def earth_rate(sys):
    """Earth rotation rate (rad/s) of the system's reference frame."""
    return OMGE_BDS if sys == SYS_BDS else OMGE_GPS


@njit(cache=True)
def _gm(sys):
    if sys == SYS_GAL:
        return GM_GAL
    if sys == SYS_BDS:
        return GM_BDS
    return GM_GPS


@njit(cache=True)
def clock_poly(eph, k, t):
    """Satellite clock offset (s) of ephemeris row ``k`` at GPS time ``t`` without the relativistic term:
    ``af0 + af1 dt + af2 dt^2``, ``dt = t - toc`` (IS-GPS-200 20.3.3.3.3.1)."""
    dt = t - eph[k, TOC]
    return eph[k, AF0] + dt * (eph[k, AF1] + dt * eph[k, AF2])


@njit(cache=True)
def _is_geo(sys, prn):
    return sys == SYS_BDS and (prn <= 5 or (59 <= prn <= 63))


@njit(cache=True)
def sat_state(eph, k, t):
    """ECEF position (m) and velocity (m/s) of ephemeris row ``k`` at GPS time ``t`` (the frame of time t),
    and the clock offset (s, with the relativistic term) and drift (s/s).

    Returns ``(x, y, z, vx, vy, vz, dts, ddts)``.
    """
    sys = int(eph[k, SYS])
    prn = int(eph[k, PRN])
    gm = _gm(sys)
    omge = earth_rate(sys)
    a = eph[k, SQRTA] * eph[k, SQRTA]
    e = eph[k, ECC]
    tk = t - eph[k, TOE]
    n = math.sqrt(gm / (a * a * a)) + eph[k, DELTAN]
    mk = eph[k, M0] + n * tk
    ek = mk
    for _ in range(30):                         # Kepler's equation, Newton
        f = ek - e * math.sin(ek) - mk
        d = f / (1.0 - e * math.cos(ek))
        ek -= d
        if abs(d) < 1e-15:
            break
    sin_e = math.sin(ek)
    cos_e = math.cos(ek)
    one_m = 1.0 - e * cos_e
    ekdot = n / one_m
    sq = math.sqrt(1.0 - e * e)
    vk = math.atan2(sq * sin_e, cos_e - e)
    phi = vk + eph[k, OMEGA]
    s2 = math.sin(2.0 * phi)
    c2 = math.cos(2.0 * phi)
    vdot = sq * ekdot / one_m
    uk = phi + eph[k, CUS] * s2 + eph[k, CUC] * c2
    rk = a * one_m + eph[k, CRS] * s2 + eph[k, CRC] * c2
    ik = eph[k, I0] + eph[k, IDOT] * tk + eph[k, CIS] * s2 + eph[k, CIC] * c2
    udot = vdot * (1.0 + 2.0 * (eph[k, CUS] * c2 - eph[k, CUC] * s2))
    rdot = a * e * sin_e * ekdot + 2.0 * vdot * (eph[k, CRS] * c2 - eph[k, CRC] * s2)
    idotk = eph[k, IDOT] + 2.0 * vdot * (eph[k, CIS] * c2 - eph[k, CIC] * s2)
    cu = math.cos(uk)
    su = math.sin(uk)
    xp = rk * cu
    yp = rk * su
    xpd = rdot * cu - rk * su * udot
    ypd = rdot * su + rk * cu * udot
    toe = eph[k, TOE] - BDT_OFFSET if sys == SYS_BDS else eph[k, TOE]
    toe_sow = toe - math.floor(toe / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
    geo = _is_geo(sys, prn)
    if geo:
        om = eph[k, OMEGA0] + eph[k, OMEGADOT] * tk - omge * toe_sow
        omd = eph[k, OMEGADOT]
    else:
        om = eph[k, OMEGA0] + (eph[k, OMEGADOT] - omge) * tk - omge * toe_sow
        omd = eph[k, OMEGADOT] - omge
    co = math.cos(om)
    so = math.sin(om)
    ci = math.cos(ik)
    si = math.sin(ik)
    x = xp * co - yp * ci * so
    y = xp * so + yp * ci * co
    z = yp * si
    vx = xpd * co - ypd * ci * so + yp * si * so * idotk - y * omd
    vy = xpd * so + ypd * ci * co - yp * si * co * idotk + x * omd
    vz = ypd * si + yp * ci * idotk
    if geo:                                       # BDS-SIS-ICD 5.2.4.12: R_Z(omge tk) R_X(-5 deg)
        y1 = COS5 * y + SIN5 * z
        z1 = -SIN5 * y + COS5 * z
        vy1 = COS5 * vy + SIN5 * vz
        vz1 = -SIN5 * vy + COS5 * vz
        ang = omge * tk
        ca = math.cos(ang)
        sa = math.sin(ang)
        xg = ca * x + sa * y1
        yg = -sa * x + ca * y1
        vxg = ca * vx + sa * vy1 + omge * (-sa * x + ca * y1)
        vyg = -sa * vx + ca * vy1 + omge * (-ca * x - sa * y1)
        x, y, z, vx, vy, vz = xg, yg, z1, vxg, vyg, vz1
    dt = t - eph[k, TOC]
    dts = eph[k, AF0] + dt * (eph[k, AF1] + dt * eph[k, AF2]) + F_REL * e * eph[k, SQRTA] * sin_e
    ddts = eph[k, AF1] + 2.0 * dt * eph[k, AF2] + F_REL * e * eph[k, SQRTA] * cos_e * ekdot
    return x, y, z, vx, vy, vz, dts, ddts
