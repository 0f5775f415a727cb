"""The innovations file: exact round trip, the documented columns, and every bad record refused (nothing written)."""
from __future__ import annotations

import os

import numpy as np
import pytest

from sinscli.errors import SinsError
from sinscli.io.innovations import COLUMNS, DTYPE, read_innovations, write_innovations


def _records(n=500, seed=2):
    rng = np.random.default_rng(seed)
    rec = np.empty(n, dtype=DTYPE)
    rec["time"] = 1.7e9 + np.sort(rng.uniform(0, 600, n))
    rec["type"] = rng.choice(["gnss_pos", "gnss_vel", "zupt", "zaru", "nhc", "odom"], n)
    rec["axis"] = np.where(np.isin(rec["type"], ["gnss_pos", "gnss_vel"]), rng.choice(list("enu"), n),
                           rng.choice(list("xyz"), n))
    rec["sigma"] = np.exp(rng.normal(-2, 2, n))
    rec["innovation"] = rng.normal(0, 1, n) * rec["sigma"]
    rec["nis"] = rng.chisquare(3, n)
    rec["accepted"] = rec["nis"] < 21.1
    return rec


def test_round_trip_is_exact(tmp_path):
    rec = _records()
    path = tmp_path / "innov.csv"
    write_innovations(path, rec)
    lines = path.read_text().splitlines()
    assert lines[0] == "time,type,axis,innovation,sigma,nis,accepted" and len(lines) == 501
    assert lines[1].split(",")[6] in ("true", "false") and '"' not in path.read_text()
    back = read_innovations(path)
    assert back.dtype == DTYPE
    for c in COLUMNS:
        assert np.array_equal(back[c], rec[c]), c


def test_empty_and_extra_fields(tmp_path):
    write_innovations(tmp_path / "e.csv", np.empty(0, dtype=DTYPE))
    assert (tmp_path / "e.csv").read_text() == ",".join(COLUMNS) + "\n"
    assert len(read_innovations(tmp_path / "e.csv")) == 0
    wide = np.empty(3, dtype=DTYPE.descr + [("epoch", "i8")])
    for c in COLUMNS:
        wide[c] = _records(3)[c]
    write_innovations(tmp_path / "w.csv", wide)                  # extra fields are not written
    assert (tmp_path / "w.csv").read_text().splitlines()[0] == ",".join(COLUMNS)


@pytest.mark.parametrize("field,value,message", [
    ("innovation", np.nan, r"record 7 \(time .*\), column 'innovation': nan is not a finite number"),
    ("time", np.inf, r"record 7 .*column 'time': inf is not a finite number"),
    ("sigma", 0.0, r"record 7 .*column 'sigma': 0.0 is not a positive finite 1-sigma"),
    ("sigma", -1.0, r"column 'sigma': -1.0 is not a positive finite 1-sigma"),
    ("nis", -0.5, r"column 'nis': -0.5 is not a finite number >= 0"),
    ("type", "gps", r"record 7, column 'type': 'gps' is not one of gnss_pos, gnss_vel, zupt, zaru, nhc, odom"),
    ("axis", "q", r"record 7, column 'axis': 'q' is not one of e, n, u, x, y, z"),
])
def test_writer_refuses_bad_records(tmp_path, field, value, message):
    rec = _records(20)
    rec[field][7] = value
    with pytest.raises(SinsError, match=r"innov\.csv: cannot write innovations: .*" + message):
        write_innovations(tmp_path / "innov.csv", rec)
    assert os.listdir(tmp_path) == []
    with pytest.raises(SinsError, match=r"lack the field\(s\) nis"):
        write_innovations(tmp_path / "x.csv", np.zeros(2, dtype=[(c, DTYPE[c]) for c in COLUMNS if c != "nis"]))


@pytest.mark.parametrize("col,value,message", [
    (4, "0", r"line 5 \(time .*\), column 'sigma': 0.0 is not a positive finite 1-sigma"),
    (3, "nan", r"line 5 .*column 'innovation': nan is not a finite number"),
    (3, "abc", r"line 5, column 'innovation': 'abc' is not a number"),
    (6, "maybe", r"column 'accepted' holds a value other than true/false"),
    (1, "ins", r"line 5, column 'type': 'ins' is not one of"),
])
def test_reader_names_line_and_column(tmp_path, col, value, message):
    path = tmp_path / "i.csv"
    write_innovations(path, _records(10))
    lines = path.read_text().splitlines()
    cells = lines[4].split(",")
    cells[col] = value
    lines[4] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(SinsError, match=r"i\.csv: " + message):
        read_innovations(path)
