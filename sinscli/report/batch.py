"""Batch comparisons: datasets x methods x Monte Carlo seeds, run in parallel, reported together.

A batch YAML (see ``configs/batch/*.yaml`` and docs/compare.md) names

- ``datasets``: a scenario to simulate (``scenario``, ``perfect``) or existing
  files (``imu``, ``truth``, ``init``, optional ``config``);
- ``methods``: navigation settings (the keys of the ``navigation`` section of
  the navigation config: ``attitude``, ``coning``, ``subsamples``, ``frame``,
  ``dcm_variant``, ...), each with a ``name`` (the report column);
- ``seeds``: Monte Carlo seeds of the simulated sensor errors (a count or a list).

:func:`load_batch` validates the file and names the offending key.
:func:`run_batch` prepares each (dataset, seed) once (simulate, or read the
files), navigates every method on it, computes the errors in the workers
(``concurrent.futures.ProcessPoolExecutor``), then writes one report per
dataset and a summary.  A failing job is recorded with its error; the other
jobs and reports are still written.
"""
from __future__ import annotations

import concurrent.futures as cf
import copy
import csv
import multiprocessing
import os
import re
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..io.inputs import load_yaml
from ..io.atomic import atomic_path
from .errors import ErrorSeries, ErrorTable, build_table, compare_trajectories
from .html import error_table_html, simple_table_html, write_summary_html
from .report import staged_dir, write_report_files
from .tables import write_errors_csv, write_errors_md

TOP_KEYS = {"title", "datasets", "methods", "seeds", "epoch", "interpolate", "timeseries_every",
            "write_trajectories"}
SCENARIO_KEYS = {"name", "scenario", "perfect"}
FILES_KEYS = {"name", "imu", "truth", "init", "config"}
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")
BODY_CODES = {"flu": 0, "rfu": 1, "frd": 2}


@dataclass
class DatasetSpec:
    """One dataset: a scenario to simulate, or existing imu/truth/init files."""
    name: str
    scenario: Path | None = None
    perfect: bool = False
    imu: Path | None = None
    truth: Path | None = None
    init: Path | None = None
    config: Path | None = None


@dataclass
class MethodSpec:
    """One navigation method: a validated ``navigation`` config section."""
    name: str
    navigation: dict


@dataclass
class BatchSpec:
    source: Path
    title: str
    datasets: list
    methods: list
    seeds: list
    epoch: float | None = None
    interpolate: bool = False
    timeseries_every: int = 1
    write_trajectories: bool = False


@dataclass
class Prepared:
    """The data of one (dataset, seed): IMU, initial state, truth, body convention code."""
    imu: object
    init: object
    truth: object
    conv: int
    launch: dict | None = None     # launch point of a simulated flight (for frame: launch-inertial)


@dataclass
class JobResult:
    dataset: str
    seed: int | None
    method: str
    label: str
    ok: bool = False
    error: str = ""
    seconds: float = 0.0
    series: ErrorSeries | None = field(default=None, repr=False)


# --------------------------------------------------------------------------- loading and validation

def _fail(src, key, msg):
    raise SinsError(f"{src}: {key}: {msg}")


def _path(src: Path, key: str, value) -> Path:
    if not isinstance(value, str) or not value:
        _fail(src, key, f"expected a file path, got {value!r}")
    p = Path(value)
    if not p.is_absolute():
        p = src.parent / p
    if not p.exists():
        _fail(src, key, f"file not found: {p}")
    return p


def _name(src, key, value) -> str:
    if not isinstance(value, str) or not _NAME_RE.match(value):
        _fail(src, key, f"expected a name of letters, digits, '.', '_', '+', '-', got {value!r}")
    return value


def default_method_name(nav: dict) -> str:
    """A readable column name from the settings, e.g. ``dcm-seed000-c1`` or ``quat-c2-s4``."""
    parts = [nav["attitude"]]
    if nav["attitude"] == "dcm" and nav["dcm_variant"] != "exact":
        parts.append(nav["dcm_variant"])
    parts.append(f"c{nav['coning']}")
    if nav["subsamples"] > 1:
        parts.append(f"s{nav['subsamples']}")
    if nav["frame"] != "enu":
        parts.append(nav["frame"])
    return "-".join(parts)


def _load_method(src: Path, k: int, item) -> MethodSpec:
    from ..config import DEFAULTS, validate
    where = f"methods[{k}]"
    if not isinstance(item, dict):
        _fail(src, where, "expected a mapping of navigation settings (attitude, coning, subsamples, frame, ...)")
    allowed = set(DEFAULTS["navigation"]) | {"name"}
    for key in item:
        if key not in allowed:
            _fail(src, f"{where}.{key}", f"unknown key; expected one of {', '.join(sorted(allowed))}")
    cfg = copy.deepcopy(DEFAULTS)
    cfg["navigation"].update({key: v for key, v in item.items() if key != "name"})
    try:
        validate(cfg, f"{src}: {where}")
    except SinsError as exc:                      # "navigation.coning" -> "methods[k].coning"
        raise SinsError(str(exc).replace(f"{where}: navigation.", f"{where}.")) from None
    nav = cfg["navigation"]
    name = _name(src, f"{where}.name", item["name"]) if "name" in item else default_method_name(nav)
    return MethodSpec(name=name, navigation=nav)


def _load_dataset(src: Path, k: int, item) -> DatasetSpec:
    where = f"datasets[{k}]"
    if not isinstance(item, dict):
        _fail(src, where, "expected a mapping with 'scenario', or with 'imu', 'truth' and 'init'")
    if "scenario" in item:
        bad = sorted(set(item) - SCENARIO_KEYS)
        if bad:
            _fail(src, f"{where}.{bad[0]}", f"unknown key for a scenario dataset; expected one of "
                  f"{', '.join(sorted(SCENARIO_KEYS))}")
        scen = _path(src, f"{where}.scenario", item["scenario"])
        perfect = item.get("perfect", False)
        if not isinstance(perfect, bool):
            _fail(src, f"{where}.perfect", f"expected true or false, got {perfect!r}")
        name = _name(src, f"{where}.name", item.get("name", scen.stem))
        return DatasetSpec(name=name, scenario=scen, perfect=perfect)
    bad = sorted(set(item) - FILES_KEYS)
    if bad:
        _fail(src, f"{where}.{bad[0]}", f"unknown key; expected 'scenario' or {', '.join(sorted(FILES_KEYS))}")
    for key in ("imu", "truth", "init"):
        if key not in item:
            _fail(src, f"{where}.{key}", "missing (a files dataset needs imu, truth and init; or give 'scenario')")
    paths = {key: _path(src, f"{where}.{key}", item[key]) for key in ("imu", "truth", "init")}
    config = _path(src, f"{where}.config", item["config"]) if item.get("config") is not None else None
    if "name" not in item:
        _fail(src, f"{where}.name", "missing (a files dataset needs a name)")
    return DatasetSpec(name=_name(src, f"{where}.name", item["name"]), config=config, **paths)


def _unique(src, what, names):
    seen = set()
    for k, n in enumerate(names):
        if n in seen:
            _fail(src, f"{what}[{k}].name", f"duplicate name '{n}'")
        seen.add(n)


def load_batch(path) -> BatchSpec:
    """Read and validate a batch YAML; every error names the file and the key."""
    src = Path(path)
    data = load_yaml(src, "batch file")
    if not isinstance(data, dict):
        raise SinsError(f"{src}: expected a mapping with keys datasets, methods (and seeds, title, ...)")
    for key in data:
        if key not in TOP_KEYS:
            _fail(src, key, f"unknown key; expected one of {', '.join(sorted(TOP_KEYS))}")
    for key in ("datasets", "methods"):
        if not isinstance(data.get(key), list) or not data[key]:
            _fail(src, key, "expected a non-empty list")
    datasets = [_load_dataset(src, k, d) for k, d in enumerate(data["datasets"])]
    methods = [_load_method(src, k, m) for k, m in enumerate(data["methods"])]
    _unique(src, "datasets", [d.name for d in datasets])
    _unique(src, "methods", [m.name for m in methods])
    seeds = data.get("seeds")
    if seeds is None:
        seeds = [None]                       # the scenario's own seed
    elif isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            _fail(src, "seeds", f"expected a count >= 1 or a list of seeds, got {seeds!r}")
        seeds = list(range(seeds))
    elif (not isinstance(seeds, list) or not seeds
          or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds)
          or len(set(seeds)) != len(seeds)):
        _fail(src, "seeds", f"expected a count >= 1 or a list of distinct seeds >= 0, got {seeds!r}")
    epoch = data.get("epoch")
    if epoch is not None and (not isinstance(epoch, (int, float)) or isinstance(epoch, bool)):
        _fail(src, "epoch", f"expected a time in seconds or null, got {epoch!r}")
    for key in ("interpolate", "write_trajectories"):
        if not isinstance(data.get(key, False), bool):
            _fail(src, key, f"expected true or false, got {data[key]!r}")
    every = data.get("timeseries_every", 1)
    if not isinstance(every, int) or isinstance(every, bool) or every < 1:
        _fail(src, "timeseries_every", f"expected a whole number >= 1, got {every!r}")
    title = data.get("title", src.stem)
    if not isinstance(title, str):
        _fail(src, "title", f"expected a text, got {title!r}")
    return BatchSpec(source=src, title=title, datasets=datasets, methods=methods, seeds=seeds,
                     epoch=None if epoch is None else float(epoch), interpolate=data.get("interpolate", False),
                     timeseries_every=every, write_trajectories=data.get("write_trajectories", False))


# --------------------------------------------------------------------------- jobs (run in worker processes)

def data_dir(outdir: Path, ds: DatasetSpec, seed: int | None) -> Path:
    """Where a simulated dataset (and optional navigation trajectories) of one seed is written."""
    return Path(outdir) / ds.name / ("data" if seed is None else f"seed{seed}")


def prepare_job(ds: DatasetSpec, seed: int | None, outdir: Path) -> Prepared:
    """Simulate the scenario with ``seed`` (writing its files under ``data_dir``) or read the files."""
    if ds.scenario is not None:
        from ..sim import simulate, write_sim
        result = simulate(ds.scenario, seed=seed, perfect=ds.perfect)
        write_sim(result, data_dir(outdir, ds, seed))
        return Prepared(imu=result.imu, init=result.init, truth=result.truth, conv=int(result.conv),
                        launch=dict(result.launch) or None)
    from ..config import load_config
    from ..io.imu_csv import read_imu_csv
    from ..io.init_state import read_init
    from ..io.trajectory import read_trajectory
    cfg = load_config(ds.config)
    conv = BODY_CODES[cfg["imu"]["body"]]
    imu = read_imu_csv(ds.imu, cfg)
    truth = read_trajectory(ds.truth)
    start = imu.t0 if imu.t0 is not None else float(imu.time[0])
    init = read_init(ds.init, start, conv)
    return Prepared(imu=imu, init=init, truth=truth, conv=conv)


def nav_options(navigation: dict, conv: int, launch: dict | None = None):
    """``NavOptions`` from a validated ``navigation`` config section, the body convention and the
    dataset's launch point (used when the method has no ``launch`` of its own)."""
    import dataclasses

    from ..nav.pipeline import NavOptions
    names = {f.name for f in dataclasses.fields(NavOptions)}
    kwargs = {k: v for k, v in navigation.items() if k in names and v is not None}
    if "conv" in names:
        kwargs["conv"] = conv
    if "launch" in names and kwargs.get("launch") is None and launch:
        kwargs["launch"] = {k: launch[k] for k in ("lat", "lon", "height", "azimuth") if k in launch}
    return NavOptions(**kwargs)


def navigate_job(prep: Prepared, method: MethodSpec, interpolate: bool, traj_path: Path | None):
    """Navigate one method on prepared data; return ``(ErrorSeries, seconds)``."""
    from ..nav.pipeline import navigate
    t0 = time.perf_counter()
    traj = navigate(prep.imu, prep.init, nav_options(method.navigation, prep.conv, prep.launch))
    seconds = time.perf_counter() - t0
    if traj_path is not None:
        from ..io.trajectory import write_trajectory
        write_trajectory(traj_path, traj, prep.conv)
    series = compare_trajectories(prep.truth, traj, conv=prep.conv, interpolate=interpolate,
                                  truth_name=str(getattr(prep.truth, "source", "truth")), nav_name=method.name)
    return series, seconds


def _describe(exc: BaseException) -> str:
    if isinstance(exc, SinsError):
        return str(exc)
    tb = traceback.extract_tb(exc.__traceback__)
    where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
    return " ".join(f"{type(exc).__name__}: {exc}{where}".split())


class _InlineExecutor(cf.Executor):
    """Runs each job at submission, in this process (``--jobs 1``)."""

    def submit(self, fn, /, *args, **kwargs):
        fut = cf.Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - recorded as the job's failure
            fut.set_exception(exc)
        return fut


# --------------------------------------------------------------------------- the runner

@dataclass
class BatchResult:
    jobs: list
    reports: dict            # dataset name -> report directory
    report_errors: dict      # dataset name -> error text (report could not be built)

    @property
    def failed(self) -> list:
        return [j for j in self.jobs if not j.ok]


def count_jobs(spec: BatchSpec) -> int:
    """Progress units: one per data preparation, per navigation, per report."""
    n_prep = sum(len(spec.seeds) if d.scenario is not None else 1 for d in spec.datasets)
    return n_prep * (1 + len(spec.methods)) + len(spec.datasets) + 1


def run_batch(spec: BatchSpec, outdir, jobs: int | None = None, on_progress=None, on_error=None) -> BatchResult:
    """Run every job of ``spec`` in parallel; write the reports and the summary into ``outdir``."""
    outdir = Path(outdir)
    jobs = max(1, int(jobs or os.cpu_count() or 1))
    tick = on_progress or (lambda n: None)
    err = on_error or (lambda msg: None)
    results: list[JobResult] = []
    if jobs == 1:
        executor = _InlineExecutor()
    else:
        executor = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"))
    with executor:
        prep_futs = {}
        for ds in spec.datasets:
            for seed in (spec.seeds if ds.scenario is not None else [None]):
                prep_futs[executor.submit(prepare_job, ds, seed, outdir)] = (ds, seed)
        nav_futs = {}
        for fut in cf.as_completed(prep_futs):
            ds, seed = prep_futs[fut]
            tick(1)
            multi = ds.scenario is not None and len(spec.seeds) > 1
            try:
                prep = fut.result()
            except BaseException as exc:  # noqa: BLE001
                msg = f"data preparation failed: {_describe(exc)}"
                for m in spec.methods:
                    label = f"{m.name}#s{seed}" if multi else m.name
                    results.append(JobResult(ds.name, seed, m.name, label, ok=False, error=msg))
                    err(f"job {ds.name}/{label} failed: {msg}")
                    tick(1)
                continue
            for m in spec.methods:
                label = f"{m.name}#s{seed}" if multi else m.name
                traj_path = (data_dir(outdir, ds, seed) / f"nav_{m.name}.csv") if spec.write_trajectories else None
                nf = executor.submit(navigate_job, prep, m, spec.interpolate, traj_path)
                nav_futs[nf] = JobResult(ds.name, seed, m.name, label)
            del prep
        prep_futs.clear()                    # release the prepared data held by the finished futures
        fut = None
        for fut in cf.as_completed(nav_futs):
            job = nav_futs[fut]
            tick(1)
            try:
                job.series, job.seconds = fut.result()
                job.ok = True
            except BaseException as exc:  # noqa: BLE001
                job.error = _describe(exc)
                err(f"job {job.dataset}/{job.label} failed: {job.error}")
            results.append(job)
    order = {(d.name): i for i, d in enumerate(spec.datasets)}
    morder = {m.name: i for i, m in enumerate(spec.methods)}
    results.sort(key=lambda j: (order[j.dataset], -1 if j.seed is None else j.seed, morder[j.method]))
    reports, report_errors = {}, {}
    for ds in spec.datasets:
        mine = [j for j in results if j.dataset == ds.name]
        try:
            path = write_dataset_report(outdir / ds.name, ds, mine, spec)
            if path is not None:
                reports[ds.name] = path
        except SinsError as exc:
            report_errors[ds.name] = str(exc)
            err(f"report {ds.name} failed: {exc}")
        tick(1)
    result = BatchResult(results, reports, report_errors)
    write_summary(outdir, spec, result)
    tick(1)
    return result


# --------------------------------------------------------------------------- reports

def monte_carlo_table(series_by_job: list[tuple[str, ErrorSeries]], table: ErrorTable) -> ErrorTable:
    """Per method over its seeds: RMS of the rows at the epoch, maximum of the maxima rows."""
    methods = list(dict.fromkeys(m for m, _ in series_by_job))
    cols = []
    for m in methods:
        idx = [k for k, (mm, _) in enumerate(series_by_job) if mm == m]
        v = table.values[:, idx]
        rms = np.sqrt(np.mean(v * v, axis=1))
        mx = np.max(v, axis=1)
        is_max = np.array([r.startswith("max_") for r in table.rows])
        cols.append(np.where(is_max, mx, rms))
    return ErrorTable(epoch=table.epoch, methods=methods, values=np.stack(cols, axis=1))


def write_dataset_report(repdir: Path, ds: DatasetSpec, jobs: list[JobResult], spec: BatchSpec) -> Path | None:
    """One dataset's report (all its successful jobs as columns); None when every job failed."""
    ok = [j for j in jobs if j.ok]
    if not ok:
        return None
    series = {j.label: j.series for j in ok}
    table = build_table(series, spec.epoch)
    what = (f"scenario {ds.scenario.name}" + (" (perfect sensors)" if ds.perfect else "")
            if ds.scenario is not None else f"truth {ds.truth.name}, IMU {ds.imu.name}")
    notes = [f"Dataset {ds.name}: {what}. Batch {spec.source.name}."]
    notes += [f"FAILED {j.label}: {j.error}" for j in jobs if not j.ok]
    title = f"{ds.name}: {spec.title}"
    with staged_dir(repdir) as tmp:
        extra_files, extra_html = [], ""
        if len({j.seed for j in ok}) > 1:
            mc = monte_carlo_table([(j.method, j.series) for j in ok], table)
            write_errors_csv(tmp / "errors_mc.csv", mc)
            write_errors_md(tmp / "errors_mc.md", mc, f"{title}: Monte Carlo over seeds "
                            "(RMS at the epoch, maximum of the maxima)")
            extra_files = ["errors_mc.csv", "errors_mc.md"]
            extra_html = ("<h2>Monte Carlo over seeds (RMS at the epoch, maximum of the maxima)</h2>\n"
                          + error_table_html(mc))
        write_report_files(tmp, series, table, title, spec.timeseries_every, notes, extra_files, extra_html)
    return repdir


SUMMARY_COLUMNS = ["dataset", "seed", "method", "status", "nav_seconds", "max_att_deg",
                   "max_pos_E", "max_pos_N", "max_pos_U", "max_vel_E", "max_vel_N", "max_vel_U", "error"]


def _summary_rows(result: BatchResult) -> list[list]:
    rows = []
    for j in result.jobs:
        if j.ok:
            s = j.series
            mp = np.max(np.abs(s.pos_enu_m), axis=0)
            mv = np.max(np.abs(s.vel_enu_mps), axis=0)
            vals = [float(np.degrees(np.max(s.angle_rad))), *map(float, mp), *map(float, mv)]
        else:
            vals = [None] * 7
        rows.append([j.dataset, "" if j.seed is None else j.seed, j.method, "ok" if j.ok else "failed",
                     round(j.seconds, 3) if j.ok else None, *vals, j.error])
    return rows


def write_summary(outdir: Path, spec: BatchSpec, result: BatchResult) -> None:
    """``summary.csv``, ``summary.md`` and ``index.html`` (links to each dataset's report)."""
    rows = _summary_rows(result)
    with atomic_path(outdir / "summary.csv") as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(SUMMARY_COLUMNS)
        for r in rows:
            w.writerow(["" if v is None else (repr(v) if isinstance(v, float) else v) for v in r])
    n_fail = len(result.failed)
    head = (f"{len(result.jobs)} jobs, {len(result.jobs) - n_fail} succeeded, {n_fail} failed. "
            f"Batch file: {spec.source.name}.")
    md = [f"# {spec.title}", "", head, "",
          "| " + " | ".join(SUMMARY_COLUMNS) + " |", "|" + "---|" * len(SUMMARY_COLUMNS)]
    for r in rows:
        cells = ["" if v is None else (f"{v:.5E}" if isinstance(v, float) and k > 4 else str(v))
                 for k, v in enumerate(r)]
        md.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    for ds, e in result.report_errors.items():
        md += ["", f"Report {ds} could not be written: {e}"]
    tables_md = []
    for ds in spec.datasets:
        if ds.name in result.reports:
            tables_md.append(f"\n## {ds.name}\n\n[report]({ds.name}/index.html)\n")
            tables_md.append((result.reports[ds.name] / "errors.md").read_text(encoding="utf-8"))
    with atomic_path(outdir / "summary.md") as tmp:
        tmp.write_text("\n".join(md) + "\n" + "\n".join(tables_md), encoding="utf-8")
    links = [[(ds.name, f"{ds.name}/index.html") if ds.name in result.reports else ds.name,
              "written" if ds.name in result.reports else f"not written: {result.report_errors.get(ds.name, 'every job failed')}"]
             for ds in spec.datasets]
    jobs_html = simple_table_html(SUMMARY_COLUMNS, rows, failed=[not j.ok for j in result.jobs])
    write_summary_html(outdir / "index.html", spec.title,
                       [("Reports", simple_table_html(["dataset", "report"], links)), ("Jobs", jobs_html)],
                       notes=[head, "Errors are truth minus navigation; maxima over the whole run "
                              "(position m, velocity m/s, attitude error angle deg)."])
