"""One comparison report in a directory: errors.csv, errors.md, timeseries.csv, PNG figures, index.html.

Everything is written into a temporary directory beside the target and moved
into place only when every file is complete, so a failure leaves no partial
report (files of an earlier report in the directory are replaced one by one).
"""
from __future__ import annotations

from pathlib import Path

from ..io.atomic import staged_dir  # noqa: F401  (re-exported: the batch runner writes reports through it)
from .errors import ErrorSeries, ErrorTable, build_table
from .figures import plot_all
from .html import write_report_html
from .tables import write_errors_csv, write_errors_md, write_timeseries_csv

REPORT_FILES = ["errors.csv", "errors.md", "timeseries.csv"]


def write_report_files(outdir: Path, series: dict[str, ErrorSeries], table: ErrorTable, title: str,
                       timeseries_every: int = 1, notes: list[str] = (), extra_files: list[str] = (),
                       extra_html: str = "") -> list[str]:
    """Write the report files into ``outdir`` (an existing, usually staging, directory)."""
    outdir = Path(outdir)
    write_errors_csv(outdir / "errors.csv", table)
    write_errors_md(outdir / "errors.md", table, title)
    write_timeseries_csv(outdir / "timeseries.csv", series, timeseries_every)
    figures = plot_all(outdir, series, title)
    files = REPORT_FILES + list(extra_files)
    write_report_html(outdir / "index.html", title, table, figures, files, notes, extra_html)
    return files + figures + ["index.html"]


def write_report(outdir, series: dict[str, ErrorSeries], title: str, epoch: float | None = None,
                 timeseries_every: int = 1, notes: list[str] = ()) -> ErrorTable:
    """Build the table (may raise :class:`SinsError`) and write the whole report atomically."""
    table = build_table(series, epoch)
    with staged_dir(outdir) as tmp:
        write_report_files(tmp, series, table, title, timeseries_every, notes)
    return table
