"""The batch runner's bookkeeping with a stand-in navigator of known errors (in-process, ``--jobs 1``).

The stand-in returns the dataset's truth displaced by ``coning`` x 0.1 m east
and rotated by ``coning`` x 1e-6 rad about up, so every report value is known;
one dataset has a broken IMU file and must be reported as failed while the
other's report is written.  (The end-to-end test with the real navigator and
simulator and worker processes is in test_report_batch_e2e.py.)
"""
import csv
import dataclasses
from pathlib import Path

import numpy as np
import yaml
from click.testing import CliRunner

from sinscli.batch import compare_job
from sinscli.cli import main
from sinscli.io.imu_csv import write_imu_csv
from sinscli.io.init_state import write_init_yaml
from sinscli.io.trajectory import read_trajectory, write_trajectory
from sinscli.types import ImuLog, NavState

from test_report_errors import displaced, make_truth


@dataclasses.dataclass
class FakeOptions:
    attitude: str = "quat"
    coning: int = 2
    subsamples: int = 1
    every: int = 1
    conv: int = 0
    frame: str = "enu"
    dcm_variant: str = "exact"


def fake_navigate(imu, init, opts, progress=None):
    truth = read_trajectory(Path(imu.source).with_name("truth.csv"))
    return displaced(truth, [0.1 * opts.coning, 0.0, 0.0], [0, 0, 0], phi_n=[0.0, 0.0, 1e-6 * opts.coning])


def make_dataset(d: Path, broken=False):
    d.mkdir()
    truth = make_truth(n=60, t0=0.0)
    write_trajectory(d / "truth.csv", truth)
    imu = ImuLog(time=truth.time[1:], dtheta_b=np.zeros((59, 3)), dvel_b=np.zeros((59, 3)), t0=0.0)
    write_imu_csv(d / "imu.csv", imu)
    if broken:
        text = (d / "imu.csv").read_text().splitlines()
        head = text[0].split(",")
        keep = [k for k, c in enumerate(head) if c != "dvel_z"]
        (d / "imu.csv").write_text("\n".join(",".join(r.split(",")[k] for k in keep) for r in text) + "\n")
    write_init_yaml(d / "init.yaml", NavState(0.0, truth.lat[0], truth.lon[0], truth.height[0], truth.vel_n[0],
                                              truth.Cbn[0]))


def test_runner_reports_known_errors_and_a_failed_job(tmp_path, monkeypatch):
    # the stand-in navigator where the batch worker looks it up (--jobs 1 runs the jobs in this process)
    monkeypatch.setattr(compare_job, "NavOptions", FakeOptions)
    monkeypatch.setattr(compare_job, "navigate", fake_navigate)
    make_dataset(tmp_path / "good")
    make_dataset(tmp_path / "bad", broken=True)
    batch = {"title": "stand-in", "timeseries_every": 7,
             "datasets": [{"name": n, "imu": f"{n}/imu.csv", "truth": f"{n}/truth.csv", "init": f"{n}/init.yaml"}
                          for n in ("good", "bad")],
             "methods": [{"name": "one", "coning": 1}, {"name": "two", "coning": 2}]}
    (tmp_path / "b.yaml").write_text(yaml.safe_dump(batch))
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["compare", str(tmp_path / "b.yaml"), "-o", str(out), "--jobs", "1", "-q"])
    assert r.exit_code == 1, r.output
    assert "job bad/one failed: data preparation failed:" in r.output and "dvel_z" in r.output
    with open(out / "good" / "errors.csv", newline="") as fh:
        rows = {row[0]: row[2:] for row in csv.reader(fh)}
    assert rows["quantity"] == ["one", "two"]
    np.testing.assert_allclose([float(x) for x in rows["pos_E"]], [0.1, 0.2], atol=1e-9)
    np.testing.assert_allclose([float(x) for x in rows["max_att_deg"]], np.degrees([1e-6, 2e-6]), rtol=1e-8)
    ts = (out / "good" / "timeseries.csv").read_text().splitlines()
    assert len(ts) == 1 + 10                 # header; epochs 0, 7, ..., 56 (9) and the last one, 59
    assert not (out / "bad").exists() or not (out / "bad" / "errors.csv").exists()
    with open(out / "summary.csv", newline="") as fh:
        summary = list(csv.DictReader(fh))
    status = {(s["dataset"], s["method"]): s for s in summary}
    assert status[("good", "two")]["status"] == "ok"
    np.testing.assert_allclose(float(status[("good", "two")]["max_pos_E"]), 0.2, atol=1e-9)
    assert status[("bad", "one")]["status"] == "failed" and "dvel_z" in status[("bad", "one")]["error"]
    html = (out / "index.html").read_text()
    assert 'href="good/index.html"' in html and "failed" in html
    assert "## good" in (out / "summary.md").read_text()
