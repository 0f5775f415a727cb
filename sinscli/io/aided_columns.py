"""The optional columns of an aided (fused or smoothed) trajectory (docs/formats.md), and their checks.

A fused navigator writes, beside the docs/formats.md trajectory columns, the
1-sigma of its own error estimate and its sensor error estimates
(``Trajectory.extra`` keys):

- ``pos_e_std, pos_n_std, pos_u_std`` (m, ENU), ``vel_e_std, vel_n_std, vel_u_std`` (m/s, ENU),
  ``roll_std, pitch_std, heading_std`` (deg);
- ``gyro_bias_x/_y/_z`` (deg/h), ``accel_bias_x/_y/_z`` (micro-g), in the body axes of the file;
- optionally ``gyro_sf_x.._z``, ``accel_sf_x.._z`` (ppm).

Every column whose name ends in ``_std`` is a 1-sigma: "a positive finite
number on every row" (docs/formats.md).  Readers refuse anything else naming the
line and the column (:func:`check_columns`); writers refuse to write it (the writer guard
:func:`sinscli.io.atomic.check_finite`, given the sigma columns).  No I/O here.
"""
from __future__ import annotations

import numpy as np

from ..errors import SinsError, num

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


def check_columns(where: str, data: dict, first_row: int = 2, row_label: str = "line") -> None:
    """The reader's check of extra columns: SinsError at the first non-finite value of any column, or the
    first sigma that is not positive (:func:`sinscli.io.limits.check_sigma`).  Writers do not call this:
    their guard is :func:`sinscli.io.atomic.check_finite` (with the sigma columns).

    ``first_row`` is the number (``row_label`` ``line`` or ``row``) of element 0,
    e.g. 2 for the first data line of a CSV file after its header.
    """
    from .limits import check_sigma
    for name, arr in data.items():
        a = np.asarray(arr)
        if a.dtype.kind != "f":
            continue
        if is_sigma(name):
            check_sigma(where, a, name, first_row, row_label, " (docs/formats.md: a sigma column holds a positive finite "
                                                               "number on every row)")
        else:
            bad = ~np.isfinite(a)
            if bad.any():
                k = int(np.argmax(bad))
                raise SinsError(f"{where}: {row_label} {first_row + k}, column '{name}': value {num(a[k])} is not "
                                "a finite number")
