"""GNSS inputs: sigma checks of the GNSS CSV, NavSatFix covariance types, and the GNSS time base against the
IMU's (every base mismatch named, with the shift that repairs it), through the library and `sins align`."""
from __future__ import annotations

import calendar
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from sinscli.errors import SinsError
from sinscli.io import ros
from sinscli.io.csvcore import read_header, read_numeric_columns, write_table_csv
from sinscli.io.gnss_csv import check_gnss_against_imu, read_gnss_csv, write_gnss_csv
from sinscli.io.timebase import GPS_EPOCH_UNIX, WEEK, diagnose, gps_minus_utc
from sinscli.sim.run import simulate, write_sim
from sinscli.types import GnssLog

SINS = Path(sys.executable).with_name("sins")
T_UNIX = 1700000000.0                     # 2023-11-14: GPS - UTC = 18 s


def _gnss(t):
    n = len(t)
    return GnssLog(np.asarray(t, dtype=float), np.full(n, 30.0), np.full(n, 114.0), np.zeros(n), source="g.csv")


def _check(imu_span, gnss_t):
    check_gnss_against_imu(_gnss(gnss_t), *imu_span)


# --------------------------------------------------------------------------- leap seconds

def test_gps_minus_utc_table():
    """IS-GPS-200 / IERS: 13 s in 2000, 14 from 2006, 15 from 2009, 16 from 2012-07, 17 from 2015-07, 18 from 2017."""
    ut = lambda y, m, d: calendar.timegm((y, m, d, 0, 0, 0))   # noqa: E731
    assert gps_minus_utc(ut(1980, 1, 6)) == 0 and gps_minus_utc(ut(2000, 6, 1)) == 13
    assert gps_minus_utc(ut(2005, 12, 31)) == 13 and gps_minus_utc(ut(2006, 1, 1)) == 14
    assert gps_minus_utc(ut(2012, 6, 30)) == 15 and gps_minus_utc(ut(2012, 7, 1)) == 16
    assert gps_minus_utc(ut(2016, 12, 31)) == 17 and gps_minus_utc(T_UNIX) == 18


# --------------------------------------------------------------------------- each base mismatch

IMU = (T_UNIX, T_UNIX + 600.0)
GNSS_UNIX = T_UNIX + 0.4 + np.arange(0, 600.0, 1.0)              # 1 Hz, inside the IMU span


def test_same_base_passes_including_partial_and_longer_gnss():
    _check(IMU, GNSS_UNIX)
    _check(IMU, GNSS_UNIX - 300.0)                                # starts before the IMU, ends inside it
    _check(IMU, T_UNIX - 5000.0 + np.arange(0, 10000.0, 1.0))     # a much longer GNSS log
    _check((0.0, 600.0), np.arange(0.5, 599.0, 1.0))              # both from the start
    _check((0.0, 600.0), np.arange(0.5, 599.0, 0.1))              # 10 Hz
    _check(IMU, GNSS_UNIX + 5.0)                                  # 5 s late at both ends: not a leap second count


def test_no_overlap():
    with pytest.raises(SinsError, match=r"^g\.csv: does not overlap the IMU log in time: the time spans are apart "
                                        r"\(g\.csv spans .*; g\.csv starts 1000.4 s after the IMU log ends\)$"):
        _check(IMU, GNSS_UNIX + 1600.0)
    with pytest.raises(SinsError, match=r"g\.csv ends .* s before the IMU log starts"):
        _check(IMU, GNSS_UNIX - 2000.0)


def test_gps_time_against_utc_unix_by_the_leap_seconds():
    with pytest.raises(SinsError, match=r"times are 18 s ahead of those of the IMU log at both ends, the GPS-UTC leap "
                                        r"seconds of that date: g\.csv seems to be in GPS time, the IMU log in "
                                        r"UTC-based UNIX time .* shift the GNSS times by -18 s \(config "
                                        r"gnss.time_offset: -18\)"):
        _check(IMU, GNSS_UNIX + 18.0)
    with pytest.raises(SinsError, match=r"18 s behind .* the IMU log seems to be in GPS time, g\.csv in UTC"):
        _check(IMU, GNSS_UNIX - 18.0)
    t2010 = calendar.timegm((2010, 5, 1, 0, 0, 0))                # 15 s then
    with pytest.raises(SinsError, match=r"15 s ahead"):
        _check((t2010, t2010 + 300.0), t2010 + 15.1 + np.arange(0, 299.9, 0.2))


def test_gps_seconds_since_1980_against_unix():
    shift = GPS_EPOCH_UNIX - 18.0
    with pytest.raises(SinsError, match=r"g\.csv seems to be in GPS time \(seconds since 1980-01-06\), the IMU log in "
                                        r"UNIX time .* shift the GNSS times by 315964782 s"):
        _check(IMU, GNSS_UNIX - shift)
    with pytest.raises(SinsError, match=r"the IMU log seems to be in GPS time \(seconds since 1980-01-06\), g\.csv in "
                                        r"UNIX time .* by -315964782 s"):
        _check((IMU[0] - shift, IMU[1] - shift), GNSS_UNIX)


def test_gps_seconds_of_week_against_unix_and_gps_time():
    sow0 = (T_UNIX - GPS_EPOCH_UNIX + 18.0) % WEEK                # the IMU start as GPS seconds of week
    week = int((T_UNIX - GPS_EPOCH_UNIX + 18.0) // WEEK)
    shift = T_UNIX - sow0
    with pytest.raises(SinsError, match=rf"g\.csv seems to be in GPS seconds of week \(week {week}\), the IMU log in "
                                        rf"UNIX time .* shift the GNSS times by {shift:.0f} s \(config "
                                        rf"gnss.time_offset: {shift:.0f}\)"):
        _check(IMU, GNSS_UNIX - shift)
    gps = (IMU[0] - GPS_EPOCH_UNIX + 18.0, IMU[1] - GPS_EPOCH_UNIX + 18.0)   # IMU in GPS time
    with pytest.raises(SinsError, match=rf"GPS seconds of week \(week {week}\), the IMU log in GPS time"):
        _check(gps, GNSS_UNIX - T_UNIX + sow0)
    with pytest.raises(SinsError, match=rf"the IMU log seems to be in GPS seconds of week \(week {week}\), g\.csv in "
                                        r"UNIX time"):
        _check((sow0, sow0 + 600.0), GNSS_UNIX)
    # an arbitrary week time against seconds from the start: different bases, no shift guessed
    with pytest.raises(SinsError, match=r"g\.csv seems to be in seconds of a GPS week or another origin, the IMU log "
                                        r"in seconds from the start .* write both with the same time origin"):
        _check((0.0, 600.0), 345600.0 + np.arange(0, 599.0))


def test_seconds_from_start_against_an_absolute_epoch():
    with pytest.raises(SinsError, match=r"g\.csv seems to be in seconds from the start, the IMU log in absolute seconds "
                                        r"\(UNIX or GPS time\)"):
        _check(IMU, GNSS_UNIX - T_UNIX)
    with pytest.raises(SinsError, match=r"g\.csv seems to be in absolute seconds \(UNIX or GPS time\), the IMU log in "
                                        r"seconds from the start"):
        _check((0.0, 600.0), GNSS_UNIX)


@pytest.mark.parametrize("scale,word", [(1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds")])
def test_milliseconds_against_seconds(scale, word):
    with pytest.raises(SinsError, match=rf"different time units: g\.csv seems to be in {word}, the IMU log in seconds"):
        _check(IMU, GNSS_UNIX * scale)
    with pytest.raises(SinsError, match=rf"g\.csv seems to be in {word}"):
        _check((0.0, 600.0), np.arange(0.5, 599.0) * scale)          # from the start: the spans overlap near 0
    with pytest.raises(SinsError, match=rf"the IMU log seems to be in {word}, g\.csv in seconds"):
        _check((0.0, 600.0 * scale), np.arange(0.5, 599.0))


def test_diagnose_is_symmetric_in_its_names():
    assert diagnose("a", (0.0, 10.0), "b", (1.0, 9.0)) is None
    assert "b: does not overlap a in time: the time spans are apart" in diagnose("a", (0.0, 10.0), "b", (11.0, 19.0))


# --------------------------------------------------------------------------- GNSS CSV sigmas

def _gnss_csv(tmp_path, **cols):
    n = 5
    data = {"time": np.arange(n, dtype=float), "lat": np.full(n, 30.0), "lon": np.full(n, 114.0),
            "height": np.zeros(n), "std_e": np.full(n, 1.5), "std_n": np.full(n, 1.5), "std_u": np.full(n, 3.0),
            "vel_e": np.zeros(n), "vel_n": np.zeros(n), "vel_u": np.zeros(n),
            "std_vel_e": np.full(n, 0.1), "std_vel_n": np.full(n, 0.1), "std_vel_u": np.full(n, 0.2)}
    for k, (row, v) in cols.items():
        data[k] = data[k].copy()
        data[k][row] = v
    path = tmp_path / "gnss.csv"
    write_table_csv(path, data)
    return path


@pytest.mark.parametrize("col,value", [("std_n", 0.0), ("std_u", -1.0), ("std_vel_e", 0.0), ("std_vel_u", -0.5)])
def test_gnss_csv_refuses_a_sigma_of_zero_or_below(tmp_path, col, value):
    path = _gnss_csv(tmp_path, **{col: (3, value)})
    with pytest.raises(SinsError, match=rf"gnss\.csv: line 5, column '{col}': {value!r} is not a positive 1-sigma"):
        read_gnss_csv(path)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_gnss_csv_refuses_non_finite_values(tmp_path, value):
    path = _gnss_csv(tmp_path)
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[lines[0].split(",").index("std_e")] = value
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(SinsError, match=r"gnss\.csv: line 3, column 'std_e': value .* is not a finite number"):
        read_gnss_csv(path)


def test_gnss_csv_sigma_columns_round_trip(tmp_path):
    g = read_gnss_csv(_gnss_csv(tmp_path))
    assert np.array_equal(g.std_pos, np.tile([1.5, 1.5, 3.0], (5, 1)))
    assert np.array_equal(g.position_sigma([9.0, 9.0, 9.0]), g.std_pos)


# --------------------------------------------------------------------------- NavSatFix covariance types

def _fixes(n=6, t0=1000.0):
    t = t0 + 0.2 * np.arange(n)
    return {"time": t, "lat": 30.0 + 1e-5 * np.arange(n), "lon": np.full(n, 114.0), "height": np.zeros(n),
            "cov": np.tile([4.0, 0, 0, 0, 9.0, 0, 0, 0, 16.0], (n, 1)), "cov_type": np.full(n, 2)}


def test_navsatfix_covariance_types(tmp_path, caplog):
    """APPROXIMATED (1), DIAGONAL_KNOWN (2), KNOWN (3) give the per-fix ENU sigma (REP-145: ENU diagonal);
    UNKNOWN (0) gives none: all unknown -> std_pos None, some unknown -> NaN rows that the config's sigma fills."""
    g = _fixes()
    g["cov_type"] = np.array([1, 2, 3, 2, 1, 3])
    out = ros.read_gnss(ros.write_log(tmp_path / "a.bag", gnss=g) or tmp_path / "a.bag")
    assert np.array_equal(out.std_pos, np.tile([2.0, 3.0, 4.0], (6, 1)))
    none = ros.read_gnss(ros.write_log(tmp_path / "b.bag", gnss={**g, "cov_type": np.zeros(6)}) or tmp_path / "b.bag")
    assert none.std_pos is None
    assert np.array_equal(none.position_sigma([1.0, 1.0, 2.0]), np.tile([1.0, 1.0, 2.0], (6, 1)))
    mixed = {**g, "cov_type": np.array([2, 0, 2, 2, 0, 2])}
    mixed["cov"] = mixed["cov"].copy()
    mixed["cov"][[1, 4]] = 0.0                                   # an UNKNOWN fix's covariance is meaningless
    with caplog.at_level("WARNING", logger="sins"):
        out = ros.read_gnss(ros.write_log(tmp_path / "c.bag", gnss=mixed) or tmp_path / "c.bag")
    assert "2 of 6 fixes have covariance type UNKNOWN" in caplog.text
    assert np.isnan(out.std_pos[[1, 4]]).all() and np.array_equal(out.std_pos[[0, 2, 3, 5]], np.tile([2.0, 3.0, 4.0], (4, 1)))
    filled = out.position_sigma([1.0, 1.0, 2.0])
    assert np.array_equal(filled[[1, 4]], np.tile([1.0, 1.0, 2.0], (2, 1))) and np.isfinite(filled).all()
    # the CSV of such a log leaves the std columns out rather than write NaN
    write_gnss_csv(tmp_path / "c.csv", out)
    assert "std_e" not in read_header(tmp_path / "c.csv") and "nan" not in (tmp_path / "c.csv").read_text()


# --------------------------------------------------------------------------- through `sins align`, installed

@pytest.fixture(scope="module")
def unix_rest(tmp_path_factory):
    """A 60 s rest with UNIX-time stamps (2023), 1 Hz GNSS."""
    sc = {"name": "rest", "start": {"time": T_UNIX, "lat": 30, "lon": 114, "height": 50, "heading": 40},
          "imu": {"rate": 50, "sensor": {"gyro": {"bias": 0.01, "arw": 0.001}, "accel": {"bias": 50, "vrw": 10}}},
          "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 60}]}
    d = tmp_path_factory.mktemp("unix_rest")
    (d / "sc.yaml").write_text(yaml.safe_dump(sc))
    write_sim(simulate(d / "sc.yaml", seed=3), d)
    return d


def _shifted_gnss(src: Path, dst: Path, f):
    cols = read_header(src)
    data = read_numeric_columns(src, {c: c for c in cols})
    data["time"] = f(data["time"])
    write_table_csv(dst, data, cols)


def _align(cwd, gnss, config=None):
    args = [str(SINS), "align", "imu.csv", "--gnss", gnss, "--method", "static", "--duration", "30", "-q",
            "-o", "init.yaml"]
    if config:
        args += ["--config", config]
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True)


@pytest.mark.parametrize("case,transform,needle,offset", [
    ("leap", lambda t: t + 18.0, "18 s ahead", -18.0),
    ("week", lambda t: t - T_UNIX + (T_UNIX - GPS_EPOCH_UNIX + 18.0) % WEEK, "GPS seconds of week",
     T_UNIX - (T_UNIX - GPS_EPOCH_UNIX + 18.0) % WEEK),
    ("gps", lambda t: t - GPS_EPOCH_UNIX + 18.0, "GPS time (seconds since 1980-01-06)", GPS_EPOCH_UNIX - 18.0),
    ("start", lambda t: t - T_UNIX, "seconds from the start", None),
    ("ms", lambda t: t * 1e3, "milliseconds", None),
    ("late", lambda t: t + 3600.0, "does not overlap the IMU log in time: the time spans are apart", None),
])
def test_align_refuses_gnss_in_another_time_base(unix_rest, tmp_path, case, transform, needle, offset):
    d = unix_rest
    work = tmp_path / case
    work.mkdir()
    os.symlink(d / "imu.csv", work / "imu.csv")
    _shifted_gnss(d / "gnss.csv", work / "gnss.csv", transform)
    res = _align(work, "gnss.csv")
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith("sins: error: gnss.csv: ") and needle in lines[0], lines[0]
    assert not (work / "init.yaml").exists()
    if offset is not None:                                   # the shift the message names repairs it
        assert f"gnss.time_offset: {offset:.0f}" in lines[0]
        (work / "cfg.yaml").write_text(f"gnss:\n  time_offset: {offset!r}\n")
        res = _align(work, "gnss.csv", "cfg.yaml")
        assert res.returncode == 0, res.stderr
        ref = tmp_path / "ref"
        ref.mkdir(exist_ok=True)
        if not (ref / "init.yaml").exists():
            os.symlink(d / "imu.csv", ref / "imu.csv")
            os.symlink(d / "gnss.csv", ref / "gnss.csv")
            assert _align(ref, "gnss.csv").returncode == 0
        a, b = yaml.safe_load((work / "init.yaml").read_text()), yaml.safe_load((ref / "init.yaml").read_text())
        for k in ("lat", "lon", "height", "roll", "pitch", "heading"):
            assert a[k] == pytest.approx(b[k], abs=1e-7), k
        assert math.isclose(a["lat"], 30.0, abs_tol=1e-6)


def test_align_refuses_a_gnss_sigma_of_zero(unix_rest, tmp_path):
    """gnss.csv with std_n = 0 on line 4: one error line naming line and column, exit 2, no output."""
    os.symlink(unix_rest / "imu.csv", tmp_path / "imu.csv")
    cols = read_header(unix_rest / "gnss.csv")
    data = read_numeric_columns(unix_rest / "gnss.csv", {c: c for c in cols})
    data.update({c: np.full(len(data["time"]), 1.5) for c in ("std_e", "std_n", "std_u")})
    data["std_n"][2] = 0.0
    write_table_csv(tmp_path / "gnss.csv", data)
    res = _align(tmp_path, "gnss.csv")
    assert res.returncode == 2 and not (tmp_path / "init.yaml").exists()
    assert res.stderr.strip().splitlines() == [
        "sins: error: gnss.csv: line 4, column 'std_n': 0.0 is not a positive 1-sigma"]


@pytest.mark.parametrize("gnss_t", [GNSS_UNIX + 5000.0, GNSS_UNIX - T_UNIX, GNSS_UNIX * 1e3,
                                    GNSS_UNIX - GPS_EPOCH_UNIX + 18.0, GNSS_UNIX - 1.7e9 + 400000.0])
def test_every_disjoint_case_says_it_does_not_overlap(gnss_t):
    with pytest.raises(SinsError, match=r"^g\.csv: does not overlap the IMU log in time: "):
        _check(IMU, gnss_t)
