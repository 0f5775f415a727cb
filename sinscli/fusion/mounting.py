"""``imu.mounting: auto``: the IMU-to-vehicle rotation estimated from a ground vehicle's log (no I/O).

The vehicle's body axes (forward, left, up for FLU) are found in the IMU's sensor axes:

1. **Up** from gravity: the mean specific force over the windows at rest (still by the IMU and by the
   GNSS, :func:`sinscli.fusion.standstill.gnss_still`), else over the whole log (a drive's accelerations
   average out; noted).  This sets roll and pitch of the mounting; an accelerometer bias ``b`` tilts it by
   ``b / g`` (10 mg: 0.6 deg), which the second stage removes.
2. **Forward** from the motion (yaw of the mounting): in the levelled sensor frame, the horizontal
   specific force integrated over each interval between GNSS epochs equals, for a vehicle that moves
   along its forward axis (the non-holonomic constraint),

       dV_x = cos(psi) dS - sin(psi) L + b_x dt,    dV_y = sin(psi) dS + cos(psi) L + b_y dt

   with ``dS`` the change of the GNSS speed over the interval, ``L = int v w_up dt`` the integral of the
   centripetal acceleration (GNSS speed times the IMU's yaw rate) and ``b`` the horizontal accelerometer
   bias: linear least squares in ``(cos psi, sin psi, b_x, b_y)`` over every interval while moving.  No
   heading is needed (``psi`` is the forward axis' azimuth in the sensor frame), so a slow rover gets it
   as well as a car; accelerating, braking and turning both ways make it well conditioned.
3. **Refinement** (:func:`refine`, from a fused pass with stage 1-2's mounting and no NHC): in that
   frame the vehicle's velocity ``C_n^b v^n`` points along its forward axis (residual yaw and pitch) and
   its attitude, freed of the accelerometer bias the filter estimates, is level on average (residual roll
   and pitch at rest).

The 1-sigmas come from the least-squares residuals (stage 2) and the scatter of the epochs (stage 3).
A log with too little motion is refused with the reason (:class:`MountingError`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SinsError
from ..nav.earth import local_en
from ..nav.rotation import conv_to_flu
from ..types import GnssLog, ImuLog, Trajectory
from ..units import G0, MG
from .standstill import StandstillDetector, gnss_still
from ..config import mounting_matrix

MIN_MOVING = 30.0          # s of motion faster than MIN_SPEED at least
MIN_SPEED = 0.5            # m/s
MAX_YAW_SIGMA = 30.0       # deg: a yaw less certain than this is refused
WARN_YAW_SIGMA = 3.0       # deg: over this, a warning (a slow vehicle's accelerations barely show its axes)
MIN_REST = 5.0             # s at rest for the up axis from gravity at standstill
ROAD_ROLL = 0.1            # deg: the average roll of the roads a drive takes (crowned, banked both ways)


class MountingError(SinsError):
    """The log cannot give the mounting (too little motion): the reason in the message."""


@dataclass
class MountingEstimate:
    """``C_sensor^body`` with its angles (``imu.mounting``'s roll, pitch, yaw, deg) and 1-sigmas (deg)."""
    C: np.ndarray
    rpy: np.ndarray
    sigma: np.ndarray
    notes: list = field(default_factory=list)

    def snippet(self) -> str:
        """A config snippet the user can keep (YAML)."""
        r, p, y = self.rpy
        sr, sp, sy = self.sigma
        return (f"imu:\n  mounting: {{roll: {r:.3f}, pitch: {p:.3f}, yaw: {y:.3f}}}   # deg, estimated by sins "
                f"(1-sigma {sr:.2g}, {sp:.2g}, {sy:.2g} deg)\n")


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def level_rotation(up_s: np.ndarray) -> np.ndarray:
    """The smallest rotation ``L`` taking the unit vector ``up_s`` (sensor axes) to ``(0, 0, 1)``."""
    u = up_s / np.linalg.norm(up_s)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(u, z)
    s, c = np.linalg.norm(v), float(u @ z)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


def mounting_angles(C: np.ndarray) -> np.ndarray:
    """``(roll, pitch, yaw)`` deg of ``C = Rz(yaw) Ry(pitch) Rx(roll)`` (:func:`sinscli.config.mounting_matrix`)."""
    pitch = math.asin(max(-1.0, min(1.0, -C[2, 0])))
    roll = math.atan2(C[2, 1], C[2, 2])
    yaw = math.atan2(C[1, 0], C[0, 0])
    return np.degrees([roll, pitch, yaw])


def _enu(gnss: GnssLog):
    return local_en(gnss.lat, gnss.lon, gnss.height)


def _epoch_velocity(gnss: GnssLog, span: float):
    """GNSS velocity ``(t, v (n, 3) ENU)`` on epochs ``span`` s apart: the log's velocity averaged over each
    span, else the fixes' displacement across it."""
    t = gnss.time
    edges = np.arange(t[0], t[-1] + 1e-9, span)
    if len(edges) < 3:
        return np.empty(0), np.empty((0, 3))
    tm = 0.5 * (edges[:-1] + edges[1:])
    if gnss.vel_n is not None:
        k = np.clip(np.searchsorted(t, edges), 0, len(t))
        cv = np.vstack([np.zeros((1, 3)), np.cumsum(gnss.vel_n, axis=0)])
        m = np.maximum(k[1:] - k[:-1], 1)
        hi = np.minimum(k[:-1] + m, len(t))
        v = (cv[hi] - cv[k[:-1]]) / (hi - k[:-1])[:, None]
        return tm, v
    e, n = _enu(gnss)
    ee, nn, hh = np.interp(edges, t, e), np.interp(edges, t, n), np.interp(edges, t, gnss.height)
    return tm, np.column_stack([np.diff(ee), np.diff(nn), np.diff(hh)]) / span


def estimate_mounting(imu: ImuLog, gnss: GnssLog, conv: int, fopts, span: float = 1.0) -> MountingEstimate:
    """Stages 1-2 (module docstring) on IMU increments in sensor axes; ``conv`` the body convention the
    mounting is for.  Raises :class:`MountingError` when the log has too little motion."""
    notes = []
    t = imu.time
    t0 = imu.t0 if imu.t0 is not None else float(t[0] - (t[1] - t[0]))
    det = StandstillDetector(fopts.standstill_window, fopts.standstill_rate_std, fopts.standstill_accel_std,
                             fopts.standstill_accel_mag, G0, fopts.standstill_lowpass)
    a, b, _ = det.feed(t, imu.dtheta_b, imu.dvel_b, t_start=t0)
    still = gnss_still(gnss, a, b) == 1 if len(a) else np.zeros(0, dtype=bool)
    rest = np.zeros(len(t), dtype=bool)
    for x, y in zip(a[still], b[still]):
        rest[(t > x) & (t <= y)] = True
    dt_all = np.diff(np.concatenate([[t0], t]))
    if dt_all[rest].sum() >= MIN_REST:
        f_mean = imu.dvel_b[rest].sum(axis=0) / dt_all[rest].sum()
        up_src = f"{dt_all[rest].sum():.0f} s at rest"
        up_sigma = 0.3                                  # deg: a road's slope at the stops, averaged
    else:
        f_mean = imu.dvel_b.sum(axis=0) / dt_all.sum()
        up_src = "the whole log's mean specific force (no standstill)"
        up_sigma = 1.0
    L = level_rotation(f_mean)
    # stage 2: yaw from the horizontal specific force against the GNSS speed changes and centripetal force
    if gnss.vel_n is None:                     # positions only: spans long enough for their noise
        sh = float(np.median(np.hypot(*gnss.position_sigma(fopts.gnss_pos_sigma)[:, :2].T)))
        span = max(span, min(5.0, 2.0 * sh))
    tg, v = _epoch_velocity(gnss, span)
    if len(tg) < 5:
        raise MountingError(f"imu.mounting: auto: the GNSS log spans {float(gnss.time[-1] - gnss.time[0]):.3g} s; "
                            f"the mounting needs {MIN_MOVING:g} s of driving at least")
    speed = np.hypot(v[:, 0], v[:, 1])
    # sin of the road's slope: gravity along the forward axis; from GNSS velocity only (a height differenced
    # over seconds is too noisy: the slope then stays in the fitted bias, its changes in the residuals)
    vertical = gnss.vel_n is not None and bool(np.isfinite(gnss.vel_n[:, 2]).all())    # not speed and course only
    slope = v[:, 2] / np.maximum(speed, 1e-3) if vertical else np.zeros(len(speed))
    edges = np.concatenate([[tg[0] - 0.5 * span], tg + 0.5 * span])
    cum_dv = np.vstack([np.zeros((1, 3)), np.cumsum(imu.dvel_b, axis=0)])
    cum_th = np.vstack([np.zeros((1, 3)), np.cumsum(imu.dtheta_b, axis=0)])
    cum_t = np.concatenate([[t0], t])
    k = np.clip(np.searchsorted(cum_t, edges), 0, len(cum_t) - 1)
    dv_l = (cum_dv[k[1:]] - cum_dv[k[:-1]]) @ L.T            # levelled sensor frame
    dth_l = (cum_th[k[1:]] - cum_th[k[:-1]]) @ L.T
    dts = cum_t[k[1:]] - cum_t[k[:-1]]
    # intervals between consecutive epochs (i -> i+1), both moving
    i = np.arange(len(tg) - 1)
    mov = (speed[i] > MIN_SPEED) & (speed[i + 1] > MIN_SPEED) & (dts[i] > 0) & (dts[i + 1] > 0)
    if mov.sum() * span < MIN_MOVING:
        raise MountingError(f"imu.mounting: auto: the log moves faster than {MIN_SPEED:g} m/s for only "
                            f"{mov.sum() * span:.0f} s; the mounting needs {MIN_MOVING:g} s of driving with "
                            f"speed changes and turns (give imu.mounting instead)")
    i = i[mov]
    # over [tg_i, tg_i+1]: half of each epoch's interval is inside; the specific force over the epochs' halves
    dvx = 0.5 * (dv_l[i, 0] + dv_l[i + 1, 0])
    dvy = 0.5 * (dv_l[i, 1] + dv_l[i + 1, 1])
    dtt = 0.5 * (dts[i] + dts[i + 1])
    g = G0
    dS = speed[i + 1] - speed[i] + g * 0.5 * (slope[i] + slope[i + 1]) * dtt
    wz = 0.5 * (dth_l[i, 2] / dts[i] + dth_l[i + 1, 2] / dts[i + 1])
    Lc = 0.5 * (speed[i] + speed[i + 1]) * wz * dtt
    n = len(i)
    psi, sig_psi, scale, bias = _planar_rotation(np.column_stack([dS, Lc]), np.column_stack([dvx, dvy]), dtt)
    excitation = float(np.sqrt(np.mean(dS ** 2 + Lc ** 2)))
    if sig_psi > MAX_YAW_SIGMA or (sig_psi < WARN_YAW_SIGMA and not 0.5 < scale < 1.5):
        raise MountingError(f"imu.mounting: auto: the log's speed changes and turns ({excitation:.2g} m/s per "
                            f"{span:.3g} s RMS over {n * span:.0f} s of driving) leave the mounting's yaw "
                            f"uncertain to {sig_psi:.2g} deg (scale {scale:.2f} of 1); it needs more accelerating, "
                            f"braking and turning (give imu.mounting instead)")
    C_flu = _rz(psi).T @ L                       # v_body = Rz(psi)^T L v_sensor
    C = conv_to_flu(conv).T @ C_flu
    rpy = mounting_angles(C)
    # the levelling's own error tilts the plane the forward axis is fitted in: half of it as a yaw floor
    sig = np.array([up_sigma, up_sigma, math.hypot(sig_psi, 0.5 * up_sigma)])
    notes.append(f"up from {up_src}, forward from {n * span:.0f} s of driving (speed changes and turns; "
                 f"horizontal accelerometer bias {np.hypot(*bias) / MG:.2g} mg fitted)")
    if sig_psi > WARN_YAW_SIGMA:
        notes.append(f"warning: the yaw is uncertain to {sig_psi:.2g} deg: the vehicle's accelerations barely show "
                     f"its forward axis; with NHC (--vehicle car|robot) the heading follows the GNSS course "
                     f"whatever the yaw, but dead reckoning through accelerations suffers")
    return MountingEstimate(C, rpy, sig, notes)


def _planar_rotation(u, w, dt, k=2.5, iters=6):
    """The angle ``psi`` (rad) of ``w ~ s R(psi) u + b dt`` for planar vectors (n, 2), with its 1-sigma (deg),
    the scale ``s`` and the bias ``b``: the 2-D Wahba solution ``atan2(sum u x w, sum u . w)`` of the
    centred vectors (noise on the GNSS-side ``u`` shrinks the scale but leaves the angle unbiased), each
    pair weighted by ``|u|^2`` and, robustly (Huber, ``k`` robust sigmas), by its own angle's residual."""
    wgt = np.ones(len(u))
    psi, scale, b = 0.0, 1.0, np.zeros(2)
    for _ in range(iters):
        sw = wgt.sum()
        uc = u - (wgt @ u) / sw
        wc = w - (wgt @ w) / sw
        cross = wgt @ (uc[:, 0] * wc[:, 1] - uc[:, 1] * wc[:, 0])
        dot = wgt @ (uc[:, 0] * wc[:, 0] + uc[:, 1] * wc[:, 1])
        psi = math.atan2(cross, dot)
        scale = math.hypot(cross, dot) / max(float(wgt @ (uc ** 2).sum(axis=1)), 1e-300)
        c, s = math.cos(psi), math.sin(psi)
        ru = np.column_stack([c * u[:, 0] - s * u[:, 1], s * u[:, 0] + c * u[:, 1]]) * scale
        b = (wgt @ ((w - ru) / dt[:, None])) / sw
        r = w - ru - b[None, :] * dt[:, None]
        rn = np.hypot(r[:, 0], r[:, 1])
        sr = 1.4826 * np.median(rn) + 1e-12
        q = rn / sr
        wgt = np.where(q <= k, 1.0, k / q)
    # angle's sigma: the residual across each rotated u, over the weighted |u|^2
    c, s = math.cos(psi), math.sin(psi)
    ru = np.column_stack([c * u[:, 0] - s * u[:, 1], s * u[:, 0] + c * u[:, 1]])
    nrm = np.hypot(ru[:, 0], ru[:, 1]) + 1e-300
    perp = (r[:, 0] * -ru[:, 1] + r[:, 1] * ru[:, 0]) / nrm
    den = float(wgt @ (nrm ** 2)) * scale
    var = float(wgt @ (perp ** 2 * nrm ** 2)) / max(den ** 2, 1e-300) * len(u) / max(len(u) - 4, 1)
    return psi, math.degrees(math.sqrt(var)), scale, b


def refine(est: MountingEstimate, traj: Trajectory, conv: int, min_speed: float = 2.0) -> MountingEstimate:
    """Stage 3 (module docstring) from a fused trajectory navigated with ``est`` applied and no NHC: the
    residual rotation ``D`` (body of ``est`` -> vehicle) from the mean direction of the body-frame velocity
    while moving faster than ``min_speed`` (yaw, pitch) and the mean attitude's level (roll)."""
    c_flu = conv_to_flu(conv)
    cb = traj.Cbn @ c_flu.T                                    # FLU body -> ENU
    v_b = np.einsum("nji,nj->ni", cb, traj.vel_n)
    sp = np.linalg.norm(v_b, axis=1)
    m = sp > min_speed
    if m.sum() < 50:
        return est
    u = v_b[m] / sp[m, None]
    x = u.mean(axis=0)
    x /= np.linalg.norm(x)
    # up of the vehicle in the body frame: the ENU up seen from the body, averaged over the moving epochs
    up = cb[m][:, 2, :]                                        # rows: ENU z in body axes
    z = up.mean(axis=0)
    z = z - (z @ x) * x
    z /= np.linalg.norm(z)
    yv = np.cross(z, x)
    D = np.vstack([x, yv, z])                                  # v_vehicle = D v_body
    C_flu = D @ (c_flu @ est.C)
    C = c_flu.T @ C_flu
    n_eff = max(m.sum() / 100.0, 1.0)                          # epochs are correlated over ~1 s at 100 Hz
    scatter = np.degrees([np.std(np.arctan2(up[:, 1], up[:, 2])), np.std(np.arcsin(np.clip(u[:, 2], -1, 1))),
                          np.std(np.arctan2(u[:, 1], u[:, 0]))]) / math.sqrt(n_eff)
    # the fused pass's own attitude error is common to every epoch: its claimed 1-sigma adds in full; the
    # roll rests on the roads being level on average (ROAD_ROLL)
    x = traj.extra
    att = np.array([np.median(x["roll_std"][m]), np.median(x["pitch_std"][m]), np.median(x["heading_std"][m])]) \
        if "roll_std" in x else np.zeros(3)
    sig = np.sqrt(scatter ** 2 + att ** 2 + np.array([ROAD_ROLL, 0.0, 0.0]) ** 2)
    # each angle from the stage that knows it better (a slow rover's fused pass without NHC has no heading
    # to speak of: its yaw stays with stage 2)
    rpy_new = mounting_angles(C)
    better = sig < est.sigma
    if not better.any():
        return est
    rpy = np.where(better, rpy_new, est.rpy)
    C = mounting_matrix({"roll": float(rpy[0]), "pitch": float(rpy[1]), "yaw": float(rpy[2])})
    kept = [n for n, b in zip(("roll", "pitch", "yaw"), better) if b]
    return MountingEstimate(C, mounting_angles(C), np.where(better, sig, est.sigma),
                            est.notes + [f"{', '.join(kept)} refined from a fused pass over {m.sum()} epochs faster "
                                         f"than {min_speed:g} m/s"])
