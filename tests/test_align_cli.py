"""``sins align`` through the CLI: outputs, the round trip into ``sins navigate --init``, heading
observability, Monte Carlo, and every bad input (exit 2, one line, nothing written)."""
import copy
import math

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.align import sway
from sinscli.cli import main
from sinscli.io.init_state import INIT_KEYS, read_init
from sinscli.io.trajectory import read_trajectory
from sinscli.nav.rotation import attitude_error_many
from sinscli.sim.run import write_sim

REST = {"name": "rest", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 40},
        "imu": {"rate": 50, "sensor": {"gyro": {"bias": 0.01, "arw": 0.001}, "accel": {"bias": 50, "vrw": 10}}},
        "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 200}]}
CONFIG = {"align": {"sensor": {"gyro_bias": 0.01, "gyro_arw": 0.001, "accel_bias": 50, "accel_vrw": 10}}}


def _write(tmp, name, scenario, sway_spec=None, seed=1):
    r = sway.ScenarioRuns(sway.prepare_scenario(copy.deepcopy(scenario), sway_spec, name, None)).run(seed)
    write_sim(r, tmp / name)
    return tmp / name


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("align_cli")
    rest = _write(tmp, "rest", REST)
    swaying = _write(tmp, "sway", REST, {"roll": {"amplitude": 5, "freq": 0.15}, "pitch": {"amplitude": 5, "freq": 0.1},
                                         "heave": {"amplitude": 0.5, "freq": 0.12}})
    mems = dict(copy.deepcopy(REST), imu={"rate": 50, "sensor": "mems"})
    mems_dir = _write(tmp, "mems", mems)
    cfg = tmp / "align.yaml"
    cfg.write_text(yaml.safe_dump(CONFIG))
    return {"tmp": tmp, "rest": rest, "sway": swaying, "mems": mems_dir, "cfg": cfg}


def run(args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_align_writes_an_init_that_navigate_takes(data, tmp_path):
    out = tmp_path / "init.yaml"
    series = tmp_path / "series.csv"
    plot = tmp_path / "att.png"
    res = run(["align", data["rest"] / "imu.csv", "--method", "inertial", "--position", "30,114,50",
               "--duration", 150, "--config", data["cfg"], "--series", series, "--plot", plot, "-q", "-o", out])
    assert res.exit_code == 0, res.output
    d = yaml.safe_load(out.read_text())
    for k in INIT_KEYS + ["method", "duration", "sigma_roll", "sigma_pitch", "sigma_heading", "heading_source"]:
        assert k in d, k
    assert d["method"] == "inertial" and d["duration"] == pytest.approx(150.0)
    assert d["time"] == pytest.approx(150.0) and d["heading_source"] == "earth-rate"
    assert abs(d["heading"] - 40.0) < 0.1 and abs(d["roll"]) < 0.01 and abs(d["pitch"]) < 0.01
    assert 0.002 < d["sigma_roll"] < 0.004 and 0.03 < d["sigma_heading"] < 0.1
    assert series.stat().st_size > 0 and plot.read_bytes()[:4] == b"\x89PNG"
    cols = series.read_text().splitlines()[0].split(",")
    assert cols[:4] == ["time", "roll", "pitch", "heading"] and "roll_start" in cols
    # the init as it is drives sins navigate from the end of the alignment
    nav = tmp_path / "nav.csv"
    res = run(["navigate", data["rest"] / "imu.csv", "--init", out, "-q", "-o", nav])
    assert res.exit_code == 0, res.output
    traj = read_trajectory(nav)
    truth = read_trajectory(data["rest"] / "truth.csv")
    assert traj.time[0] == pytest.approx(150.0) and traj.time[-1] == pytest.approx(200.0)
    err = np.degrees(np.abs(attitude_error_many(truth.Cbn[-1:], traj.Cbn[-1:])[0]))
    assert err[:2].max() < 0.01 and err[2] < 0.1
    st = read_init(out)
    assert st.extra["method"] == "inertial"


@pytest.mark.parametrize("method", ["static", "kf"])
def test_other_methods_through_the_cli(data, tmp_path, method):
    out = tmp_path / "init.yaml"
    res = run(["align", data["rest"] / "imu.csv", "--method", method, "--position", "30,114,50",
               "--config", data["cfg"], "-o", out])
    assert res.exit_code == 0, res.output
    d = yaml.safe_load(out.read_text())
    assert d["method"] == method and abs(d["heading"] - 40.0) < 0.1
    if method == "kf":
        assert len(d["gyro_bias"]) == 3 and len(d["accel_bias"]) == 3
    assert "aligned (" in res.output


def test_roll_window_and_start_epoch(data, tmp_path):
    out = tmp_path / "init.yaml"
    res = run(["align", data["sway"] / "imu.csv", "--method", "inertial", "--position", "30,114,50",
               "--roll-window", 10, "--epoch", "start", "--config", data["cfg"], "-q", "-o", out])
    assert res.exit_code == 0, res.output
    d = yaml.safe_load(out.read_text())
    assert d["time"] == 0.0 and d["roll_window"] == 10.0
    truth = read_init(data["sway"] / "init.yaml")
    got = read_init(out)
    err = np.degrees(np.abs(attitude_error_many(truth.Cbn[None], got.Cbn[None])[0]))
    assert err[:2].max() < 0.01 and err[2] < 0.1


def test_low_grade_imu_heading_is_refused_then_taken_from_the_user(data, tmp_path):
    out = tmp_path / "init.yaml"
    res = run(["align", data["mems"] / "imu.csv", "--method", "static", "--position", "30,114,50", "-o", out])
    assert res.exit_code == 2
    assert "heading is not observable from earth rate" in res.output and "--heading" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not out.exists()
    res = run(["align", data["mems"] / "imu.csv", "--method", "static", "--position", "30,114,50",
               "--heading", "41.5", "-o", out])
    assert res.exit_code == 0, res.output
    assert "not observable" in res.output
    d = yaml.safe_load(out.read_text())
    assert d["heading"] == pytest.approx(41.5) and d["heading_source"] == "user" and d["sigma_heading"] is None
    assert abs(d["roll"]) < 0.6 and abs(d["pitch"]) < 0.6     # MEMS tilt: accelerometer bias 5 mg ~ 0.3 deg
    # the inertial-frame method refuses the same way and reports the gyro-bias term in its tilt 1-sigma
    res = run(["align", data["mems"] / "imu.csv", "--method", "inertial", "--position", "30,114,50", "-o", out])
    assert res.exit_code == 2 and "heading is not observable from earth rate" in res.output


def test_monte_carlo_cli(tmp_path):
    sc = copy.deepcopy(REST)
    sc["segments"] = [{"type": "rest", "duration": 60}]
    sc["imu"] = {"rate": 20, "sensor": {"gyro": {"bias_sigma": 0.01}, "accel": {"bias_sigma": 50}}}
    sc["align"] = {"method": "inertial"}
    path = tmp_path / "mc.yaml"
    path.write_text(yaml.safe_dump(sc))
    out = tmp_path / "mc"
    res = run(["align", "--monte-carlo", 3, "--scenario", path, "-q", "-o", out])
    assert res.exit_code == 0, res.output
    for f in ("summary.csv", "summary.md", "runs.csv", "mc_roll.png", "mc_pitch.png", "mc_heading.png"):
        assert (out / f).stat().st_size > 0, f
    text = (out / "summary.md").read_text()
    assert "inertial+roll-window" in text and "3 runs" in text


def test_short_interval_runs_with_a_warning_naming_the_recommended_length(data, tmp_path):
    out = tmp_path / "init.yaml"
    imu = data["rest"] / "imu.csv"
    res = run(["align", imu, "--method", "inertial", "--position", "30,114,50", "--duration", 12, "--config",
               data["cfg"], "-o", out])
    assert res.exit_code == 0, res.output
    assert ("warning: the alignment interval is 12 s, shorter than the 30 s recommended for --method inertial "
            "(align.min_duration.inertial)") in res.output
    d = yaml.safe_load(out.read_text())
    assert d["duration"] == pytest.approx(12.0) and d["sigma_heading"] > 0.0
    # the recommended lengths are config keys
    cfg = tmp_path / "short.yaml"
    cfg.write_text(yaml.safe_dump({"align": dict(CONFIG["align"], min_duration={"inertial": 10})}))
    res = run(["align", imu, "--method", "inertial", "--position", "30,114,50", "--duration", 12, "--config", cfg,
               "-o", out])
    assert res.exit_code == 0 and "warning" not in res.output, res.output
    cfg.write_text(yaml.safe_dump({"align": {"min_duration": {"inertial": -1}}}))
    _bad(["align", imu, "--config", cfg, "--position", "30,114,50", "-o", tmp_path / "x.yaml"], tmp_path / "x.yaml",
         "align.min_duration.inertial: must be >= 0")


def _bad(args, out, *expect):
    res = run(args)
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sins: error:"), res.output
    for e in expect:
        assert e in lines[0], lines[0]
    assert not out.exists()


def test_bad_inputs(data, tmp_path):
    out = tmp_path / "init.yaml"
    imu = data["rest"] / "imu.csv"
    _bad(["align", imu, "--method", "inertial", "--position", "30,114,50", "--duration", 2, "-o", out],
         out, "alignment interval is 2 s", "needs at least 3 s", "recommended: 30 s", "align.min_duration.inertial")
    _bad(["align", imu, "--method", "kf", "--position", "30,114,50", "--duration", 4, "-o", out],
         out, "needs at least 6 s")
    _bad(["align", imu, "--method", "static", "--position", "30,114,50", "--duration", 500, "-o", out],
         out, "the log holds only 200 s")
    _bad(["align", data["sway"] / "imu.csv", "--method", "static", "--position", "30,114,50", "-o", out],
         out, "the base moves", "--method static needs a base at rest")
    _bad(["align", imu, "--method", "inertial", "-o", out], out, "needs the latitude", "--position")
    short_gnss = tmp_path / "gnss.csv"
    lines = (data["rest"] / "gnss.csv").read_text().splitlines()
    short_gnss.write_text("\n".join(lines[:60]) + "\n")            # fixes up to 58 s only
    _bad(["align", imu, "--gnss", short_gnss, "--method", "gnss-inertial", "--duration", 100, "-o", out],
         out, "does not cover the alignment interval")
    _bad(["align", imu, "--method", "gnss-inertial", "--position", "30,114,50", "-o", out], out,
         "needs a GNSS log")
    _bad(["align", imu, "--method", "inertial", "--position", "95,114,50", "-o", out], out, "latitude 95")
    _bad(["align", imu, "--method", "inertial", "--position", "30,114,50", "--roll-window", 500, "-o", out],
         out, "--roll-window 500 s")
    bad_cfg = tmp_path / "bad.yaml"
    bad_cfg.write_text("align:\n  sensor:\n    gyro_drift: 1\n")
    _bad(["align", imu, "--config", bad_cfg, "-o", out], out, "align.sensor.gyro_drift: unknown key")
    _bad(["align", "--monte-carlo", 3, "-o", out], out, "--monte-carlo N and --scenario FILE go together")


def test_kf_plot_draws_a_supplied_heading_as_a_marker(data, tmp_path):
    """The kf series ends with the written state; with --heading that is the user's heading, which the
    figure draws as a separate marker instead of a jump of the line at the last epoch."""
    import matplotlib.image as mpimg

    from sinscli.report import align_figures as figures

    seen = {}
    real = figures.series_figure

    def spy(*args, **kw):
        seen["fig"] = fig = real(*args, **kw)
        seen["t"], seen["eul"] = args[0], args[1]
        return fig

    out, plot = tmp_path / "init.yaml", tmp_path / "kf.png"
    figures.series_figure = spy
    try:
        res = run(["align", data["mems"] / "imu.csv", "--method", "kf", "--position", "30,114,50",
                   "--heading", "41.5", "--plot", plot, "-q", "-o", out])
    finally:
        figures.series_figure = real
    assert res.exit_code == 0, res.output
    assert mpimg.imread(plot).shape[0] > 100
    lines = {ln.get_label(): ln for ln in seen["fig"].axes[2].get_lines()}
    mark = lines["supplied heading (--heading)"]
    assert list(mark.get_ydata()) == [pytest.approx(41.5)]
    assert seen["eul"][-1, 2] == pytest.approx(41.5)      # the series' last epoch is the written state ...
    est = lines["estimate"]
    assert len(est.get_xdata()) == len(seen["t"]) - 1     # ... which the line leaves out: no jump
    np.testing.assert_array_equal(est.get_ydata(), seen["eul"][:-1, 2])
    assert list(mark.get_xdata()) == [seen["t"][-1]]
