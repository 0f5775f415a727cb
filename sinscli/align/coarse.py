"""Static analytic coarse alignment (double-vector / TRIAD) and the at-rest check.

At rest the accelerometers measure ``f^b = -C_n^b g^n`` and the gyros
``w^b = C_n^b w_ie^n``.  With the vertical as the primary vector,

    body:  r1 = f/|f|,   r2 = (f x w)/|f x w|,           r3 = r1 x r2
    nav:   n1 = up,      n2 = (up x w_ie)/|up x w_ie|,   n3 = n1 x n2
    Cbn = [n1 n2 n3] [r1 r2 r3]^T

so the tilt comes from the specific force alone (error ~ horizontal
accelerometer bias / g) and the heading from the horizontal earth rate
(error ~ east gyro bias / (W_ie cos L)).  Means over the interval are the
summed increments over its length.  No I/O here.
"""
from __future__ import annotations

import numpy as np

from ..nav.earth import OMEGA_IE


def _frame(v1, v2):
    """Orthonormal triad (columns) from a primary and a secondary vector; (..., 3, 3)."""
    r1 = v1 / np.linalg.norm(v1, axis=-1, keepdims=True)
    c = np.cross(v1, v2)
    n = np.linalg.norm(c, axis=-1, keepdims=True)
    # a secondary vector along the primary (a gyro reading zero) leaves the rotation about the primary
    # undefined: a body axis stands in (the heading is then unobservable, which the budget says)
    axis = np.where(np.abs(r1[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    c = np.where(n > 1e-12 * np.linalg.norm(v1, axis=-1, keepdims=True) * np.linalg.norm(v2, axis=-1, keepdims=True),
                 c, np.cross(r1, axis))
    r2 = c / np.linalg.norm(c, axis=-1, keepdims=True)
    r3 = np.cross(r1, r2)
    return np.stack([r1, r2, r3], axis=-1)


def triad(f_b, w_b, lat):
    """``Cbn`` from the mean specific force ``f_b`` and angular rate ``w_b`` (body, (3,) or (n, 3)) at latitude ``lat`` (rad)."""
    f_b = np.asarray(f_b, dtype=float)
    w_b = np.asarray(w_b, dtype=float)
    up = np.array([0.0, 0.0, 1.0])
    w_n = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    nav = _frame(up, w_n)
    body = _frame(f_b, w_b)
    return np.matmul(nav, np.swapaxes(body, -1, -2))


def cumulative_triad(time, dtheta_b, dvel_b, t0, lat, rows=None):
    """The static solution over (t0, time[k]] for the samples k in ``rows`` (all when None): (n, 3, 3)."""
    k = np.arange(len(time)) if rows is None else np.asarray(rows)
    T = (np.asarray(time, dtype=float)[k] - t0)[:, None]
    return triad(np.cumsum(dvel_b, axis=0)[k] / T, np.cumsum(dtheta_b, axis=0)[k] / T, lat)
