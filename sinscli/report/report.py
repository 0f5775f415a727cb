"""One comparison report in a directory: errors.csv, errors.md, timeseries.csv, PNG figures, index.html.

Everything is written into a temporary directory beside the target and moved
into place only when every file is complete, so a failure leaves no partial
report (files of an earlier report in the directory are replaced one by one).
"""
from __future__ import annotations

from pathlib import Path

from ..evaluate.compare_metrics import summary_lines, with_metric_rows
from ..evaluate.errors import ErrorSeries, ErrorTable, build_table, consistency_table
from ..io.atomic import staged_dir  # noqa: F401  (re-exported: the batch runner writes reports through it)
from .compare_page import compare_page, files_section
from .digest import SeriesDigest, digest
from .figures import plot_all, plot_metrics
from .tables import (
    write_errors_csv,
    write_errors_md,
    write_metric_series_csv,
    write_timeseries_csv,
)


def write_report_files(outdir: Path, digests: dict[str, SeriesDigest], table: ErrorTable, title: str,
                       notes: list[str] = (), extra_files: list[str] = (), extra_html: str = "",
                       metrics: dict | None = None, summary: list[str] = (), frame: str = "",
                       legend: dict[str, str] | None = None, truth_name: str | None = None, gnss=None,
                       page_hook=None) -> list[str]:
    """Write the report files into ``outdir`` (an existing, usually staging, directory) from each
    method's :class:`~sinscli.report.digest.SeriesDigest` (the batch gets them from its workers).

    ``digests`` may be empty (TUM inputs: trajectory metrics alone); the runs with
    the navigator's 1-sigma add the consistency rows; ``metrics`` (method ->
    :class:`~.metrics.TrajectoryMetrics`) adds ``ate.csv``, ``rpe.csv`` and their
    figures; ``summary`` lines open errors.md and the page.  ``legend`` names each
    method in the figures and the page (default: its column name); ``gnss``
    (:class:`~.compare_page.GnssOverlay`) adds the fixes to the plan view and the
    outages to the time plots; ``page_hook(page)`` may add sections (a batch's
    statistics) before the file list.
    """
    outdir = Path(outdir)
    legend = dict(legend or {})
    consistency = consistency_table({n: d.consistency for n, d in digests.items()}) if digests else None
    write_errors_csv(outdir / "errors.csv", table, consistency)
    write_errors_md(outdir / "errors.md", table, title, summary, consistency)
    files = ["errors.csv", "errors.md"]
    figures = []
    if digests:
        write_timeseries_csv(outdir / "timeseries.csv", {n: d.timeseries for n, d in digests.items()})
        files.append("timeseries.csv")
        figures = plot_all(outdir, {legend.get(n, n): d.lines for n, d in digests.items()}, title)
    if metrics:
        files += write_metric_series_csv(outdir, metrics)
        figures += plot_metrics(outdir, {legend.get(n, n): r for n, r in metrics.items()}, title, frame)
    files += [f for f in extra_files if not f.endswith(".png")]
    figures += [f for f in extra_files if f.endswith(".png")]
    page = compare_page(title, digests, table, legend, notes=notes, truth_name=truth_name, extra_summary=summary,
                        consistency=consistency, metrics=metrics, gnss=gnss, extra_html=extra_html)
    if page_hook is not None:
        page_hook(page)
    files_section(page, files, figures)
    page.write(outdir / "index.html")
    return files + figures + ["index.html"]


def write_report(outdir, series: dict[str, ErrorSeries], title: str, epoch: float | None = None,
                 timeseries_every: int = 1, notes: list[str] = (), metrics: dict | None = None,
                 metric_options=None, frame: str = "", legend: dict[str, str] | None = None,
                 truth_name: str | None = None, gnss=None) -> ErrorTable:
    """Build the table (may raise :class:`SinsError`) and write the whole report atomically.

    With ``metrics`` (and their :class:`~.compare_metrics.MetricOptions`) the
    table gains the metric rows; with no ``series`` it holds them alone.
    """
    table = build_table(series, epoch) if series else None
    summary = []
    if metrics:
        table = with_metric_rows(table, metrics, metric_options)
        summary = summary_lines(metrics, metric_options)
    with staged_dir(outdir) as tmp:
        write_report_files(tmp, {n: digest(s, timeseries_every) for n, s in series.items()}, table, title, notes,
                           metrics=metrics, summary=summary, frame=frame, legend=legend, truth_name=truth_name,
                           gnss=gnss)
    return table
