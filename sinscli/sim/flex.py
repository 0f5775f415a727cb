"""Mount flex: the IMU's mount leans and twists under the vehicle's acceleration (a motion, like the vibration).

A compliant mount (a roof plate, a phone holder) is a spring-mass: under the vehicle's kinematic
acceleration ``a^b = C_n^b dv^n/dt`` (FLU body; gravity's constant part sits in the static mounting)
it turns by the small angles

    u(t) = (k_roll a_y, -k_pitch a_x, k_yaw a_y)          (rad, about the body's x, y, z)

(it leans out of a turn, dips its nose under braking, twists with the lateral load), low-passed by its
damping with the time constant ``tau``:  ``theta' = (u - theta) / tau``, ``theta(0) = 0`` (the mount sits
on the body at the start, so that ``init.yaml`` is the sensor's attitude too).  This is the response of
a spring-mass-damper below its resonance (Thomson & Dahleh 1998, "Theory of Vibration with
Applications", 5th ed., ch. 3: the deflection is the load over the stiffness, ``x = F/k``, lagged by the
damping), for a mount resonating at several Hz under a car's manoeuvres of a fraction of a Hz.

``u`` is taken at the IMU instants and held linear between them (first-order hold), for which the
recursion ``theta_k+1 = phi theta_k + (1 - phi) u_k + s (h - tau (1 - phi))``, ``phi = exp(-h/tau)``,
``s = (u_k+1 - u_k)/h`` is the exact solution; ``theta'_k = (u_k - theta_k)/tau``.  Between the instants
the angle is the cubic Hermite interpolant of ``(theta_k, theta'_k)``, a C1 motion whose derivative is
exactly the rate the sensor measures (so the increments stay exact for the motion simulated).  The
rotation adds to the vibration's ``theta`` (:func:`sinscli.sim.vibration.vibrate`); the truth is the
vehicle body's and leaves the flex out (``sim_truth.yaml`` records its size).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from . import pinned as pm


@dataclass
class Flex:
    """Flex gains (rad per m/s^2: roll per a_y, pitch per -a_x, yaw per a_y) and the time constant (s)."""
    gain: np.ndarray
    tau: float


def flex_target(flex: Flex, acc_b: np.ndarray) -> np.ndarray:
    """``u`` (n, 3) rad from the body's kinematic acceleration ``acc_b`` (n, 3) m/s^2, FLU."""
    g = flex.gain
    return np.stack([g[0] * acc_b[:, 1], -g[1] * acc_b[:, 0], g[2] * acc_b[:, 1]], axis=-1)


def flex_knots(flex: Flex, tau: np.ndarray, u: np.ndarray):
    """``(theta, theta')`` (n, 3) at the instants ``tau`` (s) from the targets ``u`` (n, 3): the exact
    first-order-hold solution of ``theta' = (u - theta)/tau`` from ``theta(tau_0) = 0``."""
    h = np.diff(tau)
    phi = pm.exp(-h / flex.tau)
    return _low_pass(np.ascontiguousarray(u, dtype=np.float64), h, phi, float(flex.tau))


@njit(cache=True)
def _low_pass(u, h, phi, tc):
    """The recursion of :func:`flex_knots` (module docstring)."""
    n = u.shape[0]
    th = np.zeros((n, 3))
    dth = np.empty((n, 3))
    for i in range(3):
        dth[0, i] = u[0, i] / tc
    for k in range(n - 1):
        for i in range(3):
            s = (u[k + 1, i] - u[k, i]) / h[k]
            th[k + 1, i] = phi[k] * th[k, i] + (1.0 - phi[k]) * u[k, i] + s * (h[k] - tc * (1.0 - phi[k]))
            dth[k + 1, i] = (u[k + 1, i] - th[k + 1, i]) / tc
    return th, dth


def flex_between(theta: np.ndarray, dtheta: np.ndarray, h: np.ndarray, k: np.ndarray, t_local: np.ndarray):
    """``(theta, theta')`` (m, 3) at ``t_local`` s after the instant ``k`` (m,) within intervals of length
    ``h[k]``: the cubic Hermite interpolant of the knots (value and derivative continuous)."""
    hk = h[k][:, None]
    s = (t_local / h[k])[:, None]
    s2 = s * s
    s3 = s2 * s
    a0, a1 = theta[k], theta[k + 1]
    b0, b1 = dtheta[k] * hk, dtheta[k + 1] * hk
    val = (2.0 * s3 - 3.0 * s2 + 1.0) * a0 + (s3 - 2.0 * s2 + s) * b0 + (3.0 * s2 - 2.0 * s3) * a1 + (s3 - s2) * b1
    der = ((6.0 * s2 - 6.0 * s) * a0 + (3.0 * s2 - 4.0 * s + 1.0) * b0 + (6.0 * s - 6.0 * s2) * a1
           + (3.0 * s2 - 2.0 * s) * b1) / hk
    return val, der
