"""The antenna's velocity and its Jacobians in the GNSS measurement models of the fusion filter (numba, no I/O):
shared by :mod:`sinscli.fusion.kernel` (fixes, pseudoranges, range rates) and :mod:`sinscli.fusion.tdcp`."""
import numpy as np
from numba import njit

from ..nav.earth import OMEGA_IE, enu_axes, geodetic_to_ecef, radii
from ..nav.rotation import m_mul, m_vec


@njit(cache=True)
def _antenna_velocity(c, vel, lat, h, w, lever):
    """``(v_ant, Cbn (w x l), Cbn l, w_in)`` of the antenna at ``lever`` (body) with body rate ``w``."""
    wxl = (w[1] * lever[2] - w[2] * lever[1], w[2] * lever[0] - w[0] * lever[2], w[0] * lever[1] - w[1] * lever[0])
    cw = m_vec(c, wxl)
    l_n = m_vec(c, lever)
    rm, rn = radii(np.sin(lat))
    w_in = (-vel[1] / (rm + h), OMEGA_IE * np.cos(lat) + vel[0] / (rn + h),
            OMEGA_IE * np.sin(lat) + vel[0] * np.tan(lat) / (rn + h))
    wl = (w_in[1] * l_n[2] - w_in[2] * l_n[1], w_in[2] * l_n[0] - w_in[0] * l_n[2], w_in[0] * l_n[1] - w_in[1] * l_n[0])
    v_ant = (vel[0] + cw[0] - wl[0], vel[1] + cw[1] - wl[1], vel[2] + cw[2] - wl[2])
    return v_ant, cw, l_n, w_in


@njit(cache=True, inline="always")
def _cross(a, b):
    """``a x b`` of 3-tuples (``a^T [b x] = (a x b)^T``)."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def _dvant_dlever(c, w, w_in):
    """``d v_ant / d l = Cbn [w x] - [w_in x] Cbn`` (:func:`_antenna_velocity`)."""
    wx = ((0.0, -w[2], w[1]), (w[2], 0.0, -w[0]), (-w[1], w[0], 0.0))
    wix = ((0.0, -w_in[2], w_in[1]), (w_in[2], 0.0, -w_in[0]), (-w_in[1], w_in[0], 0.0))
    a1 = m_mul(c, wx)
    a2 = m_mul(wix, c)
    return ((a1[0][0] - a2[0][0], a1[0][1] - a2[0][1], a1[0][2] - a2[0][2]),
            (a1[1][0] - a2[1][0], a1[1][1] - a2[1][1], a1[1][2] - a2[1][2]),
            (a1[2][0] - a2[2][0], a1[2][1] - a2[2][1], a1[2][2] - a2[2][2]))


@njit(cache=True)
def antenna_ecef(lat, lon, h, l_n, v_ant, tau):
    """The antenna's ECEF position ``r(lat, lon, h) + C_n^e (l_n + v_ant tau)`` (at the stamp plus the GNSS time
    offset ``tau``) and the ENU axes ``(east, north, up)``."""
    ue, un, uu = enu_axes(lat, lon)
    x0, y0, z0 = geodetic_to_ecef(lat, lon, h)
    d = (l_n[0] + v_ant[0] * tau, l_n[1] + v_ant[1] * tau, l_n[2] + v_ant[2] * tau)
    return (x0 + ue[0] * d[0] + un[0] * d[1] + uu[0] * d[2], y0 + ue[1] * d[0] + un[1] * d[1] + uu[1] * d[2],
            z0 + ue[2] * d[0] + un[2] * d[1] + uu[2] * d[2], ue, un, uu)


__all__ = ["_antenna_velocity", "_cross", "_dvant_dlever", "antenna_ecef"]
