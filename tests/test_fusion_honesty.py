"""The fused filter is honest about what the log contradicts (docs/fusion.md): a clean log rejects no run of
good fixes, a wrong lever arm is named with the estimate the fixes imply, a gyro bias far outside its
description does not make it reject the fixes, and the smoother never has to clip a pivot on consistent
data.  Simulated logs with exact truth, run as a user runs them (the ``sins`` command)."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from sinscli.io.innovations import read_innovations
from sinscli.sim.run import simulate, write_sim

ROOT = Path(__file__).resolve().parents[1]
SINS = shutil.which("sins", path=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", "")) or "sins"
LEVER = [0.8, 0.0, 1.5]


def _sins(args, cwd):
    return subprocess.run([SINS, *args], cwd=cwd, capture_output=True, text=True)


def _fuse(d: Path, name: str, cfg: dict, *extra):
    (d / f"{name}.yaml").write_text(yaml.safe_dump(cfg))
    r = _sins(["navigate", "imu.csv", "--gnss", "gnss.csv", "--init", "init.yaml", "--config", f"{name}.yaml",
               "--vehicle", "car", "-o", f"{name}.csv", "--innovations", f"{name}_inn.csv", *extra], d)
    assert r.returncode == 0, r.stderr
    return r.stderr


@pytest.fixture(scope="module")
def rtk(tmp_path_factory):
    """Five minutes of the tactical RTK drive (200 Hz tactical IMU, 10 Hz fixes at 2 cm, the antenna 0.8 m
    forward and 1.5 m up), no outage."""
    d = tmp_path_factory.mktemp("rtk")
    sc = yaml.safe_load((ROOT / "configs/scenarios/tactical_rtk_drive.yaml").read_text())
    sc["gnss"]["outages"] = []
    write_sim(simulate(sc, duration=300.0), d)
    return d


def test_a_clean_log_rejects_no_run_of_good_fixes(rtk):
    """The right model (the tactical description, the documented lever arm) on 3,000 RTK fixes: no run of
    rejections, and no more fixes rejected than the gate's false-alarm rate allows (1e-4 per fix: at most 3
    of 3,000 at the 99.6 % level of the binomial)."""
    err = _fuse(rtk, "right", {"gnss": {"lever_arm": LEVER}, "fusion": {"sensor": "tactical"}})
    assert "run(s) of consecutive" not in err, err
    rec = read_innovations(rtk / "right_inn.csv")
    pos = rec[rec["type"] == "gnss_pos"]
    assert len(pos) // 3 == 3000
    assert int((~pos["accepted"]).sum()) // 3 <= 3, err
    assert "covariance widened" not in err and "contradict the lever arm" not in err, err


def test_a_lever_arm_the_fixes_contradict_is_named_with_their_estimate(rtk):
    """The same log without its lever arm: the fixes contradict the filter in the turns; a diagnosis pass that
    estimates the lever arm names it (x within 5 cm of the true 0.8 m; z, seen only through the climbs'
    pitch, within its own 3 sigma) in one warning, which says which key to set."""
    err = _fuse(rtk, "nolever", {"fusion": {"sensor": "tactical"}})
    m = re.search(r"contradict the lever arm \[0\.0, 0\.0, 0\.0\] m: a pass that estimated it found "
                  r"\[([-0-9.]+), ([-0-9.]+), ([-0-9.]+)\] m \+- \[([0-9.e-]+), ([0-9.e-]+), ([0-9.e-]+)\] m", err)
    assert m, err
    est = np.array([float(m.group(i)) for i in (1, 2, 3)])
    sig = np.array([float(m.group(i)) for i in (4, 5, 6)])
    assert abs(est[0] - LEVER[0]) < 0.05 and abs(est[1] - LEVER[1]) < 0.05, (est, sig)
    assert abs(est[2] - LEVER[2]) < 3.0 * sig[2], (est, sig)
    assert "gnss.lever_arm" in err and "fusion.estimate: [lever_arm]" in err


def test_the_smoother_clips_no_pivot_on_consistent_data(rtk):
    """The right model, smoothed: the smoother's guard never clips a pivot and never needs a ridge (the summary
    says nothing of it), and the smoothed track has no step: no row moves further from the one before than
    the platform's speed allows over the interval (plus a millimetre)."""
    err = _fuse(rtk, "smooth", {"gnss": {"lever_arm": LEVER}, "fusion": {"sensor": "tactical"}}, "--smooth")
    assert "guard" not in err, err
    import pyarrow.csv as pc
    t = pc.read_csv(rtk / "smooth.csv").to_pydict()
    lat, lon = np.radians(t["lat"]), np.radians(t["lon"])
    e = (lon - lon[0]) * 6378137.0 * np.cos(lat[0])
    n = (lat - lat[0]) * 6378137.0
    step = np.hypot(np.diff(e), np.diff(n))
    speed = np.hypot(np.array(t["vel_e"]), np.array(t["vel_n"]))
    dt = np.diff(np.array(t["time"]))
    assert np.all(step <= np.maximum(speed[1:], speed[:-1]) * dt * 1.01 + 1e-3)
