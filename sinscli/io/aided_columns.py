"""The optional columns of an aided (fused or smoothed) trajectory (FORMATS.md), and their checks.

A fused navigator writes, beside the FORMATS.md trajectory columns, the
1-sigma of its own error estimate and its sensor error estimates
(``Trajectory.extra`` keys):

- ``pos_e_std, pos_n_std, pos_u_std`` (m, ENU), ``vel_e_std, vel_n_std, vel_u_std`` (m/s, ENU),
  ``roll_std, pitch_std, heading_std`` (deg);
- ``gyro_bias_x/_y/_z`` (deg/h), ``accel_bias_x/_y/_z`` (micro-g), in the body axes of the file;
- optionally ``gyro_sf_x.._z``, ``accel_sf_x.._z`` (ppm).

Every column whose name ends in ``_std`` is a 1-sigma: "a positive finite
number on every row" (FORMATS.md).  Readers refuse anything else naming the
line and the column; writers refuse to write it.  No I/O here.
"""
from __future__ import annotations

import numpy as np

from ..errors import SinsError

POS_STD = ("pos_e_std", "pos_n_std", "pos_u_std")            # m, ENU
VEL_STD = ("vel_e_std", "vel_n_std", "vel_u_std")            # m/s, ENU
ATT_STD = ("roll_std", "pitch_std", "heading_std")          # deg
SIGMA_COLUMNS = POS_STD + VEL_STD + ATT_STD
GYRO_BIAS = ("gyro_bias_x", "gyro_bias_y", "gyro_bias_z")    # deg/h, body axes
ACCEL_BIAS = ("accel_bias_x", "accel_bias_y", "accel_bias_z")  # micro-g, body axes
GYRO_SF = ("gyro_sf_x", "gyro_sf_y", "gyro_sf_z")            # ppm
ACCEL_SF = ("accel_sf_x", "accel_sf_y", "accel_sf_z")        # ppm
BIAS_COLUMNS = GYRO_BIAS + ACCEL_BIAS + GYRO_SF + ACCEL_SF

UNITS = dict([(c, "m") for c in POS_STD] + [(c, "m/s") for c in VEL_STD] + [(c, "deg") for c in ATT_STD]
             + [(c, "deg/h") for c in GYRO_BIAS] + [(c, "micro-g") for c in ACCEL_BIAS]
             + [(c, "ppm") for c in GYRO_SF + ACCEL_SF])


def is_sigma(name: str) -> bool:
    """True for a 1-sigma column (its name ends in ``_std``)."""
    return name.endswith("_std")


def group(extra: dict, names) -> np.ndarray | None:
    """``(N, 3)`` array of three extra columns when all are present, else None."""
    if all(c in extra for c in names):
        return np.column_stack([np.asarray(extra[c], dtype=np.float64) for c in names])
    return None


def first_bad_sigma(values: np.ndarray) -> int | None:
    """Index of the first value that is not a positive finite number, or None."""
    v = np.asarray(values, dtype=np.float64)
    bad = ~(np.isfinite(v) & (v > 0.0))
    return int(np.argmax(bad)) if bad.any() else None


def check_columns(where: str, data: dict, first_row: int = 2, row_label: str = "line") -> None:
    """SinsError at the first non-finite value of any column, or the first sigma that is not positive.

    ``first_row`` is the number (``row_label`` ``line`` or ``row``) of element 0,
    e.g. 2 for the first data line of a CSV file after its header.
    """
    for name, arr in data.items():
        a = np.asarray(arr)
        if a.dtype.kind != "f":
            continue
        if is_sigma(name):
            k = first_bad_sigma(a)
            if k is not None:
                raise SinsError(f"{where}: {row_label} {first_row + k}, column '{name}': {float(a[k])!r} is not a "
                                "positive finite 1-sigma (FORMATS.md: a sigma column holds a positive finite number "
                                "on every row)")
        else:
            bad = ~np.isfinite(a)
            if bad.any():
                k = int(np.argmax(bad))
                raise SinsError(f"{where}: {row_label} {first_row + k}, column '{name}': value {float(a[k])!r} is not "
                                "a finite number")
