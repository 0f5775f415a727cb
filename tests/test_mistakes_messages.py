"""Mistakes that ended in exit 0 with a wrong result, and messages a person reads (issue 22).  Each case:
the one-line message (exit 2, nothing written), or the corrected behaviour."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from test_contract import refused, sins

from sinscli.io import ros

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
INIT = SAMPLE / "init.yaml"


@pytest.fixture(scope="module")
def deg(tmp_path_factory):
    """The sample drive (60 s at rest, then driving) as a rate CSV in deg/s, and its increments in deg."""
    d = tmp_path_factory.mktemp("units")
    inc = pd.read_csv(SAMPLE / "imu.csv")
    dt = np.diff(np.concatenate([[0.0], inc.time.to_numpy()]))
    rates = pd.DataFrame({"time": inc.time})
    for i, a in enumerate("xyz"):
        rates[f"gyro_{a}"] = np.degrees(inc[f"dtheta_{a}"] / dt)
    for a in "xyz":
        rates[f"accel_{a}"] = inc[f"dvel_{a}"] / dt
    rates.to_csv(d / "rates_deg.csv", index=False)
    inc_deg = inc.copy()
    for a in "xyz":
        inc_deg[f"dtheta_{a}"] = np.degrees(inc[f"dtheta_{a}"])
    inc_deg.to_csv(d / "inc_deg.csv", index=False)
    (d / "deg.yaml").write_text("imu:\n  units:\n    gyro: deg/s\n    dtheta: deg\n")
    init = yaml.safe_load(INIT.read_text())
    init["time"] = 0.01                                  # a rate file's first sample starts its first interval
    (d / "init_rates.yaml").write_text(yaml.safe_dump(init))
    return d


# --------------------------------------------------------------------------- gyro units

def test_deg_per_s_declared_rad_per_s_is_refused_with_the_unit_to_set(deg, tmp_path):
    """Before: a warning, then a garbage trajectory (exit 0).  At rest the gyros read 0.07 rad/s as
    declared, a bias no sensor preset allows (mems: 5 sigma 0.015 rad/s), and 0.0012 rad/s as deg/s."""
    refused(["navigate", deg / "rates_deg.csv", "--init", deg / "init_rates.yaml", "-o", tmp_path / "n.csv"],
            "rates_deg.csv: gyro units: at rest", "the data are in deg/s; set imu.units.gyro: deg/s",
            "--force")
    refused(["navigate", deg / "inc_deg.csv", "--init", INIT, "-o", tmp_path / "n.csv"],
            "set imu.units.dtheta: deg")
    refused(["navigate", deg / "inc_deg.csv", "--gnss", SAMPLE / "gnss.csv", "--init", INIT, "-o",
             tmp_path / "f.csv"], "set imu.units.dtheta: deg")
    refused(["align", deg / "inc_deg.csv", "--method", "static", "--position", "30,114,50", "--duration", "50",
             "-o", tmp_path / "a.yaml"], "set imu.units.dtheta: deg")
    assert list(tmp_path.iterdir()) == []
    # with the unit set, the same data navigate to the sample's own result (to rounding of the deg/rad trip)
    rc, lines = sins(["navigate", deg / "inc_deg.csv", "--init", INIT, "--config", deg / "deg.yaml", "-o",
                      tmp_path / "ok.csv", "-q"])
    assert rc == 0, lines
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--init", INIT, "-o", tmp_path / "ref.csv", "-q"])
    a, b = pd.read_csv(tmp_path / "ok.csv"), pd.read_csv(tmp_path / "ref.csv")
    assert np.abs(a.lat - b.lat).max() * 111e3 < 1e-6 and np.abs(a.heading - b.heading).max() < 1e-9
    rc, lines = sins(["navigate", deg / "inc_deg.csv", "--init", INIT, "--force", "-o", tmp_path / "forced.csv", "-q"])
    assert rc == 0 and (tmp_path / "forced.csv").is_file(), lines


def test_the_unit_check_passes_real_units(tmp_path):
    """No false refusal: the sample MEMS (0.1 deg/s bias class), and perfect and tactical sensors at rest."""
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--init", INIT, "-o", tmp_path / "n.csv", "-q"])
    assert rc == 0, lines
    for sensor in ("tactical", "navigation"):
        sc = yaml.safe_load((ROOT / "configs/scenarios/vehicle_drive.yaml").read_text())
        sc["imu"]["sensor"] = sensor
        (tmp_path / f"{sensor}.yaml").write_text(yaml.safe_dump(sc))
        rc, lines = sins(["simulate", tmp_path / f"{sensor}.yaml", "-o", tmp_path / sensor, "--duration", "70", "-q"])
        assert rc == 0, lines
        rc, lines = sins(["navigate", tmp_path / sensor / "imu.csv", "--init", tmp_path / sensor / "init.yaml",
                          "-o", tmp_path / f"{sensor}.csv", "-q"])
        assert rc == 0, lines


def test_a_navigation_grade_gyro_in_deg_per_s_is_the_earth_rate_57_times(tmp_path):
    """A good gyro at rest reads the earth rate: in deg/s read as rad/s it is 57.3 times it, with the earth
    rate's up and horizontal components (4.2e-3 rad/s: within any preset's bias bound, so the geometry tells)."""
    sc = yaml.safe_load((ROOT / "configs/scenarios/static_1h.yaml").read_text())
    sc["imu"]["sensor"] = "navigation"
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(sc))
    rc, lines = sins(["simulate", tmp_path / "s.yaml", "-o", tmp_path / "s", "--duration", "90", "-q"])
    assert rc == 0, lines
    inc = pd.read_csv(tmp_path / "s" / "imu.csv")
    for a in "xyz":
        inc[f"dtheta_{a}"] = np.degrees(inc[f"dtheta_{a}"])
    inc.to_csv(tmp_path / "deg.csv", index=False)
    refused(["navigate", tmp_path / "deg.csv", "--init", tmp_path / "s" / "init.yaml", "--config",
             ROOT / "configs/navigation.yaml", "-o", tmp_path / "n.csv"],
            "times the earth rate; read as deg/s they are the earth rate", "set imu.units.dtheta: deg")


def test_rates_beyond_the_limit_that_fit_in_degrees_name_the_unit(deg, tmp_path):
    r = pd.read_csv(deg / "rates_deg.csv")
    r.loc[7000, "gyro_z"] = 300.0                         # 300 deg/s: a sharp turn; as rad/s, 48 turns a second
    r.to_csv(tmp_path / "r.csv", index=False)
    refused(["navigate", tmp_path / "r.csv", "--init", deg / "init_rates.yaml", "-o", tmp_path / "n.csv"],
            "r.csv: line 7002, column 'gyro_z': angular rate 300.0 rad/s is beyond the physical limit",
            "read as deg/s every value is within it: the file holds deg/s, set imu.units.gyro: deg/s")


# --------------------------------------------------------------------------- GNSS time offset

@pytest.mark.parametrize("shift, drop_velocity", [(18.0, False), (-7.3, False), (18.0, True)])
def test_a_constant_gnss_time_offset_is_found_with_the_shift_to_set(tmp_path, shift, drop_velocity):
    """Relative time bases, the GNSS times 18 s late: 41 fixes were rejected and the residual was 38 m
    (exit 0).  The turn rate and horizontal acceleration of the IMU and of the GNSS velocity (or, without
    velocity columns, of the positions twice differenced) agree best at the true shift."""
    g = pd.read_csv(SAMPLE / "gnss.csv")
    g["time"] += shift
    if drop_velocity:
        g = g.drop(columns=[c for c in g.columns if c.startswith(("vel_", "std_vel"))])
    g.to_csv(tmp_path / "gnss.csv", index=False)
    line = refused(["navigate", SAMPLE / "imu.csv", "--gnss", tmp_path / "gnss.csv", "--init", INIT, "-o",
                    tmp_path / "f.csv"], "gnss.csv: the GNSS times are", "set gnss.time_offset:", "--force")
    found = float(re.search(r"shifted by ([-+][0-9.]+) s", line).group(1))
    assert found == pytest.approx(-shift, abs=0.15), line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gnss.csv"]
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--gnss", tmp_path / "gnss.csv", "--init", INIT,
                      "--time-offset", f"{found:.2f}", "-o", tmp_path / "f.csv"])
    fixes = next(ln for ln in lines if ln.startswith("sins: fusion: GNSS fixes"))
    assert rc == 0 and "rejected" not in fixes, fixes
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--gnss", tmp_path / "gnss.csv", "--init", INIT,
                      "--force", "-o", tmp_path / "g.csv", "-q"])
    assert rc == 0, lines


def test_no_offset_is_reported_for_synchronized_logs():
    from sinscli.io.gnss_csv import read_gnss_csv
    from sinscli.io.imu_csv import read_imu_csv
    from sinscli.nav.timesync import estimate_offset, offset_refusal
    imu, g = read_imu_csv(SAMPLE / "imu.csv"), read_gnss_csv(SAMPLE / "gnss.csv")
    est = estimate_offset(imu.time, imu.dtheta_b, imu.dvel_b, 0.0, g.time, g.lat, g.lon, g.height, g.vel_n)
    assert abs(est.shift) < 0.1 and est.peak > 0.99 and offset_refusal(est, "gnss.csv") is None
    # GNSS times on another scale (ms, or 1e-4 s apart): too short an overlap, no estimate, and no runaway
    # grid of lags (the fuzzer found a fused run that did not end)
    for scale in (1e-4, 1e3):
        assert estimate_offset(imu.time, imu.dtheta_b, imu.dvel_b, 0.0, g.time * scale, g.lat, g.lon, g.height,
                               g.vel_n) is None


# --------------------------------------------------------------------------- logs too short

def test_subsamples_or_every_beyond_the_log_is_refused(tmp_path):
    """Before: exit 0 with only the initial row written."""
    lines = (SAMPLE / "imu.csv").read_text().splitlines()
    (tmp_path / "short.csv").write_text("\n".join(lines[:6]) + "\n")
    refused(["navigate", tmp_path / "short.csv", "--init", INIT, "--subsamples", "10", "-o", tmp_path / "s.csv"],
            "short.csv: 5 IMU sample(s) after the initial time 0.0 s: fewer than one attitude update of "
            "--subsamples 10 samples; nothing would be navigated")
    refused(["navigate", SAMPLE / "imu.csv", "--init", INIT, "--every", "100000", "-o", tmp_path / "e.csv"],
            "18,000 attitude update(s) of 1 sample(s), fewer than one output row every 100000 updates (--every)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.csv"]


def test_a_one_row_increment_file_says_what_is_missing(tmp_path):
    """Before: "the initial time 0.0 is before the log starts (0.01)", while the same init works with
    more rows."""
    lines = (SAMPLE / "imu.csv").read_text().splitlines()
    (tmp_path / "one.csv").write_text("\n".join(lines[:2]) + "\n")
    refused(["navigate", tmp_path / "one.csv", "--init", INIT, "-o", tmp_path / "o.csv"],
            "one.csv: a single increment row (t = 0.01): where its interval starts cannot be told",
            "give two rows or more")
    (tmp_path / "two.csv").write_text("\n".join(lines[:3]) + "\n")
    rc, out = sins(["navigate", tmp_path / "two.csv", "--init", INIT, "-o", tmp_path / "t.csv", "-q"])
    assert rc == 0, out


def test_convert_applies_navigates_gap_rule(tmp_path):
    """Before: convert bridged a 600 s IMU gap silently with one increment, which navigate then refused."""
    t = np.concatenate([np.arange(0.0, 5.0, 0.01), 605.0 + np.arange(0.0, 5.0, 0.01)])
    ros.write_log(tmp_path / "gap.bag", imu={"time": t, "gyro": np.zeros((t.size, 3)),
                                             "accel": np.tile([0.0, 0.0, 9.8], (t.size, 1))})
    refused(["convert", tmp_path / "gap.bag", "-o", tmp_path / "out"],
            "message 500: gap of 600.01 s before time 605.0", "use --allow-gaps to bridge it")
    assert not (tmp_path / "out").exists()
    rc, lines = sins(["convert", tmp_path / "gap.bag", "-o", tmp_path / "out", "--allow-gaps", "-q"])
    assert rc == 0, lines
    t_out = pd.read_csv(tmp_path / "out" / "imu.csv").time.to_numpy()
    assert np.diff(t_out).max() == pytest.approx(600.01)          # the one bridging increment


# --------------------------------------------------------------------------- messages

def test_long_refusals_are_cut_in_the_middle_at_spaces(tmp_path):
    """The allan refusal was cut mid-word (`... in --`): its end (what to do) is kept."""
    deep = tmp_path / ("a_long_folder_name_" * 8) / ("and_another_one_" * 8)
    deep.mkdir(parents=True)
    shutil.copy(SAMPLE / "imu.csv", deep / "imu.csv")
    line = refused(["allan", deep / "imu.csv", "-o", tmp_path / "noise"], f"sins: error: {tmp_path}",
                   " ... ", "choose a static stretch with --start/--end (limits: align.static_check in --config)")
    assert len(line) <= len("sins: error: ") + 480
    line = refused(["allan", SAMPLE / "imu.csv", "-o", tmp_path / "noise"], "imu.csv: not a static log",
                   "choose a static stretch with --start/--end (limits: align.static_check in --config)")
    assert " ... " not in line                                   # a plain path: nothing cut
    from sinscli.errors import SinsError
    text = str(SinsError("x" * 100 + " " + " ".join(f"word{i}" for i in range(200)) + " the end"))
    assert len(text) <= 480 and text.endswith(" the end") and " ... " in text
    assert all(re.fullmatch(r"x+|word\d+|the|end|\.\.\.", w) for w in text.split())


def test_progress_bars_only_on_a_terminal_and_quiet_convert(tmp_path):
    """Progress-bar labels printed as bare lines (`batch`, `compare`, `navigating`) when stderr was not a
    terminal; `convert -q` printed its `wrote` lines."""
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--init", INIT, "-o", tmp_path / "n.csv"])
    assert rc == 0 and all(ln.startswith("sins: ") for ln in lines), lines
    rc, lines = sins(["compare", "--truth", SAMPLE / "truth.csv", tmp_path / "n.csv", "-o", tmp_path / "rep"])
    assert rc == 0 and all(ln.startswith("sins: ") for ln in lines), lines
    t = np.arange(0.0, 3.0, 0.01)
    ros.write_log(tmp_path / "log.bag", imu={"time": t, "gyro": np.zeros((t.size, 3)),
                                             "accel": np.tile([0.0, 0.0, 9.8], (t.size, 1))})
    rc, lines = sins(["convert", tmp_path / "log.bag", "-o", tmp_path / "c", "-q"])
    assert rc == 0 and lines == [], lines
    rc, lines = sins(["convert", tmp_path / "log.bag", "-o", tmp_path / "c"])
    assert rc == 0 and [ln.split(":")[0] for ln in lines] == [f"wrote {tmp_path / 'c' / 'imu.csv'}"], lines


def test_the_program_ends_after_its_work_without_the_interpreter_teardown(tmp_path):
    """The process lingered 2-9 s after its last line: the interpreter's teardown (freeing numba, llvmlite,
    pyarrow, matplotlib and every array).  The `sins` program now runs the atexit handlers and ends
    (os._exit): an atexit handler still runs, an object's finalizer at teardown does not."""
    code = f"""
import atexit, sys
from pathlib import Path
out = Path({str(tmp_path)!r})
atexit.register(lambda: (out / "atexit").write_text("ran"))
class Teardown:
    def __del__(self):
        (out / "teardown").write_text("ran")
keep = Teardown()
sys.argv = ["sins", "navigate", {str(SAMPLE / "imu.csv")!r}, "--init", {str(INIT)!r}, "-o", str(out / "n.csv"), "-q"]
from sinscli.cli import main
main()
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "atexit").read_text() == "ran" and not (tmp_path / "teardown").exists()
    assert (tmp_path / "n.csv").is_file()
    r = subprocess.run([sys.executable, "-c", code.replace('"-q"]', '"-q", "--every", "0"]')], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and (tmp_path / "atexit").is_file()


def test_log_axis_ticks_are_decades_or_plain_values():
    """The report's log-scale axis printed `1e-1.4000000000000001`: within less than two decades the ticks
    are 1, 2, 5 (or every digit) times the decades, labelled with their values (report.js, run by node)."""
    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.skip("node is not installed")
    js = ROOT / "sinscli" / "report" / "assets" / "report.js"
    ranges = [(-1.5, -1.3), (-2.2, 0.3), (-1.52, -1.48), (-5.0, 2.0), (0.1, 0.9), (-1.4000000000000001, -1.2)]
    script = (f"const r = require({str(js)!r}); console.log(JSON.stringify("
              f"{json.dumps(ranges)}.map(([a, b]) => r.logTicks(a, b))));")
    out = json.loads(subprocess.run([node, "-e", script], capture_output=True, text=True, check=True).stdout)
    for (a, b), ticks in zip(ranges, out):
        assert len(ticks) >= 2, (a, b, ticks)
        for pos, label in ticks:
            assert a - 1e-9 <= pos <= b + 1e-9
            if label.startswith("1e"):
                assert re.fullmatch(r"1e-?\d+", label) and float(label) == 10.0 ** pos
            else:
                assert re.fullmatch(r"[0-9.]+", label) and abs(np.log10(float(label)) - pos) < 1e-12, label


def test_docs_hold_what_users_need():
    """Docs and the package pointed to FORMATS.md, ALGORITHMS.md and KRYLOV.md, which users of the repository
    do not have, and configs/fusion/husky.yaml named a machine path.  Every docs/ page that anything names
    exists, and nothing users read names a file outside the repository."""
    texts = {p: p.read_text(encoding="utf-8") for p in
             [ROOT / "README.md", ROOT / "sample_data" / "README.md", *(ROOT / "docs").glob("*.md"),
              *(ROOT / "configs").rglob("*.yaml"), *(ROOT / "sinscli").rglob("*.py")]}
    for p, text in texts.items():
        for bad in ("FORMATS.md", "ALGORITHMS.md", "KRYLOV.md", "/work/", "shared/docs", "shared/data"):
            assert bad not in text, (str(p), bad)
        for ref in re.findall(r"docs/([a-z_]+\.md)", text):
            assert (ROOT / "docs" / ref).is_file(), (str(p), ref)
    assert "## Formulas" in texts[ROOT / "docs" / "krylov.md"]
    for key in ("Gravity", "IMU CSV", "GNSS CSV", "Trajectory CSV", "Initial state", "Error tables"):
        assert f"## {key}" in texts[ROOT / "docs" / "formats.md"], key


@pytest.mark.parametrize("key, delta", [("height", 1.0e7), ("lat", 20.0)])
def test_an_init_far_from_the_fixes_is_refused_naming_the_init(tmp_path, key, delta):
    """An init 10,000 km above the fixes (or 20 deg of latitude away) with --gnss: the filter fought it until
    its covariance broke ("covariance lost positive definiteness", naming the IMU log); now the init is
    refused before any work, naming it, and nothing is written.  The shipped init, 0-2 m from its fix, runs."""
    init = yaml.safe_load(INIT.read_text())
    init[key] = float(init[key]) + delta
    (tmp_path / "init.yaml").write_text(yaml.safe_dump(init))
    line = refused(["navigate", SAMPLE / "imu.csv", "--gnss", SAMPLE / "gnss.csv", "--init", tmp_path / "init.yaml",
                    "-o", tmp_path / "f.csv"], "init.yaml: the initial position is", " m from the GNSS fix at t = ",
                   "limits.speed")
    assert str(SAMPLE / "gnss.csv") in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["init.yaml"]


def test_the_init_check_bound_against_a_hand_computed_distance():
    """The bound: 1 km + 3 sigma + limits.speed x |dt|, the distance straight through the Earth (ECEF)."""
    from sinscli.errors import SinsError
    from sinscli.io.gnss_csv import check_init_against_gnss
    from sinscli.types import GnssLog, NavState
    gnss = GnssLog(time=np.array([0.0, 1.0]), lat=np.array([45.0, 45.0]), lon=np.array([7.0, 7.0]),
                   height=np.array([100.0, 100.0]), std_pos=np.ones((2, 3)), source="g.csv")
    st = NavState(time=0.0, lat=np.radians(45.0), lon=np.radians(7.0), height=100.0 + 1000.0 + 3 * np.sqrt(3) - 0.01,
                  vel_n=np.zeros(3), Cbn=np.eye(3))
    check_init_against_gnss(st, gnss, 0.0, "i.yaml")                   # just inside: 1 km + 3 * sqrt(3) m
    far = NavState(time=0.0, lat=np.radians(45.0), lon=np.radians(7.0), height=100.0 + 1000.0 + 3 * np.sqrt(3) + 0.01,
                   vel_n=np.zeros(3), Cbn=np.eye(3))
    with pytest.raises(SinsError, match="i.yaml: the initial position is 1,005 m"):
        check_init_against_gnss(far, gnss, 0.0, "i.yaml")
    check_init_against_gnss(far, gnss, 1.0, "i.yaml") if False else None
    late = NavState(time=0.5, lat=np.radians(45.0), lon=np.radians(7.0), height=100.0 + 1500.0,
                    vel_n=np.zeros(3), Cbn=np.eye(3))
    check_init_against_gnss(late, gnss, 1000.0, "i.yaml")             # 1.5 km: within 1 km + 5 m + 1000 m/s x 0.5 s
    with pytest.raises(SinsError, match="in 0.5 s"):
        check_init_against_gnss(late, gnss, 100.0, "i.yaml")          # not within 1 km + 5 m + 50 m
