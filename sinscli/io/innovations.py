"""The filter's innovations file (``sins navigate --gnss ... --innovations FILE.csv``): write and read.

One row per measured component, in the order the filter processed them:

| column | unit | meaning |
|---|---|---|
| ``time`` | s | measurement time (the filter is propagated exactly to it) |
| ``type`` | | ``gnss_pos``, ``gnss_vel``, ``zupt``, ``zaru``, ``nhc``, ``odom``, or one satellite's ``pseudorange``, ``doppler`` (range rate, ``--gnss-raw``) or ``tdcp`` (time-differenced carrier phase, ``--tdcp``) |
| ``axis`` | | ``e``, ``n``, ``u`` (ENU measurements), ``x``, ``y``, ``z`` (body axes) or ``los`` (a satellite's line of sight) |
| ``innovation`` | m, m/s or rad/s | measurement minus prediction (SI: m for gnss_pos, pseudorange and tdcp, rad/s for zaru, m/s otherwise) |
| ``sigma`` | same | 1-sigma of the innovation, ``sqrt((H P H^T + R)_ii)`` |
| ``nis`` | 1 | normalized innovation squared of the whole measurement vector (same on its rows) |
| ``accepted`` | | ``true`` / ``false``: passed the chi-square gate and was applied |
| ``sat`` | | the satellite (``G05``) of a pseudorange, Doppler or TDCP row; the column only in files that have such rows |

Floats are written in shortest round-trip form.  Every value is finite and
every sigma positive: the writer refuses anything else through the writer guard
(:func:`sinscli.io.atomic.check_finite`; a NaN innovation is a filter failure,
not a row), the reader names the line and column.  The records are a numpy structured array of
:data:`DTYPE`.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..errors import SinsError, num
from ..inputs import native_path
from .atomic import atomic_path, check_finite
from .csvcore import _finite_columns, _locate_bad_cell, read_header
from .limits import check_sigma

DTYPE = np.dtype([("time", "f8"), ("type", "U16"), ("axis", "U8"), ("innovation", "f8"), ("sigma", "f8"),
                  ("nis", "f8"), ("accepted", "?")])
COLUMNS = list(DTYPE.names)
TYPES = ("gnss_pos", "gnss_vel", "zupt", "zaru", "nhc", "odom", "pseudorange", "doppler", "tdcp")
AXES = ("e", "n", "u", "x", "y", "z", "los")
SAT_DTYPE = np.dtype(DTYPE.descr + [("sat", "U4")])      # with a satellite column (raw GNSS rows)
FLOATS = ("time", "innovation", "sigma", "nis")


def check_records(where: str, rec: np.ndarray, first_row: int = 1, row_label: str = "record") -> None:
    """SinsError at the first record with an unknown type or axis, or a NIS below 0 (the values' finiteness
    and the sigma's sign are checked by the writer guard and the reader, as for every file)."""
    for name, known in (("type", TYPES), ("axis", AXES)):
        bad = ~np.isin(rec[name], known)
        if bad.any():
            k = int(np.argmax(bad))
            raise SinsError(f"{where}: {row_label} {first_row + k}, column '{name}': {str(rec[name][k])!r} is not one "
                            f"of {', '.join(known)}")
    bad = ~(rec["nis"] >= 0)
    if bad.any():
        k = int(np.argmax(bad))
        raise SinsError(f"{where}: {row_label} {first_row + k} (time {num(rec['time'][k])}, {rec['type'][k]} "
                        f"{rec['axis'][k]}), column 'nis': {num(rec['nis'][k])} is not a finite number >= 0")


def write_innovations(path, records: np.ndarray) -> None:
    """Write innovation records (structured array with the fields of :data:`DTYPE`) atomically.

    Refuses (SinsError naming the record and field, nothing written) records
    that lack a field, or hold an unknown type/axis, a non-finite value, a
    sigma <= 0 or a NIS < 0.
    """
    import pyarrow as pa  # pyarrow (0.3 s to import) only for a Parquet or innovations file
    import pyarrow.csv as pacsv  # pyarrow (0.3 s to import) only for a Parquet or innovations file
    rec = np.asarray(records)
    names = rec.dtype.names or ()
    missing = [c for c in COLUMNS if c not in names]
    if missing:
        raise SinsError(f"{path}: innovation records lack the field(s) {', '.join(missing)}; expected "
                        f"{', '.join(COLUMNS)}")
    rec = rec.reshape(-1)
    check_finite(path, {c: rec[c] for c in FLOATS}, rec["time"], sigmas=("sigma",))
    check_records(f"{path}: cannot write innovations", rec)
    cols = {"time": np.ascontiguousarray(rec["time"], dtype=np.float64),
            "type": pa.array(rec["type"].astype(str).tolist(), pa.string()),
            "axis": pa.array(rec["axis"].astype(str).tolist(), pa.string()),
            "innovation": np.ascontiguousarray(rec["innovation"], dtype=np.float64),
            "sigma": np.ascontiguousarray(rec["sigma"], dtype=np.float64),
            "nis": np.ascontiguousarray(rec["nis"], dtype=np.float64),
            "accepted": pa.array(rec["accepted"].astype(bool))}
    names = list(COLUMNS)
    if "sat" in rec.dtype.names and np.any(rec["sat"].astype(str) != ""):
        cols["sat"] = pa.array(rec["sat"].astype(str).tolist(), pa.string())
        names.append("sat")
    table = pa.table(cols)
    buf = io.BytesIO()
    pacsv.write_csv(table, buf, write_options=pacsv.WriteOptions(include_header=False, quoting_style="none",
                                                                 batch_size=1 << 16))
    with atomic_path(path, suffix=".csv") as tmp:
        with open(tmp, "wb") as fh:
            fh.write((",".join(names) + "\n").encode())
            fh.write(buf.getbuffer())


def read_innovations(path) -> np.ndarray:
    """Read an innovations CSV back into a structured array of :data:`DTYPE` (checks as the writer)."""
    import pyarrow as pa  # pyarrow (0.3 s to import) only for a Parquet or innovations file
    import pyarrow.csv as pacsv  # pyarrow (0.3 s to import) only for a Parquet or innovations file
    path = Path(path)
    header = read_header(path)
    if header not in (COLUMNS, COLUMNS + ["sat"]):
        raise SinsError(f"{path}: header {','.join(header)!r} is not that of an innovations file "
                        f"({','.join(COLUMNS)}[,sat])")
    types = {"time": pa.float64(), "type": pa.string(), "axis": pa.string(), "innovation": pa.float64(),
             "sigma": pa.float64(), "nis": pa.float64(), "accepted": pa.bool_(), "sat": pa.string()}
    try:
        table = pacsv.read_csv(native_path(path), convert_options=pacsv.ConvertOptions(
            column_types=types, strings_can_be_null=False, quoted_strings_can_be_null=False, null_values=[],
            true_values=["true"], false_values=["false"]))
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
        msg = _locate_bad_cell(path, list(FLOATS), exc)
        if "cannot parse" in msg:
            msg = f"{path}: column 'accepted' holds a value other than true/false, or a row is malformed ({msg})"
        raise SinsError(msg) from None
    rec = np.empty(table.num_rows, dtype=SAT_DTYPE if "sat" in header else DTYPE)
    for c in header:
        col = table.column(c)
        rec[c] = col.to_numpy(zero_copy_only=False) if c not in ("type", "axis", "sat") else \
            np.array(col.to_pylist(), dtype=str)
    _finite_columns(path, {c: c for c in FLOATS}, table.column, 2)
    check_sigma(path, rec["sigma"], "sigma", 2)
    check_records(str(path), rec, first_row=2, row_label="line")
    return rec
