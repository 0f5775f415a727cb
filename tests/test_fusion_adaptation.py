"""Every adaptive mechanism of the fused filter (docs/fusion.md, "Adaptation you can reason about") does nothing
on a log whose model is right, bit for bit, and acts where the log shows its part of the model wrong.

The log whose model is right: the shipped sample drive (the `mems` preset the simulation used, white GNSS noise
at the stated sigma, the documented lever arm) with two 20 s outages cut into its fixes.  Each mechanism switched
off gives the identical output file.  Then, one case each, a log that contradicts the mechanism's part of the
model, run with the mechanism on and off (the calibration passes off in both where they would hide the online
mechanism): the mechanism reports itself in the summary and the errors against the simulation's truth fall
inside the claimed 3 sigma more often (or the outage errors are smaller) than without it.
"""
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

from sinscli.evaluate.fusion import errors_at, outage_mask
from sinscli.io.trajectory import read_trajectory
from sinscli.sensors import preset_text
from sinscli.sim.run import simulate, write_sim

ROOT = Path(__file__).resolve().parents[1]
SINS = shutil.which("sins", path=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", "")) or "sins"
SAMPLE = ROOT / "sample_data"
OUTAGES = [(60.0, 80.0), (120.0, 140.0)]          # s since the start, cut into the sample drive's fixes
LEVER = [0.8, 0.0, 1.5]


def _sins(args, cwd):
    return subprocess.run([SINS, *args], cwd=cwd, capture_output=True, text=True)


def _cut(src: Path, dst: Path, outages, t0: float, std=None) -> None:
    """Copy a GNSS CSV without the fixes inside ``outages`` (s since ``t0``); ``std``: the values its std_e/n/u
    columns then state."""
    lines = src.read_text().splitlines()
    head = lines[0].split(",")
    cols = [head.index(c) for c in ("std_e", "std_n", "std_u")]
    out = [lines[0]]
    for ln in lines[1:]:
        f = ln.split(",")
        if any(a <= float(f[0]) - t0 < b for a, b in outages):
            continue
        if std is not None:
            for c, v in zip(cols, std):
                f[c] = repr(float(v))
        out.append(",".join(f))
    dst.write_text("\n".join(out) + "\n")


def _fuse(d: Path, name: str, fusion: dict, gnss="gnss.csv", *extra):
    cfg = {"gnss": {"lever_arm": LEVER}, "fusion": fusion}
    (d / f"{name}.yaml").write_text(yaml.safe_dump(cfg))
    r = _sins(["navigate", "imu.csv", "--gnss", gnss, "--init", "init.yaml", "--config", f"{name}.yaml",
               "--vehicle", "car", "-o", f"{name}.csv", *extra], d)
    assert r.returncode == 0, r.stderr
    return r.stderr


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    d = tmp_path_factory.mktemp("sample")
    for f in ("imu.csv", "init.yaml", "truth.csv"):
        shutil.copy(SAMPLE / f, d / f)
    t0 = yaml.safe_load((SAMPLE / "init.yaml").read_text())["time"]
    _cut(SAMPLE / "gnss.csv", d / "gnss.csv", OUTAGES, t0)
    _fuse(d, "on", {"sensor": "mems"})
    return d


OFF = {"measurement_noise": {"adapt": {"measurement_noise": False}},
       "outage_exits": {"adapt": {"outage_exits": False}},
       "widen": {"adapt": {"widen": False}},
       "passes": {"adapt": {"passes": False}},
       "robust_weights": {"robust_probability": None},
       "gnss_error_states": {"gnss_error": {"tau": 0}},
       "noise_from_data": {"noise_from_data": False}}


@pytest.mark.parametrize("mechanism", sorted(OFF))
def test_each_mechanism_does_nothing_where_the_model_is_right(sample, mechanism):
    """The sample drive with two outages, the mems preset it was simulated with: the output with the mechanism
    switched off is the same file, byte for byte."""
    _fuse(sample, f"off_{mechanism}", {"sensor": "mems", **OFF[mechanism]})
    assert (sample / f"off_{mechanism}.csv").read_bytes() == (sample / "on.csv").read_bytes(), mechanism


def _coverage(traj, truth, sel=None):
    """Fractions of the rows (``sel``: a mask of them) whose E, N, U position errors lie inside 3 sigma."""
    m, dr, dv, phi = errors_at(traj, truth)
    x = {k: v[m] for k, v in traj.extra.items()}
    ok = np.column_stack([np.abs(dr[:, i]) <= 3.0 * x[c] for i, c in enumerate(("pos_e_std", "pos_n_std",
                                                                                 "pos_u_std"))])
    if sel is not None:
        ok = ok[sel(traj.time[m] - truth.time[0])]
    return ok.mean(axis=0)


def test_measurement_noise_acts_on_fixes_noisier_than_stated(sample):
    """Fixes that state a third of their real noise (0.5 m against 1.5 m): the online measurement-noise scale
    rises and the position's 3 sigma covers the truth far more often than without it (calibration passes off in
    both: they would find the same from the first pass)."""
    d = sample
    t0 = yaml.safe_load((SAMPLE / "init.yaml").read_text())["time"]
    _cut(SAMPLE / "gnss.csv", d / "gnss_std.csv", OUTAGES, t0, std=(0.5, 0.5, 1.0))
    truth = read_trajectory(d / "truth.csv")
    err = _fuse(d, "mn_on", {"sensor": "mems", "adapt": {"passes": False}}, "gnss_std.csv")
    _fuse(d, "mn_off", {"sensor": "mems", "adapt": {"passes": False, "measurement_noise": False}}, "gnss_std.csv")
    assert re.search(r"gnss_pos [en] noise variance x", err), err
    on = _coverage(read_trajectory(d / "mn_on.csv"), truth)
    off = _coverage(read_trajectory(d / "mn_off.csv"), truth)
    assert on[:2].min() >= 0.9 and on[:2].min() > off[:2].min() + 0.1, (on, off)


def test_outage_exits_act_on_an_optimistic_description(sample):
    """A description ten times optimistic in every sigma (white noise, biases, instability): the first outage's
    exit raises the drift process noise, and the second outage's errors fall inside 3 sigma more often than
    without the mechanism (passes and noise from the data off in both)."""
    d = sample
    base = yaml.safe_load(preset_text("mems"))
    opt = {w: {k: (v / 10.0 if k != "bias_tau" else v) for k, v in base[w].items()} for w in ("gyro", "accel")}
    (d / "opt10.yaml").write_text(yaml.safe_dump(opt))
    truth = read_trajectory(d / "truth.csv")
    common = {"sensor": "opt10.yaml", "noise_from_data": False}
    err = _fuse(d, "ex_on", {**common, "adapt": {"passes": False}})
    _fuse(d, "ex_off", {**common, "adapt": {"passes": False, "outage_exits": False}})
    assert "outage exits whose innovation was" in err, err
    second = lambda t: (t >= OUTAGES[1][0]) & (t < OUTAGES[1][1])  # noqa: E731
    on = _coverage(read_trajectory(d / "ex_on.csv"), truth, second)
    off = _coverage(read_trajectory(d / "ex_off.csv"), truth, second)
    assert on[:2].mean() > off[:2].mean(), (on, off)


@pytest.fixture(scope="module")
def biased(tmp_path_factory):
    """A 4-min drive whose gyros have turn-on biases of about 1 deg/s (a phone's, 36x the mems preset's 0.1
    deg/s), 1 Hz GNSS at 1.5 m with two 20 s outages, fused with the mems description."""
    d = tmp_path_factory.mktemp("biased")
    sc = yaml.safe_load((ROOT / "configs/scenarios/vehicle_drive.yaml").read_text())
    sc["imu"]["sensor"] = {"gyro": {"bias_sigma": 3600, "bias_instability": 10, "bias_tau": 100, "arw": 0.3},
                           "accel": {"bias_sigma": 5000, "bias_instability": 50, "bias_tau": 100, "vrw": 100}}
    sc["gnss"]["outages"] = [[120, 140], [190, 210]]
    write_sim(simulate(sc, seed=3, duration=240.0), d)
    return d, [(120.0, 140.0), (190.0, 210.0)]


def _outage_rms(d, name, outages):
    truth = read_trajectory(d / "truth.csv")
    traj = read_trajectory(d / f"{name}.csv")
    m, dr, dv, phi = errors_at(traj, truth)
    t = traj.time[m] - truth.time[0]
    sel = outage_mask(t, outages)
    return float(np.sqrt(np.mean(dr[sel, 0] ** 2 + dr[sel, 1] ** 2)))


def test_widening_acts_on_a_gyro_bias_far_outside_its_description(biased):
    """The mems description on a gyro 36x more biased: fixes that agree with one another drift away from the
    prediction; the consistency test widens the covariance (said in the summary) and no fix is rejected,
    where without it the filter rejects runs of good fixes (calibration passes and the noise from the first
    minute at rest, which would give the bias prior away, off in both)."""
    d, outages = biased
    common = {"sensor": "mems", "noise_from_data": False}   # the rest would give the bias prior away
    on = _fuse(d, "w_on", {**common, "adapt": {"passes": False}})
    off = _fuse(d, "w_off", {**common, "adapt": {"passes": False, "widen": False}})
    assert "covariance widened" in on and "run(s) of consecutive rejected fixes" not in on, on
    assert "run(s) of consecutive rejected fixes" in off, off


def test_passes_act_on_a_gyro_bias_far_outside_its_description(biased):
    """The same log: the first pass's bias estimates lie far outside the prior; the next pass starts from the
    turn-on bias prior they imply (said in the summary) and the outages' horizontal errors are smaller."""
    d, outages = biased
    on = _fuse(d, "p_on", {"sensor": "mems", "noise_from_data": False})
    _fuse(d, "p_off", {"sensor": "mems", "noise_from_data": False, "adapt": {"passes": False}})
    assert "turn-on bias 1-sigma gyro" in on, on
    assert _outage_rms(d, "p_on", outages) < _outage_rms(d, "p_off", outages)


def test_gnss_error_states_act_on_fixes_with_a_correlated_error(tmp_path):
    """Fixes whose 1.5 m error is a Gauss-Markov process of 60 s (a receiver's multipath and atmosphere), not
    white, under a tactical IMU that holds its position over seconds: a first pass finds their innovations
    correlated and carries the error as states (said in the summary); the position's 3 sigma then covers the
    truth far more often than with the errors taken as white (``gnss_error.tau: 0``).  (Under a MEMS IMU that
    follows the fixes within a second the innovations show no correlation to find: docs/fusion.md.)"""
    sc = yaml.safe_load((ROOT / "configs/scenarios/vehicle_drive.yaml").read_text())
    sc["imu"]["sensor"] = "tactical"
    sc["gnss"]["pos_tau"] = 60.0
    sc["gnss"]["outages"] = []
    write_sim(simulate(sc, seed=5, duration=300.0), tmp_path)
    truth = read_trajectory(tmp_path / "truth.csv")
    on = _fuse(tmp_path, "ge_on", {"sensor": "tactical"})
    _fuse(tmp_path, "ge_off", {"sensor": "tactical", "gnss_error": {"tau": 0}})
    assert "time-correlated error estimated as states" in on, on
    c_on = _coverage(read_trajectory(tmp_path / "ge_on.csv"), truth)
    c_off = _coverage(read_trajectory(tmp_path / "ge_off.csv"), truth)
    assert c_on.min() >= 0.9 and c_on.min() > c_off.min(), (c_on, c_off)
