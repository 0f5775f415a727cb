"""The mounting check of every ``sins navigate`` (issue 10, sinscli/nav/sanity.py): gravity in the first
rest-like second against the initial attitude, or the body's up axis with ``--align``."""
from __future__ import annotations

import copy
import glob
import math
import re
from pathlib import Path

import numpy as np
import pytest
from realdata import HUSKY_BAG

from sinscli.config import ImuSection, mounting_matrix
from sinscli.io.imu_csv import apply_mounting
from sinscli.io.readers import read_imu
from sinscli.nav.earth import gravity
from sinscli.nav.rotation import euler_to_dcm
from sinscli.nav.sanity import check_mounting
from sinscli.config import load_config, override
from test_contract import sins

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
BAG = HUSKY_BAG
G = gravity(math.sin(math.radians(30.0)), 50.0)
LEVEL = euler_to_dcm(0.0, 0.0, math.radians(30.0), 0)        # the sample's initial attitude (FLU)


@pytest.fixture(scope="module")
def sample():
    return read_imu(SAMPLE / "imu.csv", load_config())


def _mounted(imu, m):
    """A copy of ``imu`` in the axes ``m`` (apply_mounting rotates in place)."""
    return apply_mounting(copy.deepcopy(imu), m)


def _check(imu, cbn0=LEVEL, conv=0, mounting=None):
    return check_mounting(imu.time, imu.dtheta_b, imu.dvel_b, imu.t0 if imu.t0 is not None else 0.0, G, conv,
                          cbn0, mounting)


def test_no_warning_on_the_sample_and_every_scenario(sample, tmp_path, caplog):
    assert _check(sample) is None and _check(sample, None) is None
    from sinscli.sim.run import simulate
    for sc in sorted(glob.glob(str(ROOT / "configs" / "scenarios" / "*.yaml"))):
        r = simulate(sc, duration=60.0)                      # with the scenario's sensor errors
        g = gravity(math.sin(r.init.lat), r.init.height)
        for cbn0 in (r.init.Cbn, None):                      # --init and --align
            assert check_mounting(r.imu.time, r.imu.dtheta_b, r.imu.dvel_b, r.imu.t0, g, r.conv, cbn0) is None, sc
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--init", SAMPLE / "init.yaml", "-q", "-o",
                      tmp_path / "nav.csv"])
    assert rc == 0 and not [r for r in caplog.records if "mounting" in r.getMessage()], lines


@pytest.mark.parametrize("wrong", [{"roll": 90}, {"roll": -90}, {"pitch": 90}, {"pitch": -90},
                                   {"roll": 90, "yaw": 30}, {"pitch": 90, "roll": 180}, {"roll": 135}])
def test_wrong_mounting_named_with_a_fix_that_works(sample, wrong):
    m0 = mounting_matrix(wrong)
    msg = _check(_mounted(sample, m0), mounting=m0)
    assert msg is not None and "imu.mounting: {roll: " in msg, msg
    fix = dict(zip(("roll", "pitch", "yaw"), map(float, re.search(
        r"imu\.mounting: \{roll: (\S+), pitch: (\S+), yaw: (\S+)\}", msg).groups())))
    m1 = mounting_matrix(fix)
    fixed = _mounted(sample, m1)                       # the raw (correct FLU) data, read with the fix
    assert _check(fixed) is None
    f = fixed.dvel_b[:100].sum(axis=0) / 1.0
    assert math.degrees(math.acos(f[2] / np.linalg.norm(f))) < 2.0    # gravity back on +z
    turn = round(math.degrees(math.acos((np.trace(m0) - 1) / 2)))
    if turn in (90, 135):                                   # about one axis: the fix is no mounting at all
        assert f"a {turn} deg mounting error" in msg and np.abs(m1 - np.eye(3)).max() < (1e-3 if turn == 90 else 0.035), msg


def test_frd_data_read_as_flu_and_back(sample):
    frd = _mounted(sample, mounting_matrix({"roll": 180}))    # FLU -> FRD axes
    msg = _check(frd)                                                 # read as FLU, level init
    assert "the data look FRD: set imu.body: frd" in msg, msg
    msg = _check(sample, euler_to_dcm(0.0, 0.0, math.radians(30.0), 2), conv=2)   # FLU data read as FRD
    assert "the data look FLU: set imu.body: flu" in msg, msg
    assert _check(frd, euler_to_dcm(0.0, 0.0, math.radians(30.0), 2), conv=2) is None
    assert _check(frd, None, conv=2) is None and "imu.body: flu" in _check(sample, None, conv=2)


def test_first_rest_stretch_after_a_turn():
    """A start that rolls 90 deg in 3 s, then rests: the check uses the rest second and carries the initial
    attitude there with the gyro (no warning); with the init's roll wrong by 90 deg it warns, naming it."""
    dt, n_turn, n_rest = 0.01, 300, 200
    rate = math.radians(30.0)
    time = dt * np.arange(1, n_turn + n_rest + 1)
    dtheta = np.zeros((time.size, 3))
    dtheta[:n_turn, 0] = rate * dt
    ang = np.concatenate([rate * time[:n_turn] - rate * dt / 2, np.full(n_rest, math.pi / 2)])
    dvel = np.column_stack([np.zeros_like(ang), np.sin(ang), np.cos(ang)]) * G * dt
    assert check_mounting(time, dtheta, dvel, 0.0, G, 0, np.eye(3)) is None
    msg = check_mounting(time, dtheta, dvel, 0.0, G, 0, euler_to_dcm(math.pi / 2, 0.0, 0.0, 0))
    assert "over the first second at rest (3 to 4 s after the start)" in msg and "init's roll and pitch" in msg


@pytest.mark.skipif(not BAG.exists(), reason=f"real data not present: {BAG}")
def test_husky_without_its_mounting_warns_and_names_the_fix(tmp_path, caplog):
    """The Husky bag navigated without configs/align/husky.yaml (its mounting) ran silently to
    hundreds of km off: now the run warns and names imu.mounting with the fix."""
    init = tmp_path / "init.yaml"
    init.write_text("time: 1432235497.988949\nlat: 42.0\nlon: -71.0\nheight: 30\nvel_e: 0\nvel_n: 0\nvel_u: 0\n"
                    "roll: 0\npitch: 0\nheading: 0\n")
    rc, lines = sins(["navigate", BAG, "--init", init, "-q", "-o", tmp_path / "h.csv"])
    warn = [r.getMessage() for r in caplog.records if "mounting check" in r.getMessage()]
    assert rc == 0 and len(warn) == 1, lines
    assert "along +y" in warn[0] and "imu.mounting: {roll: 90, pitch: 0, yaw: 0}" in warn[0], warn
    caplog.clear()
    rc, lines = sins(["navigate", BAG, "--init", init, "--config", ROOT / "configs" / "align" / "husky.yaml",
                      "-q", "-o", tmp_path / "h2.csv"])
    assert rc == 0 and not [r for r in caplog.records if "mounting" in r.getMessage()], lines
    cfg = override(load_config(), "ros", imu_topic="/imu/data")
    imu = read_imu(BAG, cfg)                               # --align: the up axis
    msg = check_mounting(imu.time, imu.dtheta_b, imu.dvel_b, imu.t0 if imu.t0 is not None else imu.time[0],
                         9.80, 0, None)
    assert "from the body's up axis" in msg and "imu.mounting: {roll: 90" in msg


def test_init_later_in_the_log_is_checked_there(tmp_path, caplog):
    """An init from the truth at 100 s (the vehicle driving, turned from its start heading): the check
    uses the samples after the init, with the attitude of the init: no false warning; with the init's
    attitude rolled by 90 deg the warning names it."""
    rc, lines = sins(["navigate", SAMPLE / "imu.csv", "--init", SAMPLE / "truth.csv", "--start", "100", "-q",
                      "-o", tmp_path / "n.csv"])
    assert rc == 0 and not [r for r in caplog.records if "mounting" in r.getMessage()], lines
    from sinscli.io.readers import read_imu as _read
    from sinscli.io.trajectory import read_trajectory
    truth = read_trajectory(SAMPLE / "truth.csv")
    k = int(np.flatnonzero(truth.time == 100.0)[0])
    imu = _read(SAMPLE / "imu.csv", load_config())
    from sinscli.nav.sanity import mounting_warning
    assert mounting_warning(imu, 100.0, G, 0, truth.Cbn[k], ImuSection()) is None
    rolled = truth.Cbn[k] @ euler_to_dcm(math.pi / 2, 0.0, 0.0, 0)
    assert "init's roll and pitch" in mounting_warning(imu, 100.0, G, 0, rolled, ImuSection())


def test_no_warning_fused_on_the_sample(tmp_path, caplog):
    (tmp_path / "imu.csv").write_text("\n".join((SAMPLE / "imu.csv").read_text().splitlines()[:3102]) + "\n")
    (tmp_path / "gnss.csv").write_text("\n".join((SAMPLE / "gnss.csv").read_text().splitlines()[:31]) + "\n")
    rc, lines = sins(["navigate", "imu.csv", "--gnss", "gnss.csv", "--init", SAMPLE / "init.yaml", "-q", "-o",
                      "f.csv"], cwd=tmp_path)
    assert rc == 0, lines
    # --align: the check runs before the alignment (which refuses this MEMS log's earth-rate heading)
    rc, lines = sins(["navigate", "imu.csv", "--gnss", "gnss.csv", "--align", "static", "-q", "-o", "f.csv"],
                     cwd=tmp_path)
    assert not [r for r in caplog.records if "mounting" in r.getMessage()]
    frd = tmp_path / "frd.yaml"                    # the same log said to be FRD without turning it: named
    frd.write_text("imu:\n  body: frd\n")
    rc, lines = sins(["navigate", "imu.csv", "--gnss", "gnss.csv", "--align", "static", "--config", frd, "-q",
                      "-o", "f.csv"], cwd=tmp_path)
    assert [r for r in caplog.records if "the data look FLU: set imu.body: flu" in r.getMessage()], lines
