"""Trajectory files (FORMATS.md trajectory CSV): read, and write as CSV or Parquet (streamed).

Extra columns (e.g. the 1-sigma and bias columns of an aided trajectory,
:mod:`sinscli.io.aided_columns`) are written and read as they are; every
value must be finite and every ``*_std`` column positive, on writing and on
reading (FORMATS.md).

Other formats register a writer in :data:`WRITERS` by suffix
(``function(path, traj, conv)``, writing atomically).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..nav.rotation import dcm_to_euler_many, dcm_to_quat_many, quat_to_dcm_many
from ..types import Trajectory
from . import aided_columns
from .atomic import atomic_path
from .csvcore import CsvTableWriter, read_header, read_numeric_columns

BASE_COLUMNS = ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u", "roll", "pitch", "heading",
                "qw", "qx", "qy", "qz"]
DCM_COLUMNS = [f"c{i}{j}" for i in range(1, 4) for j in range(1, 4)]
REQUIRED = BASE_COLUMNS

# suffix -> writer(path, traj, conv); filled by format modules (MCAP, TUM, GeoJSON, KML).
WRITERS: dict = {}


def trajectory_columns(traj: Trajectory, conv: int = 0, with_dcm: bool = True) -> dict[str, np.ndarray]:
    """FORMATS.md columns of a trajectory (degrees for angles), plus its extra columns."""
    cbn = np.ascontiguousarray(traj.Cbn, dtype=np.float64)
    eul = dcm_to_euler_many(cbn, conv)
    q = dcm_to_quat_many(cbn)
    d = math.degrees(1.0)
    cols = {"time": traj.time, "lat": traj.lat * d, "lon": traj.lon * d, "height": traj.height,
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
    """Stream trajectory chunks to ``.csv`` or ``.parquet`` through a temporary file.

    ``close()`` renames into place; ``abort()`` (or an exception inside a
    ``with`` block) removes the temporary file, leaving no output.
    """

    def __init__(self, path, conv: int = 0, extra_columns=()):
        self.path = Path(path)
        self.conv = conv
        self.suffix = self.path.suffix.lower()
        if self.suffix not in (".csv", ".parquet"):
            raise SinsError(f"{path}: streaming output supports .csv and .parquet")
        self.columns = BASE_COLUMNS + DCM_COLUMNS + list(extra_columns)
        self._ctx = atomic_path(self.path)
        self._tmp = self._ctx.__enter__()
        self._writer = None
        self._rows = 0

    def write(self, traj: Trajectory) -> None:
        cols = trajectory_columns(traj, self.conv)
        # no writer emits NaN, infinity or a sigma <= 0 (rows counted from the initial row, 0)
        aided_columns.check_columns(f"{self.path}: cannot write", {c: cols[c] for c in self.columns},
                                    first_row=self._rows, row_label="row")
        self._rows += len(traj)
        if self.suffix == ".csv":
            if self._writer is None:
                self._writer = CsvTableWriter(self._tmp, self.columns)
            self._writer.write(cols)
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq
            table = pa.table({c: np.ascontiguousarray(cols[c], dtype=np.float64) for c in self.columns})
            if self._writer is None:
                self._writer = pq.ParquetWriter(self._tmp, table.schema)
            self._writer.write_table(table)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        self._ctx.__exit__(None, None, None)

    def abort(self, exc=None) -> None:
        if self._writer is not None:
            try:
                self._writer.close()
            except Exception:
                pass
        try:
            self._ctx.__exit__(type(exc) if exc else RuntimeError, exc or RuntimeError("aborted"), None)
        except BaseException:
            pass

    def __enter__(self):
        return self

    def __exit__(self, et, ev, tb):
        if et is None:
            self.close()
        else:
            self.abort(ev)
        return False


def write_trajectory(path, traj: Trajectory, conv: int = 0) -> None:
    """Write a whole trajectory; the format follows the suffix (.csv, .parquet, or a registered one)."""
    suffix = Path(path).suffix.lower()
    if suffix in (".csv", ".parquet"):
        with TrajectoryWriter(path, conv, extra_columns=list(traj.extra)) as w:
            w.write(traj)
        return
    if suffix not in WRITERS:
        known = ", ".join(sorted({".csv", ".parquet", *WRITERS}))
        raise SinsError(f"{path}: unknown output format '{suffix}'; expected one of {known}")
    WRITERS[suffix](path, traj, conv)


def read_trajectory(path) -> Trajectory:
    """Read a trajectory CSV or Parquet.  ``c11..c33`` are used when present, else the quaternion."""
    path = Path(path)
    if path.suffix.lower() == ".parquet":
        if not path.exists():
            raise SinsError(f"{path}: file not found")
        import pyarrow.parquet as pq
        try:
            table = pq.read_table(path)
        except Exception as exc:
            raise SinsError(f"{path}: cannot read as Parquet ({type(exc).__name__})") from None
        header = table.column_names
        _check_columns(path, header)
        data = {c: table.column(c).to_numpy().astype(float) for c in header}
        for c, a in data.items():
            if not np.all(np.isfinite(a)):
                k = int(np.argmax(~np.isfinite(a)))
                raise SinsError(f"{path}: row {k + 1}, column '{c}': value is not a finite number")
    else:
        header = read_header(path)
        _check_columns(path, header)
        data = read_numeric_columns(path, {c: c for c in header})
    from .imu_csv import check_time
    check_time(path, data["time"], allow_gaps=True)
    d2r = math.radians(1.0)
    if all(c in data for c in DCM_COLUMNS):
        cbn = np.stack([np.stack([data[f"c{i}{j}"] for j in range(1, 4)], axis=-1) for i in range(1, 4)],
                       axis=-2)
    else:
        q = np.column_stack([data["qw"], data["qx"], data["qy"], data["qz"]])
        cbn = quat_to_dcm_many(q / np.linalg.norm(q, axis=1, keepdims=True))
    extra = {c: data[c] for c in data if c not in BASE_COLUMNS and c not in DCM_COLUMNS}
    parquet = path.suffix.lower() == ".parquet"
    aided_columns.check_columns(str(path), extra, first_row=1 if parquet else 2, row_label="row" if parquet else "line")
    return Trajectory(data["time"], data["lat"] * d2r, data["lon"] * d2r, data["height"],
                      np.column_stack([data["vel_e"], data["vel_n"], data["vel_u"]]), cbn, extra,
                      source=str(path))


def _check_columns(path, header):
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise SinsError(f"{path}: missing trajectory column(s) {', '.join(missing)}; expected "
                        f"{', '.join(REQUIRED)} (FORMATS.md)")


# Result formats of other modules (MCAP for Foxglove/ROS, TUM for evo, GeoJSON and KML for maps).
from .foxglove import write_trajectory_mcap  # noqa: E402
from .geo import write_geojson, write_kml  # noqa: E402
from .tum import write_tum  # noqa: E402

WRITERS.update({".mcap": write_trajectory_mcap, ".tum": write_tum, ".geojson": write_geojson, ".kml": write_kml})
