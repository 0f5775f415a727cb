"""Shared CSV machinery: fast exact reading with pyarrow, writing, and precise error messages.

Reading parses every float exactly (pyarrow's parser is correctly rounded);
writing uses the compiled shortest round-trip float formatter (``floatfmt``, Ryu),
so every float reads back to the identical float64 (docs/formats.md).
"""
from __future__ import annotations

import collections
import contextlib
import csv
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from ..errors import SinsError, num, quote
from .atomic import check_finite
from ..inputs import closing_native, input_file, native_path


MAX_LINE_BYTES = 128 * 1024      # a numeric CSV line is far shorter; the header is refused beyond this
MAX_COLUMNS = 1024               # header columns (bounds the header work: no parse of 100,000 columns)


def read_header(path) -> list[str]:
    """Column names of a CSV file (whitespace around names accepted), with clear errors for a missing,
    empty or non-regular file, a header that is not UTF-8, too long, too wide, or names a column twice."""
    path = input_file(path, "CSV file")
    if path.stat().st_size == 0:
        raise SinsError(f"{path}: file is empty, expected a header row and data rows")
    with open(path, "rb") as fh:
        first = fh.readline(MAX_LINE_BYTES + 1)
    if len(first) > MAX_LINE_BYTES:
        raise SinsError(f"{path}: line 1: the header is longer than {MAX_LINE_BYTES} bytes (it starts "
                        f"{quote(first[:40].decode('utf-8', 'replace'))}); expected a CSV header row")
    if first.startswith(b"\xef\xbb\xbf"):
        first = first[3:]
    try:
        text = first.decode("utf-8")
    except UnicodeDecodeError as exc:
        k = first[:exc.start].count(b",")
        raise SinsError(f"{path}: line 1, header column {k + 1}: byte 0x{first[exc.start]:02x} is not UTF-8 "
                        f"(save the file as UTF-8)") from None
    if not text.strip():
        raise SinsError(f"{path}: first line is empty, expected a header row")
    try:
        names = [c.strip() for c in next(csv.reader([text.rstrip("\r\n")]), [])]
    except csv.Error as exc:
        raise SinsError(f"{path}: line 1: cannot read the header as CSV ({exc})") from None
    if len(names) > MAX_COLUMNS:
        raise SinsError(f"{path}: line 1: the header has {len(names)} columns; at most {MAX_COLUMNS} are read")
    seen = set()
    for k, c in enumerate(names):
        if not c:
            raise SinsError(f"{path}: line 1, header column {k + 1}: empty column name")
        if c in seen:
            raise SinsError(f"{path}: line 1, header column {k + 1}: column {quote(c)} appears twice")
        seen.add(c)
    return names


def name_list(names, n: int = 6) -> str:
    """Column names for a message: the first ``n``, quoted and cut, then how many more."""
    names = list(names)
    more = f", ... ({len(names) - n} more)" if len(names) > n else ""
    return ", ".join(quote(c, 40) for c in names[:n]) + more


def _read_options(path, file_cols, **kw):
    """pyarrow read options with the header names of :func:`read_header` (stripped), so that the
    names asked for are exactly the file's; a name the header lacks is refused here, naming it."""
    header = read_header(path)
    missing = [c for c in file_cols if c not in header]
    if missing:
        raise SinsError(f"{path}: no column {quote(missing[0])} in the header (columns: "
                        f"{', '.join(header[:12])}{', ...' if len(header) > 12 else ''}); check the column names "
                        f"and the config's column mapping")
    return pacsv.ReadOptions(column_names=header, skip_rows=1, **kw)


def _convert_options(file_cols):
    """Only the wanted columns, all parsed as float64; no string is taken as null."""
    return pacsv.ConvertOptions(include_columns=file_cols, column_types={c: pa.float64() for c in file_cols},
                                strings_can_be_null=False, quoted_strings_can_be_null=False, null_values=[])


def float_column(col) -> np.ndarray:
    """A pyarrow float64 column (Array or ChunkedArray) as a numpy float64 array.

    Without nulls each chunk is viewed in place (``np.frombuffer``): pyarrow's own ``to_numpy`` imports
    pandas on first use, 0.15-0.3 s of every ``sins navigate``; other types and nulls go through it.
    The result is always writable (a copy when pyarrow's buffer is not; the CSV reader's are), so the
    numba kernels see the same array type as for logs made in memory: one compiled signature.
    """
    chunks = col.chunks if isinstance(col, pa.ChunkedArray) else [col]
    parts = []
    for c in chunks:
        if c.type == pa.float64() and c.null_count == 0:
            parts.append(np.frombuffer(c.buffers()[1], dtype=np.float64, count=len(c), offset=c.offset * 8))
        else:
            parts.append(c.to_numpy(zero_copy_only=False).astype(np.float64, copy=False))
    out = parts[0] if len(parts) == 1 else np.concatenate(parts) if parts else np.empty(0)
    return out if out.flags.writeable else out.copy()


def _finite_columns(path, columns: dict[str, str], column, first_line: int) -> dict[str, np.ndarray]:
    """``{our name: float64 array}`` via ``column(file name)``; SinsError at the first NaN or infinity."""
    out = {}
    for ours, theirs in columns.items():
        arr = float_column(column(theirs))
        bad = ~np.isfinite(arr)
        if bad.any():
            k = int(np.argmax(bad))
            raise SinsError(f"{path}: line {first_line + k}, column {quote(theirs)}: value {num(arr[k])} "
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
    source = native_path(path)
    try:
        table = pacsv.read_csv(
            source,
            read_options=_read_options(path, file_cols, use_threads=True, block_size=1 << 24),
            parse_options=pacsv.ParseOptions(newlines_in_values=False),
            convert_options=_convert_options(file_cols),
        )
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
        raise SinsError(_locate_bad_cell(path, file_cols, exc)) from None
    finally:
        closing_native(source)
    if table.num_rows == 0:
        raise SinsError(f"{path}: no data rows after the header")
    return _finite_columns(path, columns, table.column, 2)


def read_mapped_columns(path, section, names: list[str], required: list[str], groups: list[list[str]],
                        unknown_hint: str, missing_hint: str, horizontal=()) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Read a CSV whose columns are ``names`` (or config-mapped to them): ``(our name -> array, mapping)``.

    ``section`` is the config's section, with ``columns`` (our name -> file column) and ``ignore_columns``.
    Refused naming the file: unknown columns (``unknown_hint`` says what is expected), missing required
    ones (``missing_hint``), a group of three (e.g. std_x, std_y, std_z) given in part (the groups named in
    ``horizontal`` may also come as their first two columns: east and north without up); then every value
    as in :func:`read_numeric_columns`.
    """
    path = Path(path)
    header = read_header(path)
    mapping = dict(section.columns)
    inverse = {v: k for k, v in mapping.items()}
    ignored = set(section.ignore_columns)
    known = [inverse.get(c, c) for c in header]
    unknown = [c for c, k in zip(header, known) if k not in names and c not in ignored]
    if unknown:
        raise SinsError(f"{path}: unknown column(s) {name_list(unknown)}; {unknown_hint}")
    missing = [c for c in required if c not in known]
    if missing:
        raise SinsError(f"{path}: missing column(s) {', '.join(missing)}; {missing_hint}")
    for group in groups:
        present = [c for c in group if c in known]
        if present and len(present) != len(group) and not (group in horizontal and present == group[:2]):
            pair = f" (or {', '.join(group[:2])} alone: horizontal only)" if group in horizontal else ""
            raise SinsError(f"{path}: has {', '.join(present)} but not all of {', '.join(group)}{pair}")
    wanted = [c for c in names if c in known]
    return read_numeric_columns(path, {c: mapping.get(c, c) for c in wanted}), mapping


def _locate_bad_cell(path: Path, cols: list[str], exc: Exception) -> str:
    """Find the first cell that does not parse as a float (slow path, only on error; lines are read
    with a bound, so a giant line is reported, not parsed)."""
    header = read_header(path)
    idx = {c: header.index(c) for c in cols if c in header}
    with open(path, "rb") as fh:
        fh.readline(MAX_LINE_BYTES + 1)
        lineno = 1
        while True:
            raw = fh.readline(MAX_LINE_BYTES + 1)
            if not raw:
                break
            lineno += 1
            if len(raw) > MAX_LINE_BYTES:
                return f"{path}: line {lineno}: longer than {MAX_LINE_BYTES} bytes; expected {len(header)} numbers"
            line = raw.decode("utf-8", errors="replace").rstrip("\r\n")
            try:
                row = next(csv.reader([line]), [])
            except csv.Error as exc:
                return f"{path}: line {lineno}: cannot read as CSV ({exc})"
            if not row or all(not x.strip() for x in row):
                return f"{path}: line {lineno}: empty row, expected {len(header)} comma-separated values"
            if len(row) != len(header):
                return f"{path}: line {lineno}: {len(row)} values, expected {len(header)} (one per header column)"
            for c, i in idx.items():
                try:
                    float(row[i])
                except ValueError:
                    return f"{path}: line {lineno}, column {quote(c)}: {quote(row[i].strip())} is not a number"
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return f"{path}: cannot parse as CSV: {first}"


# bytes of text per streamed block: Arrow's streaming reader keeps its read-ahead blocks and their parsed
# columns in memory (about 150 MB at 4 MB blocks, 300 MB at 8, 600 at 16, whatever the file size); as
# fast at 4 MB as at 16
STREAM_BLOCK = 1 << 22


def iter_numeric_columns(path, columns: dict[str, str], block_bytes: int = STREAM_BLOCK):
    """Stream the named columns as float64 in blocks: yields ``(first_line_number, {name: array})``.

    Same checks and messages as :func:`read_numeric_columns`; memory stays at
    a few blocks (:data:`STREAM_BLOCK`) whatever the file size.
    """
    path = Path(path)
    file_cols = list(dict.fromkeys(columns.values()))
    try:
        # no threaded read-ahead: the reader would run ahead of the navigator and buffer the file
        reader = pacsv.open_csv(
            native_path(path),
            read_options=_read_options(path, file_cols, use_threads=False, block_size=block_bytes),
            convert_options=_convert_options(file_cols))
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
        raise SinsError(_locate_bad_cell(path, file_cols, exc)) from None
    line = 2
    total = 0
    # one block parsed ahead on a thread (Arrow releases the GIL) while the caller works on the last one
    pool = ThreadPoolExecutor(1, thread_name_prefix="sins-csv-read")
    try:
        ahead = pool.submit(reader.read_next_batch)
        while True:
            try:
                batch = ahead.result()
            except StopIteration:
                break
            except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
                raise SinsError(_locate_bad_cell(path, file_cols, exc)) from None
            ahead = pool.submit(reader.read_next_batch)
            if batch.num_rows == 0:
                continue
            yield line, _finite_columns(path, columns, batch.column, line)
            line += batch.num_rows
            total += batch.num_rows
    finally:
        pool.shutdown(wait=True)
    if total == 0:
        raise SinsError(f"{path}: no data rows after the header")


FORMAT_ROWS = 1 << 15          # rows per formatting task of CsvTableWriter (~17 MB of text for 26 columns)


def writer_threads() -> int:
    """Formatting threads of :class:`CsvTableWriter`: the CPUs this process may use, at most 4."""
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return max(1, min(4, n))


def float64_table(columns: dict[str, np.ndarray]) -> pa.Table:
    """An Arrow table over float64 columns, zero-copy for contiguous ones.

    Built from the arrays' buffers: ``pa.table``/``pa.array`` on a NumPy array import pandas (0.2-0.3 s
    of start-up) to check for its types.
    """
    arrays = []
    for a in columns.values():
        a = np.ascontiguousarray(a, dtype=np.float64)
        arrays.append(pa.Array.from_buffers(pa.float64(), a.shape[0], [None, pa.py_buffer(a)]))
    return pa.Table.from_arrays(arrays, names=list(columns))


def _format_csv(rows: np.ndarray, suffix: np.ndarray) -> memoryview:
    """CSV text (no header) of ``rows`` (float64, C-contiguous, shape (rows, columns)), each ended by ``suffix`` and a
    newline, by the compiled shortest round-trip formatter (``floatfmt.format_rows``); it releases the GIL,
    so slices are formatted on threads at once."""
    from .floatfmt import format_rows, row_bytes    # numba: loaded by the first writer, not by the readers
    out = np.empty(rows.shape[0] * row_bytes(rows.shape[1], suffix.shape[0]), np.uint8)
    return memoryview(out[:format_rows(rows, suffix, out)])


class CsvTableWriter:
    """Stream float64 columns to a CSV file in chunks (exact round-trip floats).

    Use inside :func:`sinscli.io.atomic.atomic_path`; ``write`` takes a dict of
    equally long 1-D arrays with the same keys each time.  Every chunk passes
    :func:`sinscli.io.atomic.check_finite` (``sigmas``: the 1-sigma columns, which must be positive).

    Floats are formatted by the compiled Ryu formatter (``floatfmt``), which writes the shortest text that
    reads back to the identical float64, in the layout pyarrow's writer had (``tests/test_io_csv_roundtrip.py``,
    ``tests/test_io_floatfmt.py``: hard cases and random bit patterns against Python's ``repr`` and pyarrow,
    byte for byte).  Formatting runs on :func:`writer_threads` threads in slices of :data:`FORMAT_ROWS`
    rows, while the caller computes the next chunk; the slices are written in order, and at most
    ``2 * threads`` slices wait in memory.
    """

    def __init__(self, path, columns: list[str], sigmas=(), text_columns: dict[str, str] | None = None,
                 threads: int | None = None):
        self.columns = list(columns)
        self.path = path
        self.sigmas = tuple(sigmas)
        self.text_columns = dict(text_columns or {})     # name -> the same text on every row, after the numbers
        self._rows = 0
        self._threads = writer_threads() if threads is None else max(1, int(threads))
        self._pool = ThreadPoolExecutor(self._threads, thread_name_prefix="sins-csv") if self._threads > 1 else None
        self._pending = collections.deque()
        self._fh = open(path, "wb")
        self._fh.write((",".join(self.columns + list(self.text_columns)) + "\n").encode())
        self._suffix = np.frombuffer("".join("," + t for t in self.text_columns.values()).encode(), np.uint8)

    def write(self, data: dict[str, np.ndarray]) -> None:
        check_finite(self.path, {c: data[c] for c in self.columns}, data.get("time"), self._rows + 1, self.sigmas)
        rows = np.empty((len(data[self.columns[0]]), len(self.columns)), np.float64)   # row slices: contiguous
        for k, c in enumerate(self.columns):
            rows[:, k] = data[c]
        n = rows.shape[0]
        self._rows += n
        if self._pool is None:
            self._fh.write(_format_csv(rows, self._suffix))
            return
        for a in range(0, n, FORMAT_ROWS):
            self._pending.append(self._pool.submit(_format_csv, rows[a:a + FORMAT_ROWS], self._suffix))
            self._drain(2 * self._threads)

    def _drain(self, keep: int) -> None:
        """Write the finished slices at the head of the queue, and wait until at most ``keep`` are left."""
        while self._pending and (len(self._pending) > keep or self._pending[0].done()):
            self._fh.write(self._pending.popleft().result())

    def close(self) -> None:
        try:
            self._drain(0)
            self._fh.flush()
            os.fsync(self._fh.fileno())
        finally:
            self._shutdown()
            self._fh.close()       # (after a failed flush it raises again; the first error is kept)

    def discard(self) -> None:
        """Stop without finishing the file (its staged file is removed by the caller)."""
        self._shutdown()
        with contextlib.suppress(OSError):
            self._fh.close()

    def _shutdown(self) -> None:
        if self._pool is not None:
            for f in self._pending:
                f.cancel()
            self._pool.shutdown(wait=True)
            self._pool = None
        self._pending.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if not self._fh.closed:
            self.discard()


def write_table_csv(path, data: dict[str, np.ndarray], columns: list[str] | None = None, sigmas=()) -> None:
    """Write a dict of columns to ``path`` (already an atomic temporary path); ``sigmas`` as for
    :class:`CsvTableWriter`."""
    cols = columns or list(data)
    with CsvTableWriter(path, cols, sigmas) as w:
        w.write(data)
        w.close()
