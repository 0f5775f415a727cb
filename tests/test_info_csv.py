"""``sins info`` on an IMU CSV (issue 10): rate, gaps, rest windows, the mean readings at the start and the
likely up axis, printed by the formatter of the ROS summary."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from test_contract import refused
from click.testing import CliRunner
from sinscli.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
SINS = Path(sys.executable).with_name("sins")


def _info(args, cwd=None):
    r = CliRunner().invoke(main, ["info", *map(str, args)])
    assert r.exit_code == 0, r.output
    return r.stdout


def test_sample_summary_against_truth(tmp_path):
    s = json.loads(_info([SAMPLE / "imu.csv", "--json"]))
    row = s["topics"][0]
    assert s["format"] == "IMU CSV" and row["count"] == 18000 and row["gaps"] == 0
    assert abs(row["rate_hz"] - 100.0) < 1e-9 and abs(s["duration"] - 179.99) < 1e-9
    (m,) = s["imu"].values()
    assert m["messages"] == 100 and abs(m["accel_norm"] - 9.79) < 0.05 and m["gyro_norm"] < 0.01
    truth = np.genfromtxt(SAMPLE / "truth.csv", delimiter=",", names=True)
    speed = np.sqrt(truth["vel_e"] ** 2 + truth["vel_n"] ** 2 + truth["vel_u"] ** 2)
    t_move = truth["time"][np.argmax(speed > 0.01)]                      # 60.69 s: the drive starts
    first = s["rest"][0]
    assert first[0] == 0.0 and abs(first[1] - t_move) < 2.0, (first, t_move)
    assert all(b <= 180.0 + 1e-9 and a < b for a, b in s["rest"])
    text = _info([SAMPLE / "imu.csv"])
    assert "at rest the up axis is +z" in text and "set imu.mounting" not in text
    assert "rest windows (the fusion's standstill detector): " in text and "0.000-62.000" in text


def test_gap_and_axis_hints(tmp_path):
    lines = (SAMPLE / "imu.csv").read_text().splitlines()
    (tmp_path / "gap.csv").write_text("\n".join(lines[:501] + lines[601:3001]) + "\n")    # 1 s missing at 5 s
    s = json.loads(_info([tmp_path / "gap.csv", "--json"]))
    assert s["topics"][0]["gaps"] == 1 and abs(s["topics"][0]["max_gap"] - 1.01) < 1e-9
    (tmp_path / "m.yaml").write_text("imu:\n  mounting: {roll: 90}\n")
    text = _info([tmp_path / "gap.csv", "--config", tmp_path / "m.yaml"])
    assert "up axis is -y; set imu.mounting" in text
    (tmp_path / "frd.yaml").write_text("imu:\n  body: frd\n  mounting: {roll: 180}\n")
    text = _info([tmp_path / "gap.csv", "--config", tmp_path / "frd.yaml"])
    assert "up axis is -z" in text and "set imu.mounting" not in text


def test_installed_script_and_bad_csv(tmp_path):
    (tmp_path / "imu.csv").write_text("\n".join((SAMPLE / "imu.csv").read_text().splitlines()[:2001]) + "\n")
    r = subprocess.run([str(SINS), "info", "imu.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                       env={**os.environ, "PYTHONPATH": ""})
    assert r.returncode == 0, r.stderr
    assert "imu.csv: IMU CSV, 2000 messages" in r.stdout and "rest windows" in r.stdout
    (tmp_path / "bad.csv").write_text("time,x\n1,2\n")
    refused(["info", tmp_path / "bad.csv"], "bad.csv", "unknown column(s) 'x'")
