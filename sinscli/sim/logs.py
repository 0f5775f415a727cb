"""What a real log adds to the exact data (issue 19): rate samples, stamp jitter and clock offsets,
wheel odometry, and the run's record of its true geometry and realized errors (``sim_truth.yaml``).

Random draws come from children of the run's ``SeedSequence(seed)`` after the three of
:mod:`.errors` (gyro, accel, GNSS): child 4 the stamp jitter, child 5 the odometry noise, child 6 the
dropped rows, child 7 the RTK float errors, so the existing realizations are unchanged whether these
are on or off.

Clock sign (the navigation config's ``gnss.time_offset`` is "s added to every GNSS time on
reading"): a written stamp is ``true time + offset``, so the config value ``-offset`` (for the IMU,
``imu.time_offset``, same meaning) brings the log back onto the true time of ``truth.csv``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from ..config import mounting_angles
from ..io.atomic import atomic_path
from ..io.body_vel_csv import write_body_velocity_csv
from ..io.imu_csv import write_imu_csv, write_imu_rates_csv
from ..nav.rotation import conv_to_flu
from ..sensors import ACCEL_UNITS, GYRO_UNITS
from ..units import G0, MG, UG
from ..types import BodyVelLog
from . import pinned as pm
from .environment import environment_rates
from .errors import apply_imu_errors, quantize
from .recorder import round_to_step, runs_of

JITTER_STREAM, ODOMETRY_STREAM, DROP_STREAM, RTK_STREAM, N_STREAMS = 4, 5, 6, 7, 8
MOVING = 0.01            # m/s: odometry noise only above this true speed (a still wheel counts nothing)


@dataclass
class ImuRates:
    """Rate samples at the true IMU instants ``time`` (N+1,): ``gyro`` rad/s, ``accel`` m/s^2 (sensor axes)."""
    time: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray


def stream(seed: int, k: int) -> np.random.Generator:
    """The generator of child ``k`` of the run's ``SeedSequence(seed)``."""
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(N_STREAMS)[k])


def imu_rates(sc, td, c_out: np.ndarray, sensor: dict, seed: int, perfect: bool = False) -> ImuRates:
    """The instantaneous sensor outputs at every IMU instant (``td.w_imu``, ``td.f_imu``, FLU body) in the
    sensor axes (``x_s = x_flu @ c_out``), with the environment's terms (:mod:`.environment`), the sensor's
    errors: the increment model of :mod:`.errors` applied to ``rate * dt`` over the nominal interval ``dt``
    and divided by it (the same realized constants; white noise of density ``arw``/``vrw``, i.e. sigma
    ``arw / sqrt(dt)`` per sample), and the written values' quantization (:mod:`.recorder`)."""
    if td.w_imu is None:
        raise ValueError("imu.output: rates needs the truth engine's rates (generate(..., rates=True))")
    gyro, accel = td.w_imu @ c_out, td.f_imu @ c_out
    tau = td.tau[td.imu_idx]
    if not perfect and sc.environment.active():
        gyro, accel = environment_rates(sc.environment, gyro, accel, tau)
    if sensor and (sensor.get("gyro") or sensor.get("accel")):
        dt = np.full(gyro.shape[0], 1.0 / sc.imu_rate)
        g, a, _ = apply_imu_errors(gyro * dt[:, None], accel * dt[:, None], dt, sensor, seed)
        gyro, accel = g / dt[:, None], a / dt[:, None]
    if not perfect and sc.quantization is not None:
        gyro = round_to_step(gyro, sc.quantization["gyro"])
        accel = round_to_step(accel, sc.quantization["accel"])
    return ImuRates(sc.t0 + tau, gyro, accel)


def quantize_increments(dtheta: np.ndarray, dvel: np.ndarray, q: dict, rate: float):
    """Increments quantized to the steps ``q`` (rad/s, m/s^2) times the nominal interval ``1/rate``, the
    remainder carried (:func:`sinscli.sim.errors.quantize`, :mod:`.recorder`)."""
    dt = 1.0 / rate
    return quantize(dtheta, np.full(3, q["gyro"] * dt)), quantize(dvel, np.full(3, q["accel"] * dt))


def realism_sizes(sc, td, dropped, rtk, n_instants: int) -> dict:
    """What the realism terms did to this run, for ``sim_truth.yaml``: the flex's largest and RMS angle
    (deg, per body axis), the truth's largest lateral velocity and slip angle, the rows dropped, the
    float and wrong-fix epochs."""
    out = {}
    if td.flex_theta is not None:
        th = td.flex_theta * (180.0 / np.pi)
        out["mount_flex"] = {"max_angle_deg": np.abs(th).max(axis=0).tolist(),
                             "rms_angle_deg": np.sqrt(np.mean(th * th, axis=0)).tolist()}
    if sc.sideslip != 0.0:
        idx = td.imu_idx
        v_b = pm.matmul(np.swapaxes(td.cbn[idx], -1, -2), td.vel_n[idx][:, :, None])[:, :, 0]     # C_n^b v^n
        speed = np.sqrt(v_b[:, 0] * v_b[:, 0] + v_b[:, 1] * v_b[:, 1] + v_b[:, 2] * v_b[:, 2])
        beta = np.where(speed > 0.5, pm.arctan2(np.abs(v_b[:, 1]), np.abs(v_b[:, 0])) * (180.0 / np.pi), 0.0)
        out["sideslip"] = {"max_lateral_velocity_m_s": float(np.abs(v_b[:, 1]).max()),
                           "max_slip_angle_deg": float(beta.max())}
    if dropped is not None:
        runs = runs_of(dropped)
        out["dropped"] = {"rows": int(dropped.size), "runs": int(runs.size),
                          "fraction": float(dropped.size / max(n_instants - 2, 1)),
                          "longest_run": int(runs.max()) if runs.size else 0}
    if rtk is not None:
        out["rtk"] = {"float_epochs": int(rtk.floating.sum()),
                      "wrong_fix_epochs": int(np.count_nonzero(np.any(rtk.error != 0, axis=1) & ~rtk.floating)),
                      "max_error_m": np.abs(rtk.error).max(axis=0).tolist() if rtk.error.size else [0.0] * 3}
    return out


def imu_stamps(sc, tau: np.ndarray, seed: int, perfect: bool) -> np.ndarray | None:
    """Written stamps of the IMU instants 0..N: ``t0 + tau_k + e_k + offset``, ``e_k`` uniform in
    ``[-stamp_jitter, stamp_jitter]`` (strictly increasing since the jitter is under half an interval; the
    start's ``e_0`` taken <= 0, so that ``init.yaml``'s time lies within a rate log without offset);
    None when they are the true instants (no jitter, no offset, or a perfect run)."""
    if perfect or (sc.stamp_jitter == 0.0 and sc.imu_time_offset == 0.0):
        return None
    t = sc.t0 + tau
    if sc.stamp_jitter > 0.0:
        e = stream(seed, JITTER_STREAM).uniform(-sc.stamp_jitter, sc.stamp_jitter, tau.shape[0])
        e[0] = -abs(e[0])           # the start's stamp never late: an init at the true start lies in a rate log
        t = t + e
    return t + sc.imu_time_offset


def odometry_log(sc, td, conv: int, seed: int, perfect: bool) -> BodyVelLog:
    """Wheel odometry at every ``step``-th IMU instant: the truth point's velocity in the body axes of
    the output convention (after the mounting: the vehicle's axes), ``v_meas = (1 + s) v + n``, the noise
    ``n`` only while the truth point moves faster than ``MOVING`` (at standstill the odometer reads 0)."""
    o = sc.odometry
    idx = td.imu_idx[::o["step"]]
    v_flu = np.einsum("nji,nj->ni", td.cbn[idx], td.vel_n[idx])            # C_n^b v^n
    vel = v_flu @ conv_to_flu(conv)                                        # rows: FLU -> conv
    std = None
    if not perfect:
        vel = (1.0 + o["scale_factor"]) * vel
        if np.any(o["noise"] > 0):          # slip noise while the wheels turn; at standstill the count is still
            moving = (np.linalg.norm(v_flu, axis=1) > MOVING)[:, None]
            vel = vel + moving * o["noise"] * stream(seed, ODOMETRY_STREAM).standard_normal(vel.shape)
        rep = o["reported_sigma"] if o["reported_sigma"] is not None else (o["noise"] if np.all(o["noise"] > 0)
                                                                            else None)
        std = None if rep is None else np.tile(rep, (vel.shape[0], 1))
    return BodyVelLog(time=sc.t0 + td.tau[idx], vel_b=vel, std=std, source=f"simulate:{sc.name}")


def _plain(x):
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    return x


def _sensor_record(realized: dict, c_sb: np.ndarray) -> dict:
    """Realized constant errors in the sensor axes, in the sensor description's units, and the turn-on bias
    in the body axes too (``C_sensor^body b``: what a filter after the mounting estimates)."""
    out = {}
    for which, units in (("gyro", GYRO_UNITS), ("accel", ACCEL_UNITS)):
        r = realized.get(which)
        if not r:
            continue
        out[which] = {k: (np.asarray(r[k]) / units[k]).tolist() for k in ("bias", "scale_factor", "misalignment")}
        out[which]["bias_body"] = (c_sb @ np.asarray(r["bias"]) / units["bias"]).tolist()
        if r.get("bias_gm") is not None:
            gm = np.asarray(r["bias_gm"]) / units["bias"]
            out[which]["bias_instability_first_last"] = [gm[0].tolist(), gm[-1].tolist()]
    return out


def sim_record(res, vibration=None) -> dict:
    """The true geometry, clocks and realized errors of a run (``sim_truth.yaml``), plus the navigation
    config snippet that undoes the geometry and the clocks (``imu.time_offset`` is the reader's key of
    issue 19)."""
    sc = res.scenario
    perfect = res.perfect
    c_sb = np.eye(3) if sc.mounting is None else sc.mounting
    imu_off = 0.0 if perfect else sc.imu_time_offset
    gnss_off = 0.0 if perfect else sc.gnss["time_offset"]
    rec = {
        "scenario": res.name, "seed": res.seed, "perfect": perfect, "body": ("flu", "rfu", "frd")[res.conv],
        "imu": {
            "rate": sc.imu_rate, "output": sc.imu_output, "sensor": sc.sensor if isinstance(sc.sensor, str) else None,
            "mounting": mounting_angles(c_sb), "mounting_matrix": c_sb.tolist(),
            "time_offset": imu_off, "stamp_jitter": 0.0 if perfect else sc.stamp_jitter,
            "errors": _sensor_record(res.sensor, c_sb),
            "errors_units": "sensor axes (bias_body: body axes); gyro bias deg/h, accel bias micro-g, scale_factor ppm, misalignment "
                            "arcsec [xy, xz, yx, yz, zx, zy]; bias_instability_first_last: the Gauss-Markov "
                            "part at the first and last interval",
        },
        "gnss": {
            "rate": sc.gnss["rate"], "lever_arm": sc.gnss["lever_arm"].tolist(), "time_offset": gnss_off,
            "pos_noise": (0.0 * sc.gnss["pos_noise"] if perfect else sc.gnss["pos_noise"]).tolist(),
            "vel_noise": (0.0 * sc.gnss["vel_noise"] if perfect else sc.gnss["vel_noise"]).tolist(),
            "pos_tau": sc.gnss["pos_tau"].tolist(), "vel_tau": sc.gnss["vel_tau"].tolist(),
            "outages": [list(o) for o in sc.gnss["outages"]], "velocity": sc.gnss["velocity"],
        },
        "config": {"imu": {"body": ("flu", "rfu", "frd")[res.conv], "mounting": mounting_angles(c_sb),
                           "time_offset": -imu_off + 0.0},
                   "gnss": {"lever_arm": sc.gnss["lever_arm"].tolist(), "time_offset": -gnss_off + 0.0}},
    }
    for k in ("reported_pos_sigma", "reported_vel_sigma"):
        if sc.gnss.get(k) is not None and not perfect:
            rec["gnss"][k] = sc.gnss[k].tolist()
    if vibration is not None:
        rec["vibration"] = vibration.record()
    if sc.gait is not None:
        g = sc.gait
        rec["gait"] = {"speed": g.speed, "step_freq": g.step_freq, "bob": g.bob, "surge": g.surge, "sway": g.sway,
                       "wobble_deg": np.degrees(g.wobble).tolist()}
    imu_r, gnss_r, top = _realism_record(sc, perfect, res.realism)
    rec["imu"].update(imu_r)
    rec["gnss"].update(gnss_r)
    rec.update(top)
    if sc.odometry is not None:
        o = sc.odometry
        rec["odometry"] = {"rate": o["rate"], "scale_factor": 0.0 if perfect else o["scale_factor"],
                           "noise": (0.0 * o["noise"] if perfect else o["noise"]).tolist(), "frame": "body"}
    return _plain(rec)


def _tidy(x):
    """Plain numbers at 12 significant digits (a unit conversion's last bits: 0.03, not 0.029999999999999995)."""
    a = np.asarray(x, dtype=float)
    out = np.vectorize(lambda v: float(f"{v:.12g}"), otypes=[float])(a) if a.size else a
    return out.tolist() if a.ndim else float(out)


def _realism_record(sc, perfect: bool, sizes: dict) -> dict:
    """The realism terms as configured (the scenario's units) and their sizes in this run, as the record's
    ``(imu, gnss, top-level)`` entries; the error terms only when not perfect (the flex and the sideslip are
    motion: always)."""
    deg = np.pi / 180.0
    out = {}
    imu, g = {}, {}
    env = sc.environment
    if not perfect:
        if sc.quantization is not None:
            imu["quantization"] = {"gyro_deg_s": _tidy(sc.quantization["gyro"] / deg),
                                   "accel_mg": _tidy(sc.quantization["accel"] / MG)}
        if env.g_sensitivity is not None:
            imu["g_sensitivity_deg_s_per_g"] = _tidy(env.g_sensitivity * G0 / deg)
        if env.rectification is not None:
            imu["vibration_rectification_ug_per_g2"] = _tidy(env.rectification * G0 * G0 / UG)
        if "dropped" in sizes:
            imu["dropped"] = dict(sizes["dropped"], run=list(sc.dropped["run"]))
        if env.temperature is not None:
            t = env.temperature
            out["temperature"] = {"rise": t["rise"], "tau": t["tau"], "swing": t["swing"], "period": t["period"],
                                  "gyro_deg_s_per_k": _tidy(t["gyro"] / deg), "accel_mg_per_k": _tidy(t["accel"] / MG)}
        if sc.gnss["float"] is not None:
            f = sc.gnss["float"]
            g["float"] = {"windows": [list(w) for w in f["windows"]], "sigma": f["sigma"].tolist(),
                          "walk": f["walk"].tolist(), "drift": f["drift"].tolist(), "reported": f["reported"].tolist()}
        if sc.gnss["jumps"]:
            g["jumps"] = [{"start": j["start"], "duration": j["duration"], "offset": j["offset"].tolist()}
                          for j in sc.gnss["jumps"]]
        if "rtk" in sizes:
            g["rtk_sizes"] = sizes["rtk"]
    if sc.flex is not None:
        gain = _tidy(sc.flex.gain / deg)
        out["mount_flex"] = dict({"gain_deg_per_m_s2": {"roll": gain[0], "pitch": gain[1], "yaw": gain[2]},
                                  "tau": sc.flex.tau},
                                 **sizes.get("mount_flex", {}))
    if sc.sideslip != 0.0:
        out["vehicle"] = dict({"sideslip_deg_per_g": _tidy(sc.sideslip * G0 / deg)}, **sizes.get("sideslip", {}))
    return imu, g, out


def write_imu_log(path, res) -> None:
    """``imu.csv`` as the scenario asks: increments or rates, at the true or the written stamps."""
    stamps = res.imu_stamps
    if res.imu_rates is not None:
        r = res.imu_rates
        write_imu_rates_csv(path, r.time if stamps is None else stamps, r.gyro, r.accel)
    elif stamps is None:
        write_imu_csv(path, res.imu)
    else:
        write_imu_csv(path, replace(res.imu, time=stamps[1:]))


def write_odometry(path, bv: BodyVelLog) -> None:
    write_body_velocity_csv(path, bv)


def write_record(path, record: dict) -> None:
    """``sim_truth.yaml``, atomically (every number finite by construction)."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(yaml.safe_dump(record, sort_keys=False, default_flow_style=None))
