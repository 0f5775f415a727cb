"""Physical limits: a value that cannot be physical is refused at the reader, naming its line and column.

The limits are the config's ``limits`` section (``configs/navigation.yaml``): angular rate, specific
force, speed, height range and time stamp magnitude.  An increment is judged by the rate it implies
over its interval (``|dtheta| / dt``, ``|dvel| / dt``), so a log in either form meets the same bound.
NaN never passes a check (every comparison is written so that NaN fails it).
"""
from __future__ import annotations

import numpy as np

from ..errors import SinsError, num, quote

LON_RANGE = 360.0            # deg: longitudes in [-360, 360] (both -180..180 and 0..360 conventions)
ANGLE_RANGE = 360.0          # deg: roll and heading in [-360, 360]
MAX_LOCAL_POSITION = 1.0e8   # m: a position in a local frame (TUM files), as far as the height limit
MAX_SIGMA = 1.0e9            # a 1-sigma read from a file (m, m/s, deg ...): positive and at most this (its square
                             # stays far from overflow)


def resolve(limits: dict | None) -> dict:
    """The limits to use: the given (validated) section, else the defaults of ``configs/navigation.yaml``."""
    if limits is None:
        from ..config import DEFAULTS
        return DEFAULTS["limits"]
    return limits


def _loc(row: str, k: int, column) -> str:
    """``: line 5, column 'gyro_x'`` (a file row), or ``: vel_e`` (a key, when ``row`` is empty)."""
    if not row:
        return f": {column}" if column is not None else ""
    return f": {row} {k}" + (f", column {quote(column)}" if column is not None else "")


def _refuse(where, row, k, column, what, value, bound, unit, key, hint=""):
    limit = f" (the config's limits.{key})" if key else ""
    raise SinsError(f"{where}{_loc(row, k, column)}: {what} {num(value)}{unit} is beyond the physical limit "
                    f"{num(bound)}{unit}{limit}{hint}")


def check_abs(where, values, bound: float, what: str, key: str | None, unit: str = "", columns=None,
              first=0, row: str = "line") -> None:
    """Refuse ``|value| > bound`` (or NaN) in a 1-D array or in the columns of a 2-D one.

    ``columns`` names the file column(s); ``first`` is the row number (in ``row`` units) of element 0,
    or an array of the row numbers of all elements.
    """
    v = np.asarray(values, dtype=np.float64)
    ok = np.abs(v) <= bound
    if ok.all():
        return
    bad = ~ok
    if v.ndim == 1:
        k, j = int(np.argmax(bad)), None
    else:
        k = int(np.argmax(bad.any(axis=1)))
        j = int(np.argmax(bad[k]))
    value = v[k] if j is None else v[k, j]
    column = columns if (j is None or columns is None) else columns[j]
    _refuse(where, row, _row(first, k), column, what, value, bound, unit, key)


def _row(first, k: int) -> int:
    return int(first[k]) if isinstance(first, np.ndarray) else first + k


def check_range(where, values, lo: float, hi: float, what: str, key: str | None, unit: str = "",
                column=None, first=0, row: str = "line") -> None:
    """Refuse values outside ``[lo, hi]`` (or NaN) in a 1-D array (``first`` as for :func:`check_abs`)."""
    v = np.asarray(values, dtype=np.float64)
    ok = (v >= lo) & (v <= hi)
    if ok.all():
        return
    k = int(np.argmax(~ok))
    limit = f" (the config's limits.{key})" if key else ""
    raise SinsError(f"{where}{_loc(row, _row(first, k), column)}: {what} {num(v[k])}{unit} is outside "
                    f"[{num(lo)}, {num(hi)}]{unit}{limit}")


def check_sigma(where, values, column=None, first=0, row: str = "line", hint: str = "",
                variance: bool = False) -> None:
    """Refuse a 1-sigma (1-D array) that is not a positive finite number at most :data:`MAX_SIGMA`, or
    with ``variance`` a variance not in (0, MAX_SIGMA^2] (``first`` as for :func:`check_abs`; ``hint`` is
    added to the message)."""
    v = np.asarray(values, dtype=np.float64)
    bound = MAX_SIGMA ** 2 if variance else MAX_SIGMA
    ok = (v > 0.0) & (v <= bound)
    if ok.all():
        return
    k = int(np.argmax(~ok))
    name = "variance" if variance else "1-sigma"
    what = f"{name} {num(v[k])} is beyond {num(bound)}" if v[k] > bound else f"{num(v[k])} is not a positive finite {name}"
    raise SinsError(f"{where}{_loc(row, _row(first, k), column)}: {what}{hint}")


def _unit_hint(check, declared: str | None, fits_in_degrees: bool):
    """Run ``check``; a refusal of rates declared in radians that would fit the limit in degrees says so."""
    try:
        check()
    except SinsError as exc:
        if declared in ("rad/s", "rad") and fits_in_degrees:
            key, unit = ("imu.units.gyro", "deg/s") if declared == "rad/s" else ("imu.units.dtheta", "deg")
            raise SinsError(f"{exc}; read as {unit} every value is within it: the file holds {unit}, set {key}: "
                            f"{unit} in the config") from None
        raise


def check_imu_rates(where, gyro, accel, lim: dict, columns=None, first=0, row: str = "line",
                    gyro_unit: str | None = None) -> None:
    """Angular rates (rad/s) and specific forces (m/s^2), (N, 3) each, against the limits.  ``gyro_unit``:
    the unit the file declares (a refusal of rad/s data that fit the limit in deg/s names the unit to set)."""
    gcols, acols = (columns[:3], columns[3:]) if columns is not None else (None, None)
    _unit_hint(lambda: check_abs(where, gyro, lim["rate"], "angular rate", "rate", " rad/s", gcols, first, row),
               gyro_unit, bool(np.all(np.abs(np.asarray(gyro)) * (np.pi / 180.0) <= lim["rate"])))
    check_abs(where, accel, lim["specific_force"], "specific force", "specific_force", " m/s^2", acols, first, row)


def check_imu_increments(where, dt, dtheta, dvel, lim: dict, columns=None, first=0, row: str = "line",
                         dtheta_unit: str | None = None) -> None:
    """Increments over intervals ``dt`` (s, > 0), (N, 3) each: the rate and specific force they imply.
    ``dtheta_unit``: the unit the file declares (rad data that fit the limit in deg name the unit to set)."""
    dt = np.asarray(dt, dtype=np.float64)
    fits = bool(np.all(np.abs(np.asarray(dtheta, dtype=np.float64)) * (np.pi / 180.0) <= lim["rate"] * dt[:, None]))
    _unit_hint(lambda: _check_increments(where, dt, dtheta, dvel, lim, columns, first, row), dtheta_unit, fits)


def _check_increments(where, dt, dtheta, dvel, lim, columns, first, row) -> None:
    for inc, key, what, unit, cols in ((dtheta, "rate", "angular rate", " rad", columns and columns[:3]),
                                       (dvel, "specific_force", "specific force", " m/s", columns and columns[3:])):
        inc = np.asarray(inc, dtype=np.float64)
        ok = np.abs(inc) <= lim[key] * dt[:, None]
        if ok.all():
            continue
        bad = ~ok
        k = int(np.argmax(bad.any(axis=1)))
        j = int(np.argmax(bad[k]))
        raise SinsError(f"{where}{_loc(row, _row(first, k), cols[j] if cols else None)}: increment {num(inc[k, j])}"
                        f"{unit} over {dt[k]:.6g} s implies an {what} beyond the physical limit "
                        f"{num(lim[key])}{unit}/s (the config's limits.{key})")


def check_time(where, time, lim: dict, column=None, first=0, row: str = "line") -> None:
    """Time stamps (s) within the limit; a stamp that fits once read as milli-, micro- or nanoseconds says so."""
    t = np.asarray(time, dtype=np.float64)
    ok = np.abs(t) <= lim["time"]
    if ok.all():
        return
    k = int(np.argmax(~ok))
    from .timebase import SCALES
    unit = next((u for scale, u in SCALES if abs(t[k]) / scale <= lim["time"]), None)
    hint = f"; it looks like {unit}, but time stamps are seconds" if unit else ""
    _refuse(where, row, _row(first, k), column, "time stamp", t[k], lim["time"], " s", "time", hint)


def check_position(where, lat_deg, lon_deg, height, lim: dict, columns=("lat", "lon", "height"), first=0,
                   row: str = "line") -> None:
    """Latitude in [-90, 90] deg, longitude in [-360, 360] deg, height in the limits' range (m)."""
    check_range(where, lat_deg, -90.0, 90.0, "latitude", None, " deg", columns[0], first, row)
    check_range(where, lon_deg, -LON_RANGE, LON_RANGE, "longitude", None, " deg", columns[1], first, row)
    check_range(where, height, lim["height_min"], lim["height_max"], "height", "height_min/height_max", " m",
                columns[2], first, row)


NEAR_POLE = 89.99          # deg: closer to a pole the ENU frame (east, north) is undefined


def check_near_pole(where, lat_deg, column=None, first=0, row: str = "line", use: str = "") -> None:
    """Refuse a latitude within 0.01 deg of a pole, where the ENU frame is undefined: the one rule of the
    init reader (an initial state) and the GNSS readers (a fix that would aid the ENU navigation).
    ``use``: what to do instead, added to the message."""
    v = np.asarray(lat_deg, dtype=np.float64).reshape(-1)
    bad = np.abs(v) > NEAR_POLE
    if not bad.any():
        return
    k = int(np.argmax(bad))
    raise SinsError(f"{where}{_loc(row, _row(first, k), column)}: latitude {num(v[k])} deg is within "
                    f"{90.0 - NEAR_POLE:.2g} deg of a pole, where the ENU frame is undefined{use}")


def check_velocity(where, vel, lim: dict, columns=None, first=0, row: str = "line") -> None:
    """Velocity components (m/s), (N, 3), against the speed limit (each component and the norm)."""
    v = np.asarray(vel, dtype=np.float64)
    check_abs(where, v, lim["speed"], "velocity", "speed", " m/s", columns, first, row)
    check_abs(where, np.linalg.norm(v, axis=1), lim["speed"], "speed", "speed", " m/s",
              None if columns is None else "/".join(columns), first, row)
