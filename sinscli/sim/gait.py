"""Step dynamics of a handheld walker: analytic modulations of the motion, exact through the jets.

With the walking speed ``V(t)`` (the speed channel) and ``m(t) = V(t) / V_ref``, the step phase
``s(t) = 2 pi f_step t`` (``t`` since the scenario start) and the path's forward, left and up unit
vectors ``e_f = (sin psi cos theta, cos psi cos theta, sin theta)``, ``e_l = (-cos psi, sin psi, 0)``,
``e_u = (0, 0, 1)`` (ENU):

    v^n  = (V + A_surge m cos s) e_f + d/dt[A_bob m sin s] e_u + d/dt[A_sway m sin(s/2)] e_l
    Cbn  = C_path Rz(yaw_w) Ry(pitch_w) Rx(roll_w),
           roll_w = A_roll m sin(s/2 + 0.5), pitch_w = A_pitch m sin(s + 1), yaw_w = A_yaw m sin(s/2 + 2)

so the phone bobs ``A_bob`` up and down once a step, surges ``A_surge`` (m/s) along the path, sways
``A_sway`` sideways once a stride (two steps) and wobbles in the hand; every amplitude is
proportional to the speed, so standing still is still and the gait fades in and out with the speed.
All terms are jets (value and derivatives exact), so the sensor outputs and the truth stay exact.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .jets import Jet, axis_rotation, stack


@dataclass
class Gait:
    """Gait amplitudes (SI: m, m/s, rad) at the reference speed ``speed`` (m/s), step frequency in Hz."""
    speed: float
    step_freq: float
    bob: float
    surge: float
    sway: float
    wobble: np.ndarray          # (3,) rad: roll, pitch, yaw amplitudes

    @property
    def omega(self) -> float:
        return 2.0 * np.pi * self.step_freq


def gait_terms(g: Gait, t_local: Jet, t_start: float, spd: Jet, hdg: Jet, pit: Jet):
    """``(R, dv)``: the hand's rotation jet (order 1, right factor of ``Cbn``) and the velocity jet
    (order 1, ENU) to add, at local times ``t_local`` (order-2 jet) of a primitive starting at
    ``t_start`` s; ``spd`` is the speed channel (order 2), ``hdg`` and ``pit`` order 1."""
    phase0 = np.remainder(g.omega * t_start, 4.0 * np.pi)       # the stride (s/2) period is 4 pi
    s = g.omega * t_local + phase0
    m = spd / g.speed
    sin_s, cos_s, sin_h = np.sin(s), np.cos(s), np.sin(0.5 * s)
    bob = (g.bob * m * sin_s).deriv()
    sway = (g.sway * m * sin_h).deriv()
    surge = (g.surge * m * cos_s).truncate(1)
    ch, sh, cp, sp = np.cos(hdg), np.sin(hdg), np.cos(pit), np.sin(pit)
    zero = 0.0 * ch
    dv = (surge[..., None] * stack([sh * cp, ch * cp, sp], axis=-1)
          + sway[..., None] * stack([-ch, sh, zero], axis=-1)
          + bob[..., None] * stack([zero, zero, zero + 1.0], axis=-1))
    m1 = m.truncate(1)
    s1 = s.truncate(1)
    roll = g.wobble[0] * m1 * np.sin(0.5 * s1 + 0.5)
    pitch = g.wobble[1] * m1 * np.sin(s1 + 1.0)
    yaw = g.wobble[2] * m1 * np.sin(0.5 * s1 + 2.0)
    rot = (axis_rotation(2, yaw) @ axis_rotation(1, pitch)) @ axis_rotation(0, roll)
    return rot, dv
