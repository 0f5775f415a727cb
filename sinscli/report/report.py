"""One comparison report in a directory: errors.csv, errors.md, timeseries.csv, PNG figures, index.html.

Everything is written into a temporary directory beside the target and moved
into place only when every file is complete, so a failure leaves no partial
report (files of an earlier report in the directory are replaced one by one).
"""
from __future__ import annotations

from pathlib import Path

from ..io.atomic import staged_dir  # noqa: F401  (re-exported: the batch runner writes reports through it)
from .digest import SeriesDigest, digest
from .errors import ErrorSeries, ErrorTable, build_table, consistency_table
from .figures import plot_all, plot_metrics
from .html import consistency_table_html, summary_html, write_report_html
from .tables import write_errors_csv, write_errors_md, write_metric_series_csv, write_timeseries_csv


def write_report_files(outdir: Path, digests: dict[str, SeriesDigest], table: ErrorTable, title: str,
                       notes: list[str] = (), extra_files: list[str] = (), extra_html: str = "",
                       metrics: dict | None = None, summary: list[str] = (), frame: str = "") -> list[str]:
    """Write the report files into ``outdir`` (an existing, usually staging, directory) from each
    method's :class:`~sinscli.report.digest.SeriesDigest` (the batch gets them from its workers).

    ``digests`` may be empty (TUM inputs: trajectory metrics alone); the runs with
    the navigator's 1-sigma add the consistency rows; ``metrics`` (method ->
    :class:`~.metrics.TrajectoryMetrics`) adds ``ate.csv``, ``rpe.csv`` and their
    figures; ``summary`` lines open errors.md and the page.
    """
    outdir = Path(outdir)
    consistency = consistency_table({n: d.consistency for n, d in digests.items()}) if digests else None
    write_errors_csv(outdir / "errors.csv", table, consistency)
    write_errors_md(outdir / "errors.md", table, title, summary, consistency)
    files = ["errors.csv", "errors.md"]
    figures = []
    if digests:
        write_timeseries_csv(outdir / "timeseries.csv", {n: d.timeseries for n, d in digests.items()})
        files.append("timeseries.csv")
        figures = plot_all(outdir, {n: d.lines for n, d in digests.items()}, title)
    if metrics:
        files += write_metric_series_csv(outdir, metrics)
        figures += plot_metrics(outdir, metrics, title, frame)
    files += list(extra_files)
    if consistency is not None:
        extra_html = consistency_table_html(consistency) + extra_html
    if summary:
        extra_html = summary_html(summary) + extra_html
    write_report_html(outdir / "index.html", title, table, figures, files, notes, extra_html)
    return files + figures + ["index.html"]


def write_report(outdir, series: dict[str, ErrorSeries], title: str, epoch: float | None = None,
                 timeseries_every: int = 1, notes: list[str] = (), metrics: dict | None = None,
                 metric_options=None, frame: str = "") -> ErrorTable:
    """Build the table (may raise :class:`SinsError`) and write the whole report atomically.

    With ``metrics`` (and their :class:`~.compare_metrics.MetricOptions`) the
    table gains the metric rows; with no ``series`` it holds them alone.
    """
    table = build_table(series, epoch) if series else None
    summary = []
    if metrics:
        from .compare_metrics import summary_lines, with_metric_rows
        table = with_metric_rows(table, metrics, metric_options)
        summary = summary_lines(metrics, metric_options)
    with staged_dir(outdir) as tmp:
        write_report_files(tmp, {n: digest(s, timeseries_every) for n, s in series.items()}, table, title, notes,
                           metrics=metrics, summary=summary, frame=frame)
    return table
