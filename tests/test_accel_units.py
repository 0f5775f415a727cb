"""Accelerometer units (sinscli/nav/sanity.py ``accel_unit_check``): a log in g read as m/s^2 (or the reverse)
ended with exit 0, height -143 km and roll swinging from -88 to 138 deg.  Now it is refused in one line naming
the key to set, exit 2, nothing written; ``--force`` takes the data as declared; no real log is refused."""
from __future__ import annotations

import glob
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from realdata import HUSKY_BAG
import yaml

from test_contract import refused, sins

from sinscli.config import load_config
from sinscli.nav.sanity import accel_unit_refusal
from sinscli.units import G0

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
INIT = SAMPLE / "init.yaml"
BAG = HUSKY_BAG


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """The sample drive (60 s at rest, then 2 min driving) as rates in g and as increments in g*s."""
    d = tmp_path_factory.mktemp("accel")
    inc = pd.read_csv(SAMPLE / "imu.csv")
    dt = np.diff(np.concatenate([[0.0], inc.time.to_numpy()]))
    rates = pd.DataFrame({"time": inc.time})
    for a in "xyz":
        rates[f"gyro_{a}"] = inc[f"dtheta_{a}"] / dt
    for a in "xyz":
        rates[f"accel_{a}"] = inc[f"dvel_{a}"] / dt / G0
    rates.to_csv(d / "rates_g.csv", index=False)
    inc_g = inc.copy()
    for a in "xyz":
        inc_g[f"dvel_{a}"] = inc[f"dvel_{a}"] / G0
    inc_g.to_csv(d / "inc_gs.csv", index=False)
    ms2 = rates.copy()
    for a in "xyz":
        ms2[f"accel_{a}"] = rates[f"accel_{a}"] * G0
    ms2.to_csv(d / "rates_ms2.csv", index=False)
    (d / "g.yaml").write_text("imu:\n  units:\n    accel: g\n")
    init = yaml.safe_load(INIT.read_text())
    init["time"] = 0.01                                  # a rate file's first sample starts its first interval
    (d / "init_rates.yaml").write_text(yaml.safe_dump(init))
    return d


def test_g_read_as_m_s2_is_refused_naming_the_key(logs, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for cmd in (["navigate", logs / "rates_g.csv", "--init", logs / "init_rates.yaml", "-o", out / "n.csv"],
                ["navigate", logs / "rates_g.csv", "--gnss", SAMPLE / "gnss.csv", "--init", logs / "init_rates.yaml",
                 "-o", out / "f.csv"],
                ["navigate", logs / "rates_g.csv", "--gnss", SAMPLE / "gnss.csv", "--align", "gnss-inertial",
                 "-o", out / "a.csv"],
                ["align", logs / "rates_g.csv", "--method", "static", "--position", "30,114,50", "--duration", "50",
                 "-o", out / "a.yaml"]):
        line = refused(cmd, "rates_g.csv: accelerometer units: the median specific force over",
                       "read as m/s^2, far from gravity", "the data are in g; set imu.units.accel: g",
                       "(--force takes them as m/s^2)")
        med = float(line.split(" one-second blocks from t = ")[1].split(" is ")[1].split()[0])
        assert med == pytest.approx(9.79 / G0, rel=0.02), line   # the sample's |f| ~ g, in g
    assert list(out.iterdir()) == []
    # the unit set: the sample's own trajectory; --force: the data as declared (a wrong but finished run)
    rc, lines = sins(["navigate", logs / "rates_g.csv", "--init", logs / "init_rates.yaml", "--config", logs / "g.yaml",
                      "-o", tmp_path / "ok.csv", "-q"])
    assert rc == 0, lines
    rc, lines = sins(["navigate", logs / "rates_ms2.csv", "--init", logs / "init_rates.yaml", "-o", tmp_path / "ref.csv",
                      "-q"])
    a, b = pd.read_csv(tmp_path / "ok.csv"), pd.read_csv(tmp_path / "ref.csv")
    assert np.abs(a.height - b.height).max() < 1e-6 and np.abs(a.roll - b.roll).max() < 1e-9
    rc, lines = sins(["navigate", logs / "rates_g.csv", "--init", logs / "init_rates.yaml", "--force", "-o",
                      tmp_path / "forced.csv", "-q"])
    assert rc == 0 and (tmp_path / "forced.csv").is_file(), lines


def test_m_s2_read_as_g_and_increments_in_g_s(logs, tmp_path):
    refused(["navigate", logs / "rates_ms2.csv", "--init", logs / "init_rates.yaml", "--config", logs / "g.yaml",
             "-o", tmp_path / "n.csv"], "read as g, far from gravity", "the data are in m/s^2; set imu.units.accel: m/s^2")
    refused(["navigate", logs / "inc_gs.csv", "--init", INIT, "-o", tmp_path / "n.csv"],
            "inc_gs.csv: accelerometer units:", "m/s^2 (as dvel / dt) read as m/s", "the data are in g*s",
            "convert the dvel columns to m/s (imu.units.dvel takes m/s only)")
    assert list(tmp_path.iterdir()) == []


def _refusal(imu, conv_units="m/s^2"):
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0])
    kind = "rates" if imu.kind == "rates" else "increments"
    return accel_unit_refusal(imu.time, imu.dtheta_b, imu.dvel_b, t0, conv_units if kind == "rates" else "m/s",
                              str(imu.source), kind)


@pytest.mark.parametrize("scenario", sorted(Path(p).name for p in glob.glob(str(ROOT / "configs/scenarios/*.yaml"))))
def test_no_false_refusal_on_the_shipped_scenarios(scenario):
    """Every shipped scenario, its first 30 s with its sensor errors: cars with engine vibration, a walker,
    an aircraft rolling, pulling up and turning, the spinning boost (3 g), rest."""
    from sinscli.sim.run import simulate
    r = simulate(str(ROOT / "configs/scenarios" / scenario), duration=30.0)
    assert _refusal(r.imu) is None


def test_no_false_refusal_on_a_sustained_turn_and_heavy_vibration():
    """The worst real cases: an aircraft in a coordinated turn for the whole log (12 deg/s at 100 m/s: a 65 deg
    bank, |f| 2.2 g median), and a mount shaking at 3 g rms (the 1-s means see neither as a unit mistake)."""
    from sinscli.sim.run import simulate
    sc = {"name": "turn", "start": {"lat": 45, "lon": 7, "height": 3000, "heading": 0, "speed": 100},
          "imu": {"rate": 100, "sensor": "mems"}, "gnss": {"rate": 1},
          "segments": [{"type": "turn", "angle": 720, "duration": 60, "bank": "coordinated"}]}
    r = simulate(sc)
    dt = np.diff(np.concatenate([[r.imu.t0], r.imu.time]))
    assert np.median(np.linalg.norm(r.imu.dvel_b / dt[:, None], axis=1)) > 2.0 * G0     # 2.2 g
    assert _refusal(r.imu) is None
    shake = {"name": "shake", "start": {"lat": 45, "lon": 7, "height": 0, "heading": 0},
             "imu": {"rate": 200, "sensor": "consumer"}, "gnss": {"rate": 1},
             "vibration": {"gyro_rms": 5.0, "accel_rms": 30.0, "band": [20, 60], "lines": 4, "seed": 3},
             "segments": [{"type": "rest", "duration": 30}]}
    r = simulate(shake)
    assert _refusal(r.imu) is None
    dt = np.diff(np.concatenate([[r.imu.t0], r.imu.time]))
    assert np.sqrt(np.mean(np.sum((r.imu.dvel_b / dt[:, None]) ** 2, axis=1) - G0 ** 2)) > 25.0


@pytest.mark.skipif(not BAG.exists(), reason="the Husky bag is not present")
def test_no_false_refusal_on_the_husky_bag():
    from sinscli.io.readers import read_imu
    cfg = load_config(ROOT / "configs/fusion/husky.yaml")
    imu = read_imu(BAG, cfg)
    assert _refusal(imu) is None
