"""Motion segments: smooth analytic profiles of heading, pitch, roll and speed.

The vehicle's motion is four *channels* ``x = (heading, pitch, roll, speed)``
(rad, rad, rad, m/s), each an analytic function of time inside a
*primitive*, plus an optional body *perturbation* (coning or sculling).

Inside a primitive of duration ``T`` starting at ``ts`` (``u = (t - ts)/T``)
every channel is the polynomial

    x(t) = x0 + T [r0 u + (r1 - r0) S1(u)] + D S(u)

with the septic smooth step ``S(u) = 35u^4 - 84u^5 + 70u^6 - 20u^7`` and its
integral ``S1``.  The rate ramps smoothly from ``r0`` to ``r1`` and a step
``D`` is added; since ``S', S'', S'''`` vanish at both ends, channel values are
C^3 and rates C^2 across primitive joints (so are the angular rate and the
acceleration), and analytic inside a primitive.

Attitude and velocity (FLU body axes, ENU navigation frame):

    Cbn = Rz(-heading) Rx(pitch) Ry(roll) C_FLU^RFU P(t)     (docs/formats.md Euler chain)
    v^n = speed (sin hdg cos pitch, cos hdg cos pitch, sin pitch) + d'(t) u^n

so the velocity is along the path's forward axis (no angle of attack; a sideslip in turns only with
``vehicle.sideslip``, :mod:`.sideslip`); ``P(t)`` is the perturbation rotation and ``d(t) u^n`` a linear
vibration displacement along a fixed ENU direction.  Pitch and heading are
unwrapped real numbers: a loop is pitch going through 360 deg.

A user segment (``turn``, ``climb``, ``boost``...) expands into one to three
primitives; :func:`expand` checks the physical requests and names the segment
in its ``SinsError``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SinsError
from ..nav.rotation import FLU, RFU, conv_to_flu, euler_to_dcm
from ..units import G0
from .jets import Jet, axis_rotation, polynomial, stack
from .gait import gait_terms
from .sideslip import slip_velocity

HEADING, PITCH, ROLL, SPEED = 0, 1, 2, 3
G_BANK = G0               # m/s^2, only shapes the coordinated-bank profile

# Septic smooth step S and its integral S1 = int_0^u S, as polynomials in s = 2u - 1 in [-1, 1]
# (coefficients in increasing powers of s).  The symmetric form keeps the terms small (no
# cancellation: S = 1/2 + (35 s - 35 s^3 + 21 s^5 - 5 s^7)/32, S1 = (1/2) int_{-1}^s S ds).
S_COEF = np.array([0.5, 35.0, 0.0, -35.0, 0.0, 21.0, 0.0, -5.0]) / np.array([1, 32, 1, 32, 1, 32, 1, 32])
S1_COEF = 0.5 * np.array([105.0 / 768.0, 0.5, 35.0 / 64.0, 0.0, -35.0 / 128.0, 0.0, 7.0 / 64.0, 0.0,
                          -5.0 / 256.0])
DS_COEF = 2.0 * np.polynomial.polynomial.polyder(S_COEF)          # dS/du = 140 u^3 (1-u)^3, in s
S_U = (np.array([0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0]),   # the same in powers of u (tests)
       np.array([0.0, 0.0, 0.0, 0.0, 0.0, 7.0, -14.0, 10.0, -2.5]))

# C_FLU^RFU: FLU vectors into RFU axes.
C_FLU_TO_RFU = conv_to_flu(RFU).T.copy()
AXES = {"x": 0, "y": 1, "z": 2}


@dataclass
class Perturbation:
    """Coning or sculling on top of the channel attitude, in FLU body axes.

    ``envelope`` shapes the amplitude over the primitive: ``flat`` (1), ``up``
    (S(u)) or ``down`` (1 - S(u)); the phase ``omega (t - t_ref)`` runs on
    across the primitives of one user segment.
    """
    kind: str                   # "coning" | "sculling"
    omega: float                # rad/s
    t_ref: float                # s, phase origin
    envelope: str               # "flat" | "up" | "down"
    amplitude: float            # rad: coning half angle, or sculling angle amplitude
    offset: float = 0.0         # s, this primitive's start minus t_ref
    axis: int = 0               # sculling rotation axis (FLU)
    accel: float = 0.0          # m/s^2 sculling linear acceleration amplitude
    direction_n: np.ndarray = field(default_factory=lambda: np.zeros(3))   # ENU unit vector


@dataclass
class Primitive:
    """One analytic piece of the motion (see the module docstring)."""
    t_start: float              # s since the scenario start
    duration: float             # s
    x0: np.ndarray              # (4,) channel values at the start
    r0: np.ndarray              # (4,) channel rates at the start
    r1: np.ndarray              # (4,) channel rates at the end
    delta: np.ndarray           # (4,) smooth steps
    bank: bool = False          # add a coordinated bank for the heading step
    pert: Perturbation | None = None
    index: int = 0              # user segment index
    kind: str = ""              # user segment type
    gait: object = None         # a :class:`~sinscli.sim.gait.Gait` (walker step dynamics) or None
    sideslip: float = 0.0       # rad per m/s^2: slip angle per lateral acceleration (:mod:`.sideslip`)

    @property
    def t_end(self) -> float:
        return self.t_start + self.duration

    def end_state(self):
        """Channel values and rates at the end (S(1) = 1, S1(1) = 1/2)."""
        x1 = self.x0 + self.duration * (self.r0 + 0.5 * (self.r1 - self.r0)) + self.delta
        x1[:3] = np.remainder(x1[:3] + np.pi, 2.0 * np.pi) - np.pi     # same attitude, smaller numbers
        return x1, self.r1.copy()

    def channel_coeffs(self) -> np.ndarray:
        """(4, 9) polynomial coefficients of the four channels in ``s = 2u - 1``."""
        T = self.duration
        c = np.zeros((4, 9))
        c[:, 0] = self.x0 + 0.5 * self.r0 * T            # r0 T u = r0 T (s + 1)/2
        c[:, 1] = 0.5 * self.r0 * T
        c += np.outer((self.r1 - self.r0) * T, S1_COEF)
        c[:, :8] += np.outer(self.delta, S_COEF)
        return c

    def max_frequency(self) -> float:
        """A bound on the angular frequencies (rad/s) of the motion, for the quadrature step."""
        rates = np.abs(np.concatenate([self.r0[:3], self.r1[:3]]))
        w = max(float(rates.max()), 2.2 * float(np.abs(self.delta[:3]).max()) / self.duration,
                10.0 / self.duration)
        if self.pert is not None:
            w = max(w, abs(self.pert.omega))
        if self.gait is not None:
            w = max(w, self.gait.omega)
        return w

    def kinematics(self, t_local: np.ndarray):
        """``(Cbn, vel_n, disp_n)`` at times ``t_local`` (s since this primitive's start), FLU body, ENU.

        ``Cbn`` (n, 3, 3) and ``vel_n`` (n, 3) are jets of order 1 (with the
        time derivatives ``dCbn/dt`` and ``dv^n/dt``); ``disp_n`` (n, 3) is the
        ENU displacement of the linear vibration (zeros without one).  Local
        times keep the rounding of fast phases at the scale of the primitive.
        """
        T = self.duration
        u = Jet.time(np.asarray(t_local, dtype=float), 2) / T
        sv = 2.0 * u - 1.0
        coeffs = self.channel_coeffs()
        hdg, pit, rol, spd = (polynomial(coeffs[k], sv) for k in range(4))
        slip = slip_velocity(self.sideslip, spd, hdg, pit) if self.sideslip != 0.0 else None
        if self.bank and self.delta[HEADING] != 0.0:
            turn_rate = polynomial(DS_COEF * (self.delta[HEADING] / T), sv)   # rad/s of the step
            rol = rol + np.arctan(spd * turn_rate / G_BANK)
        hdg, pit, rol = hdg.truncate(1), pit.truncate(1), rol.truncate(1)
        c_path = axis_rotation(2, -hdg) @ axis_rotation(0, pit)
        cbn = (c_path @ axis_rotation(1, rol)) @ C_FLU_TO_RFU
        ch, sh, cp, sp = np.cos(hdg), np.sin(hdg), np.cos(pit), np.sin(pit)
        vel = spd.truncate(1)[..., None] * stack([sh * cp, ch * cp, sp], axis=-1)
        if slip is not None:
            vel = vel + slip
        if self.gait is not None:
            rot, dv = gait_terms(self.gait, T * u, self.t_start, spd, hdg, pit)
            cbn = cbn @ rot
            vel = vel + dv
        disp = np.zeros(vel.shape)
        if self.pert is not None:
            rot, lin = _perturbation(self.pert, u, T)
            cbn = cbn @ rot
            if lin is not None:
                vel = vel + lin.deriv()
                disp = lin.v
        return cbn, vel, disp


def _envelope(env: str, u: Jet) -> Jet:
    if env == "flat":
        return Jet.const(np.ones(u.shape), u.order)
    s = polynomial(S_COEF, 2.0 * u - 1.0)
    return s if env == "up" else 1.0 - s


def _perturbation(p: Perturbation, u: Jet, T: float):
    """Rotation jet (order 1) and linear-vibration displacement jet (order 2, or None)."""
    t = u * T                                   # time since primitive start, jet
    m = _envelope(p.envelope, u)
    return _pert_rotation(p, m, t), _pert_displacement(p, m, t)


def _phase(p: Perturbation, t: Jet) -> Jet:
    return p.omega * (t + p.offset)


def _pert_rotation(p, m, t):
    ph = _phase(p, t)
    if p.kind == "coning":
        # Rotation by beta about the body axis n = (0, cos ph, sin ph) (Rodrigues, which avoids the
        # cancelling fast terms of Rx(ph) Ry(beta) Rx(-ph)):  R = cos b I + sin b [n x] + (1 - cos b) n n^T.
        beta = (p.amplitude * m).truncate(1)
        ph1 = ph.truncate(1)
        zero = 0.0 * ph1
        cph, sph = np.cos(ph1), np.sin(ph1)
        n = stack([zero, cph, sph], axis=-1)
        nx = stack([stack([zero, -sph, cph], axis=-1), stack([sph, zero, zero], axis=-1),
                    stack([-cph, zero, zero], axis=-1)], axis=-2)
        cb, sb = np.cos(beta), np.sin(beta)
        return (cb[..., None, None] * np.eye(3) + sb[..., None, None] * nx
                + (1.0 - cb)[..., None, None] * (n[..., :, None] * n[..., None, :]))
    ang = (p.amplitude * m * np.sin(ph)).truncate(1)
    return axis_rotation(p.axis, ang)


def _pert_displacement(p, m, t):
    if p.kind != "sculling" or p.accel == 0.0:
        return None
    s = -(p.accel / (p.omega * p.omega)) * m * np.sin(_phase(p, t))   # d'' ~ accel m sin(ph)
    return s[..., None] * np.asarray(p.direction_n)


# ---------------------------------------------------------------------------
# Expansion of user segments into primitives
# ---------------------------------------------------------------------------

def _num(seg, key, default=None):
    v = seg.get(key, default)
    return None if v is None else float(v)


def expand(segments: list[dict], x_start: np.ndarray, where: str) -> list[Primitive]:
    """Turn validated user segments into primitives, carrying the channel state across joints.

    ``x_start`` = (heading, pitch, roll, speed) at the start (rad, m/s).
    ``where`` prefixes error messages (the scenario file name).
    """
    x = np.asarray(x_start, dtype=float).copy()
    r = np.zeros(4)
    t = 0.0
    prims: list[Primitive] = []
    n = len(segments)
    for i, seg in enumerate(segments):
        key = f"{where}: key segments[{i}]"           # the one message style (sinscli.schema)
        kind = seg["type"]
        dur = float(seg["duration"])
        new = _expand_one(kind, seg, i, n, t, dur, x, r, key)
        for p in new:
            _check_speed(p, key)
            x, r = p.end_state()
        prims.extend(new)
        t = new[-1].t_end
    return prims


def _prim(t, dur, x, r, i, kind, r1=None, delta=None, bank=False, pert=None):
    return Primitive(t, dur, x.copy(), r.copy(), r.copy() if r1 is None else r1,
                     np.zeros(4) if delta is None else delta, bank, pert, i, kind)


def _check_speed(p: Primitive, key: str):
    s = np.linspace(-1.0, 1.0, 201)
    v = np.polynomial.polynomial.polyval(s, p.channel_coeffs()[SPEED])
    if v.min() < -1e-9:
        raise SinsError(f"{key}: the speed would become negative ({v.min():.6g} m/s); "
                        "decelerate to 0 at most")


def _expand_one(kind, seg, i, n, t, dur, x, r, key):
    deg = np.pi / 180.0
    if kind == "rest":
        if abs(x[SPEED]) > 1e-9 or np.any(np.abs(r) > 1e-12):
            raise SinsError(f"{key}: 'rest' needs the vehicle at rest at its start (speed {x[SPEED]:.6g} m/s, "
                            f"rates {np.round(r, 9).tolist()}); decelerate first")
        return [_prim(t, dur, x, np.zeros(4), i, kind)]
    if kind == "cruise":
        return [_prim(t, dur, x, r, i, kind)]
    if kind in ("accelerate", "decelerate"):
        r1, d = r.copy(), np.zeros(4)
        if "speed" in seg:
            d[SPEED] = float(seg["speed"]) - x[SPEED]
        else:
            r1[SPEED] = float(seg["accel"])
        return [_prim(t, dur, x, r, i, kind, r1, d)]
    if kind in ("turn", "pitch", "pull_up", "pitch_over", "roll", "loop"):
        ch = {"turn": HEADING, "roll": ROLL}.get(kind, PITCH)
        r1, d = r.copy(), np.zeros(4)
        if kind == "loop":
            d[ch] = _num(seg, "angle", 360.0) * deg
        elif "angle" in seg:
            d[ch] = float(seg["angle"]) * deg
        else:
            r1[ch] = float(seg["rate"]) * deg
        bank = kind == "turn" and "angle" in seg and _bank(seg, key)
        return [_prim(t, dur, x, r, i, kind, r1, d, bank)]
    if kind == "maneuver":
        r1, d = r.copy(), np.zeros(4)
        for name, ch in (("heading", HEADING), ("pitch", PITCH), ("roll", ROLL)):
            if name in seg:
                d[ch] = float(seg[name]) * deg
        if "speed" in seg:
            d[SPEED] = float(seg["speed"]) - x[SPEED]
        for name, ch, scale in (("heading_rate", HEADING, deg), ("pitch_rate", PITCH, deg),
                                ("roll_rate", ROLL, deg), ("accel", SPEED, 1.0)):
            if name in seg:
                r1[ch] = float(seg[name]) * scale
        return [_prim(t, dur, x, r, i, kind, r1, d, _bank(seg, key) if "bank" in seg else False)]
    if kind in ("climb", "descend"):
        ang = float(seg["pitch"]) * deg * (1.0 if kind == "climb" else -1.0)
        tr = _num(seg, "transition", min(5.0, dur / 4.0))
        if tr <= 0.0 or 2.0 * tr > dur:
            raise SinsError(f"{key}.transition: must be > 0 and at most half the duration ({dur:g} s); got {tr:g}")
        return _chain(t, x, r, i, kind, [(tr, None, _d(PITCH, ang)), (dur - 2 * tr, None, None),
                                          (tr, None, _d(PITCH, -ang))])
    if kind == "boost":
        acc = float(seg["accel"])
        spin = _num(seg, "spin", 0.0) * deg
        ramp = _num(seg, "ramp", min(1.0, dur / 4.0))
        if ramp <= 0.0 or 2.0 * ramp > dur:
            raise SinsError(f"{key}.ramp: must be > 0 and at most half the duration ({dur:g} s); got {ramp:g}")
        up = r.copy()
        up[SPEED] += acc
        up[ROLL] += spin
        pitch = _num(seg, "pitch", 0.0) * deg
        return _chain(t, x, r, i, kind, [(ramp, up, None), (dur - 2 * ramp, None, _d(PITCH, pitch)),
                                          (ramp, r.copy(), None)])
    if kind in ("coning", "sculling"):
        return _vibration(kind, seg, i, n, t, dur, x, r, key)
    raise SinsError(f"{key}.type: unknown segment type {kind!r}")   # scenario.py checks first


def _d(ch, value):
    d = np.zeros(4)
    d[ch] = value
    return d


def _bank(seg, key) -> bool:
    b = seg.get("bank", "coordinated")
    if b in ("coordinated", True):
        return True
    if b in ("none", False, 0):
        return False
    raise SinsError(f"{key}.bank: expected 'coordinated' or 'none'; got {b!r}")


def _chain(t, x, r, i, kind, parts):
    """Consecutive primitives ``(duration, r1 or None, delta or None)`` carrying the state."""
    out = []
    for dur, r1, d in parts:
        if dur <= 0.0:
            continue
        p = _prim(t, dur, x, r, i, kind, r1, d)
        out.append(p)
        x, r = p.end_state()
        t = p.t_end
    return out


def _vibration(kind, seg, i, n, t, dur, x, r, key):
    deg = np.pi / 180.0
    omega = 2.0 * np.pi * float(seg["freq"])
    ramp = _num(seg, "ramp", min(2.0, dur / 4.0))
    if ramp < 0.0 or 2.0 * ramp > dur:
        raise SinsError(f"{key}.ramp: must be >= 0 and at most half the duration ({dur:g} s); got {ramp:g}")
    if ramp == 0.0 and 0 < i < n - 1:
        raise SinsError(f"{key}.ramp: 0 is allowed only for the first or the last segment "
                        "(the attitude or the rate would jump at the joint)")
    ramp_in = ramp if (ramp > 0.0 or i > 0) else 0.0
    ramp_out = ramp if (ramp > 0.0 or i < n - 1) else 0.0
    if kind == "coning":
        base = dict(kind=kind, omega=omega, t_ref=t, amplitude=float(seg["half_angle"]) * deg)
    else:
        axis = AXES[seg.get("axis", "x")]
        acc_axis = AXES[seg.get("accel_axis", "y")]
        cbn0 = euler_to_dcm(x[ROLL], x[PITCH], x[HEADING], FLU)
        base = dict(kind=kind, omega=omega, t_ref=t, amplitude=float(seg.get("angle", 0.0)) * deg,
                    axis=axis, accel=float(seg.get("accel", 0.0)), direction_n=cbn0[:, acc_axis].copy())

    def pert_for(j, ts):
        return Perturbation(envelope=("up", "flat", "down")[j], offset=ts - base["t_ref"], **base)

    parts = [(ramp_in, None, None), (dur - ramp_in - ramp_out, None, None), (ramp_out, None, None)]
    out = []
    for j, (d, _, _) in enumerate(parts):
        if d <= 0.0:
            continue
        p = _prim(t, d, x, r, i, kind, pert=pert_for(j, t))
        out.append(p)
        x, r = p.end_state()
        t = p.t_end
    return out
