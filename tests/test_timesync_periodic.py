"""The GNSS-IMU time-offset finder on periodic motion (sinscli/nav/timesync.py).  A weave repeats every
second: the correlation peaks as high at every multiple of it, and the finder used to refuse the run
proposing one of them (a drone rolling with a 2 s period: +1.35 s proposed, +0.7 s true).  Now a peak is
named only when it beats every other by three standard errors; otherwise the candidates are listed in a
warning and the run goes on.  The unique cases (the sample drive 18 s late) are found as before."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from test_contract import sins

from sinscli.io.gnss_csv import write_gnss_csv
from sinscli.io.imu_csv import write_imu_csv
from sinscli.io.init_state import write_init_yaml
from sinscli.nav.timesync import estimate_offset, offset_refusal, offset_warning
from sinscli.sim.run import simulate

# a slalom at 10 m/s: +-15 deg heading turns of 1 s each, no bank (a car's lateral force), 5 Hz GNSS
WEAVE = [{"type": "turn", "angle": a, "duration": 1.0, "bank": "none"} for _ in range(30) for a in (15, -15)]
BASE = {"name": "weave", "start": {"lat": 45, "lon": 7, "height": 100, "heading": 0, "speed": 10},
        "imu": {"rate": 50, "sensor": "mems"}, "gnss": {"rate": 5, "vel_noise": 0.05, "pos_noise": 0.5}}


@pytest.fixture(scope="module")
def weave():
    return simulate(dict(BASE, segments=WEAVE), seed=1)


def _estimate(r, late):
    """The estimate with the GNSS stamped ``late`` s late: the true shift to add is ``-late``."""
    g = r.gnss
    return estimate_offset(r.imu.time, r.imu.dtheta_b, r.imu.dvel_b, r.imu.t0, g.time + late, g.lat, g.lon,
                           g.height, g.vel_n)


@pytest.mark.parametrize("late", [0.7, -0.7, 3.3, 12.4])
def test_periodic_motion_never_proposes_a_wrong_shift(weave, late):
    """Every shift k s - late agrees (correlation 0.99): ambiguous, the true one among the candidates, no
    refusal; the warning names gnss.time_offset and the candidates nearest zero."""
    est = _estimate(weave, late)
    assert est.peak > 0.95
    assert est.ambiguous and len(est.candidates) > 20
    assert min(abs(c + late) for c in est.candidates) < 0.1, est.candidates[:6]
    # the candidates repeat with the motion's period (1 s)
    c = np.sort(np.array(est.candidates))
    assert np.median(np.diff(c)) == pytest.approx(1.0, abs=0.05)
    assert offset_refusal(est, "gnss.csv") is None
    text = offset_warning(est, "gnss.csv")
    assert "cannot be told: the motion repeats" in text and "set gnss.time_offset" in text
    if abs(late) < 3.0:
        assert f"{-late:+.2f}" in text, text


def test_a_unique_event_after_the_weave_is_found(weave):
    """Ten seconds of weave, then 100 s of turns and speed changes: one lag explains those; the finder names
    it (every other peak falls short by more than the margin)."""
    drive = [{"type": "turn", "angle": 90, "duration": 6, "bank": "none"},
             {"type": "accelerate", "speed": 18, "duration": 5}, {"type": "cruise", "duration": 8},
             {"type": "turn", "angle": -45, "duration": 5, "bank": "none"},
             {"type": "decelerate", "speed": 8, "duration": 6}, {"type": "cruise", "duration": 10},
             {"type": "turn", "angle": -120, "duration": 9, "bank": "none"}, {"type": "cruise", "duration": 6},
             {"type": "accelerate", "speed": 15, "duration": 4}, {"type": "turn", "angle": 30, "duration": 3,
                                                                   "bank": "none"},
             {"type": "cruise", "duration": 12}, {"type": "decelerate", "speed": 6, "duration": 5},
             {"type": "turn", "angle": 70, "duration": 7, "bank": "none"}, {"type": "cruise", "duration": 10}]
    r = simulate(dict(BASE, segments=WEAVE[:10] + drive), seed=2)
    est = _estimate(r, 7.3)
    assert not est.ambiguous and est.shift == pytest.approx(-7.3, abs=0.1), (est.shift, est.candidates[:5])
    assert "set gnss.time_offset: -7.2" in offset_refusal(est, "gnss.csv") or "set gnss.time_offset: -7.3" in \
        offset_refusal(est, "gnss.csv")


def test_the_fused_run_warns_and_goes_on(weave, tmp_path, caplog):
    """Through `sins navigate --gnss`: exit 0, one warning naming gnss.time_offset and the true shift."""
    r = weave
    write_imu_csv(tmp_path / "imu.csv", r.imu)
    g = r.gnss
    g.time = g.time + 0.7
    write_gnss_csv(tmp_path / "gnss.csv", g)
    write_init_yaml(tmp_path / "init.yaml", r.init, 0, {})
    rc, lines = sins(["navigate", tmp_path / "imu.csv", "--gnss", tmp_path / "gnss.csv", "--init",
                      tmp_path / "init.yaml", "-o", tmp_path / "f.csv", "-q"])
    assert rc == 0, lines
    warn = [r.getMessage() for r in caplog.records if "cannot be told" in r.getMessage()]
    assert len(warn) == 1 and "-0.70" in warn[0] and "gnss.time_offset" in warn[0], warn
    assert len(pd.read_csv(tmp_path / "f.csv")) > 100
