"""``sins align --monte-carlo N``: the alignment Monte Carlo as a batch of seeds on a back end.

One job per seed (:func:`mc_task`): the worker reads the scenario file once
(the path must be reachable from every worker; a different file there is an
error naming the host), builds the exact truth once per process, then
simulates the seed's sensor errors and aligns with every variant.  Only the
run's errors travel back (its series decimated to :data:`SERIES_EPOCHS` epochs
in a large study) and are written to ``DIR/jobs/`` as they arrive; ``--resume``
runs only the missing seeds.  The client then reads the runs in seed order
into :class:`~sinscli.align.montecarlo.McAccumulator`, so the report is the
same whichever back end ran them, and writes:

``summary.csv``, ``summary.md``   end errors per variant: mean, std, rms, static-base theory; and
                                  the reported 1-sigma against the errors of the written states
``sigma.csv``                     that check: rms sigma and error, runs inside 1 and 3 sigma
``runs.csv``                      every run's end errors (current attitude)
``results.parquet``               every run x variant (partitioned by variant as ``method``)
``stats.csv``, ``stats.md``       mean, std, rms, percentiles, extremes of the end errors per variant
``mc_stats.png``                  their box plots
``mc_roll.png`` ...               seed 001 Figs. 1-3: each run's error against time (N <= 20 or
                                  ``--figures all``), else the first 20 runs and every run's mean +- 1 sigma
``timing.csv``, ``index.html``
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from .. import __version__
from ..align import montecarlo as mcmod
from ..errors import SinsError
from ..evaluate.stats import row_statistics
from ..io.atomic import atomic_path
from ..io.csvcore import write_table_csv
from ..report.align_figures import ANGLES as ANG
from ..report.align_figures import plot_monte_carlo, robust_range
from ..report.compare_page import add_box_plots, files_section
from ..report.figures import envelope
from ..report.stats_render import (
    plot_boxes,
    stats_html,
    write_stats_csv,
    write_stats_md,
)
from ..report.webpage import Page, table
from .compare_job import describe
from .exec import where
from .jobs import JobStore, file_digest, run_study
from .results import ResultsWriter

PER_RUN_MAX = 20          # runs drawn one by one (and series kept whole) up to this count
SERIES_EPOCHS = 100       # epochs of each run's series kept in a larger study
ANGLES = ("roll", "pitch", "heading")
END_QUANTITIES = [f"{w}_{a}" for w in ("current", "start") for a in ANGLES]
RUN_ARRAYS = ("time", "current", "start", "end_current", "end_start", "start_at_window", "state", "sigma",
              "sigma_floor", "state_time")       # the RunErrors fields a job file holds
SIGMA_COLUMNS = ["variant", "angle", "runs", "sigma_rms_deg", "error_rms_deg", "inside_1sigma", "inside_3sigma",
                 "floor_rms_deg"]

_RUNS: dict = {}          # per worker process: (path, digest) -> ScenarioRuns


def mc_key(seed: int) -> tuple:
    """``jobs/<seed // 1000>k/seed<N>.npz``: a thousand files a folder."""
    return (f"{seed // 1000:03d}k", f"seed{seed}")


def _runs_for(plan, digest: str):
    key = (plan.path, digest)
    if key not in _RUNS:
        p = Path(plan.path)
        if not p.is_file():
            raise SinsError(f"{p}: not found on {where()}; the scenario must be on a filesystem that every "
                            "worker sees (docs/align.md)")
        if file_digest(p) != digest:
            raise SinsError(f"{p}: on {where()} it differs from the client's copy")
        _RUNS.clear()
        _RUNS[key] = mcmod.scenario_runs(plan)
    return _RUNS[key]


def mc_task(plan, digest: str, seed: int, max_epochs: int | None) -> list[tuple]:
    """One job on a worker: the seed's run with every variant, as ``[(key, meta, arrays)]``."""
    meta = {"seed": seed, "host": where()}
    t0 = time.perf_counter()
    try:
        errs = mcmod.run_seed(plan, _runs_for(plan, digest), seed, max_epochs)
    except Exception as exc:  # noqa: BLE001 - the run's failure, reported
        return [(mc_key(seed), dict(meta, ok=False, error=describe(exc)), {})]
    arrays = {}
    for name, e in errs.items():
        for attr in RUN_ARRAYS:
            v = getattr(e, attr)
            if v is not None:
                arrays[f"{name}:{attr}"] = v
    return [(mc_key(seed), dict(meta, ok=True, error="", seconds=time.perf_counter() - t0), arrays)]


def _run_errors(plan, arrays) -> dict:
    return {name: mcmod.RunErrors(**{a: arrays.get(f"{name}:{a}") for a in RUN_ARRAYS}) for name, _ in plan.variants}


@dataclass
class McStudy:
    mc: object                          # McResult of the runs that finished
    failed: dict = field(default_factory=dict)     # seed -> error
    files: list = field(default_factory=list)
    resumed: int = 0
    ran: int = 0


def run_mc_study(path, outdir, runs: int | None = None, seed0: int | None = None, *, jobs: int | None = None,
                 scheduler: str | None = None, resume: bool = False, figures: str = "auto", on_progress=None,
                 on_error=None, on_info=None, verbose: bool = False) -> McStudy:
    """Run the Monte Carlo of an alignment scenario on a back end and write its report into ``outdir``."""
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise SinsError(f"{outdir}: exists and is not a directory (--monte-carlo writes a directory)")
    plan = mcmod.plan_monte_carlo(path, runs, seed0)
    digest = file_digest(plan.path)
    per_run = figures == "all" or plan.runs <= PER_RUN_MAX
    max_epochs = None if per_run else SERIES_EPOCHS
    store = JobStore(outdir, {"kind": "sins align --monte-carlo", "sinscli": __version__, "scenario": digest,
                              "seeds": [plan.seeds[0], plan.runs], "per_run": per_run}, resume)
    tick = on_progress or (lambda n: None)
    err = on_error or (lambda msg: None)
    failed: dict = {}

    def on_job(key, meta):
        if not meta.get("ok"):
            failed[meta["seed"]] = meta.get("error", "")
            err(f"run seed {meta['seed']} failed: {failed[meta['seed']]}")
        tick(1)

    def tasks(backend):
        todo = [s for s in plan.seeds if not store.done(mc_key(s))]
        if not todo:
            return
        shared = backend.share(dataclasses.replace(plan, seeds=[]))      # sent once; a worker needs no seed list
        for s in todo:
            yield (("mc", s), mc_task, (shared, digest, s, max_epochs), [(mc_key(s), {"seed": s})])

    def finish(stage, counts):
        study = write_mc_report(stage, plan, store, failed, None if per_run else PER_RUN_MAX)
        study.resumed, study.ran = counts.resumed, counts.ran
        return study

    study, _ = run_study(outdir, store, [mc_key(s) for s in plan.seeds], tasks, finish, describe, jobs=jobs,
                         scheduler=scheduler, on_job=on_job, on_resumed=tick, on_info=on_info, verbose=verbose)
    return study


def _csv(path, lines: list[str]) -> None:
    with atomic_path(path, suffix=".csv") as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n")


def _cell(v) -> str:
    return "" if v is None else (v if isinstance(v, str) else repr(v))


def _end_frame(mc) -> pd.DataFrame:
    """One row per run and variant (variant by variant, runs in seed order): the end errors."""
    parts = []
    for name, v in mc.variants.items():
        cols = {"variant": name, "seed": mc.seeds}
        for w, end in (("current", v.end_current), ("start", v.end_start)):
            for i, a in enumerate(ANGLES):
                cols[f"{w}_{a}"] = np.full(mc.runs, np.nan) if end is None else end[:, i]
        parts.append(pd.DataFrame(cols))
    return pd.concat(parts, ignore_index=True)


def write_mc_report(outdir: Path, plan, store: JobStore, failed: dict, keep: int | None) -> McStudy:
    """Every file of the study from the finished runs under ``store`` (read in seed order)."""

    acc = mcmod.McAccumulator(plan, keep)
    timing = []
    schema = pa.schema([("seed", pa.int64()), ("status", pa.string()), ("error", pa.string()),
                        ("seconds", pa.float64()), ("host", pa.string())]
                       + [(q, pa.float64()) for q in END_QUANTITIES + [f"{w}_{a}" for w in ("start_at_window", "state",
                                                                                              "sigma") for a in ANGLES]])
    with ResultsWriter(outdir / "results.parquet", schema) as parquet:
        for s in plan.seeds:
            if s in failed or not store.done(mc_key(s)):
                timing.append([s, "failed", None, ""])
                for name, _ in plan.variants:
                    parquet.add({"method": name, "seed": s, "status": "failed", "error": failed.get(s, "not run")})
                continue
            meta, arrays = store.read(mc_key(s))
            errs = _run_errors(plan, arrays)
            acc.add(s, errs)
            timing.append([s, "ok", round(float(meta["seconds"]), 4), meta["host"]])
            for name, e in errs.items():
                row = {"method": name, "seed": s}
                for w, end in (("current", e.end_current), ("start", e.end_start)):
                    for i, a in enumerate(ANGLES):
                        row[f"{w}_{a}"] = None if end is None else float(end[i])
                for w in ("start_at_window", "state", "sigma"):
                    v = getattr(e, w)
                    row.update({f"{w}_{a}": None if v is None or not np.isfinite(v[i]) else float(v[i])
                                for i, a in enumerate(ANGLES)})
                parquet.add({**row, "status": "ok", "error": "", "seconds": float(meta["seconds"]),
                             "host": meta["host"]})
    if not acc.seeds:
        raise SinsError(f"every run failed (seed {plan.seeds[0]}: {failed.get(plan.seeds[0], 'not run')})")
    mc = acc.result()
    files = ["summary.csv", "summary.md", "sigma.csv", "runs.csv", "stats.csv", "stats.md", "timing.csv",
             "results.parquet"]
    summary = mc.summary_rows()
    cols = ["variant", "attitude", "angle", "mean_deg", "std_deg", "rms_deg", "theory_deg"]
    _csv(outdir / "summary.csv", [",".join(cols)] + [",".join(_cell(r[c]) for c in cols) for r in summary])
    md = [f"# Monte Carlo: {mc.scenario}, {mc.runs} runs (seeds {mc.seeds[0]}..{mc.seeds[-1]})", "",
          "Errors at the end of the interval, degrees (estimate minus truth); theory: static-base 1-sigma.", "",
          "| variant | attitude | angle | mean | std | rms | theory |", "|---|---|---|---|---|---|---|"]
    for r in summary:
        th = "" if r["theory_deg"] is None else f"{r['theory_deg']:.3g}"
        md.append(f"| {r['variant']} | {r['attitude']} | {r['angle']} | {r['mean_deg']:.3g} | {r['std_deg']:.3g} | "
                  f"{r['rms_deg']:.3g} | {th} |")
    if mc.roll_window is not None:
        base = next(iter(mc.variants))
        for name in (base, f"{base}+roll-window"):
            if name in mc.variants and mc.variants[name].start_at_window is not None:
                md.append("")
                md.append(f"{name}: rms change of the start-attitude roll error from {mc.roll_window:g} s to the end: "
                          f"{mc.drift(name, mc.roll_window):.3g} deg")
    sigma_rows = mc.sigma_rows()
    _csv(outdir / "sigma.csv", [",".join(SIGMA_COLUMNS)] + [",".join(_cell(r[c]) for c in SIGMA_COLUMNS)
                                                            for r in sigma_rows])
    if sigma_rows:
        md += ["", "The 1-sigma each run reports for the state it writes, against that state's error (degrees; "
               "an honest Gaussian claim has 0.683 of the runs inside 1 sigma and 0.9973 inside 3 sigma):", "",
               "| variant | angle | rms sigma | rms error | inside 1 sigma | inside 3 sigma | noise floor |",
               "|---|---|---|---|---|---|---|"]
        md += [f"| {r['variant']} | {r['angle']} | {r['sigma_rms_deg']:.3g} | {r['error_rms_deg']:.3g} | "
               f"{r['inside_1sigma']:.3f} | {r['inside_3sigma']:.3f} | {r['floor_rms_deg']:.3g} |" for r in sigma_rows]
    if failed:
        md += ["", f"{len(failed)} run(s) failed and are left out:"] + [f"- seed {s}: {e}" for s, e in
                                                                        sorted(failed.items())]
    with atomic_path(outdir / "summary.md", suffix=".md") as tmp:
        Path(tmp).write_text("\n".join(md) + "\n")
    data = {"seed": np.array(mc.seeds, dtype=float)}
    for name, v in mc.variants.items():
        for i, ang in enumerate(ANGLES):
            data[f"{name}:{ang}"] = v.end_current[:, i]
    with atomic_path(outdir / "runs.csv", suffix=".csv") as tmp:
        write_table_csv(tmp, data)
    _csv(outdir / "timing.csv", ["seed,status,seconds,host"] + [",".join(_cell(v) for v in r) for r in timing])
    frame = _end_frame(mc)
    quantities = [q for q in END_QUANTITIES if frame[q].notna().any()]
    units = {q: "deg" for q in quantities}
    labels = {q: f"{q.split('_')[1]} error, {q.split('_')[0]} attitude" for q in quantities}
    stats = row_statistics(frame, "variant", quantities, units)
    write_stats_csv(outdir / "stats.csv", stats)
    title = f"Monte Carlo {mc.scenario}: end errors over {mc.runs} runs"
    write_stats_md(outdir / "stats.md", stats, "variant", title, labels)
    plot_boxes(outdir / "mc_stats.png", frame, "variant", quantities, units, title, labels)
    figs = ["mc_stats.png"] + [Path(p).name for p in plot_monte_carlo(outdir, mc)]
    notes = [f"{mc.runs} runs of {Path(plan.path).name} (seeds {mc.seeds[0]}..{mc.seeds[-1]})"
             + (f"; {len(failed)} failed (summary.md)" if failed else "") + "."]
    mc_page(mc, summary, cols, sigma_rows, stats, labels, units, quantities, notes, files, figs).write(
        outdir / "index.html")
    return McStudy(mc=mc, failed=failed, files=files + figs + ["index.html"])


MC_LINE_BINS = 300         # min/max bins per run line on the page


def mc_page(mc, summary, cols, sigma_rows, stats, labels, units, quantities, notes, files, figs):
    """The study's interactive, self-contained ``index.html``: summary in words, each run's error against
    time (seed 001 Figs. 1-3) with a robust y-range, box plots of the end errors, the tables."""
    page = Page(f"Alignment Monte Carlo: {mc.scenario}, {mc.runs} runs")
    lines = [f"{mc.runs} seeded runs of scenario {mc.scenario} (seeds {mc.seeds[0]}..{mc.seeds[-1]}), "
             f"variants: {', '.join(mc.variants)}. Errors are estimate minus truth, in degrees."]
    for r in summary:
        if r["attitude"] != "current":
            continue
        th = "" if r["theory_deg"] is None else f" (static-base theory {r['theory_deg']:.3g} deg)"
        lines.append(f"{r['variant']}: {r['angle']} error at the end RMS {r['rms_deg']:.3g} deg, "
                     f"mean {r['mean_deg']:.3g} deg{th}.")
    for r in sigma_rows:
        lines.append(f"{r['variant']}, {r['angle']}: {r['inside_1sigma']:.3f} of the runs inside the reported "
                     f"1 sigma and {r['inside_3sigma']:.4f} inside 3 sigma (0.683 and 0.9973 when honest).")
    page.h("Summary")
    page.items(lines)
    for n in notes:
        page.p(n, "note")
    page.h("Errors against alignment time (seed 001 Figs. 1-3)")
    page.p("Each run's error; a start-up transient is outside the initial y-range (zoom in to see it); "
           "dashed: the static-base 1-sigma limit.", "note")
    for i, ang in enumerate(ANG):
        for name, v in mc.variants.items():
            for which, label in (("current", "current attitude Cbn(t)"), ("start", "start attitude Cbn(0)")):
                arr = getattr(v, which)
                if arr is None:
                    continue
                series = []
                band = v.band.get(which) if v.band else None
                if band is not None:
                    series.append({"name": f"mean +- 1 sigma of all {mc.runs} runs", "style": "band",
                                   "x": v.time, "lo": band[0][:, i] - band[1][:, i],
                                   "hi": band[0][:, i] + band[1][:, i], "color": "#888", "opacity": 0.3})
                for k, run in enumerate(arr):
                    t, y = envelope(v.time, run[:, i], MC_LINE_BINS)
                    series.append({"name": f"run {k + 1}", "x": t, "y": y, "ci": k, "nolegend": True, "width": 0.8})
                lim = mc.theory.get(name)
                keep = []
                if lim is not None:
                    s_ = lim["heading" if i == 2 else "tilt"]
                    keep = [-s_, s_]
                    for sign in (1, -1):
                        series.append({"name": "static-base 1-sigma limit", "x": [v.time[0], v.time[-1]],
                                       "y": [sign * s_, sign * s_], "color": "#000", "dash": "5 4",
                                       "nolegend": sign < 0})
                yr = robust_range(v.time, [arr[:, :, i]], keep)
                page.plot({"id": f"mc-{ang}-{name}-{which}", "kind": "line", "group": "time",
                           "title": f"{ang.capitalize()} error, {name}: {label} ({arr.shape[0]} of {mc.runs} runs)",
                           "xlabel": "alignment time (s)", "ylabel": f"{ang} error (deg)", "series": series,
                           "robust": list(yr) if yr is not None else None})
    page.h("End errors over the runs")
    page.p("Box: 25th to 75th percentile; line: median; whiskers: 5th to 95th percentile; points: minimum and "
           "maximum.", "note")
    add_box_plots(page, stats, "variant", quantities, labels, units, "box")
    page.h("End errors (deg) against the static-base theory")
    page.raw(table(cols, [[r[c] for c in cols] for r in summary], sortable=True, num_format="{:.4g}"))
    if sigma_rows:
        page.h("The reported 1-sigma against the errors (deg)")
        page.raw(table(SIGMA_COLUMNS, [[r[c] for c in SIGMA_COLUMNS] for r in sigma_rows], sortable=True,
                       num_format="{:.4g}"))
    page.h("Statistics over the runs")
    page.raw(stats_html(stats, "variant", labels))
    files_section(page, files, figs)
    return page
