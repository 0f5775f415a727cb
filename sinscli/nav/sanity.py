"""The mounting check of every ``sins navigate`` (issue 10): the specific force at rest against what the
initial attitude predicts.

At rest (or in unaccelerated motion) the accelerometers measure ``f^b = C_n^b (0, 0, g)`` (ENU, FORMATS.md):
the initial attitude ``Cbn`` predicts it, and a gross mismatch (tens of degrees) is not a sensor error but
an axis mistake: a missing or wrong ``imu.mounting``, FRD data read as FLU (``imu.body``), or a wrong
roll/pitch in the init.  Without an initial attitude (``--align`` takes it from the log), the body's up axis
is checked instead: +z of FLU/RFU, -z of FRD.  No I/O here: the caller logs the warning.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from ..config import mounting_angles, mounting_matrix
from ..conventions import FRD
from ..types import time_tolerance
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


def mounting_warning(imu, t0: float, g: float, conv: int, cbn0, imu_cfg: dict) -> str | None:
    """:func:`check_mounting` on an :class:`~sinscli.types.ImuLog` (block) with the config's ``imu`` section,
    over the samples after ``t0`` (the epoch of ``cbn0``: the init's time, when it is inside the log)."""
    k = int(np.searchsorted(imu.time, t0 + time_tolerance(t0), side="right"))
    return check_mounting(imu.time[k:], imu.dtheta_b[k:], imu.dvel_b[k:], t0, g, conv, cbn0,
                          mounting_matrix(imu_cfg.get("mounting")), str(imu.source or "IMU log"))
