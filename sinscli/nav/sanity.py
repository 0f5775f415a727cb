"""The mounting check of every ``sins navigate`` (issue 10): the specific force at rest against what the
initial attitude predicts.

At rest (or in unaccelerated motion) the accelerometers measure ``f^b = C_n^b (0, 0, g)`` (ENU, docs/formats.md):
the initial attitude ``Cbn`` predicts it, and a gross mismatch (tens of degrees) is not a sensor error but
an axis mistake: a missing or wrong ``imu.mounting``, FRD data read as FLU (``imu.body``), or a wrong
roll/pitch in the init.  Without an initial attitude (``--align`` takes it from the log), the body's up axis
is checked instead: +z of FLU/RFU, -z of FRD.  No I/O here: the caller logs the warning.

The unit checks below refuse gyros (:func:`gyro_unit_check`) and accelerometers (:func:`accel_unit_check`)
whose data are impossible in their declared unit and plausible in another, naming the key to set.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from ..config import ACCEL_UNITS, ImuSection, mounting_angles, mounting_matrix
from ..conventions import FRD
from ..errors import SinsError
from ..types import time_tolerance
from ..units import G0, MG
from .earth import OMEGA_IE
from .imu_stats import block_means
from .rotation import rotvec_to_dcm

REST_RATE = 0.2            # rad/s: largest mean angular rate of a second taken as "at rest"
REST_FORCE = 0.1           # |f| within 10 % of g
SEARCH = 60.0              # s: the first rest-like second is looked for in this much of the log's start
MAX_ANGLE = 30.0           # deg between measured and predicted specific force: a gross mismatch
MAX_UP_ANGLE = 45.0        # deg between the specific force and the body's up axis (no initial attitude)
SNAP = 10.0                # deg: a fix by a right-angle axis permutation is proposed when it is this close


def _rotations():
    """The 24 proper rotations that permute the axes (with signs): the candidate mounting fixes."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            for i, j in enumerate(perm):
                m[i, j] = signs[i]
            if np.linalg.det(m) > 0:
                out.append(m)
    return out


def _fix_rotation(f_b, pred) -> np.ndarray:
    """The rotation (new body <- current body) that brings the measured gravity ``f_b`` onto ``pred``: the
    smallest axis permutation when it does so within :data:`SNAP` deg (mounts are square), else the
    smallest rotation between the two directions (about x for a flip)."""
    cands = sorted(_rotations(), key=lambda r: (round(_angle(r @ f_b, pred), 6),
                                                 round(float(np.trace(r)) * -1.0, 6)))
    if _angle(cands[0] @ f_b, pred) <= SNAP:
        return cands[0]
    a, b = f_b / np.linalg.norm(f_b), pred / np.linalg.norm(pred)
    axis = np.cross(a, b)
    if np.linalg.norm(axis) < 1e-9:
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    return rotvec_to_dcm(np.ascontiguousarray(axis / np.linalg.norm(axis) * math.radians(_angle(a, b))))


def rest_window(time, dtheta_b, dvel_b, t0, g: float):
    """The first second of the log's first :data:`SEARCH` s that looks at rest (mean rate under
    :data:`REST_RATE`, mean |f| within :data:`REST_FORCE` of g): ``(k, f_b, C_b0^bk)``, the block index, its
    mean specific force and the body rotation from the start to it (the gyro increments summed per block;
    earth and transport rate ignored: a gross check), or None."""
    time = np.asarray(time, dtype=float)
    sel = time <= t0 + SEARCH
    if sel.sum() < 2 or time[sel][-1] - t0 < 0.5:
        return None
    block = min(1.0, float(time[sel][-1] - t0))
    w, f = block_means(time[sel], dtheta_b[sel], dvel_b[sel], t0, block)
    rot = np.eye(3)
    for k in range(w.shape[0]):
        if np.linalg.norm(w[k]) < REST_RATE and abs(np.linalg.norm(f[k]) - g) < REST_FORCE * g:
            return k, f[k], rot
        rot = rot @ rotvec_to_dcm(np.ascontiguousarray(w[k] * block))
    return None


def _angle(a, b) -> float:
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def _axis_name(v) -> str:
    k = int(np.argmax(np.abs(v)))
    return f"{'+' if v[k] > 0 else '-'}{'xyz'[k]}"


def check_mounting(time, dtheta_b, dvel_b, t0: float, g: float, conv: int, cbn0=None,
                   mounting=None, source: str = "IMU log") -> str | None:
    """A warning text when the specific force of the first rest-like second disagrees grossly with the
    initial attitude ``cbn0`` (body -> ENU; None: check against the body's up axis, where gravity along +x,
    a vehicle standing nose up like a rocket on its pad, is accepted), else None.

    The text names the window used, where gravity lies in body axes, the likely mistake and the config
    key that fixes it: ``imu.body`` for FRD/FLU read the wrong way round, else ``imu.mounting`` with the
    ``{roll, pitch, yaw}`` (:func:`_fix_rotation` composed with the current ``mounting`` matrix).  None also when no second of the first minute is at rest.
    """
    found = rest_window(time, np.asarray(dtheta_b), np.asarray(dvel_b), t0, g)
    if found is None:
        return None
    k, f_b, c_b0_bk = found
    up = -1.0 if conv == FRD else 1.0
    if cbn0 is None:
        pred = np.array([0.0, 0.0, up * g])
        limit, against = MAX_UP_ANGLE, f"the body's up axis ({'-z, FRD' if conv == FRD else '+z, FLU/RFU'})"
    else:
        pred = (np.asarray(cbn0) @ c_b0_bk).T @ np.array([0.0, 0.0, g])
        limit, against = MAX_ANGLE, "what the initial attitude predicts"
    err = _angle(f_b, pred)
    if err <= limit or (cbn0 is None and _angle(f_b, np.array([1.0, 0.0, 0.0])) <= MAX_UP_ANGLE):
        return None          # (without an attitude, gravity along +x is a vehicle standing nose up: a rocket)
    fix = _fix_rotation(f_b, pred)
    when = "over the first second" if k == 0 else f"over the first second at rest ({k} to {k + 1} s after the start)"
    f_txt = ", ".join(f"{x:.2f}" for x in f_b)
    p_txt = ", ".join(f"{x:.2f}" for x in pred)
    head = (f"{source}: mounting check: the specific force {when} is ({f_txt}) m/s^2 in body axes, "
            f"along {_axis_name(f_b)}, {err:.0f} deg from {against} ({p_txt})")
    if abs(f_b[2]) > 0.8 * np.linalg.norm(f_b) and np.sign(f_b[2]) != np.sign(pred[2]) and \
            abs(pred[2]) > 0.8 * g:
        other = "flu" if conv == FRD else "frd"
        return (f"{head}: gravity is along the opposite z axis; the data look {other.upper()}: set imu.body: "
                f"{other} (or imu.mounting: {{roll: 180}})")
    m0 = np.eye(3) if mounting is None else np.asarray(mounting, dtype=float)
    ang = mounting_angles(fix @ m0)
    turn = round(math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(fix) - 1) / 2)))))
    fix_txt = "{" + ", ".join(f"{n}: {round(v, 1) + 0.0:g}" for n, v in ang.items()) + "}"
    init = "" if cbn0 is None else " (or the init's roll and pitch are wrong)"
    return (f"{head}: gravity is on the wrong axis, a {turn} deg mounting error{init}; set imu.mounting: "
            f"{fix_txt} (gravity fixes the roll and pitch of the mounting, not its yaw: check the "
            f"forward axis)")


def mounting_warning(imu, t0: float, g: float, conv: int, cbn0, imu_cfg: ImuSection) -> str | None:
    """:func:`check_mounting` on an :class:`~sinscli.types.ImuLog` (block) with the config's ``imu`` section,
    over the samples after ``t0`` (the epoch of ``cbn0``: the init's time, when it is inside the log)."""
    k = int(np.searchsorted(imu.time, t0 + time_tolerance(t0), side="right"))
    return check_mounting(imu.time[k:], imu.dtheta_b[k:], imu.dvel_b[k:], t0, g, conv, cbn0,
                          mounting_matrix(imu_cfg.mounting), str(imu.source or "IMU log"))


# --- gyro units (issue 22) ---------------------------------------------------------------------------
#
# At rest the gyros measure the earth rate W (7.29e-5 rad/s) plus their bias.  Rates in deg/s read as rad/s
# are 57.3 times that.  The window is "at rest" by the accelerometers: over it the specific force keeps its
# direction to within STILL of the tilt that the declared horizontal rate would have turned it by (so the
# rate is not a real rotation: a slow turn, a swaying base tilt it; a turn about the vertical is not used).
# The data are then physically impossible as declared when either
#   * the mean rate, read as deg/s, has the earth rate's geometry (its component along the up axis W sin L,
#     the horizontal one W cos L, both within UNIT_MATCH W) while as declared it is at least
#     UNIT_MIN_EXCESS earth rates (a good gyro's deg/s data), or
#   * its horizontal part needs a bias beyond any shipped sensor's (BIAS_SIGMAS times the turn-on and
#     in-run bias sigmas per axis of the 'mems' preset, the worst the project ships, or of the sensor
#     description when that is looser: a wrong description never refuses real data), while read as deg/s
#     the whole rate is within that bound.
# A warning with a plausible-but-wrong trajectory is not enough: the run is refused, naming the unit to
# set; --force accepts the data as declared (a gyro with a bias beyond every preset).

UNIT_MATCH = 0.25          # of W: largest departure of (up, horizontal) of the rate/57.3 from the earth rate's
UNIT_MIN_EXCESS = 10.0     # the declared mean rate at rest is at least this many earth rates
STILL = 0.1                # the specific force turns by at most this fraction of the declared tilt rotation
MIN_REST = 5.0             # s: the shortest rest window used
BIAS_SIGMAS = 5.0          # the bias bound, in sigmas per axis (the norm bound is sqrt(3) times this)
REST_AVERAGE = 60.0        # s: the rest average runs over at most this many consecutive rest seconds


def rest_mean_rate(time, dtheta_b, dvel_b, t0: float, g: float):
    """``(w_b, f_b, seconds, start, turned)``: the mean angular rate and specific force over the first run
    of consecutive rest-like seconds (:func:`rest_window`'s test) of the first :data:`SEARCH` s, at most
    :data:`REST_AVERAGE` s long, and the angle (rad) by which the specific force turned from its first to
    its last second; None without one."""
    time = np.asarray(time, dtype=float)
    sel = time <= t0 + SEARCH + REST_AVERAGE
    if sel.sum() < 2 or time[sel][-1] - t0 < 1.0:
        return None
    w, f = block_means(time[sel], np.asarray(dtheta_b)[sel], np.asarray(dvel_b)[sel], t0, 1.0)
    rest = (np.linalg.norm(w, axis=1) < REST_RATE) & (np.abs(np.linalg.norm(f, axis=1) - g) < REST_FORCE * g)
    idx = np.flatnonzero(rest)
    if idx.size == 0 or idx[0] > SEARCH:
        return None
    k0 = k1 = int(idx[0])
    while k1 + 1 < rest.size and rest[k1 + 1] and k1 + 1 - k0 < REST_AVERAGE:
        k1 += 1
    turned = _angle(f[k0], f[k1]) * math.pi / 180.0          # the specific force's turn over the window, rad
    return w[k0:k1 + 1].mean(axis=0), f[k0:k1 + 1].mean(axis=0), float(k1 + 1 - k0), t0 + k0, turned


def gyro_bias_bound(sensor: dict | None) -> float:
    """rad/s: the largest norm of a gyro bias (:data:`BIAS_SIGMAS` sigmas per axis) of the 'mems' preset, or
    of the sensor description when that allows more."""
    from ..sensors import load_sensor   # PyYAML: only when a gyro-unit check needs the presets

    def bound(s):
        gyro = (s or {}).get("gyro") or {}
        sig = np.hypot(np.asarray(gyro.get("bias_sigma", 0.0), dtype=float),
                       np.asarray(gyro.get("bias_instability", 0.0), dtype=float)) * np.ones(3)
        return float(BIAS_SIGMAS * np.linalg.norm(sig))
    return max(bound(load_sensor("mems", None, "preset", None)), bound(sensor))


def gyro_unit_refusal(time, dtheta_b, dvel_b, t0: float, g: float, lat: float | None, declared: str,
                      source: str, sensor: dict | None = None, fix: str | None = None) -> str | None:
    """The refusal text when a log's gyros, read in ``declared`` units (``rad/s``, or ``rad`` for
    increments), are physically impossible at rest but plausible in deg/s (see above); else None.
    ``lat`` (rad; None: unknown) enables the earth-rate geometry; ``fix`` is what to do instead of the
    config key (a ROS log, whose messages are rad/s by definition)."""
    if declared not in ("rad/s", "rad"):
        return None
    found = rest_mean_rate(time, dtheta_b, dvel_b, t0, g)
    if found is None:
        return None
    w_b, f_b, seconds, start, turned = found
    if seconds < MIN_REST:
        return None
    up = f_b / np.linalg.norm(f_b)
    w_h = float(np.linalg.norm(w_b - float(w_b @ up) * up))   # the declared rate that would tilt the body
    if turned > STILL * w_h * seconds:                     # the accelerometers see (part of) that rotation
        return None
    as_deg = w_b * math.pi / 180.0                       # the same numbers read as deg/s
    norm, norm_deg = float(np.linalg.norm(w_b)), float(np.linalg.norm(as_deg))
    bound = gyro_bias_bound(sensor)
    why = None
    if lat is not None and norm >= UNIT_MIN_EXCESS * OMEGA_IE:
        v_up = float(as_deg @ up)
        v_h = float(np.linalg.norm(as_deg - v_up * up))
        if math.hypot(v_up - OMEGA_IE * math.sin(lat), v_h - OMEGA_IE * math.cos(lat)) <= UNIT_MATCH * OMEGA_IE:
            why = (f"{norm / OMEGA_IE:.0f} times the earth rate; read as deg/s they are the earth rate ({v_up:.3g} "
                   f"rad/s up, {v_h:.3g} horizontal; expected {OMEGA_IE * math.sin(lat):.3g}, "
                   f"{OMEGA_IE * math.cos(lat):.3g})")
    if why is None and w_h > bound + OMEGA_IE and norm_deg <= bound + OMEGA_IE:
        why = (f"{w_h:.3g} rad/s of it horizontal while the specific force stays put ({turned:.2g} rad in "
               f"{seconds:.0f} s): a bias beyond every shipped sensor's bound of {bound:.3g} rad/s; read as deg/s "
               f"they are {norm_deg:.3g} rad/s, within it")
    if why is None:
        return None
    key, unit = ("imu.units.gyro", "deg/s") if declared == "rad/s" else ("imu.units.dtheta", "deg")
    todo = fix or f"set {key}: {unit} in the config"
    return (f"{source}: gyro units: at rest ({seconds:.0f} s from t = {start:.6g} s) the gyros read {norm:.3g} "
            f"{declared if declared == 'rad/s' else 'rad/s'} as declared, {why}: the data are in {unit}; {todo} "
            f"(--force takes them as {declared})")


def gyro_unit_check(imu, t0: float, g: float, lat: float | None, imu_cfg: ImuSection | None,
                    sensor: dict | None = None,
                    force: bool = False, ros: bool = False) -> None:
    """Refuse (:func:`gyro_unit_refusal`) an IMU block read with the config's ``imu`` section, unless ``force``.
    ``ros``: the log is a ROS/MCAP log (sensor_msgs/Imu is rad/s; no unit key applies)."""
    if force or len(imu) < 2:
        return
    units = imu_cfg.units if imu_cfg is not None else ImuSection().units
    declared = "rad/s" if ros else (units.get("gyro", "rad/s") if imu.kind == "rates" else units.get("dtheta", "rad"))
    k = int(np.searchsorted(imu.time, t0, side="right"))
    fix = "the publisher writes deg/s where sensor_msgs/Imu holds rad/s: convert the log" if ros else None
    text = gyro_unit_refusal(imu.time[k:], imu.dtheta_b[k:], imu.dvel_b[k:], t0, g, lat, declared,
                             str(imu.source or "IMU log"), sensor, fix)
    if text:
        raise SinsError(text)


# --- accelerometer units --------------------------------------------------------------------------------
#
# Whatever a vehicle on (or near) the earth does, its specific force averages to about gravity: over one second
# a car, a walker, a robot or an aircraft in a coordinated turn or a pull-up measures |f| between ~0.5 g and
# ~2 g, and the median of the one-second magnitudes over a log is within a factor 3 of g (vibration averages
# out over a second; a log that starts moving changes a few seconds).  The unit mistakes are a factor 9.81
# (g read as m/s^2, or m/s^2 read as g) or 1000 (mg): the median then lies outside that factor 3 as declared,
# and near g in the other unit.  Only free fall (a coasting rocket, a drop test, a parabolic flight) or a boost
# longer than half the log give such a median with the right unit: --force covers them.

ACCEL_PLAUSIBLE = 3.0      # the median 1-s |f| as declared is refused outside g/3 .. 3 g
ACCEL_MATCH = 0.25         # and accepted in another unit within this fraction of g
ACCEL_MIN_BLOCKS = 5       # one-second blocks needed (a shorter log is not judged)


def accel_unit_refusal(time, dtheta_b, dvel_b, t0: float, declared: str, source: str, kind: str = "rates",
                       fix: str | None = None, g: float = G0) -> str | None:
    """The refusal text when the specific force, read in ``declared`` units (``m/s^2``, ``g``, ``mg`` for
    rates, ``m/s`` for increments), is implausible for any vehicle and plausible in another unit (see
    above); else None.  ``dvel_b`` is in SI as the reader converted it; ``fix`` replaces the config advice
    (a ROS log, whose messages are m/s^2 by definition)."""
    time = np.asarray(time, dtype=float)
    if time.shape[0] < 2 or time[-1] - t0 < ACCEL_MIN_BLOCKS:
        return None
    _, f = block_means(time, np.asarray(dtheta_b), np.asarray(dvel_b), t0, 1.0)
    if f.shape[0] < ACCEL_MIN_BLOCKS:
        return None
    med = float(np.median(np.linalg.norm(f, axis=1)))
    if g / ACCEL_PLAUSIBLE <= med <= ACCEL_PLAUSIBLE * g:
        return None
    if kind == "rates":
        units = dict(ACCEL_UNITS)
        key = "imu.units.accel"
    else:                           # increments: m/s is the only unit the config offers for dvel
        units = {"m/s": 1.0, "g*s": G0, "mg*s": MG}
        key = "imu.units.dvel"
    scale = units.get(declared, 1.0)
    for unit, factor in units.items():
        if unit == declared:
            continue
        other = med / scale * factor
        if abs(other - g) <= ACCEL_MATCH * g:
            break
    else:
        return None
    shown = "m/s^2" if kind == "rates" else "m/s^2 (as dvel / dt)"
    if fix is None:
        fix = (f"set {key}: {unit} in the config" if unit in ACCEL_UNITS and kind == "rates" else
               f"convert the dvel columns to m/s ({key} takes m/s only)")
    return (f"{source}: accelerometer units: the median specific force over {f.shape[0]} one-second blocks from "
            f"t = {t0:.6g} s is {med:.3g} {shown} read as {declared}, far from gravity ({g:.4g} m/s^2, what any "
            f"vehicle averages to within a factor {ACCEL_PLAUSIBLE:g}); read as {unit} it is {other:.3g} m/s^2: the "
            f"data are in {unit}; {fix} (--force takes them as {declared})")


def accel_unit_check(imu, t0: float, imu_cfg: ImuSection | None, force: bool = False, ros: bool = False) -> None:
    """Refuse (:func:`accel_unit_refusal`) an IMU block read with the config's ``imu`` section, unless ``force``.
    ``ros``: the log is a ROS/MCAP log (sensor_msgs/Imu is m/s^2; no unit key applies)."""
    if force or len(imu) < 2:
        return
    units = imu_cfg.units if imu_cfg is not None else ImuSection().units
    kind = "rates" if (ros or imu.kind == "rates") else "increments"
    declared = "m/s^2" if ros else (units.get("accel", "m/s^2") if kind == "rates" else units.get("dvel", "m/s"))
    k = int(np.searchsorted(imu.time, t0, side="right"))
    fix = "the publisher writes g where sensor_msgs/Imu holds m/s^2: convert the log" if ros else None
    text = accel_unit_refusal(imu.time[k:], imu.dtheta_b[k:], imu.dvel_b[k:], t0, declared,
                              str(imu.source or "IMU log"), kind, fix)
    if text:
        raise SinsError(text)
