"""NED frames and radians in the init, GNSS and truth files (issue 10): the config's ``init``, ``gnss`` and
``truth`` sections (``frame: ned``, ``units: {angle: rad}``) read converted copies of the sample data into the
same navigation and the same compare report."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from sinscli.frames import C_NED_ENU
from sinscli.io.trajectory import read_trajectory
from sinscli.nav.rotation import FRD, cbn_from_flu, dcm_to_quat_many
from test_contract import refused, sins

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
R = math.pi / 180.0


def _write(path, header, rows):
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows([[repr(float(x)) for x in r] for r in rows])


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    d = tmp_path_factory.mktemp("frames")
    (d / "imu.csv").write_text("\n".join((SAMPLE / "imu.csv").read_text().splitlines()[:3102]) + "\n")   # 31 s
    (d / "gnss.csv").write_text("\n".join((SAMPLE / "gnss.csv").read_text().splitlines()[:31]) + "\n")
    (d / "truth.csv").write_bytes((SAMPLE / "truth.csv").read_bytes())
    init = yaml.safe_load((SAMPLE / "init.yaml").read_text())
    (d / "init.yaml").write_text(yaml.safe_dump(init, sort_keys=False))
    # init YAML: NED velocity (vel_d), radians
    ned = {k: (v * R if k in ("lat", "lon", "roll", "pitch", "heading") else v) for k, v in init.items()}
    ned["vel_d"] = -ned.pop("vel_u")
    (d / "init_ned.yaml").write_text(yaml.safe_dump(ned, sort_keys=False))
    # GNSS CSV: NED columns, radians
    g = np.genfromtxt(d / "gnss.csv", delimiter=",", names=True)
    _write(d / "gnss_ned.csv", ["time", "lat", "lon", "height", "vel_n", "vel_e", "vel_d", "std_n", "std_e",
                                "std_d", "std_vel_n", "std_vel_e", "std_vel_d"],
           np.column_stack([g["time"], g["lat"] * R, g["lon"] * R, g["height"], g["vel_n"], g["vel_e"], -g["vel_u"],
                            g["std_n"], g["std_e"], g["std_u"], g["std_vel_n"], g["std_vel_e"], g["std_vel_u"]]))
    # truth: NED, radians, FRD body, no marker (the attitude columns body -> NED)
    t = read_trajectory(d / "truth.csv")
    raw = np.genfromtxt(d / "truth.csv", delimiter=",", names=True)
    c = np.matmul(C_NED_ENU, cbn_from_flu(t.Cbn, FRD))
    q = dcm_to_quat_many(np.ascontiguousarray(c))
    _write(d / "truth_ned.csv", ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_d", "roll", "pitch",
                                 "heading", "qw", "qx", "qy", "qz"] + [f"c{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)],
           np.column_stack([raw["time"], raw["lat"] * R, raw["lon"] * R, raw["height"], raw["vel_e"], raw["vel_n"],
                            -raw["vel_u"], raw["roll"] * R, raw["pitch"] * R, raw["heading"] * R, q,
                            c.reshape(-1, 9)]))
    (d / "ned.yaml").write_text("init:\n  frame: ned\n  units: {angle: rad}\ngnss:\n  frame: ned\n  units: {angle: rad}\n"
                                "truth:\n  frame: NED\n  units: {angle: rad}\n")
    return d


def _nav(d, out, *args):
    rc, lines = sins(["navigate", "imu.csv", "-q", "-o", out, *args], cwd=d)
    assert rc == 0, lines
    return read_trajectory(d / out)


def _same(a, b, pos=1e-12, att=1e-12):
    assert len(a) == len(b) and np.array_equal(a.time, b.time)
    assert np.abs(a.lat - b.lat).max() < pos and np.abs(a.lon - b.lon).max() < pos
    assert np.abs(a.vel_n - b.vel_n).max() < 1e-6 and np.abs(a.Cbn - b.Cbn).max() < att


def test_init_yaml_ned_radians(d):
    _same(_nav(d, "a.csv", "--init", "init.yaml"), _nav(d, "b.csv", "--init", "init_ned.yaml", "--config", "ned.yaml"))


def test_init_trajectory_ned_radians_frd(d):
    a = _nav(d, "c.csv", "--init", "truth.csv", "--start", "20")
    b = _nav(d, "e.csv", "--init", "truth_ned.csv", "--start", "20", "--config", "ned.yaml")
    assert read_trajectory(d / "truth_ned.csv", None, "ned", 180 / math.pi).body == FRD     # told by its angles
    _same(a, b, att=1e-9)


def test_gnss_ned_radians(d):
    a = _nav(d, "f.csv", "--init", "init.yaml", "--gnss", "gnss.csv")
    b = _nav(d, "g.csv", "--init", "init_ned.yaml", "--gnss", "gnss_ned.csv", "--config", "ned.yaml")
    _same(a, b, pos=1e-11, att=1e-8)


def test_truth_ned_radians_frd(d):
    _nav(d, "h.csv", "--init", "init.yaml")
    errs = []
    for truth, extra in (("truth.csv", []), ("truth_ned.csv", ["--config", "ned.yaml"])):
        rc, lines = sins(["compare", "--truth", truth, "h.csv", "-o", f"rep_{truth}", "-q", *extra], cwd=d)
        assert rc == 0, lines
        errs.append({r[0]: float(r[2]) for r in csv.reader((d / f"rep_{truth}" / "errors.csv").open())
                     if r[0] != "quantity"})
    assert errs[0].keys() == errs[1].keys()
    for k in errs[0]:
        assert errs[1][k] == pytest.approx(errs[0][k], rel=1e-6, abs=1e-6), k


@pytest.mark.parametrize("cfg, args, fragments", [
    ("init:\n  frame: nwu\n", ["navigate", "imu.csv", "--init", "init.yaml"], ["init.frame", "expected one of enu, ned"]),
    ("gnss:\n  units: {angle: grad}\n", ["navigate", "imu.csv", "--init", "init.yaml"],
     ["gnss.units.angle", "expected one of deg, rad"]),
    ("truth:\n  units: {length: ft}\n", ["compare", "--truth", "truth.csv", "truth.csv"], ["truth.units.length"]),
    ("", ["navigate", "imu.csv", "--init", "init_ned.yaml"], ["missing key(s) vel_u", "init.frame: ned"]),
    ("", ["compare", "--truth", "truth_ned.csv", "truth.csv"], ["missing trajectory column(s) vel_u", "frame: ned"]),
])
def test_unknown_frame_or_units_refused(d, cfg, args, fragments):
    (d / "bad.yaml").write_text(cfg or "imu: {}\n")
    out = "rep_bad" if args[0] == "compare" else "bad.csv"
    refused([*args, "--config", "bad.yaml", "-o", out], *fragments, cwd=d)
    assert not (d / out).exists()
