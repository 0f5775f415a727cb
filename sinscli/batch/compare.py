"""Batch comparisons: datasets x methods x Monte Carlo seeds, run in parallel, reported together.

A batch YAML (see ``configs/batch/*.yaml`` and docs/compare.md) names

- ``datasets``: a scenario to simulate (``scenario``, ``perfect``) or existing
  files (``imu``, ``truth``, ``init``, optional ``config``);
- ``methods``: navigation settings (the keys of the ``navigation`` section of
  the navigation config: ``attitude``, ``coning``, ``subsamples``, ``frame``,
  ``dcm_variant``, ...), each with a ``name`` (the report column);
- ``seeds``: Monte Carlo seeds of the simulated sensor errors (a count or a list).

:func:`load_batch` validates the file and names the offending key.
:func:`run_batch` runs the jobs (one per dataset, seed and method) on a back
end of :mod:`.exec` (local pool, or Dask distributed): each task simulates or
reads one (dataset, seed) on its worker and navigates some of its methods
(:mod:`.batch_job`); each finished job's small result is written to
``DIR/jobs/`` (:mod:`.jobs`) as it arrives, so ``--resume`` runs only the
rest; the reports are then assembled from those files (:mod:`.batch_report`).
A failing job is recorded with its error; the other jobs and reports are
still written.  Interrupted (SIGINT, SIGTERM, SIGHUP), the batch stops its
workers at once and leaves only the finished jobs' files.
"""
from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass
from pathlib import Path

from .. import __version__
from ..config import DEFAULTS, validate
from ..errors import SinsError
from ..inputs import load_yaml
from .compare_job import JobOptions, describe, run_group
from .compare_report import PER_RUN_MAX, BatchResult, JobRef, write_batch_reports
from .jobs import JobStore, file_digest, file_stamp, run_study

TOP_KEYS = {"title", "datasets", "methods", "seeds", "epoch", "interpolate", "timeseries_every",
            "write_trajectories"}
SCENARIO_KEYS = {"name", "scenario", "perfect"}
FILES_KEYS = {"name", "imu", "truth", "init", "config"}
RESERVED_NAMES = {"jobs", "results.parquet", "index.html", "summary.csv", "summary.md"}
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")
FIGURES = ("auto", "all")


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
    for k, d in enumerate(datasets):
        if d.name in RESERVED_NAMES:
            _fail(src, f"datasets[{k}].name", f"'{d.name}' is taken by a file of the batch's output; choose another")
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


# --------------------------------------------------------------------------- the runner

def seed_tag(seed: int | None) -> str:
    """The file stem of a job's result: ``seed<N>``, or ``data`` for a files dataset."""
    return "data" if seed is None else f"seed{seed}"


def job_refs(spec: BatchSpec) -> list[JobRef]:
    """Every job in report order: datasets in file order, seeds ascending, methods in file order."""
    refs = []
    for ds in spec.datasets:
        seeds = spec.seeds if ds.scenario is not None else [None]
        multi = ds.scenario is not None and len(spec.seeds) > 1
        for seed in sorted(seeds, key=lambda s: -1 if s is None else s):
            for m in spec.methods:
                label = f"{m.name}#s{seed}" if multi else m.name
                refs.append(JobRef((ds.name, m.name, seed_tag(seed)), ds.name, seed, m.name, label))
    return refs


def count_jobs(spec: BatchSpec) -> int:
    """Progress units: one per job, per dataset report, and the summary."""
    return len(job_refs(spec)) + len(spec.datasets) + 1


def per_run_reports(spec: BatchSpec, figures: str = "auto") -> dict[str, bool]:
    """Per dataset: a column and figure lines per run (True), or the statistical report."""
    return {ds.name: figures == "all" or ds.scenario is None or len(spec.seeds) <= PER_RUN_MAX
            for ds in spec.datasets}


def fingerprint(spec: BatchSpec, figures: str = "auto") -> dict:
    """What makes two runs' job results interchangeable (checked by ``--resume``)."""
    return {"kind": "sins compare batch", "sinscli": __version__, "batch": file_digest(spec.source),
            "scenarios": {d.name: file_digest(d.scenario) for d in spec.datasets if d.scenario is not None},
            "files": {d.name: [file_stamp(p) for p in (d.imu, d.truth, d.init, d.config) if p is not None]
                      for d in spec.datasets if d.scenario is None},
            "per_run": per_run_reports(spec, figures)}


def _tasks(spec: BatchSpec, refs: list[JobRef], store: JobStore, capacity: int, per_run: dict):
    """Tasks: one per (dataset, seed) with its unfinished methods, split into chunks (each
    simulating the data again) only when there are fewer (dataset, seed) groups than workers."""
    by_name = {d.name: d for d in spec.datasets}
    methods = {m.name: m for m in spec.methods}
    groups: dict = {}
    for r in refs:
        if not store.done(r.key):
            groups.setdefault((r.dataset, r.seed), []).append(r)
    if not groups:
        return []
    chunks = max(1, math.ceil(capacity / len(groups)))
    tasks = []
    for (dname, seed), todo in groups.items():
        k = min(chunks, len(todo))
        opts = JobOptions(spec.interpolate, spec.epoch, spec.timeseries_every, per_run[dname])
        for c in range(k):
            part = todo[c::k]
            jobs = [(r.key, {"dataset": r.dataset, "seed": r.seed, "method": r.method, "label": r.label},
                     methods[r.method], store.sidecar(r.key, ".nav.csv") if spec.write_trajectories else None)
                    for r in part]
            tasks.append(((dname, seed_tag(seed), c), run_group, (by_name[dname], seed, jobs, opts),
                          [(key, meta) for key, meta, _, _ in jobs]))
    return tasks


def run_batch(spec: BatchSpec, outdir, jobs: int | None = None, on_progress=None, on_error=None, *,
              scheduler: str | None = None, resume: bool = False, figures: str = "auto", on_info=None,
              verbose: bool = False, backend=None) -> BatchResult:
    """Run every job of ``spec`` on the chosen back end; write the reports and the summary into ``outdir``.

    Raises :class:`~sinscli.batch.jobs.StudyInterrupted` on SIGINT, SIGTERM or SIGHUP, after
    stopping the workers and removing everything the run wrote but the finished jobs' results.
    """
    if figures not in FIGURES:
        raise SinsError(f"--figures: expected one of {', '.join(FIGURES)}, got {figures!r}")
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise SinsError(f"{outdir}: exists and is not a directory (a batch writes a report directory)")
    tick = on_progress or (lambda n: None)
    err = on_error or (lambda msg: None)
    refs = job_refs(spec)
    per_run = per_run_reports(spec, figures)
    store = JobStore(outdir, fingerprint(spec, figures), resume)
    failed: dict = {}

    def on_job(key, meta):
        if not meta.get("ok"):
            failed[key] = meta.get("error", "")
            err(f"job {meta['dataset']}/{meta['label']} failed: {failed[key]}")
        tick(1)

    def finish(stage, counts):
        result = write_batch_reports(stage, spec, refs, store, failed, figures, tick, err)
        result.reports = {k: outdir / k for k in result.reports}
        result.resumed, result.ran = counts.resumed, counts.ran
        return result

    result, _ = run_study(outdir, store, [r.key for r in refs],
                          lambda backend: _tasks(spec, refs, store, backend.capacity, per_run), finish, describe,
                          jobs=jobs, scheduler=scheduler, on_job=on_job, on_resumed=tick, on_info=on_info,
                          verbose=verbose, backend=backend)
    return result
