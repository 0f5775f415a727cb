"""IMU CSV reader and writer (docs/formats.md ``imu.csv``), plus the checks every IMU log gets.

Two forms are read: rates (``gyro_*`` rad/s, ``accel_*`` m/s^2 at ``time``)
and increments (``dtheta_*`` rad, ``dvel_*`` m/s over (previous time, time]).
Rates are turned into increments by the trapezoidal rule between consecutive
samples (:func:`rates_to_increments`); the first rate sample's time starts the
first interval.  Other column names and units come from the config.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..config import ACCEL_UNITS, ANGLE_UNITS, GYRO_UNITS, IMU_NAMES, VEL_UNITS, ImuSection, Limits, mounting_matrix
from ..errors import SinsError
from ..types import ImuLog, merged_resolution, value_step
from . import limits as limits_mod
from .atomic import atomic_path
from .csvcore import STREAM_BLOCK, iter_numeric_columns, name_list, read_header, write_table_csv

log = logging.getLogger("sins")

RATE_COLS = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
INC_COLS = ["dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z"]
GAP_FACTOR = 5.0


def rates_to_increments(time, gyro, accel):
    """Trapezoidal increments between rate samples.

    ``dtheta_k = (w_{k-1} + w_k)/2 (t_k - t_{k-1})`` and likewise for ``dvel``;
    returns ``(time[1:], dtheta, dvel, t0 = time[0])``.
    """
    time = np.asarray(time, dtype=float)
    if time.shape[0] < 2:
        raise SinsError("rate log has fewer than 2 samples; cannot form increments")
    dt = np.diff(time)[:, None]
    dtheta = 0.5 * (gyro[1:] + gyro[:-1]) * dt
    dvel = 0.5 * (accel[1:] + accel[:-1]) * dt
    return time[1:].copy(), dtheta, dvel, float(time[0])


def _resolve_columns(path, header, cfg_imu):
    """Map FORMATS names to file columns; decide the form; reject unknown columns."""
    mapping = dict(cfg_imu.columns)
    inverse = {v: k for k, v in mapping.items()}
    known = {inverse.get(c, c) for c in header}
    ignored = set(cfg_imu.ignore_columns)
    unknown = [c for c in header if inverse.get(c, c) not in IMU_NAMES and c not in ignored]
    if unknown:
        raise SinsError(f"{path}: unknown column(s) {name_list(unknown)}; expected time with "
                        f"gyro_x..accel_z (rates) or dtheta_x..dvel_z (increments); map other names with the "
                        f"config's imu.columns or list them in imu.ignore_columns")
    has_rates = any(c in known for c in RATE_COLS)
    has_incs = any(c in known for c in INC_COLS)
    if has_rates and has_incs:
        raise SinsError(f"{path}: holds both rate and increment columns; expected one form")
    form_cols = INC_COLS if has_incs else RATE_COLS
    missing = [c for c in ["time"] + form_cols if c not in known]
    if missing:
        raise SinsError(f"{path}: missing column(s) {', '.join(missing)}; expected time, "
                        f"{', '.join(form_cols)}" + (" (or their config imu.columns mapping)" if mapping else ""))
    cols = {c: mapping.get(c, c) for c in ["time"] + form_cols}
    return ("increments" if has_incs else "rates"), cols


class TimeChecker:
    """Strictly increasing time; gaps over 5 nominal intervals refused unless allowed.

    Works block by block (the nominal interval is the median spacing of the
    first block); messages give file line numbers (header = line 1).  A bridged gap is warned about,
    the first ``MAX_GAP_WARNINGS`` of a file one by one, the rest in one line; ``warn_gaps`` False for
    logs whose gaps are expected and reported elsewhere (a GNSS log's outages: the fused run's summary).
    """
    MAX_GAP_WARNINGS = 3

    def __init__(self, path, allow_gaps=False, what="time", row_label="line", warn_gaps=True):
        self.path, self.allow_gaps, self.what, self.row = path, allow_gaps, what, row_label
        self.warn_gaps = warn_gaps
        self.prev = None
        self.nominal = None
        self.n_gaps = 0

    def check(self, time, first_line):
        path = self.path
        if self.prev is not None:
            full = np.concatenate([[self.prev], time])
            line0 = first_line - 1
        else:
            full = time
            line0 = first_line
        dt = np.diff(full)
        if dt.size:
            bad = dt <= 0
            if bad.any():
                k = int(np.argmax(bad))
                how = "repeats" if dt[k] == 0 else "goes backwards"
                raise SinsError(f"{path}: {self.row} {line0 + k + 1}, {self.what}: time {float(full[k + 1])!r} "
                                f"{how} (previous row {float(full[k])!r}); time must strictly increase")
            if self.nominal is None:
                self.nominal = float(np.median(dt))
            gaps = np.nonzero(dt > GAP_FACTOR * self.nominal)[0]
            for k in gaps:
                if not self.allow_gaps:
                    raise SinsError(f"{path}: {self.row} {line0 + k + 1}: gap of {dt[k]:.6g} s before time "
                                    f"{float(full[k + 1])!r} ({dt[k] / self.nominal:.1f} nominal intervals of "
                                    f"{self.nominal:.6g} s; at most {GAP_FACTOR:g} allowed); use --allow-gaps "
                                    f"to bridge it")
                self.n_gaps += 1
                if self.warn_gaps and self.n_gaps <= self.MAX_GAP_WARNINGS:
                    log.warning("%s: bridging a gap of %.6g s from time %r to %r (%.1f nominal intervals)%s",
                                path, dt[k], float(full[k]), float(full[k + 1]), dt[k] / self.nominal,
                                "; further gaps are bridged without a warning each" if
                                self.n_gaps == self.MAX_GAP_WARNINGS else "")
        self.prev = float(time[-1])


def check_time(path, time, allow_gaps=False, what="time", warn_gaps=True):
    """Check a whole time column (see :class:`TimeChecker`)."""
    TimeChecker(path, allow_gaps, f"column '{what}'", warn_gaps=warn_gaps).check(np.asarray(time, dtype=float), 2)


def iter_imu_csv(path, cfg: ImuSection | None = None, allow_gaps=False, block_bytes=STREAM_BLOCK,
                 limits: Limits | None = None):
    """Stream an IMU CSV (either form) as :class:`ImuLog` blocks of increments, SI units, body axes.

    ``cfg`` is the config's ``imu`` section (column mapping, units, mounting; default: the defaults),
    ``limits`` its ``limits`` section (default: the defaults): rates, forces and the rates an increment implies
    beyond them are refused naming the line and column.
    Rate logs carry their last sample into the next block, so the increments
    are the same as for the whole file at once.
    """
    cfg_imu = cfg if cfg is not None else ImuSection()
    lim = limits if limits is not None else Limits()
    path = Path(path)
    header = read_header(path)
    form, cols = _resolve_columns(path, header, cfg_imu)
    units = cfg_imu.units
    c_sb = mounting_matrix(cfg_imu.mounting)
    checker = TimeChecker(path, allow_gaps, what=f"column '{cols['time']}'")
    value_cols = [cols[c] for c in (RATE_COLS if form == "rates" else INC_COLS)]
    last = None       # last rate sample (time, gyro, accel) of the previous block
    rows = 0
    for line, data in iter_numeric_columns(path, cols, block_bytes):
        time = data["time"]
        limits_mod.check_time(path, time, lim, cols["time"], line)
        prev_time = checker.prev
        checker.check(time, line)
        rows += time.shape[0]
        if form == "rates":
            gyro = np.column_stack([data[c] for c in RATE_COLS[:3]]) * GYRO_UNITS[units["gyro"]]
            accel = np.column_stack([data[c] for c in RATE_COLS[3:]]) * ACCEL_UNITS[units["accel"]]
            limits_mod.check_imu_rates(path, gyro, accel, lim, value_cols, line, gyro_unit=units["gyro"])
            if last is None:
                check_rate_units(path, gyro, units["gyro"])
            else:
                time = np.concatenate([[last[0]], time])
                gyro = np.vstack([last[1], gyro])
                accel = np.vstack([last[2], accel])
            last = (time[-1], gyro[-1:].copy(), accel[-1:].copy())
            if time.shape[0] < 2:
                continue
            tend, dtheta, dvel, t0 = rates_to_increments(time, gyro, accel)
            imu = ImuLog(tend, dtheta, dvel, t0=t0, source=str(path), kind="rates",
                         resolution=(value_step(gyro), value_step(accel)))
        else:
            dtheta = np.column_stack([data[c] for c in INC_COLS[:3]]) * ANGLE_UNITS[units["dtheta"]]
            dvel = np.column_stack([data[c] for c in INC_COLS[3:]]) * VEL_UNITS[units["dvel"]]
            # the interval of each row; the first row's (which starts at the initial time) is taken
            # as long as the next one, so a shorter true first interval only makes the check milder
            dt = np.diff(time, prepend=prev_time if prev_time is not None else np.nan)
            if prev_time is None:
                dt[0] = dt[1] if dt.shape[0] > 1 else np.inf
            limits_mod.check_imu_increments(path, dt, dtheta, dvel, lim, value_cols, line, dtheta_unit=units["dtheta"])
            imu = ImuLog(time, dtheta, dvel, t0=None, source=str(path), kind="increments",
                         resolution=(value_step(dtheta), value_step(dvel)))
        yield apply_mounting(imu, c_sb)
    if form == "rates" and rows < 2:
        raise SinsError(f"{path}: a rate log needs at least 2 rows to form increments")


def concat_imu(blocks) -> ImuLog:
    """One :class:`ImuLog` from consecutive blocks."""
    blocks = list(blocks)
    if len(blocks) == 1:
        return blocks[0]
    first = blocks[0]
    return ImuLog(np.concatenate([b.time for b in blocks]), np.vstack([b.dtheta_b for b in blocks]),
                  np.vstack([b.dvel_b for b in blocks]), t0=first.t0, source=first.source, kind=first.kind,
                  resolution=merged_resolution([b.resolution for b in blocks]))


def read_imu_csv(path, cfg: ImuSection | None = None, allow_gaps=False) -> ImuLog:
    """Read a whole IMU CSV into one :class:`ImuLog` (see :func:`iter_imu_csv`)."""
    return concat_imu(iter_imu_csv(path, cfg, allow_gaps))


def apply_mounting(imu: ImuLog, c_sb: np.ndarray) -> ImuLog:
    """Rotate increments from sensor to body axes: ``x_b = C_s^b x_s`` (exact for a fixed mount)."""
    if np.array_equal(c_sb, np.eye(3)):
        return imu
    imu.dtheta_b = imu.dtheta_b @ c_sb.T
    imu.dvel_b = imu.dvel_b @ c_sb.T
    return imu


def check_rate_units(path, gyro_rad_s, unit):
    """Warn when gyro values look like deg/s although the file is read as rad/s."""
    if unit != "rad/s" or gyro_rad_s.shape[0] < 10:
        return
    p99 = float(np.percentile(np.abs(gyro_rad_s), 99))
    if p99 > 2 * np.pi:
        log.warning("%s: gyro rates reach %.3g rad/s (99th percentile): the file probably holds deg/s; "
                    "set imu.units.gyro: deg/s in the config", path, p99)


def check_static_start(imu: ImuLog, g_local: float, conv: int = 0, seconds: float = 1.0):
    """Warn when the mean specific force over the first seconds is far from g (said to be static).

    Names the likely mistake: units of g or mg, or an axis pointing down or
    sideways (wrong body convention or a missing mounting rotation).
    """
    t_first = imu.time[0] - (imu.time[1] - imu.time[0]) if len(imu) > 1 else imu.time[0]
    sel = imu.time <= t_first + seconds
    if sel.sum() < 1:
        return None
    span = imu.time[sel][-1] - t_first
    f = imu.dvel_b[sel].sum(axis=0) / span
    mag = float(np.linalg.norm(f))
    if abs(mag - g_local) <= 0.05 * g_local:
        up_sign = -1.0 if conv == 2 else 1.0        # FRD: z down
        k = int(np.argmax(np.abs(f)))
        if k == 2 and f[2] * up_sign > 0:
            return None
        axis = "xyz"[k]
        sign = "+" if f[k] > 0 else "-"
        expect = "-z (FRD)" if conv == 2 else "+z (FLU/RFU)"
        if k == 2:
            hint = "set imu.body: flu" if conv == 2 else "FRD axes? set imu.body: frd"
        else:
            hint = "set imu.mounting (sensor axes are rotated against the body)"
        msg = (f"{imu.source}: at rest the specific force should point along {expect}, "
               f"but it is along {sign}{axis} ({f[0]:.3f}, {f[1]:.3f}, {f[2]:.3f}) m/s^2: {hint}")
        log.warning(msg)
        return msg
    if abs(mag * ACCEL_UNITS["g"] - g_local) < 0.05 * g_local:
        hint = "the file probably holds g; set imu.units.accel: g"
    elif abs(mag * ACCEL_UNITS["mg"] - g_local) < 0.05 * g_local:
        hint = "the file probably holds mg; set imu.units.accel: mg"
    else:
        hint = "check the accelerometer units and scale"
    msg = (f"{imu.source}: mean specific force over the first {seconds:g} s is {mag:.4g} m/s^2, "
           f"far from local gravity {g_local:.4f} m/s^2 although the start is said to be static: {hint}")
    log.warning(msg)
    return msg


def write_imu_rates_csv(path, time, gyro, accel) -> None:
    """Write rates (docs/formats.md rate form: ``time``, ``gyro_*`` rad/s, ``accel_*`` m/s^2), atomically, exact floats."""
    data = {"time": time}
    for i, ax in enumerate("xyz"):
        data[f"gyro_{ax}"] = gyro[:, i]
    for i, ax in enumerate("xyz"):
        data[f"accel_{ax}"] = accel[:, i]
    with atomic_path(path) as tmp:
        write_table_csv(tmp, data, ["time"] + RATE_COLS)


def write_imu_csv(path, imu: ImuLog) -> None:
    """Write increments (docs/formats.md increment form), atomically, exact floats."""
    data = {"time": imu.time}
    for i, ax in enumerate("xyz"):
        data[f"dtheta_{ax}"] = imu.dtheta_b[:, i]
    for i, ax in enumerate("xyz"):
        data[f"dvel_{ax}"] = imu.dvel_b[:, i]
    with atomic_path(path) as tmp:
        write_table_csv(tmp, data, ["time"] + INC_COLS)
