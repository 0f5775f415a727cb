"""One comparison report in a directory: errors.csv, errors.md, timeseries.csv, PNG figures, index.html.

Everything is written into a temporary directory beside the target and moved
into place only when every file is complete, so a failure leaves no partial
report (files of an earlier report in the directory are replaced one by one).
"""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from .errors import ErrorSeries, ErrorTable, build_consistency, build_table
from .figures import plot_all
from .html import consistency_table_html, write_report_html
from .tables import write_errors_csv, write_errors_md, write_timeseries_csv

REPORT_FILES = ["errors.csv", "errors.md", "timeseries.csv"]


@contextlib.contextmanager
def staged_dir(outdir):
    """Yield a temporary directory; on success move its files into ``outdir`` (created if needed)."""
    outdir = Path(outdir)
    parent = outdir.parent
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.", suffix=".part", dir=parent))
    try:
        yield tmp
        outdir.mkdir(parents=True, exist_ok=True)
        for p in sorted(tmp.rglob("*")):
            rel = p.relative_to(tmp)
            if p.is_dir():
                (outdir / rel).mkdir(parents=True, exist_ok=True)
            else:
                (outdir / rel).parent.mkdir(parents=True, exist_ok=True)
                os.replace(p, outdir / rel)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_report_files(outdir: Path, series: dict[str, ErrorSeries], table: ErrorTable, title: str,
                       timeseries_every: int = 1, notes: list[str] = (), extra_files: list[str] = (),
                       extra_html: str = "") -> list[str]:
    """Write the report files into ``outdir`` (an existing, usually staging, directory)."""
    outdir = Path(outdir)
    consistency = build_consistency(series)
    write_errors_csv(outdir / "errors.csv", table, consistency)
    write_errors_md(outdir / "errors.md", table, title, consistency)
    if consistency is not None:
        extra_html = consistency_table_html(consistency) + extra_html
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
