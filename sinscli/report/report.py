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

from .digest import SeriesDigest, digest
from .errors import ErrorSeries, ErrorTable, build_table
from .figures import plot_all
from .html import write_report_html
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


def write_report_files(outdir: Path, digests: dict[str, SeriesDigest], table: ErrorTable, title: str,
                       notes: list[str] = (), extra_files: list[str] = (), extra_html: str = "") -> list[str]:
    """Write the report files into ``outdir`` (an existing, usually staging, directory) from each
    method's :class:`~sinscli.report.digest.SeriesDigest` (the batch gets them from its workers)."""
    outdir = Path(outdir)
    write_errors_csv(outdir / "errors.csv", table)
    write_errors_md(outdir / "errors.md", table, title)
    write_timeseries_csv(outdir / "timeseries.csv", {n: d.timeseries for n, d in digests.items()})
    figures = plot_all(outdir, {n: d.lines for n, d in digests.items()}, title)
    files = REPORT_FILES + list(extra_files)
    write_report_html(outdir / "index.html", title, table, figures, files, notes, extra_html)
    return files + figures + ["index.html"]


def write_report(outdir, series: dict[str, ErrorSeries], title: str, epoch: float | None = None,
                 timeseries_every: int = 1, notes: list[str] = ()) -> ErrorTable:
    """Build the table (may raise :class:`SinsError`) and write the whole report atomically."""
    table = build_table(series, epoch)
    with staged_dir(outdir) as tmp:
        write_report_files(tmp, {n: digest(s, timeseries_every) for n, s in series.items()}, table, title, notes)
    return table
