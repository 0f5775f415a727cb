"""The client side of a compare batch: the reports, assembled from the finished jobs under ``DIR/jobs/``.

Everything here reads the job files in job order (dataset, seed, method), so
the files written are the same whichever back end ran the jobs, in whatever
order they finished, and whether the batch ran at once or was resumed.

Per dataset:

- per-run report (N seeds <= :data:`PER_RUN_MAX` or ``--figures all``): the
  error table with one column per run, ``timeseries.csv`` and the figures,
  as ``sins compare`` draws them;
- statistical report (more seeds): per method, the mean, standard deviation,
  RMS, percentiles and extremes of every table row over the runs
  (``errors_stats.csv``/``.md``) with box plots (``stats_*.png``); never a
  figure per run.

And for the batch: ``results.parquet`` (every run, partitioned by method),
``summary.csv`` (every job), ``summary.md`` and ``index.html``.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from ..errors import SinsError
from ..evaluate.errors import ROW_UNITS, ROWS, ErrorTable
from ..evaluate.stats import pivot, row_statistics
from ..io.atomic import atomic_path
from ..report.compare_page import (
    add_box_plots,
    compare_page,
    error_table,
    files_section,
    overlay_from_arrays,
)
from ..report.digest import SeriesDigest, TailTable, table_from_tails
from ..report.report import write_report_files
from ..report.stats_render import (
    plot_boxes,
    stats_html,
    write_stats_csv,
    write_stats_md,
)
from ..report.tables import ROW_LABELS, write_errors_csv, write_errors_md
from ..report.webpage import Page, table
from .results import ResultsWriter

PER_RUN_MAX = 20          # seeds up to which a dataset's report has a column and figure lines per run
SUMMARY_ROWS = 500        # jobs listed one by one in summary.md / index.html (all are in summary.csv)
MAX_ROWS = [r for r in ROWS if r.startswith("max_")]
BOX_FIGURES = [           # (file, quantities, title)
    ("stats_position.png", ["pos_E", "pos_N", "pos_U", "max_pos_E", "max_pos_N", "max_pos_U"], "Position error"),
    ("stats_velocity.png", ["vel_E", "vel_N", "vel_U", "max_vel_E", "max_vel_N", "max_vel_U"], "Velocity error"),
    ("stats_attitude.png", [f"C{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)] + ["max_att_deg"],
     "Attitude: DCM element errors and the maximum error angle"),
]
_LABELS = {k: v.replace("\\|", "|") for k, v in ROW_LABELS.items()}


@dataclass
class JobRef:
    """One job of the batch: (dataset, seed, method) and where its result lives."""
    key: tuple
    dataset: str
    seed: int | None
    method: str
    label: str


@dataclass
class JobResult:
    dataset: str
    seed: int | None
    method: str
    label: str
    ok: bool = False
    error: str = ""
    seconds: float = 0.0
    worker_seconds: float = 0.0        # the job's time on its worker, its share of the data preparation included
    host: str = ""
    maxima: np.ndarray | None = field(default=None, repr=False)     # rows 16-22


@dataclass
class BatchResult:
    jobs: list
    reports: dict            # dataset name -> report directory
    report_errors: dict      # dataset name -> error text (report could not be built)
    resumed: int = 0
    ran: int = 0
    job_pages: dict = field(default_factory=dict)    # (dataset, seed, method) -> page path relative to the batch

    @property
    def failed(self) -> list:
        return [j for j in self.jobs if not j.ok]


def mc_table(stats: pd.DataFrame, epoch: float) -> ErrorTable:
    """Seed 000's table over the seeds: per method the RMS of rows 1-15, the maximum of rows 16-22."""
    rms, mx = pivot(stats, "method", "rms"), pivot(stats, "method", "max")
    values = np.where(np.array([r in MAX_ROWS for r in ROWS])[:, None], mx.loc[ROWS].to_numpy(),
                      rms.loc[ROWS].to_numpy())
    return ErrorTable(epoch=epoch, methods=list(rms.columns), values=values)


def results_schema() -> pa.Schema:
    """``results.parquet`` columns (``method`` is the partition)."""
    return pa.schema([("dataset", pa.string()), ("seed", pa.int64()), ("label", pa.string()),
                      ("status", pa.string()), ("error", pa.string()), ("nav_seconds", pa.float64()),
                      ("worker_seconds", pa.float64()), ("host", pa.string()), ("epoch", pa.float64())]
                     + [(r, pa.float64()) for r in ROWS])


BOX_QUANTITIES = ["pos_E", "pos_N", "pos_U", *MAX_ROWS]     # the interactive box plots of a dataset page


def _stats_section(stage_ds: Path, frame: pd.DataFrame, title: str, epoch: float):
    """``errors_stats.*``, ``errors_mc.*`` and the box plots; returns (files, a function adding the
    section to a :class:`~.webpage.Page`)."""
    stats = row_statistics(frame, "method", ROWS, ROW_UNITS)
    write_stats_csv(stage_ds / "errors_stats.csv", stats)
    n = int(frame.groupby("method", sort=False).size().max())
    head = f"{title}: statistics over {n} seeds of each table row (epoch t = {epoch!r} s; maxima over each run)"
    write_stats_md(stage_ds / "errors_stats.md", stats, "method", head, _LABELS)
    mc = mc_table(stats, epoch)
    write_errors_csv(stage_ds / "errors_mc.csv", mc)
    write_errors_md(stage_ds / "errors_mc.md", mc, f"{title}: Monte Carlo over seeds "
                    "(RMS at the epoch, maximum of the maxima)")
    figs = []
    for fname, quantities, what in BOX_FIGURES:
        plot_boxes(stage_ds / fname, frame, "method", quantities, ROW_UNITS, f"{title}: {what}", _LABELS)
        figs.append(fname)

    def add(page) -> None:
        page.h(f"Statistics across {n} seeds and {len(mc.methods)} method(s)")
        page.p("Box: 25th to 75th percentile over the seeds; line: median; whiskers: 5th to 95th percentile; "
               "points: minimum and maximum.", "note")
        add_box_plots(page, stats, "method", BOX_QUANTITIES, _LABELS, ROW_UNITS, "box")
        page.h("Monte Carlo over seeds (RMS at the epoch, maximum of the maxima)")
        page.raw(error_table(mc, {}))
        page.h(f"Statistics over {n} seeds")
        page.raw(stats_html(stats, "method", _LABELS))

    return ["errors_stats.csv", "errors_stats.md", "errors_mc.csv", "errors_mc.md"] + figs, add


def _page_name(label: str) -> str:
    """A run's page file name: its label with every character but letters, digits, '.', '-' and '_' as '_'."""
    return "runs/" + re.sub(r"[^A-Za-z0-9._-]", "_", label) + ".html"


def _job_pages(stage_ds: Path, ok: list[JobRef], digests: dict, table: ErrorTable, title: str, notes: list[str],
               ds, gnss_of: dict) -> dict[str, str]:
    """One self-contained page per run (its plan view, errors against time, table column), written into
    ``stage_ds/runs/``; returns label -> path relative to the dataset's directory."""
    pages = {}
    (stage_ds / "runs").mkdir(exist_ok=True)
    for k, r in enumerate(ok):
        one = ErrorTable(epoch=table.epoch, methods=[r.label], values=table.values[:, k:k + 1], rows=table.rows)
        name = _page_name(r.label)
        page = compare_page(f"{title}: {r.method}" + ("" if r.seed is None else f", seed {r.seed}"),
                            {r.label: digests[r.label]}, one, notes=notes[:2],
                            truth_name=str(ds.truth.name) if ds.scenario is None else None, gnss=gnss_of.get(r.key))
        page.links("The dataset's report:", ["../index.html"])
        page.write(stage_ds / name)
        pages[r.label] = name
    return pages


def _dataset_report(stage_ds: Path, ds, spec, refs: list[JobRef], loaded: dict, failed: dict,
                    per_run: bool, job_pages: dict | None = None, gnss_of: dict | None = None) -> ErrorTable | None:
    """Write one dataset's report into ``stage_ds``; returns its table (None when every job failed)."""
    ok = [r for r in refs if r.key in loaded]
    if not ok:
        return None
    tails = {r.label: loaded[r.key][0] for r in ok}
    table = table_from_tails(tails, spec.epoch)
    what = (f"scenario {ds.scenario.name}" + (" (perfect sensors)" if ds.perfect else "")
            if ds.scenario is not None else f"truth {ds.truth.name}, IMU {ds.imu.name}")
    seeds = sorted({r.seed for r in refs if r.seed is not None})
    notes = [f"Dataset {ds.name}: {what}. Batch {spec.source.name}."]
    if ds.scenario is not None:
        notes.append("Each run's data are reproduced bit for bit by sins simulate "
                     f"{ds.scenario.name} --seed N{' --perfect' if ds.perfect else ''} -o DIR.")
    notes += [f"FAILED {r.label}: {failed[r.key]}" for r in refs if r.key in failed]
    title = f"{ds.name}: {spec.title}"
    stage_ds.mkdir(parents=True, exist_ok=True)
    extra_files, add_stats = [], None
    if len(seeds) > 1:
        frame = pd.DataFrame({"method": [r.method for r in ok], "seed": [r.seed for r in ok],
                              **{row: table.values[i] for i, row in enumerate(ROWS)}})
        extra_files, add_stats = _stats_section(stage_ds, frame, title, table.epoch)
    if per_run:
        digests = {r.label: loaded[r.key][1] for r in ok}
        gnss_of = gnss_of or {}
        pages = _job_pages(stage_ds, ok, digests, table, title, notes, ds, gnss_of)

        def hook(page):
            if add_stats is not None:
                add_stats(page)
            page.h("One page per run")
            page.links("Each run alone (self-contained pages):", list(pages.values()))

        seeds_ok = {r.seed for r in ok}          # the GNSS of one seed: every run of a single-seed dataset shares it
        write_report_files(stage_ds, digests, table, title, notes, extra_files, page_hook=hook,
                           truth_name=str(ds.truth.name) if ds.scenario is None else None,
                           gnss=gnss_of.get(ok[0].key) if len(seeds_ok) == 1 else None)
        if job_pages is not None:
            job_pages.update({(r.dataset, r.seed, r.method): f"{ds.name}/{pages[r.label]}" for r in ok})
        return table
    page = Page(title)
    page.h("Summary")
    page.items([f"{len(ok)} runs of {len({r.method for r in ok})} method(s) over {len(seeds)} seeds; errors truth "
                f"minus navigation at t = {float(table.epoch)!r} s, maxima over each run.",
                "No figure per run at this number of seeds (sins compare --figures all draws them); every run's "
                "table row is in ../results.parquet."])
    for n in notes:
        page.p(n, "note")
    if add_stats is not None:
        add_stats(page)
    files_section(page, [f for f in extra_files if not f.endswith(".png")] + ["../results.parquet"],
                  [f for f in extra_files if f.endswith(".png")])
    page.write(stage_ds / "index.html")
    return table


def write_batch_reports(stage: Path, spec, refs: list[JobRef], store, failed: dict, figures: str,
                        tick=lambda n: None, err=lambda msg: None) -> BatchResult:
    """Every report of the batch, written into ``stage`` (moved into place by the caller)."""
    results, reports, report_errors, job_pages = [], {}, {}, {}
    with ResultsWriter(stage / "results.parquet", results_schema()) as parquet:
        for ds in spec.datasets:
            mine = [r for r in refs if r.dataset == ds.name]
            n_seeds = len({r.seed for r in mine})
            per_run = figures == "all" or n_seeds <= PER_RUN_MAX
            loaded, metas, gnss_of = {}, {}, {}
            for r in mine:
                if r.key in failed or not store.done(r.key):
                    continue
                meta, arrays = store.read(r.key)
                metas[r.key] = meta
                tail = TailTable(arrays["tail.time"], arrays["tail.columns"], int(arrays["tail.last"]))
                loaded[r.key] = (tail, SeriesDigest.from_arrays(arrays) if per_run else None)
                if per_run and r.key not in gnss_of:
                    gnss_of[r.key] = overlay_from_arrays(arrays, f"simulated, seed {r.seed}")
            table = None
            try:
                table = _dataset_report(stage / ds.name, ds, spec, mine, loaded, failed, per_run, job_pages, gnss_of)
                if table is not None:
                    reports[ds.name] = stage / ds.name
            except SinsError as exc:
                report_errors[ds.name] = str(exc)
                err(f"report {ds.name} failed: {exc}")
            col = {label: k for k, label in enumerate(table.methods)} if table is not None else {}
            for r in mine:
                meta = metas.get(r.key)
                ok = meta is not None
                jr = JobResult(r.dataset, r.seed, r.method, r.label, ok=ok,
                               error="" if ok else failed.get(r.key, "not run"),
                               seconds=float(meta["seconds"]) if ok else 0.0, host=meta["host"] if ok else "",
                               worker_seconds=float(meta.get("worker_seconds", 0.0)) if ok else 0.0,
                               maxima=loaded[r.key][0].columns[-1][len(ROWS) - len(MAX_ROWS):] if ok else None)
                results.append(jr)
                values = table.values[:, col[r.label]] if ok and r.label in col else [None] * len(ROWS)
                parquet.add({"method": r.method, "dataset": r.dataset, "seed": r.seed, "label": r.label,
                             "status": "ok" if ok else "failed", "error": jr.error,
                             "nav_seconds": jr.seconds if ok else None,
                             "worker_seconds": jr.worker_seconds if ok else None, "host": jr.host,
                             "epoch": None if table is None else float(table.epoch),
                             **{row: (None if v is None else float(v)) for row, v in zip(ROWS, values)}})
            loaded.clear()
            tick(1)
    result = BatchResult(results, reports, report_errors, job_pages=job_pages)
    write_summary(stage, spec, result)
    tick(1)
    return result


SUMMARY_COLUMNS = ["dataset", "seed", "method", "status", "max_att_deg",
                   "max_pos_E", "max_pos_N", "max_pos_U", "max_vel_E", "max_vel_N", "max_vel_U", "error"]
TIMING_COLUMNS = ["dataset", "seed", "method", "status", "nav_seconds", "worker_seconds", "host"]
_MAX_ORDER = ["max_att_deg", "max_pos_E", "max_pos_N", "max_pos_U", "max_vel_E", "max_vel_N", "max_vel_U"]


def _summary_rows(result: BatchResult) -> list[list]:
    rows = []
    for j in result.jobs:
        vals = ([float(j.maxima[MAX_ROWS.index(k)]) for k in _MAX_ORDER] if j.ok else [None] * 7)
        rows.append([j.dataset, "" if j.seed is None else j.seed, j.method, "ok" if j.ok else "failed",
                     *vals, j.error])
    return rows


def _write_csv(path, header: list[str], rows: list[list]) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for r in rows:
            w.writerow(["" if v is None else (repr(v) if isinstance(v, float) else v) for v in r])


def write_summary(outdir: Path, spec, result: BatchResult) -> None:
    """``summary.csv`` (every job), ``summary.md`` and ``index.html`` (links to each dataset's report), and
    ``timing.csv`` (each job's navigation time and host: the only file that differs between two runs)."""
    rows = _summary_rows(result)
    _write_csv(outdir / "summary.csv", SUMMARY_COLUMNS, rows)
    _write_csv(outdir / "timing.csv", TIMING_COLUMNS,
               [[j.dataset, "" if j.seed is None else j.seed, j.method, "ok" if j.ok else "failed",
                 round(j.seconds, 4) if j.ok else None, round(j.worker_seconds, 4) if j.ok else None, j.host]
                for j in result.jobs])
    n_fail = len(result.failed)
    head = (f"{len(result.jobs)} jobs, {len(result.jobs) - n_fail} succeeded, {n_fail} failed. "
            f"Batch file: {spec.source.name}.")
    listed, failed_flags = rows, [not j.ok for j in result.jobs]
    note = ""
    if len(rows) > SUMMARY_ROWS:
        keep = [k for k, j in enumerate(result.jobs) if not j.ok][:SUMMARY_ROWS]
        listed, failed_flags = [rows[k] for k in keep], [True] * len(keep)
        note = (f"{len(rows)} jobs: only the failed ones are listed here (at most {SUMMARY_ROWS}); "
                "every job is in summary.csv and results.parquet.")
    md = [f"# {spec.title}", "", head, ""] + ([note, ""] if note else []) + [
        "| " + " | ".join(SUMMARY_COLUMNS) + " |", "|" + "---|" * len(SUMMARY_COLUMNS)]
    for r in listed:
        cells = ["" if v is None else (f"{v:.5E}" if isinstance(v, float) else str(v)) for v in r]
        md.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    for ds, e in result.report_errors.items():
        md += ["", f"Report {ds} could not be written: {e}"]
    tables_md = []
    for ds in spec.datasets:
        if ds.name in result.reports:
            tables_md.append(f"\n## {ds.name}\n\n[report]({ds.name}/index.html)\n")
            for name in ("errors.md", "errors_mc.md"):
                p = result.reports[ds.name] / name
                if p.exists():
                    tables_md.append(p.read_text(encoding="utf-8"))
    with atomic_path(outdir / "summary.md") as tmp:
        tmp.write_text("\n".join(md) + "\n" + "\n".join(tables_md), encoding="utf-8")
    _summary_page(outdir, spec, result, rows, listed, failed_flags, head, note)


def _summary_page(outdir: Path, spec, result: BatchResult, rows, listed, failed_flags, head: str, note: str) -> None:
    """The batch's ``index.html``: summary in words, box plots of each run's maxima by dataset and method,
    links to every dataset's report, and the sortable table of jobs (each linked to its report)."""
    page = Page(spec.title)
    ok = [j for j in result.jobs if j.ok]
    page.h("Summary")
    lines = [head, "Errors are truth minus navigation; maxima over the whole run (position m, velocity m/s, "
             "attitude error angle deg)."] + ([note] if note else [])
    if ok:
        frame = pd.DataFrame({"group": [f"{j.dataset} / {j.method}" for j in ok],
                              **{k: [float(j.maxima[MAX_ROWS.index(k)]) for j in ok] for k in _MAX_ORDER}})
        stats = row_statistics(frame, "group", _MAX_ORDER, ROW_UNITS)
        for q, what, unit in (("max_att_deg", "largest attitude error angle", "deg"),
                              ("max_pos_E", "largest east position error", "m")):
            sub = stats[stats["quantity"] == q]
            best = sub.loc[sub["p50"].idxmin()]
            ties = sub[sub["p50"] <= best["p50"] * (1 + 1e-3) + 1e-300]["group"].tolist()
            lines.append(f"Lowest median {what}: {best['group']} ({best['p50']:.3g} {unit} over {int(best['n'])} "
                         "run(s))." if len(ties) == 1 else
                         f"Equal lowest median {what} (within 0.1 %): {', '.join(ties)} ({best['p50']:.3g} {unit}).")
    page.items(lines)
    links = [[(ds.name, f"{ds.name}/index.html") if ds.name in result.reports else ds.name,
              "written" if ds.name in result.reports else f"not written: {result.report_errors.get(ds.name, 'every job failed')}"]
             for ds in spec.datasets]
    page.h("Reports")
    page.raw(table(["dataset", "report"], links))
    page.raw("<p>Every run: <a href=\"results.parquet\">results.parquet</a> (partitioned by method), "
             "<a href=\"summary.csv\">summary.csv</a>; navigation times and hosts: "
             "<a href=\"timing.csv\">timing.csv</a>.</p>")
    if ok:
        page.h("Maxima over each run, by dataset and method")
        page.p("Box: 25th to 75th percentile over the runs; line: median; whiskers: 5th to 95th percentile; "
               "points: minimum and maximum.", "note")
        add_box_plots(page, stats, "group", _MAX_ORDER, _LABELS, ROW_UNITS, "box")
    page.h("Jobs")
    page.p("Click a column header to sort; a dataset name links to its report, a page to the run's own page.",
           "note")
    reported = set(result.reports)
    keys = {(j.dataset, "" if j.seed is None else j.seed, j.method): j.seed for j in result.jobs}
    linked = []
    for r in listed:
        page_path = result.job_pages.get((r[0], keys.get((r[0], r[1], r[2])), r[2]))
        linked.append([(r[0], f"{r[0]}/index.html") if r[0] in reported else r[0], *r[1:],
                       ("page", page_path) if page_path else None])
    page.raw(table(SUMMARY_COLUMNS + ["run page"], linked, sortable=True, failed=failed_flags))
    page.write(outdir / "index.html")
