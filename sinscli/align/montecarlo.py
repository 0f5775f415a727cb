"""Monte Carlo of the alignment (seed 001 Figs. 1-3): N seeded runs of one scenario.

The motion of a scenario has no randomness, so its exact truth is computed
once (:class:`sinscli.align.sway.ScenarioRuns`) and each run draws only its
sensor errors and GNSS noise from its seed.  Every run is aligned with each
variant (the method without and with the roll window, and any extra methods
asked for) and its roll, pitch and heading errors are kept against alignment
time, both of the estimate of the start attitude ``Cbn(0)`` (what the
attitude-determination method solves for, and where the roll window acts)
and of the current attitude ``Cbn(t)`` (what navigation starts from).
Statistics at the end are compared with the static-base limits of
:mod:`.observability`, and the error of the state each run writes with the
1-sigma it reports (:meth:`McResult.sigma_rows`, :class:`Coverage`).

For studies spread over workers (``sins align --monte-carlo N --scheduler``,
:mod:`sinscli.batch.mc_study`) the work is split: :func:`plan_monte_carlo`
checks the file at the client and gives a small :class:`McPlan`; each worker
builds the truth once (:func:`scenario_runs`) and runs seeds
(:func:`run_seed`); the client adds the runs in seed order into a
:class:`McAccumulator`, which keeps every run's end errors but only the
first few runs' series (plus the per-epoch mean and spread of all) for a
large study.  :func:`run_monte_carlo` does all of it in this process.  No
file output here.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SinsError
from ..nav.earth import gravity
from ..nav.rotation import dcm_to_euler_many
from ..types import time_tolerance
from . import observability
from .options import SensorSpec, build_options, from_sensor, merge_section
from .pipeline import align
from .sway import ScenarioRuns, load_align_scenario, prepare_scenario

MC_DEFAULTS = {"runs": 100, "seed": 0, "roll_window": 10.0, "methods": []}


@dataclass
class RunErrors:
    """One run's errors (deg; roll, pitch, heading) of one variant: its series against alignment time
    (decimated for a large study) and the values the statistics use, taken at full resolution."""
    time: np.ndarray                   # (epochs,) s since the alignment start
    current: np.ndarray                # (epochs, 3) error of the Cbn(t) estimate
    start: np.ndarray | None           # (epochs, 3) error of the Cbn(0) estimate, when the method has one
    end_current: np.ndarray            # (3,) at the end of the interval
    end_start: np.ndarray | None       # (3,)
    start_at_window: np.ndarray | None  # (3,) start-attitude error at the end of the roll window
    # the state the alignment writes: its error and the 1-sigma it reports (None in job files from before)
    state: np.ndarray | None = None        # (3,) error of the written state (its epoch: end or start)
    sigma: np.ndarray | None = None        # (3,) reported 1-sigma (heading nan when not reported)
    sigma_floor: np.ndarray | None = None  # (3,) the method's noise-only floor
    state_time: np.ndarray | None = None   # () s, the state's time (log time)


@dataclass
class VariantErrors:
    """Errors (deg) of one variant over the runs.

    ``current``/``start``: the series of the kept runs (all of them, or the first few of a large
    study), (runs kept, epochs, 3); ``band``: ``{"current": (mean, std), "start": ...}`` per epoch over
    every run when not all are kept; ``end_*`` and ``start_at_window``: (runs, 3), every run."""
    name: str
    time: np.ndarray                   # (epochs,) s since the alignment start
    current: np.ndarray                # (kept, epochs, 3) error of Cbn(t) estimate
    start: np.ndarray | None           # (kept, epochs, 3) error of the Cbn(0) estimate, when the method has one
    end_current: np.ndarray | None = None
    end_start: np.ndarray | None = None
    start_at_window: np.ndarray | None = None
    band: dict = field(default_factory=dict)
    coverage: Coverage | None = None   # every run's written state against its reported 1-sigma


@dataclass
class McResult:
    scenario: str
    runs: int
    seeds: list
    variants: dict                     # name -> VariantErrors
    theory: dict                       # variant -> {"tilt", "heading"} 1-sigma deg (static-base limits; empty moving)
    roll_window: float | None
    notes: list = field(default_factory=list)

    def summary_rows(self):
        """One row per variant and angle: mean, std and rms at the end (current and start attitude), theory."""
        rows = []
        for v in self.variants.values():
            for which, end in (("current", v.end_current), ("start", v.end_start)):
                if end is None:
                    continue
                for i, ang in enumerate(("roll", "pitch", "heading")):
                    lim = self.theory.get(v.name)
                    th = None if lim is None else lim["heading" if i == 2 else "tilt"]
                    rows.append({"variant": v.name, "attitude": which, "angle": ang,
                                 "mean_deg": float(end[:, i].mean()), "std_deg": float(end[:, i].std(ddof=1))
                                 if end.shape[0] > 1 else 0.0,
                                 "rms_deg": float(np.sqrt((end[:, i] ** 2).mean())), "theory_deg": th})
        return rows

    def drift(self, name: str, t_from: float, which: str = "start", angle: int = 0) -> float:
        """RMS over runs of the change of an error from ``t_from`` to the end (deg).  At the end of the
        roll window it comes from every run; at another time from the kept series (every run when all
        are kept)."""
        v = self.variants[name]
        if which == "start" and v.start_at_window is not None and t_from == self.roll_window:
            return _rms_change(v.end_start[:, angle], v.start_at_window[:, angle])
        arr = v.start if which == "start" else v.current
        if arr.shape[0] != self.runs:
            raise ValueError(f"drift from {t_from} s: only {arr.shape[0]} of {self.runs} runs' series are kept")
        j = int(np.searchsorted(v.time, t_from - 1e-9))
        return _rms_change(arr[:, -1, angle], arr[:, j, angle])

    def sigma_rows(self):
        """One row per variant and angle: is the 1-sigma the alignment reports for its written state
        borne out by the runs?  rms of the reported sigma and of the error, the fractions of runs inside
        1 and 3 reported sigma (0.683 and 0.9973 for an honest Gaussian claim), and the rms noise-only
        floor.  Angles without a reported sigma (a user heading) are left out."""
        rows = []
        for v in self.variants.values():
            c = v.coverage
            if c is None or c.err.shape[0] == 0:
                continue
            in1, in3 = c.inside(1.0), c.inside(3.0)
            for i, ang in enumerate(("roll", "pitch", "heading")):
                if not np.isfinite(c.sigma[:, i]).all():
                    continue
                rows.append({"variant": v.name, "angle": ang, "runs": int(c.err.shape[0]),
                             "sigma_rms_deg": float(np.sqrt((c.sigma[:, i] ** 2).mean())),
                             "error_rms_deg": float(np.sqrt((c.err[:, i] ** 2).mean())),
                             "inside_1sigma": float(in1[i]), "inside_3sigma": float(in3[i]),
                             "floor_rms_deg": float(np.sqrt((c.floor[:, i] ** 2).mean()))})
        return rows


def _rms_change(end: np.ndarray, at: np.ndarray) -> float:
    return float(np.sqrt(((end - at) ** 2).mean()))


def _euler_err(est, truth, conv):
    e = np.degrees(dcm_to_euler_many(np.ascontiguousarray(est), conv)
                   - dcm_to_euler_many(np.ascontiguousarray(truth), conv))
    e[..., 2] = (e[..., 2] + 180.0) % 360.0 - 180.0
    e[..., 0] = (e[..., 0] + 180.0) % 360.0 - 180.0
    return e


def _state_error(res, truth, conv) -> np.ndarray:
    """(3,) deg: roll, pitch, heading error (estimate - truth) of the state an alignment writes."""
    k = int(np.argmin(np.abs(truth.time - res.state.time)))
    return _euler_err(res.state.Cbn[None], truth.Cbn[k][None], conv)[0]


def sensor_budget(sensor: dict):
    """1-sigma sensor errors (SI) of a resolved simulator sensor (``Prepared.sensor``): the rms over
    the axes of the fixed bias, the turn-on spread and the instability, and of the random walks."""
    def rms(d, keys):
        tot = np.zeros(3)
        for k in keys:
            if k in d:
                tot += np.asarray(d[k], dtype=float) ** 2
        return float(np.sqrt(tot.mean()))
    gy, ac = sensor.get("gyro", {}), sensor.get("accel", {})
    return {"gyro_bias": rms(gy, ("bias", "bias_sigma", "bias_instability")), "gyro_arw": rms(gy, ("arw",)),
            "accel_bias": rms(ac, ("bias", "bias_sigma", "bias_instability")), "accel_vrw": rms(ac, ("vrw",)),
            "gyro_spread": rms(gy, ("bias_sigma", "bias_instability")),
            "accel_spread": rms(ac, ("bias_sigma", "bias_instability"))}


def theory_limits(lat, T, sb: dict, g, method: str = "inertial") -> dict:
    """Static-base 1-sigma spread (deg): tilt = accelerometer bias spread / g (plus noise), heading =
    east gyro bias spread / (W_ie cos L) plus the noise terms (gyro; and, for the inertial-frame
    method, accelerometer) and the tan L term."""
    tilt = observability.tilt_sigma(T, sb["accel_spread"], sb["accel_vrw"], g)
    head = observability.earth_rate_heading_sigma(lat, T, sb["gyro_spread"], sb["gyro_arw"], sb["accel_spread"], g,
                                                  sb["accel_vrw"] if method != "static" else 0.0)
    return {"tilt": math.degrees(tilt), "heading": math.degrees(head)}


@dataclass
class McPlan:
    """Everything the runs of a study need but the truth: small, sent to the workers."""
    path: str                          # the alignment scenario file (read again on each worker)
    name: str                          # the scenario's name
    seeds: list
    variants: list                     # [(name, roll window s or None)]
    base_opts: object                  # AlignOptions of the scenario's align section
    uses_gnss: dict                    # variant -> bool
    conv: int
    lat: float                         # rad
    h0: float                          # m
    budget: dict                       # sensor_budget() of the scenario's sensor
    at_rest: bool
    roll_window: float | None

    @property
    def runs(self) -> int:
        return len(self.seeds)


def plan_monte_carlo(path, runs: int | None = None, seed0: int | None = None) -> McPlan:
    """Read and check an alignment scenario file (simulator scenario + ``align`` + ``monte_carlo``)."""
    sim_part, align_sec, sway_sec, src, base = load_align_scenario(path)
    mc = dict(MC_DEFAULTS)
    mc_sec = sim_part.pop("monte_carlo", None) or {}
    if not isinstance(mc_sec, dict) or set(mc_sec) - set(MC_DEFAULTS):
        raise SinsError(f"{src}: monte_carlo: expected a mapping with keys {', '.join(MC_DEFAULTS)}")
    mc.update(mc_sec)
    if runs is not None:
        mc["runs"] = runs
    if seed0 is not None:
        mc["seed"] = seed0
    n = mc["runs"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise SinsError(f"{src}: monte_carlo.runs: expected a whole number >= 2, got {n!r}")
    merged = merge_section(align_sec, src)
    prepared = prepare_scenario(sim_part, sway_sec, src, base)
    sc = prepared.scenario
    if merged["position"] is None:
        merged["position"] = [sc.start_deg["lat"], sc.start_deg["lon"], sc.h0]
    sb = sensor_budget(prepared.sensor)
    base_opts = build_options(merged, src, conv=sc.conv, lever_arm=sc.gnss["lever_arm"], base_dir=base)
    if not base_opts.sensor.given:
        # the alignment is told the sensor the runs are drawn from (align.sensor overrides)
        base_opts.sensor = from_sensor(prepared.sensor, "scenario")
    rw = mc["roll_window"]
    variants = [(base_opts.method, None)]
    if rw is not None and base_opts.method != "static":
        variants.append((f"{base_opts.method}+roll-window", rw))
    for m in mc["methods"] or []:
        variants.append((m, None))
    at_rest = all(seg["type"] == "rest" for seg in sc.segments)
    uses_gnss = {name: name.split("+")[0] == "gnss-inertial" or (name.split("+")[0] == "kf" and not at_rest)
                 for name, _ in variants}
    return McPlan(path=str(path), name=sc.name, seeds=[int(mc["seed"]) + k for k in range(n)], variants=variants,
                  base_opts=base_opts, uses_gnss=uses_gnss, conv=sc.conv, lat=sc.lat0, h0=sc.h0, budget=sb,
                  at_rest=at_rest, roll_window=rw)


def scenario_runs(plan: McPlan) -> ScenarioRuns:
    """The exact truth of the plan's scenario (read from its file), ready for seeded runs."""
    sim_part, _, sway_sec, src, base = load_align_scenario(plan.path)
    sim_part.pop("monte_carlo", None)
    return ScenarioRuns(prepare_scenario(sim_part, sway_sec, src, base))


def _decimate(n: int, max_epochs: int | None) -> np.ndarray:
    """Indices of at most about ``max_epochs`` evenly spaced epochs of ``n``, the last included."""
    if max_epochs is None or n <= max_epochs:
        return np.arange(n)
    keep = np.arange(0, n, int(math.ceil(n / max_epochs)))
    return keep if keep[-1] == n - 1 else np.append(keep, n - 1)


def run_seed(plan: McPlan, runs_src: ScenarioRuns, seed: int, max_epochs: int | None = None) -> dict:
    """Align one seeded run with every variant: variant -> :class:`RunErrors` (series decimated to
    about ``max_epochs``; end and roll-window values at full resolution)."""
    r = runs_src.run(seed)
    out = {}
    for name, window in plan.variants:
        o = copy.copy(plan.base_opts)
        o.method = name.split("+")[0]
        o.roll_window = window
        res = align(r.imu, o, r.gnss if plan.uses_gnss[name] else None)
        ser = res.series
        idx = np.searchsorted(r.truth.time, ser.time - time_tolerance(float(ser.time[0])))
        t = ser.time - res.t0
        cur = _euler_err(ser.cbn, r.truth.Cbn[idx], plan.conv)
        start = at_window = None
        if ser.cbn0 is not None:
            k0 = int(np.searchsorted(r.truth.time, res.t0 - 1e-9))
            start = _euler_err(ser.cbn0, np.broadcast_to(r.truth.Cbn[k0], ser.cbn0.shape), plan.conv)
            if plan.roll_window is not None:
                at_window = start[int(np.searchsorted(t, plan.roll_window - 1e-9))].copy()
        keep = _decimate(t.shape[0], max_epochs)
        floor = np.full(3, np.nan) if res.sigma_floor is None else np.degrees(res.sigma_floor)
        out[name] = RunErrors(time=t[keep], current=cur[keep], start=None if start is None else start[keep],
                              end_current=cur[-1].copy(), end_start=None if start is None else start[-1].copy(),
                              start_at_window=at_window, state=_state_error(res, r.truth, plan.conv),
                              sigma=np.degrees(res.sigma), sigma_floor=floor,
                              state_time=np.array(float(res.state.time)))
    return out


class _Welford:
    """Per-epoch mean and standard deviation over runs added one at a time (in seed order)."""

    def __init__(self):
        self.n, self.mean, self.m2 = 0, None, None

    def add(self, x: np.ndarray) -> None:
        self.n += 1
        if self.mean is None:
            self.mean, self.m2 = x.astype(float).copy(), np.zeros_like(x, dtype=float)
            return
        d = x - self.mean
        self.mean += d / self.n
        self.m2 += d * (x - self.mean)

    def result(self):
        return self.mean, np.sqrt(self.m2 / max(self.n - 1, 1))


class McAccumulator:
    """The runs of a study, added in seed order, into a :class:`McResult`; keeps the series of the
    first ``keep`` runs (all with None) and the per-epoch mean and spread of every run's."""

    def __init__(self, plan: McPlan, keep: int | None = None):
        self.plan, self.keep = plan, keep
        self.seeds: list = []
        self.acc = {name: {"t": None, "cur": [], "start": [], "end_cur": [], "end_start": [], "at_w": [],
                           "band": {"current": _Welford(), "start": _Welford()},
                           "cov": {"err": [], "sigma": [], "floor": [], "times": [], "seeds": []}}
                    for name, _ in plan.variants}

    def add(self, seed: int, errs: dict) -> None:
        self.seeds.append(seed)
        for name, e in errs.items():
            a = self.acc[name]
            if a["t"] is None:
                a["t"] = e.time
            if self.keep is None or len(a["cur"]) < self.keep:
                a["cur"].append(e.current)
                if e.start is not None:
                    a["start"].append(e.start)
            a["band"]["current"].add(e.current)
            a["end_cur"].append(e.end_current)
            if e.start is not None:
                a["band"]["start"].add(e.start)
                a["end_start"].append(e.end_start)
            if e.start_at_window is not None:
                a["at_w"].append(e.start_at_window)
            if e.sigma is not None:
                for k, v in (("err", e.state), ("sigma", e.sigma), ("floor", e.sigma_floor),
                             ("times", float(e.state_time)), ("seeds", seed)):
                    a["cov"][k].append(v)

    def result(self) -> McResult:
        plan = self.plan
        out = {}
        for name, _ in plan.variants:
            a = self.acc[name]
            all_kept = len(a["cur"]) == len(self.seeds)
            band = {} if all_kept else {w: b.result() for w, b in a["band"].items() if b.n}
            c = a["cov"]
            out[name] = VariantErrors(
                name, a["t"], np.array(a["cur"]), np.array(a["start"]) if a["start"] else None,
                end_current=np.array(a["end_cur"]), end_start=np.array(a["end_start"]) if a["end_start"] else None,
                start_at_window=np.array(a["at_w"]) if a["at_w"] else None, band=band,
                coverage=Coverage(*(np.array(c[k]).reshape(-1, 3) for k in ("err", "sigma", "floor")),
                                  np.array(c["times"]), c["seeds"]) if c["seeds"] else None)
        g = float(gravity(math.sin(plan.lat), plan.h0))
        T = float(next(iter(out.values())).time[-1])
        theory = ({name: theory_limits(plan.lat, T, plan.budget, g, name.split("+")[0]) for name in out}
                  if plan.at_rest else {})
        return McResult(plan.name, len(self.seeds), list(self.seeds), out, theory, plan.roll_window)


def run_monte_carlo(path, runs: int | None = None, seed0: int | None = None, progress=None) -> McResult:
    """Run the Monte Carlo of an alignment scenario file in this process (every series kept)."""
    plan = plan_monte_carlo(path, runs, seed0)
    runs_src = scenario_runs(plan)
    acc = McAccumulator(plan)
    for s in plan.seeds:
        acc.add(s, run_seed(plan, runs_src, s))
        if progress is not None:
            progress(1)
    return acc.result()


# --------------------------------------------------------------------------- coverage of the 1-sigma

def scaled_sensor(sensor: dict, factor: float) -> dict:
    """A resolved sensor description (SI, :func:`sinscli.sensors.load_sensor`) with every error figure
    multiplied by ``factor`` (its time constants and quantization kept): ``factor = 0.1`` is a
    description ten times too optimistic."""
    keep = ("bias_tau", "quantization")
    return {w: {k: (v if k in keep else np.asarray(v) * factor) for k, v in sensor.get(w, {}).items()}
            for w in ("gyro", "accel")}


@dataclass
class Coverage:
    """The runs of one method with one sensor description: end errors against the reported 1-sigma."""
    err: np.ndarray          # (n, 3) deg, roll, pitch, heading (estimate - truth) of the runs not refused
    sigma: np.ndarray        # (n, 3) deg (heading nan for a user heading without a sigma)
    floor: np.ndarray        # (n, 3) deg, the method's own noise-only floor
    times: np.ndarray        # (n,) s, the state's time
    seeds: list              # (n,) seeds of those runs
    refused: list = field(default_factory=list)     # (seed, one-line reason)

    def inside(self, k: float = 3.0) -> np.ndarray:
        """Fraction of the runs whose error lies within ``k`` 1-sigma, per angle (1 where not reported)."""
        if self.err.shape[0] == 0:
            return np.full(3, np.nan)
        ok = (np.abs(self.err) <= k * self.sigma) | ~np.isfinite(self.sigma)
        return ok.mean(axis=0)


def coverage_runs(scenario: dict, methods, seeds, cases=("right", "absent", "optimistic"), sway=None,
                  with_gnss: bool = True, **align_kw) -> dict:
    """Align each seeded run of ``scenario`` (simulator scenario mapping) with each method and sensor
    description: ``right`` (the one the runs are drawn from), ``absent``, ``optimistic`` (every figure
    ten times too small).  Returns ``{(method, case): Coverage}``; ``align_kw`` are
    :class:`~sinscli.align.options.AlignOptions` fields (``position`` defaults to the start)."""
    from .options import AlignOptions
    prepared = prepare_scenario(copy.deepcopy(scenario), sway, "coverage", None)
    sc = prepared.scenario
    runs = ScenarioRuns(prepared)
    specs = {"right": from_sensor(prepared.sensor, "right"), "absent": SensorSpec(),
             "optimistic": from_sensor(scaled_sensor(prepared.sensor, 0.1), "optimistic")}
    kw = {"position": (sc.lat0, sc.lon0, sc.h0), "conv": sc.conv,
          "lever_arm": np.asarray(sc.gnss["lever_arm"], dtype=float)}
    kw.update(align_kw)
    acc = {(m, c): {"err": [], "sigma": [], "floor": [], "times": [], "seeds": [], "refused": []}
           for m in methods for c in cases}
    for seed in seeds:
        r = runs.run(seed)
        for m in methods:
            for c in cases:
                a = acc[(m, c)]
                try:
                    res = align(r.imu, AlignOptions(method=m, sensor=specs[c], **kw), r.gnss if with_gnss else None)
                except SinsError as exc:
                    a["refused"].append((seed, str(exc).splitlines()[0]))
                    continue
                a["err"].append(_state_error(res, r.truth, sc.conv))
                a["sigma"].append(np.degrees(res.sigma))
                a["floor"].append(np.degrees(res.sigma_floor))
                a["times"].append(res.state.time)
                a["seeds"].append(seed)
    out = {}
    for key, a in acc.items():
        out[key] = Coverage(np.array(a["err"]).reshape(-1, 3), np.array(a["sigma"]).reshape(-1, 3),
                            np.array(a["floor"]).reshape(-1, 3), np.array(a["times"]), a["seeds"], a["refused"])
    return out
