"""Shared CSV machinery: fast exact reading/writing with pyarrow, and precise error messages.

Reading parses every float exactly (pyarrow's parser is correctly rounded);
writing uses pyarrow's shortest round-trip float formatting, so every float
reads back to the identical float64 (FORMATS.md).
"""
from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from ..errors import SinsError


def read_header(path) -> list[str]:
    """Column names of a CSV file, with clear errors for missing or empty files."""
    path = Path(path)
    if not path.exists():
        raise SinsError(f"{path}: file not found")
    if path.is_dir():
        raise SinsError(f"{path}: is a directory, expected a CSV file")
    if path.stat().st_size == 0:
        raise SinsError(f"{path}: file is empty, expected a header row and data rows")
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        first = fh.readline()
    if not first.strip():
        raise SinsError(f"{path}: first line is empty, expected a header row")
    return [c.strip() for c in next(csv.reader([first]))]


def _convert_options(file_cols):
    """Only the wanted columns, all parsed as float64; no string is taken as null."""
    return pacsv.ConvertOptions(include_columns=file_cols, column_types={c: pa.float64() for c in file_cols},
                                strings_can_be_null=False, quoted_strings_can_be_null=False, null_values=[])


def _finite_columns(path, columns: dict[str, str], column, first_line: int) -> dict[str, np.ndarray]:
    """``{our name: float64 array}`` via ``column(file name)``; SinsError at the first NaN or infinity."""
    out = {}
    for ours, theirs in columns.items():
        arr = column(theirs).to_numpy().astype(np.float64, copy=False)
        bad = ~np.isfinite(arr)
        if bad.any():
            k = int(np.argmax(bad))
            raise SinsError(f"{path}: line {first_line + k}, column '{theirs}': value {float(arr[k])!r} "
                            f"is not a finite number")
        out[ours] = arr
    return out


def read_numeric_columns(path, columns: dict[str, str]) -> dict[str, np.ndarray]:
    """Read the named file columns as float64; ``columns`` maps our name -> file column name.

    Errors name the file, the 1-based line number and the column: a value that
    is not a number, NaN or infinite; a file with a header but no data rows.
    """
    path = Path(path)
    file_cols = list(dict.fromkeys(columns.values()))
    try:
        table = pacsv.read_csv(
            path,
            read_options=pacsv.ReadOptions(use_threads=True, block_size=1 << 24),
            parse_options=pacsv.ParseOptions(newlines_in_values=False),
            convert_options=_convert_options(file_cols),
        )
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
        raise SinsError(_locate_bad_cell(path, file_cols, exc)) from None
    if table.num_rows == 0:
        raise SinsError(f"{path}: no data rows after the header")
    return _finite_columns(path, columns, table.column, 2)


def read_mapped_columns(path, section: dict, names: list[str], required: list[str], groups: list[list[str]],
                        unknown_hint: str, missing_hint: str) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Read a CSV whose columns are ``names`` (or config-mapped to them): ``(our name -> array, mapping)``.

    ``section`` is the config section with ``columns`` (our name -> file column) and ``ignore_columns``.
    Refused naming the file: unknown columns (``unknown_hint`` says what is expected), missing required
    ones (``missing_hint``), a group of three (e.g. std_x, std_y, std_z) given in part; then every value
    as in :func:`read_numeric_columns`.
    """
    path = Path(path)
    header = read_header(path)
    mapping = dict(section.get("columns") or {})
    inverse = {v: k for k, v in mapping.items()}
    ignored = set(section.get("ignore_columns") or [])
    known = [inverse.get(c, c) for c in header]
    unknown = [c for c, k in zip(header, known) if k not in names and c not in ignored]
    if unknown:
        raise SinsError(f"{path}: unknown column(s) {', '.join(repr(c) for c in unknown)}; {unknown_hint}")
    missing = [c for c in required if c not in known]
    if missing:
        raise SinsError(f"{path}: missing column(s) {', '.join(missing)}; {missing_hint}")
    for group in groups:
        present = [c for c in group if c in known]
        if present and len(present) != len(group):
            raise SinsError(f"{path}: has {', '.join(present)} but not all of {', '.join(group)}")
    wanted = [c for c in names if c in known]
    return read_numeric_columns(path, {c: mapping.get(c, c) for c in wanted}), mapping


def check_positive(path, data: dict[str, np.ndarray], columns, mapping: dict[str, str]) -> None:
    """SinsError at the first value of ``columns`` (present in ``data``) that is not > 0 (a 1-sigma)."""
    for c in columns:
        if c in data:
            bad = ~(data[c] > 0)
            if bad.any():
                k = int(np.argmax(bad))
                raise SinsError(f"{path}: line {k + 2}, column '{mapping.get(c, c)}': {float(data[c][k])!r} is not a "
                                "positive 1-sigma")


def _locate_bad_cell(path: Path, cols: list[str], exc: Exception) -> str:
    """Find the first cell that does not parse as a float (slow path, only on error)."""
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        reader = csv.reader(fh)
        header = [c.strip() for c in next(reader)]
        idx = {c: header.index(c) for c in cols if c in header}
        for lineno, row in enumerate(reader, start=2):
            if not row or all(not x.strip() for x in row):
                return f"{path}: line {lineno}: empty row, expected {len(header)} comma-separated values"
            if len(row) != len(header):
                return f"{path}: line {lineno}: {len(row)} values, expected {len(header)} (one per header column)"
            for c, i in idx.items():
                try:
                    float(row[i])
                except ValueError:
                    return f"{path}: line {lineno}, column '{c}': {row[i].strip()!r} is not a number"
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return f"{path}: cannot parse as CSV: {first}"


def iter_numeric_columns(path, columns: dict[str, str], block_bytes: int = 1 << 24):
    """Stream the named columns as float64 in blocks: yields ``(first_line_number, {name: array})``.

    Same checks and messages as :func:`read_numeric_columns`; memory stays at
    one block whatever the file size.
    """
    path = Path(path)
    file_cols = list(dict.fromkeys(columns.values()))
    try:
        # no threaded read-ahead: the reader would run ahead of the navigator and buffer the file
        reader = pacsv.open_csv(
            path,
            read_options=pacsv.ReadOptions(use_threads=False, block_size=block_bytes),
            convert_options=_convert_options(file_cols))
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
        raise SinsError(_locate_bad_cell(path, file_cols, exc)) from None
    line = 2
    total = 0
    while True:
        try:
            batch = reader.read_next_batch()
        except StopIteration:
            break
        except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
            raise SinsError(_locate_bad_cell(path, file_cols, exc)) from None
        if batch.num_rows == 0:
            continue
        yield line, _finite_columns(path, columns, batch.column, line)
        line += batch.num_rows
        total += batch.num_rows
    if total == 0:
        raise SinsError(f"{path}: no data rows after the header")


class CsvTableWriter:
    """Stream float64 columns to a CSV file in chunks (exact round-trip floats).

    Use inside :func:`sinscli.io.atomic.atomic_path`; ``write`` takes a dict of
    equally long 1-D arrays with the same keys each time.
    """

    def __init__(self, path, columns: list[str]):
        self.columns = list(columns)
        self._fh = open(path, "wb")
        self._fh.write((",".join(self.columns) + "\n").encode())
        self._opts = pacsv.WriteOptions(include_header=False, quoting_style="none", batch_size=1 << 16)

    def write(self, data: dict[str, np.ndarray]) -> None:
        table = pa.table({c: np.ascontiguousarray(data[c], dtype=np.float64) for c in self.columns})
        buf = io.BytesIO()
        pacsv.write_csv(table, buf, write_options=self._opts)
        self._fh.write(buf.getbuffer())

    def close(self) -> None:
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if not self._fh.closed:
            self._fh.close()


def write_table_csv(path, data: dict[str, np.ndarray], columns: list[str] | None = None) -> None:
    """Write a dict of columns to ``path`` (already an atomic temporary path)."""
    cols = columns or list(data)
    with CsvTableWriter(path, cols) as w:
        w.write(data)
        w.close()
