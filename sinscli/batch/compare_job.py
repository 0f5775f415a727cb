"""The worker side of a compare batch: simulate or read one (dataset, seed), navigate methods on it,
and return each method's small result.

Runs in a pool or Dask worker process, and never writes into the report
directory (except a trajectory with ``write_trajectories``, beside the job's
result under ``DIR/jobs/``).  A task carries specs and paths, not data:
scenarios are simulated here from their seed, datasets are read here from
their paths, which must be reachable from every worker (a shared filesystem);
one that is not is that job's error, naming the path and the host.
"""
from __future__ import annotations

import dataclasses
import os
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import load_config
from ..errors import SinsError
from ..evaluate.errors import compare_trajectories
from ..io.atomic import is_fault, os_errno, target_of
from ..io.imu_csv import read_imu_csv
from ..io.init_state import read_init
from ..io.trajectory import read_trajectory, write_trajectory
from ..nav.pipeline import NavOptions, navigate
from ..report.compare_page import gnss_overlay
from ..report.digest import digest, tail_table
from ..sim import simulate
from .exec import where

BODY_CODES = {"flu": 0, "rfu": 1, "frd": 2}


@dataclass
class Prepared:
    """The data of one (dataset, seed): IMU, initial state, truth, body convention code."""
    imu: object
    init: object
    truth: object
    conv: int
    launch: dict | None = None     # launch point of a simulated flight (for frame: launch-inertial)
    gnss: object = None            # the simulated GNSS fixes (GnssLog), drawn in the report's plan view


@dataclass
class JobOptions:
    """What every job of a batch needs besides its dataset, seed and method."""
    interpolate: bool = False
    epoch: float | None = None
    timeseries_every: int = 1
    per_run: bool = True            # also return the figure envelopes and timeseries.csv rows


def describe(exc: BaseException) -> str:
    """One line for a job's failure: the SinsError text, else the exception and where it was raised."""
    if isinstance(exc, SinsError):
        return str(exc)
    if is_fault(exc):            # the file system (a full disk): the file and the reason, not a source line
        name = f"{target_of(Path(exc.filename))}: " if getattr(exc, "filename", None) else ""
        return f"{name}{os.strerror(os_errno(exc))}"
    tb = traceback.extract_tb(exc.__traceback__)
    where_ = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
    return " ".join(f"{type(exc).__name__}: {exc}{where_}".split())


def _visible(path: Path) -> Path:
    if not Path(path).is_file():
        raise SinsError(f"{path}: not found on {where()}; the batch's input files must be on a "
                        "filesystem that every worker sees (docs/compare.md)")
    return path


def prepare_data(ds, seed: int | None) -> Prepared:
    """Simulate the scenario with ``seed``, or read the dataset's files (on this worker)."""
    if ds.scenario is not None:
        result = simulate(_visible(ds.scenario), seed=seed, perfect=ds.perfect)
        return Prepared(imu=result.imu, init=result.init, truth=result.truth, conv=int(result.conv),
                        launch=dict(result.launch) or None, gnss=result.gnss)
    for p in (ds.imu, ds.truth, ds.init, ds.config):
        if p is not None:
            _visible(p)
    cfg = load_config(ds.config)
    conv = BODY_CODES[cfg["imu"]["body"]]
    imu = read_imu_csv(ds.imu, cfg)
    truth = read_trajectory(ds.truth)
    start = imu.t0 if imu.t0 is not None else float(imu.time[0])
    init = read_init(ds.init, start, conv)
    return Prepared(imu=imu, init=init, truth=truth, conv=conv)


def gnss_arrays(gnss, truth) -> dict[str, np.ndarray]:
    """A run's GNSS fixes for the plan view (``gnss.time``, ``gnss.east``, ``gnss.north``: local ENU at the
    truth's first point; see :func:`sinscli.report.compare_page.gnss_overlay`)."""
    g = gnss_overlay(gnss, truth, "")
    return {"gnss.time": g.time, "gnss.east": g.east, "gnss.north": g.north}


def nav_options(navigation: dict, conv: int, launch: dict | None = None):
    """``NavOptions`` from a validated ``navigation`` config section, the body convention and the
    dataset's launch point (used when the method has no ``launch`` of its own)."""

    names = {f.name for f in dataclasses.fields(NavOptions)}
    kwargs = {k: v for k, v in navigation.items() if k in names and v is not None}
    if "conv" in names:
        kwargs["conv"] = conv
    if "launch" in names and kwargs.get("launch") is None and launch:
        kwargs["launch"] = {k: launch[k] for k in ("lat", "lon", "height", "azimuth") if k in launch}
    return NavOptions(**kwargs)


def navigate_job(prep: Prepared, method, interpolate: bool, traj_path: Path | None):
    """Navigate one method on prepared data; return ``(ErrorSeries, seconds)``."""
    t0 = time.perf_counter()
    traj = navigate(prep.imu, prep.init, nav_options(method.navigation, prep.conv, prep.launch))
    seconds = time.perf_counter() - t0
    if traj_path is not None:
        write_trajectory(traj_path, traj, prep.conv)
    series = compare_trajectories(prep.truth, traj, conv=prep.conv, interpolate=interpolate,
                                  truth_name=str(getattr(prep.truth, "source", "truth")), nav_name=method.name)
    return series, seconds


def run_group(ds, seed: int | None, jobs: list[tuple], opts: JobOptions) -> list[tuple]:
    """One task: prepare ``(ds, seed)`` once and run each of ``jobs`` (``(key, meta, method,
    trajectory path or None)``) on it.  Returns ``(key, meta, arrays)`` per job; a failure is
    ``meta['ok'] = False`` with its ``error``, the others still run."""
    host = where()
    t0 = time.perf_counter()
    try:
        prep = prepare_data(ds, seed)
    except Exception as exc:  # noqa: BLE001 - every job of the group fails with it
        msg = f"data preparation failed: {describe(exc)}"
        return [(key, dict(meta, ok=False, error=msg, host=host), {}) for key, meta, _, _ in jobs]
    share = (time.perf_counter() - t0) / len(jobs)          # the preparation, shared by the group's jobs
    out = []
    for key, meta, method, traj_path in jobs:
        t1 = time.perf_counter()
        try:
            series, seconds = navigate_job(prep, method, opts.interpolate, traj_path)
            tail = tail_table(series, opts.epoch)
            arrays = {"tail.time": tail.time, "tail.columns": tail.columns, "tail.last": np.array(tail.last)}
            if opts.per_run:
                arrays.update(digest(series, opts.timeseries_every).arrays())
                if prep.gnss is not None and len(prep.gnss.time):
                    arrays.update(gnss_arrays(prep.gnss, prep.truth))
            out.append((key, dict(meta, ok=True, error="", seconds=seconds, host=host,
                                  worker_seconds=share + time.perf_counter() - t1), arrays))
        except Exception as exc:  # noqa: BLE001
            out.append((key, dict(meta, ok=False, error=describe(exc), host=host), {}))
    return out
