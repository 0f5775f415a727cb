"""What travels back from a batch job: one run's errors reduced to what the report draws and tabulates.

A navigation run has one epoch per attitude update (113,000 for seed 000's
flight, 20 MB of :class:`ErrorSeries`).  The report needs far less:

- :class:`TailTable`: the error-table column (:func:`sinscli.evaluate.errors.error_column`,
  rows 1-22) at the run's first epoch, at the epoch nearest the requested
  table epoch, and at its last :data:`TAIL_EPOCHS` epochs.  The client picks
  the table epoch among these (:func:`table_from_tails`), exactly as
  :func:`sinscli.evaluate.errors.build_table` does on whole series whenever the
  last epoch common to every run lies within each run's last
  :data:`TAIL_EPOCHS` epochs (methods with different attitude-update rates on
  one dataset); otherwise it asks for an explicit ``epoch:``.
- :class:`SeriesDigest`: for the per-run report only, the figures' min/max
  envelopes (:func:`sinscli.report.figures.series_lines`, at most 8000 points
  per line), the rows of ``timeseries.csv``
  (:func:`sinscli.report.tables.timeseries_columns`) and, for a run with the
  navigator's 1-sigma columns, its consistency column
  (:func:`sinscli.evaluate.errors.consistency_column`).

The single-file ``sins compare`` draws its report from the same digests, so
both paths give identical files.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SinsError
from ..evaluate.errors import (
    ErrorSeries,
    ErrorTable,
    common_epoch,
    consistency_column,
    error_column,
    headline_errors,
)
from .figures import LINE_NAMES, series_lines
from .tables import TIMESERIES_QUANTITIES, TIMESERIES_SIGMAS, timeseries_columns

TAIL_EPOCHS = 64


@dataclass
class SeriesDigest:
    """One run's figure lines (quantity -> (t, y)), its ``timeseries.csv`` columns and, when it carries
    the navigator's 1-sigma, its column of the consistency table (else None)."""
    lines: dict
    timeseries: tuple
    consistency: np.ndarray | None = None
    headline: np.ndarray | None = None      # :func:`sinscli.evaluate.errors.headline_errors`

    def arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """Flat named arrays (for a job file)."""
        out = {f"{prefix}ts.time": self.timeseries[0]}
        if self.consistency is not None:
            out[f"{prefix}consistency"] = self.consistency
        if self.headline is not None:
            out[f"{prefix}headline"] = self.headline
        out.update({f"{prefix}ts.{k}": v for k, v in self.timeseries[1].items()})
        for k, (t, y) in self.lines.items():
            out[f"{prefix}line.{k}.t"] = t
            out[f"{prefix}line.{k}.y"] = y
        return out

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "") -> SeriesDigest:
        ts_cols = {k[len(prefix) + 3:]: arrays[k] for k in arrays
                   if k.startswith(f"{prefix}ts.") and k != f"{prefix}ts.time"}
        names = [k[len(prefix) + 5:-2] for k in arrays if k.startswith(f"{prefix}line.") and k.endswith(".t")]
        lines = {n: (arrays[f"{prefix}line.{n}.t"], arrays[f"{prefix}line.{n}.y"]) for n in names}
        ts_order = [q[0] for q in TIMESERIES_QUANTITIES + TIMESERIES_SIGMAS]
        return cls(lines={n: lines[n] for n in LINE_NAMES if n in lines},
                   timeseries=(arrays[f"{prefix}ts.time"], {k: ts_cols[k] for k in ts_order if k in ts_cols}),
                   consistency=arrays.get(f"{prefix}consistency"), headline=arrays.get(f"{prefix}headline"))


def digest(s: ErrorSeries, timeseries_every: int = 1) -> SeriesDigest:
    """The figure envelopes, ``timeseries.csv`` rows and consistency column of one run."""
    return SeriesDigest(lines=series_lines(s), timeseries=timeseries_columns(s, timeseries_every),
                        consistency=consistency_column(s) if s.has_sigma else None, headline=headline_errors(s))


@dataclass
class TailTable:
    """Error-table columns of one run at a few of its epochs: ``columns[k]`` is the column at ``time[k]``."""
    time: np.ndarray          # (K,) s, increasing; the run's first and last epochs included
    columns: np.ndarray       # (K, len(ROWS))
    last: int = 0             # the final ``last`` entries are the run's last epochs, consecutive

    @property
    def tail(self) -> TailTable:
        """Only the run's last epochs (where the default table epoch is looked for)."""
        return TailTable(self.time[-self.last:], self.columns[-self.last:], self.last)


def tail_table(s: ErrorSeries, epoch: float | None = None, tail: int = TAIL_EPOCHS) -> TailTable:
    """The columns at the first epoch, the one nearest ``epoch`` and the last ``tail`` epochs of ``s``."""
    n = len(s)
    idx = set(range(max(0, n - tail), n)) | {0}
    if epoch is not None:
        idx.add(int(np.argmin(np.abs(s.time - epoch))))
    idx = np.array(sorted(idx))
    return TailTable(time=s.time[idx].copy(), columns=np.stack([error_column(s, float(s.time[k])) for k in idx]),
                     last=min(tail, n))


def table_from_tails(tails: dict[str, TailTable], epoch: float | None = None) -> ErrorTable:
    """The error table of several runs (label -> :class:`TailTable`), as
    :func:`sinscli.evaluate.errors.build_table` gives it from the whole series."""
    try:
        t = common_epoch(tails if epoch is not None else {k: tt.tail for k, tt in tails.items()}, epoch)
    except SinsError as exc:
        if epoch is not None:
            raise
        raise SinsError(f"{exc} (among the last {TAIL_EPOCHS} epochs of each run; set epoch: in the batch "
                        "file to choose one)") from None
    values = np.stack([tt.columns[int(np.argmin(np.abs(tt.time - t)))] for tt in tails.values()], axis=1)
    return ErrorTable(epoch=t, methods=list(tails), values=values)
