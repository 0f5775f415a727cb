"""The fixes of ``sins gnss spp``: a docs/formats.md GNSS CSV (``time, lat, lon, height``, ENU velocity, 1-sigma of
position and velocity) with three more columns per fix: ``nsat`` (satellites used), ``pdop`` and
``excluded`` (the satellites the chi-square test excluded, ``G05 E11``).  ``sins navigate --gnss`` reads it
as it is (the three columns are known and ignored: :data:`SPP_COLUMNS`)."""
from __future__ import annotations

import pyarrow as pa
import pyarrow.csv as pacsv

from .atomic import atomic_path, check_finite
from .csvcore import float64_table

SPP_COLUMNS = ("nsat", "pdop", "excluded")


def write_spp_csv(path, data: dict, excluded: list[str]) -> None:
    """Write the float columns of ``data`` (``time`` first; every value finite, every ``std_*`` positive),
    then ``excluded`` (text per row), atomically."""
    sigmas = [c for c in data if c.startswith("std")]
    check_finite(path, data, data.get("time"), 1, sigmas)
    table = float64_table(data)
    table = table.append_column("excluded", pa.array(excluded, pa.string()))
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write((",".join(table.column_names) + "\n").encode())
            pacsv.write_csv(table, fh, write_options=pacsv.WriteOptions(include_header=False, quoting_style="none"))
