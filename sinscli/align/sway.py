"""A swaying base (a moored ship, a vehicle on its suspension) for the simulator, and scenario loading.

The simulator's segments (``sinscli.sim.segments``) vibrate about one axis at
a time (``sculling``) or sweep a cone (``coning``); they cannot roll and pitch
at once with heave, which is the case seed 001's method is for.  This module
adds that motion through the simulator's public pieces, without changing
them: a :class:`SwayPrimitive` (a :class:`~sinscli.sim.segments.Primitive`
whose kinematics are sinusoids) replaces the primitive of a ``rest`` segment
in a prepared scenario, and the truth engine
(:func:`sinscli.sim.truth.generate`) turns it into exact increments as for
any other motion.

    heading(t) = H0 + A_y sin(2 pi f_y t + p_y)
    pitch(t)   = P0 + A_p sin(2 pi f_p t + p_p)
    roll(t)    = R0 + A_r sin(2 pi f_r t + p_r)
    up(t)      =      A_z sin(2 pi f_z t + p_z)            (heave, m)
    Cbn = Rz(-heading) Rx(pitch) Ry(roll) C_FLU^RFU         (the docs/formats.md Euler chain)

Scenario YAML for ``sins align --monte-carlo``: a simulator scenario plus two
optional top-level sections that this module takes off before the simulator
sees the file: ``align:`` (alignment options, :mod:`sinscli.align.options`)
and ``sway:``, e.g. ``sway: {roll: {amplitude: 5, freq: 0.15}, pitch:
{amplitude: 5, freq: 0.1, phase: 90}, heave: {amplitude: 0.5, freq: 0.12}}``
(degrees, Hz, metres), allowed with a single ``rest`` segment.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..inputs import load_yaml
from ..sim.jets import Jet, axis_rotation, stack
from ..sim.segments import C_FLU_TO_RFU, Primitive

SWAY_AXES = ("heading", "pitch", "roll", "heave")
SWAY_KEYS = {"amplitude", "freq", "phase"}


@dataclass
class SwayPrimitive(Primitive):
    """Sinusoidal heading, pitch, roll (rad) and heave (m) about the channel values ``x0``.

    ``waves[i] = (amplitude, omega rad/s, phase rad)`` for heading, pitch, roll, heave.
    """
    waves: np.ndarray = field(default_factory=lambda: np.zeros((4, 3)))

    def max_frequency(self) -> float:
        return max(float(np.abs(self.waves[:, 1]).max()), 10.0 / self.duration)

    def _wave(self, i, t):
        a, w, p = self.waves[i]
        return a * np.sin(w * (t + self.t_start) + p)

    def kinematics(self, t_local):
        t = Jet.time(np.asarray(t_local, dtype=float), 2)
        hdg = (self.x0[0] + self._wave(0, t)).truncate(1)
        pit = (self.x0[1] + self._wave(1, t)).truncate(1)
        rol = (self.x0[2] + self._wave(2, t)).truncate(1)
        cbn = ((axis_rotation(2, -hdg) @ axis_rotation(0, pit)) @ axis_rotation(1, rol)) @ C_FLU_TO_RFU
        up = self._wave(3, t)                      # order 2: position, velocity, acceleration
        zero = 0.0 * up
        disp = stack([zero, zero, up], axis=-1)
        return cbn, disp.deriv(), disp.v


def sway_waves(spec: dict, src: str) -> np.ndarray:
    """``(4, 3)`` waves (amplitude rad or m, omega rad/s, phase rad) from a ``sway:`` mapping."""
    if not isinstance(spec, dict):
        raise SinsError(f"{src}: sway: expected a mapping of {', '.join(SWAY_AXES)}")
    waves = np.zeros((4, 3))
    for k, v in spec.items():
        if k not in SWAY_AXES:
            raise SinsError(f"{src}: sway.{k}: unknown key; expected one of {', '.join(SWAY_AXES)}")
        if not isinstance(v, dict) or set(v) - SWAY_KEYS:
            raise SinsError(f"{src}: sway.{k}: expected a mapping with amplitude, freq, phase")
        vals = {}
        for kk in SWAY_KEYS:
            x = v.get(kk, 0.0)
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x):
                raise SinsError(f"{src}: sway.{k}.{kk}: expected a number, got {x!r}")
            vals[kk] = float(x)
        if vals["freq"] < 0:
            raise SinsError(f"{src}: sway.{k}.freq: must be >= 0 Hz, got {vals['freq']:g}")
        i = SWAY_AXES.index(k)
        amp = vals["amplitude"] if k == "heave" else np.radians(vals["amplitude"])
        waves[i] = (amp, 2.0 * np.pi * vals["freq"], np.radians(vals["phase"]))
    return waves


def load_align_scenario(path) -> tuple[dict, dict | None, dict | None, str, Path]:
    """Read an alignment scenario YAML: ``(simulator part, align section, sway section, name, folder)``."""
    path = Path(path)
    data = load_yaml(path, "scenario")
    if not isinstance(data, dict):
        raise SinsError(f"{path}: expected a mapping of scenario keys at the top level")
    data = dict(data)
    align = data.pop("align", None)
    sway = data.pop("sway", None)
    return data, align, sway, str(path), path.parent


def prepare_scenario(sim_part: dict, sway: dict | None, src: str, base_dir: Path, duration=None):
    """A :class:`sinscli.sim.run.Prepared` scenario, with the sway primitive when ``sway`` is given."""
    from ..sim.run import prepare
    from ..sim.scenario import validate

    sc = validate(sim_part, src, base_dir)
    p = prepare(sc, duration=duration)
    if sway is not None:
        segs = sc.segments
        if len(segs) != 1 or segs[0]["type"] != "rest":
            raise SinsError(f"{src}: sway: needs exactly one 'rest' segment (the sway replaces it); "
                            f"got {len(segs)} segment(s)")
        base = p.prims[0]
        p.prims = [SwayPrimitive(base.t_start, base.duration, base.x0.copy(), np.zeros(4), np.zeros(4),
                                 np.zeros(4), kind="sway", waves=sway_waves(sway, src))]
    return p


class ScenarioRuns:
    """Seeded runs of one scenario with the exact truth computed once (the motion has no randomness).

    ``run(seed)`` returns the same :class:`~sinscli.sim.run.SimResult` as
    ``simulate(prepared, seed)`` would, at the cost of the sensor errors only.
    """

    def __init__(self, prepared, progress=None):
        from ..sim import truth as truth_mod
        from ..sim.imu_synth import GRAVITY_MODELS

        self.p = prepared
        sc = prepared.scenario
        self.td = truth_mod.generate(prepared.prims, sc.lat0, sc.lon0, sc.h0, sc.imu_rate, prepared.n_imu,
                                     extra_times=prepared.tau_gnss, gravity=GRAVITY_MODELS[sc.gravity],
                                     progress=progress, t0=sc.t0)

    def run(self, seed: int, perfect: bool = False):
        from ..sim.run import assemble
        sensor = {} if perfect else self.p.sensor
        return assemble(self.p.scenario, self.td, self.p.tau_gnss, sensor, seed, perfect)
