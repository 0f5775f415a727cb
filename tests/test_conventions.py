"""Body conventions across files (issue 10): a trajectory carries its body axes (CSV ``body`` column, Parquet
metadata ``sins.body``) and, without a marker, its physical Euler angles and attitude columns tell them; compare
and ``--init`` use each file's own axes, so an FLU truth and an FRD run of the same motion agree."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from sinscli.io.init_state import read_init
from sinscli.io.trajectory import read_trajectory, write_trajectory
from sinscli.nav.rotation import FLU, FRD, RFU, cbn_from_flu
from sinscli.types import Trajectory
from test_contract import refused, sins

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    d = tmp_path_factory.mktemp("conv")
    lines = (SAMPLE / "imu.csv").read_text().splitlines()[:6002]          # 60 s
    (d / "imu.csv").write_text("\n".join(lines) + "\n")
    (d / "truth.csv").write_bytes((SAMPLE / "truth.csv").read_bytes())
    # the same IMU read as FRD axes: the sensor's FLU axes turned by a half turn about x
    (d / "frd.yaml").write_text("imu:\n  body: frd\n  mounting: {roll: 180}\n")
    for name, extra in (("flu.csv", []), ("frd.csv", ["--config", "frd.yaml"]),
                        ("frd.parquet", ["--config", "frd.yaml"])):
        rc, lines = sins(["navigate", "imu.csv", "--init", SAMPLE / "init.yaml", "-q", "-o", name, *extra], cwd=d)
        assert rc == 0, lines
    return d


def _errors(path):
    return {r[0]: float(r[2]) for r in csv.reader(path.open()) if r[0] != "quantity"}


def _strip_body(src: Path, dst: Path):
    rows = list(csv.reader(src.open()))
    k = rows[0].index("body")
    with dst.open("w", newline="") as fh:
        csv.writer(fh).writerows([r[:k] + r[k + 1:] for r in rows])


def test_markers_written_and_read(d):
    import pyarrow.parquet as pq
    rows = list(csv.reader((d / "frd.csv").open()))
    assert rows[0][-1] == "body" and {r[-1] for r in rows[1:]} == {"frd"}          # the csv module reads it
    assert "body" not in (d / "flu.csv").read_text().splitlines()[0].split(",")    # FLU: docs/formats.md as it was
    assert pq.read_schema(d / "frd.parquet").metadata[b"sins.body"] == b"frd"
    for name, body, how in (("frd.csv", FRD, "marker"), ("frd.parquet", FRD, "marker"), ("flu.csv", FLU, "angles")):
        t = read_trajectory(d / name)
        assert (t.body, t.body_from) == (body, how), name
    f, r = read_trajectory(d / "flu.csv"), read_trajectory(d / "frd.csv")
    np.testing.assert_allclose(cbn_from_flu(f.Cbn, FRD), r.Cbn, atol=1e-9)          # the same physical attitude


def test_compare_frd_run_against_flu_truth(d):
    """Before: a 180 deg attitude error. Now the FRD run's table equals the FLU run's (metadata path), and so
    it does without the marker (convention-free path: the angles and the attitude columns)."""
    _strip_body(d / "frd.csv", d / "frd_plain.csv")
    assert read_trajectory(d / "frd_plain.csv").body_from == "angles"
    ref = None
    for name in ("flu.csv", "frd.csv", "frd.parquet", "frd_plain.csv"):
        rc, lines = sins(["compare", "--truth", "truth.csv", name, "-o", f"rep_{name}", "-q"], cwd=d)
        assert rc == 0, lines
        e = _errors(d / f"rep_{name}" / "errors.csv")
        assert e["max_att_deg"] < 20.0, (name, e["max_att_deg"])
        if ref is None:
            ref = e
        for k, v in ref.items():
            assert v == pytest.approx(e[k], rel=1e-6, abs=1e-8), (name, k)
    # an FRD truth (written with its marker) against the FLU run: the same again
    truth = read_trajectory(d / "truth.csv")
    write_trajectory(d / "truth_frd.parquet", Trajectory(truth.time, truth.lat, truth.lon, truth.height,
                                                         truth.vel_n, cbn_from_flu(truth.Cbn, FRD)), FRD)
    rc, lines = sins(["compare", "--truth", "truth_frd.parquet", "flu.csv", "-o", "rep_tf", "-q"], cwd=d)
    assert rc == 0, lines
    e = _errors(d / "rep_tf" / "errors.csv")
    assert all(e[k] == pytest.approx(v, rel=1e-6, abs=1e-8) for k, v in ref.items())
    assert "frd.csv FRD (its marker)" in (d / "rep_frd.csv" / "index.html").read_text()


def test_init_from_a_trajectory_of_other_axes(d):
    """--init with an FRD trajectory for an FLU run: its attitude is turned into the run's axes."""
    truth = read_trajectory(d / "truth.csv")
    write_trajectory(d / "truth_rfu.csv", Trajectory(truth.time, truth.lat, truth.lon, truth.height, truth.vel_n,
                                                     cbn_from_flu(truth.Cbn, RFU)), RFU)
    a = read_init(d / "truth.csv", 30.0, FLU)
    b = read_init(d / "truth_rfu.csv", 30.0, FLU)
    np.testing.assert_allclose(a.Cbn, b.Cbn, atol=1e-12)
    outs = []
    for init in ("truth.csv", "truth_rfu.csv"):
        rc, lines = sins(["navigate", "imu.csv", "--init", init, "--start", "30", "-q", "-o", f"n_{init}"], cwd=d)
        assert rc == 0, lines
        outs.append(read_trajectory(d / f"n_{init}"))
    np.testing.assert_allclose(outs[0].Cbn, outs[1].Cbn, atol=1e-9)


@pytest.mark.parametrize("edit, fragment", [
    (lambda k, v: "xyz", "line 2, column 'body': 'xyz': expected one of flu, rfu, frd"),
    (lambda k, v: "flu" if k == 5 else v, "line 6, column 'body': 'flu': expected 'frd' as on line 2"),
])
def test_bad_body_column_refused(d, edit, fragment):
    rows = list(csv.reader((d / "frd.csv").open()))
    with (d / "bad.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        for k, r in enumerate(rows[1:], start=1):
            w.writerow(r[:-1] + [edit(k, r[-1])])
    refused(["compare", "--truth", "truth.csv", "bad.csv", "-o", "rep_bad"], "bad.csv", fragment, cwd=d)
    assert not (d / "rep_bad").exists()
