"""Every failure listed in issue 11, one test each: the exact input, the one-line refusal (or the corrected
result), and no file left behind.  The fuzzer (test_fuzz_contract.py) covers the classes; these pin the
examples and the mechanisms (limits as config keys, the writer guard, the navigator's state check)."""
from __future__ import annotations

import os
import re
import shutil
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.io import ros
from sinscli.io.atomic import NonFiniteOutput, atomic_path
from sinscli.io.trajectory import read_trajectory, write_trajectory
from sinscli.nav.pipeline import NavOptions, Navigator
from sinscli.types import ImuLog

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
INIT = SAMPLE / "init.yaml"


def sins(args, cwd=None):
    """(exit code, stderr lines) of an in-process run."""
    here = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        r = CliRunner().invoke(main, [str(a) for a in args])
    finally:
        os.chdir(here)
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    return r.exit_code, [ln for ln in r.stderr.splitlines() if ln.strip()]


def refused(args, *fragments, cwd=None):
    """The run ends with exit 2 and one `sins: error:` line holding every fragment; returns the line."""
    rc, lines = sins(args, cwd)
    assert rc == 2, (rc, lines)
    errors = [ln for ln in lines if ln.startswith("sins: error:")]
    assert len(errors) == 1 and lines[-1] == errors[0], lines
    assert "Usage:" not in " ".join(lines) and "np.float" not in errors[0]
    for f in fragments:
        assert f in errors[0], (f, errors[0])
    return errors[0]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("contract")
    lines = (SAMPLE / "imu.csv").read_text().splitlines()[:3102]          # 31 s
    (d / "imu.csv").write_text("\n".join(lines) + "\n")
    return d


def _with_line(src: Path, dst: Path, k: int, col: int, value: str) -> Path:
    lines = src.read_text().splitlines()
    cells = lines[k].split(",")
    cells[col] = value
    lines[k] = ",".join(cells)
    dst.write_text("\n".join(lines) + "\n")
    return dst


# --------------------------------------------------------------------------- exit 0 with NaN (now refused)

def test_imu_csv_with_1e308_is_refused_at_its_line(data, tmp_path):
    bad = _with_line(data / "imu.csv", tmp_path / "imu.csv", 50, 2, "1e308")
    refused(["navigate", bad, "--init", INIT, "-o", tmp_path / "nav.csv"], "imu.csv: line 51, column 'dtheta_y'",
            "limits.rate")
    refused(["align", bad, "--method", "inertial", "--position", "30,114,50", "--heading", "30", "-o",
             tmp_path / "i.yaml"], "line 51, column 'dtheta_y'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imu.csv"]


def test_limits_are_config_keys(data, tmp_path):
    """A 5 rad/s sample (a fast but possible rate) passes by default, and is refused under a 1 rad/s limit."""
    fast = _with_line(data / "imu.csv", tmp_path / "imu.csv", 50, 3, "0.05")          # 0.05 rad in 0.01 s
    assert sins(["navigate", fast, "--init", INIT, "-q", "-o", tmp_path / "a.csv"])[0] == 0
    (tmp_path / "cfg.yaml").write_text("limits:\n  rate: 1.0\n")
    refused(["navigate", fast, "--init", INIT, "--config", tmp_path / "cfg.yaml", "-o", tmp_path / "b.csv"],
            "line 51, column 'dtheta_z': increment 0.05 rad over 0.01 s", "physical limit 1.0 rad/s")
    (tmp_path / "cfg2.yaml").write_text("limits:\n  speed: -5\n")
    refused(["navigate", fast, "--init", INIT, "--config", tmp_path / "cfg2.yaml", "-o", tmp_path / "c.csv"],
            "key limits.speed: expected a number > 0, got -5")


def test_imu_message_with_1e308_is_refused_naming_the_message(tmp_path):
    n = 200
    t = 0.01 * np.arange(n)
    accel = np.tile([0.0, 0.0, 9.79], (n, 1))
    accel[37, 1] = 1e308
    ros.write_log(tmp_path / "log.mcap", imu={"time": t, "gyro": np.zeros((n, 3)), "accel": accel})
    refused(["navigate", tmp_path / "log.mcap", "--init", INIT, "-o", tmp_path / "nav.csv"],
            "topic /imu/data: message 37, column 'linear_acceleration.y'", "specific force 1e+308")
    refused(["convert", tmp_path / "log.mcap", "-o", tmp_path / "conv"], "message 37")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.mcap"]


def test_config_nan_mounting_and_init_huge_velocity(data, tmp_path):
    (tmp_path / "cfg.yaml").write_text("imu:\n  mounting: {roll: .nan}\n")
    refused(["navigate", data / "imu.csv", "--init", INIT, "--config", tmp_path / "cfg.yaml", "-o",
             tmp_path / "n.csv"], "cfg.yaml: line 2, column 20: imu.mounting.roll: '.nan' is not a finite number")
    init = INIT.read_text().replace("vel_e: 0.0", "vel_e: -1.0e+308")
    (tmp_path / "init.yaml").write_text(init)
    refused(["navigate", data / "imu.csv", "--init", tmp_path / "init.yaml", "-o", tmp_path / "n.csv"],
            "init.yaml: vel_e: velocity -1e+308 m/s is beyond the physical limit 10000.0 m/s")
    assert not (tmp_path / "n.csv").exists()


def test_static_alignment_of_an_all_zero_imu(data, tmp_path):
    lines = (data / "imu.csv").read_text().splitlines()
    zero = [lines[0]] + [ln.split(",")[0] + ",0,0,0,0,0,0" for ln in lines[1:]]
    (tmp_path / "zero.csv").write_text("\n".join(zero) + "\n")
    refused(["align", tmp_path / "zero.csv", "--method", "static", "--position", "30,114,50", "--heading", "30",
             "-o", tmp_path / "i.yaml"], "zero.csv: the mean specific force over the alignment interval is 0 m/s^2")
    assert not (tmp_path / "i.yaml").exists()


# --------------------------------------------------------------------------- internal errors (now clear)

def test_csv_header_whitespace_is_accepted_bit_for_bit(data, tmp_path):
    lines = (data / "imu.csv").read_text().splitlines()
    lines[0] = " time,\tdtheta_x , dtheta_y,dtheta_z,dvel_x,dvel_y, dvel_z "
    (tmp_path / "ws.csv").write_text("\n".join(lines) + "\n")
    assert sins(["navigate", tmp_path / "ws.csv", "--init", INIT, "-q", "-o", tmp_path / "a.csv"])[0] == 0
    assert sins(["navigate", data / "imu.csv", "--init", INIT, "-q", "-o", tmp_path / "b.csv"])[0] == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_csv_header_problems(data, tmp_path):
    lines = (data / "imu.csv").read_text().splitlines()
    out = tmp_path / "o.csv"
    (tmp_path / "lat.csv").write_bytes(("\n".join([lines[0][:-1] + "\xe9"] + lines[1:]) + "\n").encode("latin-1"))
    refused(["navigate", tmp_path / "lat.csv", "--init", INIT, "-o", out], "line 1, header column 7: byte 0xe9")
    (tmp_path / "map.yaml").write_text("imu:\n  columns: {time: stamp}\n")
    refused(["navigate", data / "imu.csv", "--init", INIT, "--config", tmp_path / "map.yaml", "-o", out],
            "no column 'stamp' in the header")
    (tmp_path / "dup.csv").write_text("\n".join([lines[0] + ",dvel_z"] + [ln + ",0" for ln in lines[1:]]) + "\n")
    refused(["navigate", tmp_path / "dup.csv", "--init", INIT, "-o", out], "column 'dvel_z' appears twice")
    long = list(lines)
    long[5] += "," + "x" * 140_000
    (tmp_path / "long.csv").write_text("\n".join(long) + "\n")
    refused(["navigate", tmp_path / "long.csv", "--init", INIT, "-o", out], "line 6: longer than 131072 bytes")
    giant = "time," + "y" * 300_000
    (tmp_path / "giant.csv").write_text(giant + "\n1,2\n")
    msg = refused(["navigate", tmp_path / "giant.csv", "--init", INIT, "-o", out], "line 1: the header is longer")
    assert len(msg) < 300
    assert not out.exists()


def test_hundred_thousand_header_columns_are_refused_quickly(tmp_path):
    (tmp_path / "wide.csv").write_text(",".join(f"c{k}" for k in range(100_000)) + "\n" + "1," * 99_999 + "1\n")
    t0 = time.perf_counter()
    refused(["compare", "--truth", tmp_path / "wide.csv", SAMPLE / "truth.csv", "-o", tmp_path / "rep"],
            "wide.csv: line 1")
    assert time.perf_counter() - t0 < 5.0
    assert not (tmp_path / "rep").exists()


@pytest.mark.parametrize("text,fragment", [
    (b"time: 0.0\nlat: 30\xff\n", "line 2, column 8: byte 0xff is not UTF-8"),
    (b"time: " + b"[" * 20000 + b"]" * 20000 + b"\n", "nested more than 64 levels deep"),
    (b"time: 1" + b"0" * 400 + b"\n", "line 1, column 7: time: integer '100"),
    (INIT.read_bytes().replace(b"heading:", b"heding:"), "missing key(s) heading (found 'heding': misspelt?)"),
])
def test_init_yaml_problems(data, tmp_path, text, fragment):
    (tmp_path / "init.yaml").write_bytes(text)
    refused(["navigate", data / "imu.csv", "--init", tmp_path / "init.yaml", "-o", tmp_path / "n.csv"],
            "init.yaml", fragment)


def test_config_problems(data, tmp_path):
    out = tmp_path / "n.csv"
    (tmp_path / "every.yaml").write_text("navigation:\n  every: " + "1" + "0" * 30 + "\n")
    refused(["navigate", data / "imu.csv", "--init", INIT, "--config", tmp_path / "every.yaml", "-o", out],
            "every.yaml: line 2, column 10: navigation.every: integer")
    (tmp_path / "every2.yaml").write_text("navigation:\n  every: 4611686018427387904\n")
    refused(["navigate", data / "imu.csv", "--init", INIT, "--config", tmp_path / "every2.yaml", "-o", out],
            "key navigation.every: expected a whole number from 1 to 2147483647")
    (tmp_path / "adir.yaml").mkdir()
    refused(["navigate", data / "imu.csv", "--init", INIT, "--config", tmp_path / "adir.yaml", "-o", out],
            "adir.yaml: is a directory, expected a config file")
    assert not out.exists()


def test_special_files_are_refused_without_blocking(data, tmp_path):
    """A FIFO as init, config or log: refused up front (an open would wait for a writer forever)."""
    for name in ("init.yaml", "cfg.yaml", "log.bag", "log.mcap"):
        os.mkfifo(tmp_path / name)
    cases = [["navigate", data / "imu.csv", "--init", tmp_path / "init.yaml", "-o", tmp_path / "n.csv"],
             ["navigate", data / "imu.csv", "--init", INIT, "--config", tmp_path / "cfg.yaml", "-o", tmp_path / "n.csv"],
             ["info", tmp_path / "log.bag"], ["convert", tmp_path / "log.mcap", "-o", tmp_path / "c"]]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for args in cases:
        p = subprocess.run([sys.executable, "-c", "from sinscli.cli import main; main()", *map(str, args)],
                           capture_output=True, text=True, timeout=60, env=env, stdin=subprocess.DEVNULL)
        assert p.returncode == 2 and "is a FIFO" in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_misspelt_db3_type_and_damaged_bag_index(tmp_path, caplog):
    n = 50
    imu = {"time": 0.01 * np.arange(n), "gyro": np.zeros((n, 3)), "accel": np.tile([0, 0, 9.8], (n, 1))}
    gnss = {"time": np.arange(3.0), "lat": np.full(3, 30.0), "lon": np.full(3, 114.0), "height": np.full(3, 5.0)}
    ros.write_log(tmp_path / "log.db3", imu=imu, gnss=gnss)
    with sqlite3.connect(tmp_path / "log.db3") as con:
        con.execute("UPDATE topics SET type = 'sensor_msgs/msg/Imx' WHERE type = 'sensor_msgs/msg/Imu'")
    rc, lines = sins(["info", tmp_path / "log.db3"])
    assert rc == 0
    rc, lines = sins(["convert", tmp_path / "log.db3", "-o", tmp_path / "conv"])
    assert rc == 0 and "no sensor_msgs/Imu topic" in caplog.text and "gnss.csv only" in caplog.text
    assert sorted(p.name for p in (tmp_path / "conv").iterdir()) == ["gnss.csv"]
    ros.write_log(tmp_path / "log.bag", imu=imu)
    raw = (tmp_path / "log.bag").read_bytes()
    (tmp_path / "cut.bag").write_bytes(raw[:-100])
    refused(["info", tmp_path / "cut.bag"], "cut.bag", "rosbag reindex")


# --------------------------------------------------------------------------- outputs

def test_output_problems(data, tmp_path):
    (tmp_path / "adir").mkdir()
    refused(["navigate", data / "imu.csv", "--init", INIT, "-o", tmp_path / "adir"], "adir: output is a directory")
    (tmp_path / "afile").write_text("x")
    refused(["navigate", data / "imu.csv", "--init", INIT, "-o", tmp_path / "afile" / "n.csv"], "is a file, not a folder")
    refused(["convert", SAMPLE / "imu.csv", "-o", tmp_path / "afile"], "afile: output is a file; give a folder name")
    refused(["compare", "--truth", SAMPLE / "truth.csv", SAMPLE / "truth.csv", "-o", tmp_path / "afile"], "afile")
    refused(["navigate", data / "imu.csv", "--init", INIT, "-o", tmp_path / "n.xyz"], "unknown output format '.xyz'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "afile"] and not any((tmp_path / "adir").iterdir())


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder(data, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    refused(["navigate", data / "imu.csv", "--init", INIT, "-o", ro / "n.csv"], "permission denied")


def test_click_usage_errors_are_one_line(data, tmp_path):
    refused(["navigate", data / "imu.csv", "--init", INIT, "--every", "0", "-o", tmp_path / "n.csv"],
            "navigate: Invalid value for '--every'")
    refused(["navigate"], "navigate: Missing argument 'IMU'")
    refused(["align", data / "imu.csv", "--method", "nope", "-o", tmp_path / "i.yaml"], "align: Invalid value")
    refused(["bogus"], "No such command 'bogus'")
    assert sins(["--help"])[0] == 0


def test_sources_named_in_map_outputs(data, tmp_path):
    for suffix in (".kml", ".geojson"):
        assert sins(["navigate", data / "imu.csv", "--init", INIT, "-q", "-o", tmp_path / f"n{suffix}"])[0] == 0
        text = (tmp_path / f"n{suffix}").read_text()
        assert str(data / "imu.csv") in text and "<memory>" not in text


def test_writer_guard_and_navigator_state_check(tmp_path):
    tr = read_trajectory(SAMPLE / "truth.csv")
    tr.height = tr.height.copy()
    tr.height[7] = np.nan
    for suffix in (".csv", ".parquet", ".mcap", ".tum", ".geojson", ".kml"):
        with pytest.raises(NonFiniteOutput, match=r"internal consistency check: row 8 \(time 0.07 s\), column 'height': nan is "
                                                   r"not a finite number"):
            write_trajectory(tmp_path / f"t{suffix}", tr)
    assert list(tmp_path.iterdir()) == []
    # the navigator stops with the epoch when its state turns non-finite (an input no reader saw)
    from sinscli.io.init_state import read_init
    init = read_init(INIT)
    n = 500
    dth = np.zeros((n, 3))
    dth[300, 0] = np.inf
    imu = ImuLog(np.arange(1, n + 1) / 100.0, dth, np.tile([0, 0, 0.0979], (n, 1)), source="made.csv")
    with pytest.raises(SinsError, match=r"made.csv: the navigation state became non-finite at t = 3.01 s"):
        Navigator(init, NavOptions()).feed(imu)


def test_atomic_temporaries_are_named_after_the_target(tmp_path):
    target = tmp_path / "out.csv"
    stale = tmp_path / ".out.csv.999999999.part"          # no such process
    stale.write_text("left by a killed run")
    other = tmp_path / f".out.csv.{os.getppid()}.part"     # a live process's: kept
    other.write_text("in use")
    with atomic_path(target) as tmp:
        assert tmp.name == f".out.csv.{os.getpid()}.part"
        tmp.write_text("x")
    assert not stale.exists() and other.exists() and target.read_text() == "x"
    # the writer guard names the target, also for a file inside a staged report folder
    from sinscli.io.atomic import target_of
    assert target_of(tmp_path / f".rep.{os.getpid()}.part" / "errors.csv") == tmp_path / "rep" / "errors.csv"
    assert target_of(tmp_path / f".out.csv.{os.getpid()}.part") == target


def test_numba_cache_falls_back_when_nothing_is_writable(tmp_path):
    """An unwritable package folder and HOME ("no locator available" in numba): one warning, then it works.

    As root nothing is read-only, so the package is copied with every ``__pycache__`` made a file, and HOME
    points below a file: numba can create neither cache folder."""
    pkg = tmp_path / "pkg"
    shutil.copytree(ROOT / "sinscli", pkg / "sinscli", ignore=shutil.ignore_patterns("__pycache__"))
    for d in [p for p in (pkg / "sinscli").rglob("*") if p.is_dir()] + [pkg / "sinscli"]:
        (d / "__pycache__").write_text("")
    (tmp_path / "homefile").write_text("")
    work = tmp_path / "work"
    work.mkdir()
    lines = (SAMPLE / "imu.csv").read_text().splitlines()[:41]
    (work / "imu.csv").write_text("\n".join(lines) + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    env.update(PYTHONPATH=str(pkg), HOME=str(tmp_path / "homefile" / "home"))
    p = subprocess.run([sys.executable, "-c", "from sinscli.cli import main; main()", "navigate", "imu.csv", "--init",
                        str(INIT), "-q", "-o", "nav.csv"], cwd=work, env=env, capture_output=True, text=True,
                       timeout=600, stdin=subprocess.DEVNULL)
    assert p.returncode == 0, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    warn = [ln for ln in lines if "WARNING" in ln]
    assert len(warn) == 1 and "cannot write numba's kernel cache" in warn[0], p.stderr
    # -q: no compile note (an empty cache) and no summary line; nothing besides the warning
    assert lines == warn, p.stderr
    assert len((work / "nav.csv").read_text().splitlines()) == 1 + 1 + 40        # header, initial row, 40 samples


# --------------------------------------------------------------------------- main's new inputs and outputs

def _fused(data, tmp_path, *extra, gnss=None, init=INIT):
    return ["navigate", data / "imu.csv", "--gnss", gnss or SAMPLE / "gnss.csv", "--init", init, "-q",
            "-o", tmp_path / "f.csv", *extra]


@pytest.mark.parametrize("text,fragments", [
    ("fusion:\n  gnss_pos_sigma: [1.5, 1.0e+300, 3.0]\n", ["c.yaml: key fusion.gnss_pos_sigma[1]", "within +-1e+09"]),
    ("fusion:\n  init_sigma: {position: 1.0e+8}\n", ["key fusion.init_sigma.position: expected a number in (0, 1e+07], got 100000000.0"]),
    ("fusion:\n  standstill: {window: 1.0e+30}\n", ["fusion.standstill.window"]),
    ("fusion:\n  rejection_run: 9223372036854775807\n", ["fusion.rejection_run", "from 1 to 2147483647"]),
    ("fusion:\n  gnss_vel_sigma: .inf\n", ["c.yaml: line 2", "fusion.gnss_vel_sigma: '.inf' is not a finite"]),
    ("fusion:\n  sensor: {gyro: {arw: [a, b, c]}}\n", ["c.yaml: key gyro.arw: expected 3 numbers or one, got ['a', 'b', 'c']"]),
    ("fusion:\n  sensor: {gyro: {arw: 1.0e+300}}\n", ["key gyro.arw: expected numbers within +-1e+09, got 1e+300"]),
    ("fusion:\n  sensor: {gyro: [1, 2]}\n", ["key gyro: expected a mapping of error terms, got [1, 2]"]),
    ("gnss:\n  time_offset: 1.0e+300\n", ["c.yaml: key gnss.time_offset", "limits.time"]),
])
def test_fusion_config_values_that_cannot_be_physical(data, tmp_path, text, fragments):
    (tmp_path / "c.yaml").write_text(text)
    refused(_fused(data, tmp_path, "--config", "c.yaml"), *fragments, cwd=tmp_path)
    assert not (tmp_path / "f.csv").exists()


def test_fused_navigation_inputs(data, tmp_path):
    """GNSS rows beyond the limits, an init with broken align estimates, outputs checked up front."""
    gnss = _with_line(SAMPLE / "gnss.csv", tmp_path / "g.csv", 5, 7, "1e30")           # std_e
    refused(_fused(data, tmp_path, gnss=gnss), "g.csv: line 6, column 'std_e': 1-sigma 1e+30 is beyond 1000000000.0")
    gnss = _with_line(SAMPLE / "gnss.csv", tmp_path / "g.csv", 5, 4, "2e4")            # vel_e
    refused(_fused(data, tmp_path, gnss=gnss), "g.csv: line 6, column 'vel_e'", "limits.speed")
    for extra, *fragments in (("sigma_roll: 0.0\nsigma_pitch: 0.1\n", "sigma_roll: 0.0 is not a positive finite"),
                              ("sigma_roll: 0.1\nsigma_pitch: 0.1\nsigma_heading: text\n",
                               "sigma_heading: expected a 1-sigma in degrees"),
                              ("gyro_bias: [1, 2]\naccel_bias: [1, 2, 3]\n", "gyro_bias: expected three numbers"),
                              ("gyro_bias: [1.0e+12, 0, 0]\naccel_bias: [1, 2, 3]\n", "gyro bias", "limits.rate")):
        init = tmp_path / "i.yaml"
        init.write_text(INIT.read_text() + extra)
        refused(_fused(data, tmp_path, init=init), "i.yaml", *fragments)
    (tmp_path / "d").mkdir()
    refused(_fused(data, tmp_path, "--innovations", tmp_path / "d"), "output is a directory")
    refused(_fused(data, tmp_path, "--innovations", tmp_path / "g.csv" / "x.csv"), "is a file, not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "g.csv", "i.yaml"]


def test_tum_inputs_of_compare(data, tmp_path):
    tr = read_trajectory(SAMPLE / "truth.csv")
    write_trajectory(tmp_path / "t.tum", tr)
    text = (tmp_path / "t.tum").read_text().splitlines()
    (tmp_path / "n.tum").write_text("\n".join(text[:5] + ["1e11 0 0 0 0 0 0 1"] + text[6:]) + "\n")
    refused(["compare", "--truth", tmp_path / "t.tum", tmp_path / "n.tum", "-o", tmp_path / "r"],
            "n.tum: line 6, column 'time': time stamp 100000000000.0 s is beyond", "limits.time")
    bad = [re.sub(r"origin_lat_deg=\S+", "origin_lat_deg=95", ln) for ln in text]
    (tmp_path / "n.tum").write_text("\n".join(bad) + "\n")
    refused(["compare", "--truth", SAMPLE / "truth.csv", tmp_path / "n.tum", "-o", tmp_path / "r"],
            "n.tum: line 2, column 'origin_lat_deg': latitude 95.")
    (tmp_path / "n.tum").write_text("\n".join(text[:4] + ["3.0 1e300 0 0 0 0 0 1"] + text[5:]) + "\n")
    refused(["compare", "--truth", tmp_path / "t.tum", tmp_path / "n.tum", "-o", tmp_path / "r"],
            "n.tum: line 5, column 'tx': position 1e+300 m")
    os.mkfifo(tmp_path / "fifo.tum")
    refused(["compare", "--truth", SAMPLE / "truth.csv", tmp_path / "fifo.tum", "-o", tmp_path / "r"],
            "fifo.tum: is a FIFO")
    (tmp_path / "afile").write_text("x")
    refused(["compare", "--truth", SAMPLE / "truth.csv", tmp_path / "t.tum", "-o", tmp_path / "afile"],
            "afile")
    assert not (tmp_path / "r").exists()


def test_compare_metrics_alignment_names_the_file(tmp_path):
    """The first 31 s of the sample drive stand still: no rotation fixes the Umeyama alignment."""
    lines = (SAMPLE / "truth.csv").read_text().splitlines()[:3000]
    (tmp_path / "n.csv").write_text("\n".join(lines) + "\n")
    refused(["compare", "--truth", tmp_path / "n.csv", tmp_path / "n.csv", "--metrics", "ate", "--align-traj", "se3",
             "-o", tmp_path / "r"], "n.csv: the positions do not fix a rotation")


def test_body_velocity_csv_limits(tmp_path):
    from sinscli.config import load_config
    from sinscli.io.readers import read_body_velocity
    rows = ["time,vel_x,vel_y,vel_z,std_x,std_y,std_z"] + [f"{0.1 * k!r},1.0,0.0,0.0,0.1,0.1,0.1" for k in range(10)]
    for k, col, value, fragment in ((4, 1, "2e4", "line 5, column 'vel_x': velocity 20000.0 m/s is beyond"),
                                    (4, 0, "1e12", "line 5, column 'time': time stamp"),
                                    (4, 5, "1e300", r"line 5, column 'std_y': 1-sigma 1e\+300 is beyond")):
        cells = rows[k].split(",")
        cells[col] = value
        (tmp_path / "o.csv").write_text("\n".join(rows[:k] + [",".join(cells)] + rows[k + 1:]) + "\n")
        with pytest.raises(SinsError, match=fragment):
            read_body_velocity(tmp_path / "o.csv", load_config(None))


def test_allan_writers_guard(tmp_path):
    from sinscli.allan.output import write_allan_csv, write_fit_csv, write_sensor_yaml
    from sinscli.allan.pipeline import characterize
    rng = np.random.default_rng(4)
    n = 7000
    imu = ImuLog(0.01 * np.arange(1, n + 1), rng.normal(0, 2e-5, (n, 3)),
                 rng.normal(0, 2e-4, (n, 3)) + [0.0, 0.0, 0.097936], t0=0.0, source="static.csv")
    res = characterize(imu, None, None, 0.01, 0.1, 1.0)
    res.adev[3, 2] = np.nan
    with pytest.raises(NonFiniteOutput, match=r"allan.csv: internal consistency check: row 4, column 'adev'"):
        write_allan_csv(tmp_path / "allan.csv", res)
    res.fits[1].white = float("inf")
    with pytest.raises(NonFiniteOutput, match=r"fit.csv: .*row 2, column 'white'"):
        write_fit_csv(tmp_path / "fit.csv", res)
    with pytest.raises(NonFiniteOutput, match=r"sensor.yaml: .*column 'gyro.arw'"):
        write_sensor_yaml(tmp_path / "sensor.yaml", res, "x")
    assert list(tmp_path.iterdir()) == []
