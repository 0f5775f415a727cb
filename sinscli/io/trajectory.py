"""Trajectory files (docs/formats.md trajectory CSV): read, and write as CSV or Parquet (streamed).

Extra columns (e.g. the 1-sigma and bias columns of an aided trajectory,
:mod:`sinscli.io.aided_columns`) are written and read as they are; every
value must be finite and every ``*_std`` column positive, on writing and on
reading (docs/formats.md).

Other formats register a writer in :data:`WRITERS` by suffix
(``function(path, traj, conv)``, writing atomically).
"""
from __future__ import annotations

import contextlib
import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pyarrow as pa

from ..conventions import BODY_CONVENTIONS, FLU
from ..errors import SinsError, quote
from ..inputs import closing_native, input_file, native_path
from ..nav.rotation import dcm_to_euler_many, dcm_to_quat_many, euler_to_dcm_many, quat_to_dcm_many
from ..types import Trajectory
from . import aided_columns
from . import limits as limits_mod
from .atomic import StagedFile, check_finite, output_lon_lat, prepare_output
from .csvcore import CsvTableWriter, float64_table, float_column, read_header, read_numeric_columns
from ..frames import cbn_to_enu, file_name, to_enu

BASE_COLUMNS = ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u", "roll", "pitch", "heading",
                "qw", "qx", "qy", "qz"]
DCM_COLUMNS = [f"c{i}{j}" for i in range(1, 4) for j in range(1, 4)]
REQUIRED = BASE_COLUMNS
ROTATION_TOL = 1e-3          # a read attitude (c11..c33, or the quaternion's norm) is a rotation within this
# The body convention of the attitude (docs/io_formats.md): the CSV column ``body`` (the same text on every row,
# after the numbers; written for RFU and FRD, a file without it is FLU as docs/formats.md says) and the Parquet
# key-value metadata ``sins.body`` (always written).
BODY_COLUMN = "body"
BODY_METADATA = b"sins.body"
BODY_NAMES = {code: name for name, code in BODY_CONVENTIONS.items()}

# suffix -> writer(path, traj, conv); filled by format modules (MCAP, TUM, GeoJSON, KML).
WRITERS: dict = {}


def trajectory_columns(traj: Trajectory, conv: int = 0, with_dcm: bool = True, path=None,
                       first_row: int = 1) -> dict[str, np.ndarray]:
    """docs/formats.md columns of a trajectory (degrees for angles), plus its extra columns; latitude and
    longitude through the writers' guard (:func:`sinscli.io.atomic.output_lon_lat`: longitude in
    [-180, 180), latitude within +-90) for the output ``path``."""
    cbn = np.ascontiguousarray(traj.Cbn, dtype=np.float64)
    eul = dcm_to_euler_many(cbn, conv)
    q = dcm_to_quat_many(cbn)
    d = math.degrees(1.0)
    lat, lon = output_lon_lat(path or traj.source, traj.lat * d, traj.lon * d, traj.time, first_row)
    cols = {"time": traj.time, "lat": lat, "lon": lon, "height": traj.height,
            "vel_e": traj.vel_n[:, 0], "vel_n": traj.vel_n[:, 1], "vel_u": traj.vel_n[:, 2],
            "roll": eul[:, 0] * d, "pitch": eul[:, 1] * d, "heading": eul[:, 2] * d,
            "qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]}
    if with_dcm:
        for i in range(3):
            for j in range(3):
                cols[f"c{i + 1}{j + 1}"] = cbn[:, i, j]
    cols.update(traj.extra)
    return cols


class TrajectoryWriter:
    """Stream trajectory chunks to ``.csv`` or ``.parquet`` through a staged file
    (:class:`sinscli.io.atomic.StagedFile`).

    ``close()`` hands the complete file over to be moved into place; ``abort()`` (or an exception
    inside a ``with`` block) removes it, leaving no output.  Either raises a file system fault (disk
    full, I/O error) as the one-line write error naming the target.
    """

    def __init__(self, path, conv: int = 0, extra_columns=()):
        self.path = check_trajectory_output(path)
        self.conv = conv
        self.suffix = self.path.suffix.lower()
        if self.suffix not in (".csv", ".parquet"):
            raise SinsError(f"{path}: streaming output supports .csv and .parquet")
        self.columns = BASE_COLUMNS + DCM_COLUMNS + list(extra_columns)
        self.sigmas = [c for c in self.columns if aided_columns.is_sigma(c)]
        self._stage = StagedFile(self.path)
        self._tmp = self._stage.tmp
        self._writer = None
        self._rows = 0
        self._pool = None          # Parquet: one thread writes row groups while the caller computes the next
        self._pending = None
        self._sink = None          # a pyarrow file of a name that is not UTF-8 (io/inputs.native_path)
        self._open = True

    def write(self, traj: Trajectory) -> None:
        try:
            self._write(traj)
        except BaseException as exc:
            raise self.abort(exc) from None

    def _write(self, traj: Trajectory) -> None:
        cols = trajectory_columns(traj, self.conv, path=self.path, first_row=self._rows + 1)
        if self.suffix != ".csv":            # (the CSV table writer applies the same guard)
            check_finite(self.path, {c: cols[c] for c in self.columns}, cols["time"], self._rows + 1, self.sigmas)
        self._rows += len(traj)
        if self.suffix == ".csv":
            if self._writer is None:
                text = {BODY_COLUMN: BODY_NAMES[self.conv]} if self.conv != FLU else {}
                self._writer = CsvTableWriter(self._tmp, self.columns, self.sigmas, text_columns=text)
            self._writer.write(cols)
        else:
            import pyarrow.parquet as pq
            table = float64_table({c: cols[c] for c in self.columns})
            table = table.replace_schema_metadata({BODY_METADATA: BODY_NAMES[self.conv].encode()})
            if self._writer is None:
                # no dictionary encoding: navigation floats hardly repeat, and it costs 2.4x the write time
                self._sink = native_path(self._tmp, "wb")
                self._writer = pq.ParquetWriter(self._sink, table.schema, use_dictionary=False)
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="sins-parquet")
            self._wait()                      # in order; an error of the previous row group surfaces here
            self._pending = self._pool.submit(self._writer.write_table, table)   # pyarrow releases the GIL

    def _wait(self) -> None:
        if self._pending is not None:
            pending, self._pending = self._pending, None
            pending.result()

    def _shutdown(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def close(self) -> None:
        """Finish the file (the last row group or CSV slices, flushed) and hand it over."""
        if not self._open:
            return
        try:
            self._wait()
            self._shutdown()
            if self._writer is not None:
                self._writer.close()
                if self._sink is not None:
                    closing_native(self._sink)
            self._open = False
            self._stage.done()
        except BaseException as exc:        # a late write error (disk full at the last block): no output
            raise self.abort(exc) from None

    def abort(self, exc=None) -> BaseException | None:
        """Remove the staged file; return the exception to raise (a file system fault as the write error)."""
        if not self._open:
            return exc
        self._open = False
        with contextlib.suppress(Exception):
            self._wait()
        self._shutdown()
        if self._writer is not None:
            with contextlib.suppress(Exception):
                if isinstance(self._writer, CsvTableWriter):
                    self._writer.discard()
                else:
                    self._writer.close()
                if self._sink is not None:
                    closing_native(self._sink)
        return self._stage.fail(exc)

    def __enter__(self):
        return self

    def __exit__(self, et, ev, tb):
        if et is None:
            self.close()
            return False
        err = self.abort(ev)
        if err is not None and err is not ev:
            raise err from None
        return False


def write_trajectory(path, traj: Trajectory, conv: int = 0) -> None:
    """Write a whole trajectory; the format follows the suffix (.csv, .parquet, or a registered one)."""
    suffix = Path(path).suffix.lower()
    if suffix in (".csv", ".parquet"):
        with TrajectoryWriter(path, conv, extra_columns=list(traj.extra)) as w:
            w.write(traj)
        return
    check_trajectory_output(path)
    guard_trajectory(path, traj)
    WRITERS[suffix](path, traj, conv)


def guard_trajectory(path, traj: Trajectory) -> None:
    """The writer guards (:func:`sinscli.io.atomic.check_finite`, :func:`~sinscli.io.atomic.output_lon_lat`) on a
    whole trajectory: every value finite, every ``*_std`` column positive, every latitude within +-90 deg
    (the writers of :data:`WRITERS` rely on it)."""
    check_finite(path, {"time": traj.time, "lat": traj.lat, "lon": traj.lon, "height": traj.height,
                        "velocity": traj.vel_n, "attitude": traj.Cbn, **traj.extra}, traj.time,
                 sigmas=[c for c in traj.extra if aided_columns.is_sigma(c)])
    output_lon_lat(path, np.degrees(traj.lat), np.degrees(traj.lon), traj.time)    # no track over a pole


def check_trajectory_output(path) -> Path:
    """Refuse, before any work, an output that is a directory or has no known trajectory format."""
    path = Path(path)
    if path.is_dir():
        raise SinsError(f"{path}: output is a directory; give a file name")
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", *WRITERS):
        known = ", ".join(sorted({".csv", ".parquet", *WRITERS}))
        what = f"unknown output format '{suffix}'" if suffix else "no file suffix to tell the output format"
        raise SinsError(f"{path}: {what}; expected one of {known}")
    return prepare_output(path)


def read_trajectory(path, limits=None, frame: str = "enu", to_deg: float = 1.0) -> Trajectory:
    """Read a trajectory CSV or Parquet.  ``c11..c33`` are used when present, else the quaternion.

    Rows beyond the physical ``limits`` (the config's section; default: the defaults), Euler angles
    out of range and an attitude that is not a rotation are refused naming the row and column.  A file
    in ``frame`` NED (``vel_d``, attitude body -> NED) or with angles in radians (``to_deg``, the factor to
    degrees) is read into docs/formats.md's ENU and degrees (:mod:`sinscli.frames`, the config's ``init``
    and ``truth`` sections).
    """
    lim = limits_mod.resolve(limits)
    path = input_file(path, "trajectory file")
    if path.suffix.lower() == ".parquet":
        import pyarrow.parquet as pq
        try:
            table = pq.read_table(native_path(path))
        except Exception as exc:
            raise SinsError(f"{path}: cannot read as Parquet ({type(exc).__name__})") from None
        header = table.column_names
        _check_columns(path, header, frame)
        marker = (table.schema.metadata or {}).get(BODY_METADATA)
        body = _body_code(path, marker.decode("utf-8", "replace") if marker is not None else None,
                          f"metadata {BODY_METADATA.decode()}")
        try:
            data = {c: float_column(table.column(c)) for c in header}
        except (TypeError, ValueError, pa.ArrowException) as exc:
            raise SinsError(f"{path}: a column is not numeric ({type(exc).__name__})") from None
        for c, a in data.items():
            if not np.all(np.isfinite(a)):
                k = int(np.argmax(~np.isfinite(a)))
                raise SinsError(f"{path}: row {k + 1}, column '{c}': value is not a finite number")
        first, row = 1, "row"
    else:
        header = read_header(path)
        _check_columns(path, header, frame)
        body = _read_body_column(path) if BODY_COLUMN in header else None
        data = read_numeric_columns(path, {c: c for c in header if c != BODY_COLUMN})
        first, row = 2, "line"
    if frame == "ned":
        data["vel_u"] = data.pop("vel_d")           # (negated by to_enu)
    data = to_enu(data, frame, to_deg)
    from .imu_csv import check_time
    limits_mod.check_time(path, data["time"], lim, "time", first, row)
    check_time(path, data["time"], allow_gaps=True)
    limits_mod.check_position(path, data["lat"], data["lon"], data["height"], lim, first=first, row=row)
    vel = np.column_stack([data["vel_e"], data["vel_n"], data["vel_u"]])
    limits_mod.check_velocity(path, vel, lim, ["vel_e", "vel_n", "vel_u"], first, row)
    a = limits_mod.ANGLE_RANGE
    for c, lo, hi in (("roll", -a, a), ("pitch", -90.0, 90.0), ("heading", -a, a)):
        limits_mod.check_range(path, data[c], lo, hi, c, None, " deg", c, first, row)
    d2r = math.radians(1.0)
    if all(c in data for c in DCM_COLUMNS):
        cbn = np.stack([np.stack([data[f"c{i}{j}"] for j in range(1, 4)], axis=-1) for i in range(1, 4)],
                       axis=-2)
        limits_mod.check_abs(path, cbn.reshape(-1, 9), 1.0 + ROTATION_TOL, "direction cosine", None, "",
                             DCM_COLUMNS, first, row)
        err = np.abs(np.einsum("nij,nkj->nik", cbn, cbn) - np.eye(3)).max(axis=(1, 2))
        limits_mod.check_abs(path, err, ROTATION_TOL, "departure of c11..c33 from a rotation (|C C^T - I|)",
                             None, "", "c11..c33", first, row)
    else:
        q = np.column_stack([data["qw"], data["qx"], data["qy"], data["qz"]])
        limits_mod.check_abs(path, q, 1.0 + ROTATION_TOL, "quaternion element", None, "",
                             ["qw", "qx", "qy", "qz"], first, row)
        norm = np.linalg.norm(q, axis=1)
        limits_mod.check_abs(path, norm - 1.0, ROTATION_TOL, "departure of the quaternion norm from 1", None, "",
                             "qw..qz", first, row)
        cbn = quat_to_dcm_many(q / norm[:, None])
    cbn = np.ascontiguousarray(cbn_to_enu(cbn, frame))
    extra = {c: data[c] for c in data if c not in BASE_COLUMNS and c not in DCM_COLUMNS and c != BODY_COLUMN}
    aided_columns.check_columns(str(path), extra, first, row)
    body_from = "marker"
    if body is None:                  # no marker: the physical Euler angles and the attitude tell the axes
        body, body_from = body_from_angles(cbn, data["roll"], data["pitch"], data["heading"]), "angles"
    return Trajectory(data["time"], data["lat"] * d2r, data["lon"] * d2r, data["height"], vel, cbn, extra,
                      source=str(path), body=body, body_from=body_from if body is not None else "")


def body_from_angles(cbn, roll_deg, pitch_deg, heading_deg, rows: int = 64) -> int | None:
    """The body convention under which the file's physical Euler angles (docs/formats.md roll, pitch, heading)
    give its attitude ``cbn``, from up to ``rows`` rows spread over the file: FLU, RFU or FRD, or None when
    none fits within 1e-6 (a writer that does not follow docs/formats.md).  The three give different ``Cbn``
    for the same angles (a quarter turn about z, a half turn about x), so at most one fits."""
    n = cbn.shape[0]
    k = np.unique(np.linspace(0, n - 1, min(rows, n)).astype(np.int64))
    r = np.radians(np.asarray(roll_deg, dtype=np.float64)[k])
    p = np.radians(np.asarray(pitch_deg, dtype=np.float64)[k])
    h = np.radians(np.asarray(heading_deg, dtype=np.float64)[k])
    for code in sorted(BODY_NAMES):
        if np.abs(euler_to_dcm_many(r, p, h, code) - cbn[k]).max() < 1e-6:
            return code
    return None


def _body_code(path, text, where) -> int | None:
    if text is None:
        return None
    code = BODY_CONVENTIONS.get(text.strip().lower())
    if code is None:
        raise SinsError(f"{path}: {where}: unknown body convention {quote(text, 30)}; expected one of "
                        f"{', '.join(BODY_CONVENTIONS)}")
    return code


def _read_body_column(path) -> int:
    """The ``body`` column of a trajectory CSV: one convention name, the same on every line."""
    import pyarrow.csv as pacsv
    try:
        col = pacsv.read_csv(native_path(path), convert_options=pacsv.ConvertOptions(
            include_columns=[BODY_COLUMN], column_types={BODY_COLUMN: pa.string()})).column(BODY_COLUMN)
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as exc:
        raise SinsError(f"{path}: column '{BODY_COLUMN}': cannot read ({type(exc).__name__})") from None
    values = [str(v).strip().lower() if v is not None else "" for v in col.to_pylist()]
    if not values:
        raise SinsError(f"{path}: no data rows after the header")
    first = values[0]
    for k, v in enumerate(values):
        if v != first or v not in BODY_CONVENTIONS:
            expect = f"'{first}' as on line 2" if v != first and first in BODY_CONVENTIONS else \
                f"one of {', '.join(BODY_CONVENTIONS)}"
            raise SinsError(f"{path}: line {k + 2}, column '{BODY_COLUMN}': {quote(v, 30)}: expected {expect}")
    return BODY_CONVENTIONS[first]


def _check_columns(path, header, frame: str = "enu"):
    required = [file_name(c, frame) for c in REQUIRED]
    missing = [c for c in required if c not in header]
    if missing:
        hint = " (a NED file: config frame: ned)" if frame != "ned" and "vel_d" in header else ""
        raise SinsError(f"{path}: missing trajectory column(s) {', '.join(missing)}; expected "
                        f"{', '.join(required)} (docs/formats.md){hint}")


# Result formats of other modules (MCAP for Foxglove/ROS, TUM for evo, GeoJSON and KML for maps).
from .foxglove import write_trajectory_mcap  # noqa: E402
from .geo import write_geojson, write_kml  # noqa: E402
from .tum import write_tum  # noqa: E402

WRITERS.update({".mcap": write_trajectory_mcap, ".tum": write_tum, ".geojson": write_geojson, ".kml": write_kml})
