"""Coning and sculling: the fast-rate part of Savage's two-speed design (seed 004 eqs 41-47).

Within an attitude interval m made of fast samples l = 1..N, with ``alpha``
and ``upsilon`` the angle and velocity increments summed since the start of
the interval (eq 41, 46), the coning term ``beta`` (eqs 42, 45, 47) and the
sculling term (Savage part 2) grow by

    d_beta_l = 1/2 alpha_{l-1} x dth_l + sum_j c_j dth_{l-j} x dth_l
    d_scul_l = 1/2 (alpha_{l-1} x dv_l + upsilon_{l-1} x dth_l)
               + sum_j c_j (dth_{l-j} x dv_l + dv_{l-j} x dth_l)

where the previous samples ``l-j`` may lie in the previous interval.  With
order K the sum runs over the K-1 previous samples.  ``c`` are the
coning-optimal coefficients of this one-speed/previous-sample family,
derived by matching the pure-coning response to ``1/2 int (alpha x w) dt``
through order lambda^(2K-1) (lambda = cone frequency x sample interval):
K = 2 gives Savage's eq 45 (1/12); every set satisfies sum_j j c_j = 1/12,
so it is exact for a linearly varying rate.  The same coefficients serve
sculling (the coning/sculling equivalence).  K = 1 is seed 000's assumption of
a fixed rotation axis over the interval: no coning or sculling correction
beyond the interval's own ``1/2 alpha x dth`` terms.
"""
import numpy as np
from numba import njit

from .rotation import v_add, v_cross, v_scale, v_sub

MAX_ORDER = 4

# CONING_COEFFS[K - 1, j - 1] = c_j for order K (j = 1..K-1).
CONING_COEFFS = np.array([
    [0.0, 0.0, 0.0],
    [1.0 / 12.0, 0.0, 0.0],
    [7.0 / 60.0, -1.0 / 60.0, 0.0],
    [113.0 / 840.0, -13.0 / 420.0, 1.0 / 280.0],
])


@njit(cache=True)
def load_memory(st, i_dth, i_dv):
    """The fast-rate sample memory (previous increments, newest first) from a state vector."""
    prev_dth = np.empty((MAX_ORDER - 1, 3))
    prev_dv = np.empty((MAX_ORDER - 1, 3))
    for j in range(MAX_ORDER - 1):
        for i in range(3):
            prev_dth[j, i] = st[i_dth + 3 * j + i]
            prev_dv[j, i] = st[i_dv + 3 * j + i]
    return prev_dth, prev_dv


@njit(cache=True)
def save_memory(st, i_dth, i_dv, prev_dth, prev_dv):
    """Store the sample memory back into the state vector (for the next block)."""
    for j in range(MAX_ORDER - 1):
        for i in range(3):
            st[i_dth + 3 * j + i] = prev_dth[j, i]
            st[i_dv + 3 * j + i] = prev_dv[j, i]


@njit(cache=True, inline="always")
def push_sample(prev_dth, prev_dv, dth, dv, n_prev):
    """Shift the memory back by one sample, put (dth, dv) first; returns the new count of valid samples."""
    for j in range(MAX_ORDER - 2, 0, -1):
        for i in range(3):
            prev_dth[j, i] = prev_dth[j - 1, i]
            prev_dv[j, i] = prev_dv[j - 1, i]
    for i in range(3):
        prev_dth[0, i] = dth[i]
        prev_dv[0, i] = dv[i]
    return min(n_prev + 1, MAX_ORDER - 1)


@njit(cache=True, inline="always")
def fast_step(alpha, upsilon, beta, scul, dth, dv, prev_dth, prev_dv, n_prev, coeffs):
    """One fast-rate update of the interval sums; returns new (alpha, upsilon, beta, scul).

    ``prev_dth[j-1]``/``prev_dv[j-1]`` hold the increments j samples back
    (``n_prev`` of them valid); ``coeffs`` is the row of :data:`CONING_COEFFS`.
    """
    d_beta = v_scale(v_cross(alpha, dth), 0.5)
    d_scul = v_scale(v_add(v_cross(alpha, dv), v_cross(upsilon, dth)), 0.5)
    for j in range(n_prev):
        c = coeffs[j]
        if c != 0.0:
            pth = (prev_dth[j, 0], prev_dth[j, 1], prev_dth[j, 2])
            pdv = (prev_dv[j, 0], prev_dv[j, 1], prev_dv[j, 2])
            d_beta = v_add(d_beta, v_scale(v_cross(pth, dth), c))
            d_scul = v_add(d_scul, v_scale(v_add(v_cross(pth, dv), v_cross(pdv, dth)), c))
    return v_add(alpha, dth), v_add(upsilon, dv), v_add(beta, d_beta), v_add(scul, d_scul)


@njit(cache=True)
def _jacobian_coeffs(a2):
    """``((1 - cos a)/a^2, (a - sin a)/a^3)`` for ``a^2 = a2``; series below a = 1e-2."""
    if a2 < 1e-4:
        c1 = 0.5 * (1.0 - a2 / 12.0 * (1.0 - a2 / 30.0 * (1.0 - a2 / 56.0)))
        c2 = (1.0 - a2 / 20.0 * (1.0 - a2 / 42.0 * (1.0 - a2 / 72.0))) / 6.0
        return c1, c2
    a = np.sqrt(a2)
    return (1.0 - np.cos(a)) / a2, (a - np.sin(a)) / (a2 * a)


@njit(cache=True)
def body_increments(alpha, upsilon, beta, scul, alpha_prev, upsilon_prev, have_prev):
    """Rotation vector and velocity increment of the interval in the frame b(m-1).

    ``phi_m = alpha_m + beta_m`` (eq 35) and ``dv^b = int C_{b(t)}^{b0} f dt``:

        dv^b = upsilon + c1 alpha x upsilon + scul + c2 alpha x (alpha x upsilon)
               + 1/24 [alpha x (alpha x (upsilon - upsilon')) - (alpha - alpha') x (alpha x upsilon)]

    with ``c1 = (1 - cos a)/a^2`` (= 1/2 - a^2/24 ...) and ``c2 = (a - sin a)/a^3``
    (= 1/6 - a^2/120 ...), ``a = |alpha|``: ``int_0^1 exp(s [alpha x]) ds upsilon``,
    the rotation compensation in closed form, exact for a constant rate and
    specific force at any angle.  Its 1/2 is the textbook first-order term (which
    alone drifts at rest over an hour); the 1/6 and the a^2/24 of c1 (third order,
    about 1e-10 m/s per step in a 0.3 rad/s turn at 100 Hz) matter at the
    accuracy this project keeps.  The 1/24 bracket is the next order for
    linearly varying rate and specific force (previous interval's sums
    ``alpha'``, ``upsilon'``), with the ``int beta x f dt`` part of the
    rotation-vector expansion.
    """
    phi = v_add(alpha, beta)
    axu = v_cross(alpha, upsilon)
    c1, c2 = _jacobian_coeffs(alpha[0] * alpha[0] + alpha[1] * alpha[1] + alpha[2] * alpha[2])
    dv_b = v_add(v_add(upsilon, v_scale(axu, c1)),
                 v_add(scul, v_scale(v_cross(alpha, axu), c2)))
    if have_prev:
        corr = v_sub(v_cross(alpha, v_cross(alpha, v_sub(upsilon, upsilon_prev))),
                     v_cross(v_sub(alpha, alpha_prev), axu))
        dv_b = v_add(dv_b, v_scale(corr, 1.0 / 24.0))
    return phi, dv_b
