"""Trajectory metrics (``sins compare --metrics ate,rpe``): closed forms, the CLI, and evo's own numbers."""
import copy
import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io.trajectory import write_trajectory
from sinscli.io.tum import write_tum
from sinscli.nav.earth import enu_rotation, lla_to_ecef
from sinscli.nav.rotation import dcm_to_quat_many, rotvec_to_dcm
from sinscli.evaluate import metrics as M
from sinscli.evaluate.errors import compare_trajectories

from test_report_errors import displaced, make_truth

STATS = ("rmse", "mean", "median", "std", "min", "max")


def run(args):
    return CliRunner().invoke(main, ["compare", *map(str, args)])


def read_rows(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], {r[0]: [float(x) for x in r[2:]] for r in rows[1:]}


def figure_eight(n=2000, dt=0.05, t0=1000.0):
    """A 3-D figure eight with turning, rolling attitude: time, positions, rotations."""
    t = t0 + dt * np.arange(n)
    s = np.linspace(0.0, 1.0, n)
    pos = np.column_stack([300 * np.sin(2 * np.pi * s), 200 * np.sin(4 * np.pi * s), 10 * np.cos(2 * np.pi * s)])
    rv = np.column_stack([0.2 * np.sin(6 * s), 0.1 * np.cos(5 * s), 2 * np.pi * s])
    return t, pos, np.array([rotvec_to_dcm(v) for v in rv])


def perturbed(pos, rot, seed=3, scale=1.3):
    """Drifting positions and attitudes, then a similarity transform (as a monocular SLAM result looks)."""
    rng = np.random.default_rng(seed)
    n = pos.shape[0]
    err = np.cumsum(rng.standard_normal((n, 3)) * 0.05, axis=0)
    r_err = np.array([rotvec_to_dcm(v) for v in np.cumsum(rng.standard_normal((n, 3)) * 2e-3, axis=0)])
    r_a = rotvec_to_dcm(np.array([0.1, -0.2, 0.7]))
    return (scale * (pos + err) @ r_a.T + np.array([50.0, -20.0, 3.0]),
            np.einsum("ij,njk,nkl->nil", r_a, r_err, rot))


def write_tum_rows(path, t, pos, rot):
    """A plain TUM file (no origin line), as evo and SLAM systems write it."""
    q = dcm_to_quat_many(np.ascontiguousarray(rot))
    with open(path, "w") as f:
        for k in range(t.shape[0]):
            f.write(" ".join(repr(float(x)) for x in [t[k], *pos[k], q[k, 1], q[k, 2], q[k, 3], q[k, 0]]) + "\n")


# --------------------------------------------------------------------------- closed forms

def test_umeyama_recovers_a_similarity_exactly():
    t, pos, rot = figure_eight(400)
    r_a = rotvec_to_dcm(np.array([0.3, -0.1, 1.2]))
    est = M.Poses(t, (pos - [5.0, 1.0, 2.0]) @ r_a.T / 2.5, np.einsum("ij,njk->nik", r_a, rot))
    ref = M.Poses(t, pos, rot)
    al, a = M.align_poses(est, ref, "sim3")
    assert a.scale == pytest.approx(2.5, rel=1e-12)
    np.testing.assert_allclose(a.R, r_a.T, atol=1e-12)
    np.testing.assert_allclose(al.pos, pos, atol=1e-9)
    np.testing.assert_allclose(al.rot, rot, atol=1e-12)
    m = M.trajectory_metrics(ref, est, align="se3")           # no scale: the fit leaves the size error
    assert m.statistics()["ate"]["rmse"] > 50.0
    assert M.trajectory_metrics(ref, est, align="sim3").statistics()["ate"]["max"] < 1e-9


def test_ate_of_a_constant_offset_and_rpe_of_a_constant_drift():
    t = np.arange(0.0, 100.0 + 1e-9, 0.1)
    pos = np.column_stack([10 * np.cos(t / 10), 10 * np.sin(t / 10), 0.1 * t])
    rot = np.array([rotvec_to_dcm(np.array([0.0, 0.0, x / 10 + np.pi / 2])) for x in t])
    ref = M.Poses(t, pos, rot)
    d = np.array([0.3, -0.4, 1.2])                        # |d| = 1.3 m
    st = M.trajectory_metrics(ref, M.Poses(t, pos + d, rot), metrics=("ate",)).statistics()["ate"]
    assert st["rmse"] == pytest.approx(1.3, rel=1e-12) and st["std"] < 1e-12
    # velocity error v_err and a yaw rate error w_err: every 2 s pair sees |v_err| 2 m and w_err 2 s
    v_err, w_err = np.array([0.03, 0.04, 0.0]), 1e-3
    est_rot = np.einsum("nij,njk->nik", np.array([rotvec_to_dcm(np.array([0.2, 0.1, 0.5]) * w_err * x /
                                                                np.linalg.norm([0.2, 0.1, 0.5])) for x in t]), rot)
    m = M.trajectory_metrics(ref, M.Poses(t, pos + t[:, None] * v_err, rot), rpe_delta=2.0, rpe_unit="s")
    assert len(m.rpe_i) == 50 and np.all(m.rpe_j - m.rpe_i == 20)
    np.testing.assert_allclose(m.rpe_trans_m, 0.1, rtol=1e-9)
    assert np.max(m.rpe_rot_deg) < 1e-12
    # the attitude drifting about a fixed axis at w_err on a base at rest: rotation part w_err 2 s, no translation
    rest = M.Poses(t, np.zeros_like(pos), rot)
    m = M.trajectory_metrics(rest, M.Poses(t, np.zeros_like(pos), est_rot), rpe_delta=2.0, rpe_unit="s")
    np.testing.assert_allclose(m.rpe_rot_deg, np.degrees(2e-3), rtol=1e-9)
    assert np.max(m.rpe_trans_m) == 0.0


def test_path_pairs_follow_the_travelled_distance():
    t = np.arange(401) * 0.1
    pos = np.column_stack([0.25 * np.arange(401), np.zeros(401), np.zeros(401)])     # 0.25 m per epoch
    i, j = M.rpe_pairs(t, pos, 5.0, "m")
    np.testing.assert_array_equal(j - i, 20)
    assert i[0] == 0 and j[-1] == 400
    i, j = M.rpe_pairs(t, pos, 3.0, "f")
    np.testing.assert_array_equal(i, np.arange(0, 398, 3))


# --------------------------------------------------------------------------- evo agreement

def evo_stats(ref_file, est_file, align, kind, **rpe):
    from evo import main_ape, main_rpe
    from evo.core import metrics as em
    from evo.core import sync
    from evo.tools import file_interface
    tr = file_interface.read_tum_trajectory_file(str(ref_file))
    te = file_interface.read_tum_trajectory_file(str(est_file))
    tr, te = sync.associate_trajectories(tr, te)
    flags = dict(align=align != "none", correct_scale=align == "sim3")
    if kind == "ate":
        return main_ape.ape(copy.deepcopy(tr), copy.deepcopy(te), em.PoseRelation.translation_part, **flags).stats
    rel = em.PoseRelation.translation_part if kind == "rpe_trans" else em.PoseRelation.rotation_angle_deg
    return main_rpe.rpe(copy.deepcopy(tr), copy.deepcopy(te), rel, **flags, **rpe).stats


@pytest.mark.parametrize("align", ["se3", pytest.param("none", marks=pytest.mark.slow),
                                   pytest.param("sim3", marks=pytest.mark.slow)])
def test_cli_statistics_equal_evo_within_1e9(tmp_path, align):
    pytest.importorskip("evo", reason="evo is in the test extra: pip install '.[test]'")
    from evo.core.units import Unit
    t, pos, rot = figure_eight()
    write_tum_rows(tmp_path / "ref.txt", t, pos, rot)
    write_tum_rows(tmp_path / "est.txt", t, *perturbed(pos, rot))
    worst = 0.0
    # seconds against evo's frames (epochs every 0.05 s), path metres, pairs from either trajectory
    for unit, delta, evo_delta, evo_unit in (("s", 0.35, 7, Unit.frames), ("m", 25.0, 25.0, Unit.meters),
                                             ("f", 40, 40, Unit.frames)):
        for pairs in ("ref", "est"):
            out = tmp_path / f"rep_{unit}_{pairs}"
            r = run(["--truth", tmp_path / "ref.txt", tmp_path / "est.txt", "-o", out, "-q", "--metrics", "ate,rpe",
                     "--align-traj", align, "--rpe-delta", delta, "--rpe-unit", unit, "--rpe-pairs", pairs])
            assert r.exit_code == 0, r.output
            _, rows = read_rows(out / "errors.csv")
            for kind in ("ate", "rpe_trans", "rpe_rot"):
                ev = evo_stats(tmp_path / "ref.txt", tmp_path / "est.txt", align, kind, delta=evo_delta,
                               delta_unit=evo_unit, pairs_from_reference=pairs == "ref")
                for s in STATS:
                    ours = rows[f"{kind}_{s}"][0]
                    assert ours == pytest.approx(ev[s], rel=1e-9), (unit, pairs, kind, s)
                    worst = max(worst, abs(ours / ev[s] - 1.0))
    print(f"worst relative difference to evo ({align}): {worst:.2e}")


# --------------------------------------------------------------------------- geodetic trajectories in the CLI

def test_metrics_rows_on_csv_trajectories_agree_with_the_position_errors(tmp_path):
    truth = make_truth(n=300)
    write_trajectory(tmp_path / "truth.csv", truth)
    d = np.array([0.3, -0.4, 1.2])
    nav = displaced(truth, d, np.zeros(3))
    write_trajectory(tmp_path / "nav.csv", nav)
    out = tmp_path / "rep"
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "nav.csv", "-o", out, "-q", "--metrics", "ate,rpe",
             "--rpe-delta", 0.5])
    assert r.exit_code == 0, r.output
    header, rows = read_rows(out / "errors.csv")
    assert header == ["quantity", "unit", "nav"]
    assert "C11" in rows and "max_att_deg" in rows                    # the seed-000 rows stay
    # ATE without alignment: |d| at every epoch (positions through ECEF about the truth's start) ...
    assert rows["ate_rmse"][0] == pytest.approx(1.3, rel=1e-9)
    assert rows["ate_std"][0] < 1e-8
    # ... and the RMS of the seed-000 position errors, a second computation (radii of curvature)
    s = compare_trajectories(truth, nav)
    assert rows["ate_rmse"][0] == pytest.approx(np.sqrt(np.mean(np.sum(s.pos_enu_m ** 2, axis=1))), rel=1e-7)
    # RPE of an offset d constant in the local level frame: no rotation, and in translation the offset turned by
    # the rotation between the level frames at the pair's ends (~330 m apart: ~8e-5 m).  Second method: the
    # relative poses are frame-invariant, so form them in ECEF (C_b^e = C_n^e Cbn) without the local frame.
    assert rows["rpe_rot_max"][0] < 1e-8      # second order: level frames 2e-7 rad apart x 5e-5 rad per pair
    i = np.arange(0, 250, 50)                                                   # 0.5 s pairs at 100 Hz

    def rel_t(tr):
        r_e = np.einsum("nji,njk->nik", enu_rotation(tr.lat, tr.lon), tr.Cbn)
        p_e = lla_to_ecef(tr.lat, tr.lon, tr.height)
        return np.einsum("nji,nj->ni", r_e[i], p_e[i + 50] - p_e[i])

    expect = np.linalg.norm(rel_t(nav) - rel_t(truth), axis=1)
    got = np.array([float(line.split(",")[3]) for line in (out / "rpe.csv").read_text().splitlines()[1:]])
    np.testing.assert_allclose(got, expect, rtol=1e-4)
    text = (out / "index.html").read_text()
    assert "Summary" in text and "ATE RMSE 1.3 m" in text and "ate.png" in text
    assert "ATE RMSE" in (out / "errors.md").read_text()
    for f in ("ate.csv", "rpe.csv", "ate.png", "rpe.png", "trajectory_xy.png", "timeseries.csv", "att_pitch.png"):
        assert (out / f).stat().st_size > 0, f
    assert "ATE RMSE 1.3 m" in r.output
    # se3 alignment removes the offset, up to its turn with the level frame along the 2 km track (1.3 m x 3e-4)
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "nav.csv", "-o", tmp_path / "rep2", "-q",
             "--metrics", "ate", "--align-traj", "se3"])
    assert r.exit_code == 0, r.output
    assert read_rows(tmp_path / "rep2" / "errors.csv")[1]["ate_max"][0] < 1.3 * 2500.0 / 6.3e6


def test_tum_written_by_sins_compares_with_its_csv_truth(tmp_path):
    truth = make_truth(n=200)
    write_trajectory(tmp_path / "truth.csv", truth)
    write_tum(tmp_path / "nav.tum", displaced(truth, [0.0, 2.0, 0.0], np.zeros(3)))
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "nav.tum", "-o", tmp_path / "rep", "-q"])
    assert r.exit_code == 0, r.output
    _, rows = read_rows(tmp_path / "rep" / "errors.csv")
    assert "C11" not in rows and "ate_rmse" in rows                 # TUM: metrics alone, by default ate and rpe
    assert rows["ate_rmse"][0] == pytest.approx(2.0, rel=1e-8)
    assert "omitted" in (tmp_path / "rep" / "index.html").read_text()


def test_installed_script_compares_tum_files_from_any_directory(tmp_path):
    t, pos, rot = figure_eight(300)
    write_tum_rows(tmp_path / "ref.tum", t, pos, rot)
    write_tum_rows(tmp_path / "est.tum", t, *perturbed(pos, rot, scale=1.0))
    exe = Path(sys.executable).with_name("sins")
    p = subprocess.run([str(exe), "compare", "--truth", "ref.tum", "est.tum", "-o", "rep", "-q",
                        "--align-traj", "se3"], cwd=tmp_path, capture_output=True, text=True,
                       env=dict(os.environ, PYTHONPATH=""))
    assert p.returncode == 0, p.stderr
    _, rows = read_rows(tmp_path / "rep" / "errors.csv")
    assert 0.0 < rows["ate_rmse"][0] < 20.0


# --------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("case, args, message", [
    ("metric", ["--metrics", "ate,foo"], "--metrics 'ate,foo'"),
    ("no-metrics", ["--align-traj", "se3"], "give --metrics"),
    ("delta", ["--metrics", "rpe", "--rpe-delta", "1e6"], "gives no pose pair"),
    ("line", ["--metrics", "ate", "--align-traj", "se3", "--straight"], "Umeyama alignment is not possible"),
    ("frames", ["--metrics", "rpe", "--rpe-unit", "f", "--rpe-delta", "2.5"], "whole number of frames"),
])
def test_bad_metric_requests_fail_cleanly(tmp_path, case, args, message):
    n = 50
    t = np.arange(n) * 0.1
    pos = np.column_stack([np.arange(n) * 1.0, np.zeros(n), np.zeros(n)]) if "--straight" in args else \
        np.column_stack([np.cos(t), np.sin(t), t])
    rot = np.repeat(np.eye(3)[None], n, axis=0)
    write_tum_rows(tmp_path / "a.tum", t, pos, rot)
    write_tum_rows(tmp_path / "b.tum", t, pos + 0.1, rot)
    args = [a for a in args if a != "--straight"]
    files = [tmp_path / "a.tum", tmp_path / "b.tum"]
    if case == "no-metrics":                          # (TUM inputs turn the metrics on by themselves)
        write_trajectory(tmp_path / "a.csv", make_truth(n=20))
        files = [tmp_path / "a.csv", tmp_path / "a.csv"]
    r = run(["--truth", files[0], files[1], "-o", tmp_path / "rep", *args])
    assert r.exit_code == 2, r.output
    assert message in r.output and "Traceback" not in r.output
    assert not (tmp_path / "rep").exists()


def test_bad_tum_rows_name_line_and_column(tmp_path):
    (tmp_path / "a.tum").write_text("# c\n0 0 0 0 0 0 0 1\n1 0 0 nan 0 0 0 1\n")
    (tmp_path / "b.tum").write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 2\n")
    r = run(["--truth", tmp_path / "a.tum", tmp_path / "b.tum", "-o", tmp_path / "rep"])
    assert r.exit_code == 2 and "a.tum: line 3, column 'tz'" in r.output
    (tmp_path / "a.tum").write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n")
    r = run(["--truth", tmp_path / "a.tum", tmp_path / "b.tum", "-o", tmp_path / "rep"])
    assert r.exit_code == 2 and "b.tum: line 2, column 'qw'" in r.output
    truth = make_truth(n=20)
    write_trajectory(tmp_path / "truth.csv", truth)
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "a.tum", "-o", tmp_path / "rep"])
    assert r.exit_code == 2 and "without a '# origin_lat_deg" in r.output
    assert not (tmp_path / "rep").exists()
