"""Sideslip in turns: the vehicle's velocity leaves its forward axis (the non-holonomic constraint broken).

A car's tyres need slip angles to carry a lateral load; at the rear axle the slip angle grows with the
lateral acceleration, ``alpha_r = D_r a_y`` with the rear cornering compliance ``D_r`` of 2-4 deg/g for
passenger cars (Gillespie 1992, "Fundamentals of Vehicle Dynamics", SAE, ch. 6), so the body's velocity
points out of the turn.  The motion model takes the slip angle of the IMU point as

    beta = v_lat / V = K a_lat,     a_lat = -V cos(theta) psi'        (FLU: lateral = left, a right turn psi' > 0)

(``K`` rad per m/s^2, negative for the rear sliding out: ``v_lat`` opposite to ``a_lat``), and adds
``v_lat e_l`` to the velocity along the path's horizontal left axis ``e_l = (-cos psi, sin psi, 0)``
(ENU).  It is part of the truth (a Taylor jet: the increments and the position follow it exactly), so a
filter's zero lateral velocity is wrong by ``v_lat`` in every turn.
"""
from __future__ import annotations

import numpy as np

from .jets import stack


def slip_velocity(k_slip: float, spd, hdg, pit):
    """The velocity jet (order 1, ENU, (n, 3)) to add: ``K a_lat V e_l``; ``spd``, ``hdg`` order-2 jets
    (speed m/s, heading rad), ``pit`` (path pitch rad) order 1 or 2."""
    rate = hdg.deriv()                                    # psi' (order 1)
    v = spd.truncate(1)
    h1 = hdg.truncate(1)
    a_lat = -(v * np.cos(pit.truncate(1)) * rate)
    v_lat = k_slip * a_lat * v
    zero = 0.0 * h1
    return v_lat[..., None] * stack([-np.cos(h1), np.sin(h1), zero], axis=-1)
