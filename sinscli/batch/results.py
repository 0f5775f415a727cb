"""``DIR/results.parquet``: one row per run of a batch, a Hive-partitioned Parquet dataset by method.

``results.parquet/method=<name>/part-0.parquet`` (``pandas.read_parquet`` and
``pyarrow.dataset`` read the folder whole, with ``method`` as a column).  Rows
are appended in job order and flushed in row groups of :data:`ROW_GROUP`, so
the writer never holds more than one row group per method; the folder is
built beside the target and renamed into place when complete.
"""
from __future__ import annotations

import contextlib
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from ..io.atomic import staged_dir

ROW_GROUP = 4096


class ResultsWriter:
    """Stream rows (dicts) into a method-partitioned Parquet dataset at ``path``.

    ``schema``: ``pyarrow.Schema`` of every column but the partition column.
    """

    def __init__(self, path, schema: pa.Schema, partition: str = "method"):
        self.path = Path(path)
        self.schema = schema
        self.partition = partition
        self._stage = staged_dir(self.path, replace=True)    # the one staged mechanism (sinscli/io/atomic.py)
        self._tmp = self._stage.__enter__()
        self._writers: dict = {}
        self._buffers: dict = {}
        self.rows = 0

    def add(self, row: dict) -> None:
        key = str(row[self.partition])
        self._buffers.setdefault(key, []).append(row)
        self.rows += 1
        if len(self._buffers[key]) >= ROW_GROUP:
            self._flush(key)

    def _flush(self, key: str) -> None:
        rows = self._buffers.get(key)
        if not rows:
            return
        if key not in self._writers:
            d = self._tmp / f"{self.partition}={key}"
            d.mkdir()
            self._writers[key] = pq.ParquetWriter(d / "part-0.parquet", self.schema)
        cols = {f.name: [r.get(f.name) for r in rows] for f in self.schema}
        self._writers[key].write_table(pa.table(cols, schema=self.schema), row_group_size=ROW_GROUP)
        self._buffers[key] = []

    def close(self) -> None:
        """Flush, close and move the dataset into place (replacing an earlier one)."""
        try:
            for key in list(self._buffers):
                self._flush(key)
            for w in self._writers.values():
                w.close()
        except BaseException as exc:
            self.abort(exc)
            raise
        self._writers = {}
        self._stage.__exit__(None, None, None)

    def abort(self, exc: BaseException | None = None) -> None:
        for w in self._writers.values():
            with contextlib.suppress(Exception):
                w.close()
        self._writers = {}
        exc = exc or RuntimeError("aborted")
        self._stage.__exit__(type(exc), exc, exc.__traceback__)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort(exc)
        return False
