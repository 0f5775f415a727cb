"""Exact inertial sensor outputs from the kinematics: rates, specific force, increments.

    w_ib^b = w_nb^b + C_n^b (w_ie^n + w_en^n)
    f^b    = C_n^b (dv^n/dt + (2 w_ie^n + w_en^n) x v^n - g^n)

(the strapdown attitude and velocity equations, seed 004 / docs/algorithms.md,
solved for the sensor outputs), ENU navigation frame, FLU body axes.
``w_nb^b`` comes from the attitude jet: ``[w_nb^b x] = C_n^b dCbn/dt``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..nav.earth import earth_rate_sc, enu_rotation, gravity_py, lla_to_ecef, plumb_gravity_py, transport_rate_sc
from ..nav.rotation import cross, mtv3
from . import pinned as pm
from .jets import vee


def body_rate_nb(cbn: np.ndarray, dcbn: np.ndarray) -> np.ndarray:
    """``w_nb^b`` (n, 3) rad/s from ``Cbn`` and its time derivative (n, 3, 3): ``vee(Cbn^T dCbn/dt)``."""
    return vee(pm.matmul(np.swapaxes(cbn, -1, -2), dcbn))


def normal_gravity_n(lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``g^n = (0, 0, -g(L, h))`` (n, 3), the docs/formats.md normal gravity along the ellipsoid normal."""
    out = np.zeros(np.shape(lat) + (3,))
    out[..., 2] = -gravity_py(pm.sin(lat), h)
    return out


def j2_gravity_n(lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``g^n = C_e^n (G_J2(r^e) - W x (W x r^e))`` (n, 3): WGS-84 gravitation with J2 plus the
    centrifugal term, in ENU; the field is zonal, so it is evaluated at longitude 0.

    Unlike the normal gravity it has a north component and holds at any height (the launch-
    inertial navigator's gravitation, :func:`sinscli.nav.earth.gravitation`, is the same field).
    """
    lat = np.asarray(lat, dtype=float)
    zero = np.zeros_like(lat)
    r = lla_to_ecef(lat, zero, h, m=pm)
    g = np.stack(plumb_gravity_py(r[..., 0], r[..., 1], r[..., 2]), axis=-1)
    return np.einsum("...ij,...j->...i", enu_rotation(lat, zero, m=pm), g)


# Gravity models ``g^n(lat, h)`` (n, 3) selectable by a scenario's ``gravity`` key.
GRAVITY_MODELS = {"normal": normal_gravity_n, "j2": j2_gravity_n}


def sensor_outputs(lat, h, vel_n, acc_n, cbn, w_nb_b, g_n):
    """``(w_ib^b, f^b)`` (n, 3) each from the navigation-frame kinematics at n instants.

    ``lat`` rad, ``h`` m, ``vel_n`` / ``acc_n`` ENU m/s and m/s^2 (``acc_n`` is
    ``dv^n/dt`` of the ENU components), ``cbn`` (n, 3, 3), ``w_nb_b`` rad/s,
    ``g_n`` m/s^2 ENU.  The latitude's sine, cosine and tangent are the pinned ones (not the C library's,
    whose last bits depend on the CPU).
    """
    lat = np.asarray(lat, dtype=np.float64)
    return _sensor_outputs(pm.sin(lat), pm.cos(lat), pm.tan(lat), h, vel_n, acc_n, cbn, w_nb_b, g_n)


@njit(cache=True)
def _sensor_outputs(sin_lat, cos_lat, tan_lat, h, vel_n, acc_n, cbn, w_nb_b, g_n):
    n = sin_lat.shape[0]
    w_ib = np.empty((n, 3))
    f_b = np.empty((n, 3))
    for k in range(n):
        wie = earth_rate_sc(sin_lat[k], cos_lat[k])
        wen = transport_rate_sc(sin_lat[k], tan_lat[k], h[k], vel_n[k])
        w_in = wie + wen
        w_ib[k] = w_nb_b[k] + mtv3(cbn[k], w_in)
        a = acc_n[k] + cross(2.0 * wie + wen, vel_n[k]) - g_n[k]
        f_b[k] = mtv3(cbn[k], a)
    return w_ib, f_b


def transport_rate_many(lat, h, vel_n):
    """``w_en^n`` (n, 3) at n instants (:func:`sinscli.nav.earth.transport_rate_sc` per row, pinned trigonometry)."""
    lat = np.asarray(lat, dtype=np.float64)
    return _transport_rate_many(pm.sin(lat), pm.tan(lat), h, vel_n)


@njit(cache=True)
def _transport_rate_many(sin_lat, tan_lat, h, vel_n):
    n = sin_lat.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        out[k] = transport_rate_sc(sin_lat[k], tan_lat[k], h[k], vel_n[k])
    return out
