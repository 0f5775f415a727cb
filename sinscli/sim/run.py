"""``simulate``: a scenario -> exact truth, IMU increments with sensor errors, GNSS fixes."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..io.atomic import staged_dir
from ..io.gnss_csv import write_gnss_csv
from ..io.init_state import write_init_yaml
from ..io.nmea import write_nmea
from ..io.timebase import ABSOLUTE_MIN, to_gps, to_utc
from ..io.ubx_solution import write_ubx_solutions
from ..io.trajectory import write_trajectory
from ..nav.rotation import conv_to_flu
from ..sensors import load_sensor
from ..types import BodyVelLog, GnssLog, ImuLog, NavState, Trajectory, value_step
from . import pinned as pm
from . import truth as truth_mod
from .errors import apply_imu_errors, gnss_seedseq
from .gnss import antenna_truth, gnss_times, make_gnss
from .imu_synth import GRAVITY_MODELS
from .environment import environment_increments, sensor_moments
from .logs import (DROP_STREAM, RTK_STREAM, ImuRates, stream, imu_rates, imu_stamps, odometry_log, quantize_increments,
                   realism_sizes, sim_record, write_imu_log, write_odometry, write_record)
from .recorder import dropped_instants
from .rtk import rtk_errors
from .scenario import Scenario, load_scenario
from .segments import expand
from .vibration import Vibration, draw_vibration

DEFAULT_SEED = 0


@dataclass
class SimResult:
    """Everything a simulation produces (the IMU and truth in body convention ``conv``)."""
    imu: ImuLog                 # increments; imu.t0 = start time
    truth: Trajectory           # at t0 and every IMU time
    gnss: GnssLog               # antenna fixes (degrees)
    init: NavState              # the truth at t0
    conv: int = 0               # body convention code of imu/truth/init (FLU = 0)
    seed: int = DEFAULT_SEED
    name: str = ""
    perfect: bool = False
    launch: dict = field(default_factory=dict)      # start point: lat, lon (deg), height (m), azimuth (deg), time
    sensor: dict = field(default_factory=dict)      # realized sensor constants (SI), empty when perfect
    scenario: Scenario | None = None
    # issue 19 (None unless the scenario asks; docs/simulate.md)
    imu_rates: ImuRates | None = None   # imu.output: rates: the rate samples at every IMU instant (sensor axes)
    imu_stamps: np.ndarray | None = None    # (N+1,) the written IMU stamps of instants 0..N (jitter, offset)
    odometry: BodyVelLog | None = None  # odometry: body velocity as written
    record: dict = field(default_factory=dict)      # what sim_truth.yaml holds
    imu_dropped: np.ndarray | None = None   # imu.dropped: the instants (0..N) whose rows imu.csv leaves out
    realism: dict = field(default_factory=dict)     # sizes of the realism terms for the record (flex, slip, ...)


@dataclass
class Prepared:
    """A checked scenario ready to run: primitives, resolved sensor, sample counts."""
    scenario: Scenario
    prims: list
    sensor: dict
    n_imu: int
    tau_gnss: np.ndarray
    perfect: bool
    vibration: Vibration | None = None


def prepare(scenario, perfect: bool = False, duration: float | None = None) -> Prepared:
    """Load and check everything (raises ``SinsError``) before any work or output.

    ``duration`` (s) cuts the run short of the segments' total (like the scenario's ``duration``).
    """
    sc = load_scenario(scenario)
    if duration is not None:
        if not 0.0 < duration <= sc.duration * (1.0 + 1e-12) or duration * sc.imu_rate < 1.0:
            raise SinsError(f"--duration: must be > 0 (one IMU interval at least) and at most the "
                            f"scenario's {sc.duration:g} s; got {duration:g}")
        sc = replace(sc, duration=float(duration))
    prims = expand(sc.segments, sc.x_start, sc.source)
    if sc.gait is not None:
        for prim in prims:
            prim.gait = sc.gait
    if sc.sideslip != 0.0:
        for prim in prims:
            prim.sideslip = sc.sideslip
    sensor = {} if perfect else load_sensor(sc.sensor, sc.sensor_overrides, sc.source, sc.base_dir)
    n_imu = int(np.floor(sc.duration * sc.imu_rate + 1e-9))
    tau_g = gnss_times(n_imu / sc.imu_rate, sc.gnss["rate"], sc.gnss["outages"], sc.t0)
    vib = draw_vibration(sc.vibration) if sc.vibration is not None else None
    return Prepared(sc, prims, sensor, n_imu, tau_g, perfect, vib)


def simulate(scenario, seed: int | None = None, perfect: bool = False, *, duration: float | None = None,
             nodes: int = 8, progress=None) -> SimResult:
    """Simulate a scenario (mapping, YAML path, :class:`Scenario` or :class:`Prepared`).

    ``seed`` overrides the scenario's ``seed`` (default 0); ``perfect`` drops
    every IMU error and the GNSS noise (outages and lever arm stay: they are
    geometry, not error).  ``nodes`` Gauss-Legendre points per sub-interval;
    ``progress(k)`` is called as k more IMU intervals are done; ``duration``
    (s) cuts the run short.
    """
    p = scenario if isinstance(scenario, Prepared) else prepare(scenario, perfect, duration)
    sc = p.scenario
    perfect = perfect or p.perfect
    seed = seed if seed is not None else (sc.seed if sc.seed is not None else DEFAULT_SEED)
    td = truth_mod.generate(p.prims, sc.lat0, sc.lon0, sc.h0, sc.imu_rate, p.n_imu, extra_times=p.tau_gnss,
                            nodes=nodes, gravity=GRAVITY_MODELS[sc.gravity], progress=progress, t0=sc.t0,
                            vibration=p.vibration, rates=sc.imu_output == "rates", flex=sc.flex,
                            moments=sc.environment.rectification is not None and not perfect)
    return assemble(sc, td, p.tau_gnss, {} if perfect else p.sensor, seed, perfect, p.vibration)


def assemble(sc: Scenario, td: truth_mod.TruthData, tau_g: np.ndarray, sensor: dict, seed: int,
             perfect: bool, vibration: Vibration | None = None) -> SimResult:
    """Containers from the truth engine's output: body convention, mounting, sensor errors, GNSS, and the
    issue-19 extras (rates, stamps, odometry, the record).  ``vibration`` only goes into the record: the
    truth engine put it into ``td``."""
    conv = sc.conv
    c_flu_conv = conv_to_flu(conv).T.copy()          # C_FLU^conv
    idx = td.imu_idx
    tau = td.tau[idx]
    cbn = pm.matmul(td.cbn[idx], conv_to_flu(conv))  # Cbn_conv = Cbn_FLU C_conv^FLU
    truth = Trajectory(time=sc.t0 + tau, lat=td.lat[idx], lon=td.lon[idx], height=td.h[idx],
                       vel_n=td.vel_n[idx], Cbn=cbn, source=f"simulate:{sc.name}")
    c_out = c_flu_conv.T if sc.mounting is None else pm.matmul(c_flu_conv.T, sc.mounting)  # rows: FLU body -> sensor
    dtheta = pm.matmul(td.dtheta_b, c_out)
    dvel = pm.matmul(td.dvel_b, c_out)
    if not perfect and sc.environment.active():
        f2 = sensor_moments(td.ff_b, c_out) if sc.environment.rectification is not None else None
        dtheta, dvel = environment_increments(sc.environment, dtheta, dvel, tau, f2)
    realized = {}
    if sensor and (sensor.get("gyro") or sensor.get("accel")):
        dtheta, dvel, realized = apply_imu_errors(dtheta, dvel, np.diff(tau), sensor, seed)
    if not perfect and sc.quantization is not None and sc.imu_output == "increments":
        dtheta, dvel = quantize_increments(dtheta, dvel, sc.quantization, sc.imu_rate)
    imu = ImuLog(time=sc.t0 + tau[1:], dtheta_b=dtheta, dvel_b=dvel, t0=sc.t0,
                 source=f"simulate:{sc.name}", kind="increments",
                 resolution=(value_step(dtheta), value_step(dvel)))     # as a reader of its file finds it
    rates = imu_rates(sc, td, c_out, sensor, seed, perfect) if sc.imu_output == "rates" else None
    stamps = imu_stamps(sc, tau, seed, perfect)
    dropped = None
    if not perfect and sc.dropped is not None:
        dropped = dropped_instants(tau.size, sc.dropped["fraction"], sc.dropped["run"], stream(seed, DROP_STREAM),
                                   f"{sc.source}: key imu.dropped")
        keep = np.ones(tau.size, dtype=bool)
        keep[dropped] = False
        if rates is not None:
            rates = ImuRates(rates.time[keep], rates.gyro[keep], rates.accel[keep])
        else:
            imu = replace(imu, time=imu.time[keep[1:]], dtheta_b=imu.dtheta_b[keep[1:]], dvel_b=imu.dvel_b[keep[1:]])
        stamps = None if stamps is None else stamps[keep]
    gi = np.searchsorted(td.tau, tau_g)
    lever_flu = pm.matmul(conv_to_flu(conv), sc.gnss["lever_arm"])
    lat_a, lon_a, h_a, v_a = antenna_truth(td.lat[gi], td.lon[gi], td.h[gi], td.vel_n[gi], td.cbn[gi],
                                           td.w_nb_b[gi], lever_flu)
    rng = None if perfect else np.random.default_rng(gnss_seedseq(seed))
    rtk = None
    if not perfect and (sc.gnss["float"] is not None or sc.gnss["jumps"]):
        rtk = rtk_errors(tau_g, sc.gnss, stream(seed, RTK_STREAM))
    gnss = make_gnss(tau_g, sc.t0, lat_a, lon_a, h_a, v_a, sc.gnss, rng, f"simulate:{sc.name}", rtk)
    init = NavState(time=sc.t0, lat=float(truth.lat[0]), lon=float(truth.lon[0]),
                    height=float(truth.height[0]), vel_n=truth.vel_n[0].copy(), Cbn=cbn[0].copy())
    launch = {"time": sc.t0, "lat": sc.start_deg["lat"], "lon": sc.start_deg["lon"], "height": sc.h0,
              "azimuth": sc.start_deg["heading"] % 360.0}
    res = SimResult(imu=imu, truth=truth, gnss=gnss, init=init, conv=conv, seed=seed, name=sc.name,
                    perfect=perfect, launch=launch, sensor=realized, scenario=sc, imu_rates=rates,
                    imu_stamps=stamps,
                    odometry=odometry_log(sc, td, conv, seed, perfect) if sc.odometry is not None else None,
                    imu_dropped=dropped, realism=realism_sizes(sc, td, dropped, rtk, tau.size))
    res.record = sim_record(res, vibration)
    return res


SIM_FILES = ("imu.csv", "gnss.csv", "truth.csv", "init.yaml", "sim_truth.yaml")
# the same fixes as a receiver writes them (sins simulate --gnss-format): file name per format
RECEIVER_FILES = {"nmea": "gnss.nmea", "ubx": "gnss.ubx"}
SIM_GEOID_SEPARATION = -30.0   # m written as GGA's geoid separation (no geoid model: altitude = height + 30 m)


def check_receiver_formats(sc: Scenario, formats) -> None:
    """SinsError unless the scenario's times can be a receiver's: NMEA and UBX carry UTC dates and times, so the
    scenario time (read as UTC-based UNIX time) must be absolute."""
    unknown = [f for f in formats if f not in RECEIVER_FILES]
    if unknown:
        raise SinsError(f"--gnss-format: {unknown[0]!r} is not one of {', '.join(RECEIVER_FILES)}")
    if formats and sc.t0 < ABSOLUTE_MIN:
        raise SinsError(f"{sc.source}: key start.time: --gnss-format {formats[0]} writes UTC dates and times, so "
                        f"the scenario's time must be UNIX time (UTC), e.g. 1715680800 for 2024-05-14 10:00:00; "
                        f"got {sc.t0:g}")


def write_receiver_logs(gnss: GnssLog, outdir, formats) -> list[Path]:
    """The fixes as a receiver's logs, their times read as UTC-based UNIX time: ``gnss.nmea`` (GGA, RMC, GST:
    :func:`sinscli.io.nmea.format_sentences`, geoid separation :data:`SIM_GEOID_SEPARATION`) and ``gnss.ubx``
    (NAV-PVT and NAV-HPPOSLLH: :func:`sinscli.io.ubx_solution.solution_frames`), each with its format's rounding."""
    out = []
    for fmt in formats:
        path = Path(outdir) / RECEIVER_FILES[fmt]
        if fmt == "nmea":
            write_nmea(path, gnss, to_utc(gnss.time, "utc"), geoid_separation=SIM_GEOID_SEPARATION)
        else:
            write_ubx_solutions(path, gnss, to_gps(gnss.time, "utc"))
        out.append(path)
    return out


def write_sim(result: SimResult, outdir, gnss_formats=()) -> list[Path]:
    """Write ``imu.csv``, ``gnss.csv``, ``truth.csv``, ``init.yaml``, ``sim_truth.yaml`` (and ``odom.csv``
    with odometry; ``gnss.nmea`` and ``gnss.ubx`` for ``gnss_formats`` "nmea", "ubx": :func:`write_receiver_logs`)
    into ``outdir`` (docs/formats.md, docs/simulate.md).

    The files are one set (:func:`sinscli.io.atomic.staged_dir`): all of them replace an earlier
    set, or none does (a full disk never pairs new IMU data with an old truth).  Returns the paths.
    """
    out = Path(outdir)
    if result.scenario is not None:
        check_receiver_formats(result.scenario, tuple(gnss_formats))
    with staged_dir(out, owned=SIM_FILES + ("odom.csv",) + tuple(RECEIVER_FILES.values())) as tmp:
        write_imu_log(tmp / SIM_FILES[0], result)
        write_gnss_csv(tmp / SIM_FILES[1], result.gnss)
        write_trajectory(tmp / SIM_FILES[2], result.truth, conv=result.conv)
        extra = {"scenario": result.name, "seed": result.seed, "perfect": result.perfect,
                 "body": ("flu", "rfu", "frd")[result.conv], "launch": result.launch}
        write_init_yaml(tmp / SIM_FILES[3], result.init, result.conv, extra)
        write_record(tmp / SIM_FILES[4], result.record)
        if result.odometry is not None:
            write_odometry(tmp / "odom.csv", result.odometry)
        receivers = write_receiver_logs(result.gnss, tmp, gnss_formats)
    return ([out / name for name in SIM_FILES] + ([out / "odom.csv"] if result.odometry is not None else [])
            + [out / p.name for p in receivers])
