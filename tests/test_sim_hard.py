"""The realism terms that make a simulated log as hard as a real one, each against a closed form: the written
values' quantization, g-sensitivity, vibration rectification, temperature drift, mount flex, sideslip in
turns, dropped rows, RTK float epochs and wrong fixes; their refusals; and every term off by default."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io.gnss_csv import read_gnss_csv
from sinscli.io.imu_csv import read_imu_csv
from sinscli.nav.earth import enu_offset
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.evaluate.errors import compare_trajectories
from sinscli.sim import simulate
from sinscli.sim.flex import Flex, flex_between, flex_knots
from sinscli.sim.recorder import runs_of
from sinscli.units import G0, MG

ROOT = Path(__file__).resolve().parents[1]
DEG = math.pi / 180.0

REST = {"name": "rest", "start": {"time": 1000.0, "lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 20.0},
        "imu": {"rate": 100}, "segments": [{"type": "rest", "duration": 20}]}


def _sc(imu=None, **top):
    d = yaml.safe_load(yaml.safe_dump(REST))
    d["imu"].update(imu or {})
    d.update(top)
    return d


def _vib(**k):
    return dict({"gyro_rms": 0.0, "accel_rms": 0.0, "band": [20, 40], "lines": 4, "seed": 3, "ramp": 0.0}, **k)


def _drive(seconds=30.0):
    return [{"type": "rest", "duration": 2}, {"type": "accelerate", "speed": 10, "duration": 6},
            {"type": "turn", "angle": 60, "duration": 6, "bank": "none"}, {"type": "decelerate", "speed": 4, "duration": 5},
            {"type": "turn", "angle": -90, "duration": 6, "bank": "none"}, {"type": "cruise", "duration": seconds - 25}]


# ---- quantization of the written values -------------------------------------------------------------------

def test_rates_quantized_to_the_step_and_within_half_a_step(tmp_path):
    """Rates: every written value a multiple of its step (0.01 deg/s, 1 mg), within half a step of the
    unquantized value; the file reads back the same multiples."""
    q = {"gyro": 0.01, "accel": 1.0}
    sc = _sc({"output": "rates", "sensor": "consumer"}, vibration=_vib(gyro_rms=0.5, accel_rms=0.2))
    ref = simulate(sc, seed=3)
    sc["imu"]["quantization"] = q
    r = simulate(sc, seed=3)
    for x, x0, step in ((r.imu_rates.gyro, ref.imu_rates.gyro, 0.01 * DEG), (r.imu_rates.accel, ref.imu_rates.accel, MG)):
        k = x / step
        assert np.array_equal(np.round(k) * step, x)
        assert np.abs(k - np.round(k)).max() < 1e-9
        assert np.abs(x - x0).max() <= 0.5 * step * (1 + 1e-9)
        assert np.abs(x - x0).max() > 0.45 * step                     # the rounding is really there
    out = tmp_path / "q"
    p = tmp_path / "q.yaml"
    p.write_text(yaml.safe_dump(sc))
    assert CliRunner().invoke(main, ["simulate", str(p), "-o", str(out), "-q", "--seed", "3"]).exit_code == 0
    a = np.loadtxt(out / "imu.csv", delimiter=",", skiprows=1)
    assert np.abs(a[:, 4:7] / MG - np.round(a[:, 4:7] / MG)).max() < 1e-9
    assert np.abs(a[:, 1:4] / (0.01 * DEG) - np.round(a[:, 1:4] / (0.01 * DEG))).max() < 1e-9


def test_increments_quantized_with_the_remainder_carried():
    """Increments: multiples of step * dt, and their running sum within one step of the unquantized sum at
    every sample (a counter loses nothing); the quantization error white (lag-1 correlation of the
    differences -0.5, the differenced uniform)."""
    sc = _sc({"sensor": "consumer"}, vibration=_vib(gyro_rms=0.5, accel_rms=0.2))
    ref = simulate(sc, seed=5)
    sc["imu"]["quantization"] = {"gyro": 0.01, "accel": 1.0}
    r = simulate(sc, seed=5)
    for x, x0, step in ((r.imu.dtheta_b, ref.imu.dtheta_b, 0.01 * DEG * 0.01),
                        (r.imu.dvel_b, ref.imu.dvel_b, MG * 0.01)):
        k = x / step
        assert np.abs(k - np.round(k)).max() < 1e-6
        drift = np.abs(np.cumsum(x - x0, axis=0))
        assert drift.max() < step * (0.5 + 1e-6) and drift.max() > 0.4 * step
        e = x - x0
        c = np.corrcoef(e[1:, 0], e[:-1, 0])[0, 1]
        assert c == pytest.approx(-0.5, abs=0.05)


# ---- g-sensitivity, rectification, temperature ------------------------------------------------------------

G_SENS = [[0.1, 0.02, -0.03], [-0.04, 0.08, 0.05], [0.01, -0.06, 0.12]]   # deg/s per g


def test_g_sensitivity_is_k_times_f_on_a_static_log():
    """At rest (no sensor errors): the gyro reads the earth rate plus exactly ``G f`` of the static specific
    force, rates and increments."""
    for output in ("rates", "increments"):
        ref = simulate(_sc({"output": output}))
        r = simulate(_sc({"output": output, "g_sensitivity": G_SENS}))
        g = np.array(G_SENS) * DEG / G0
        if output == "rates":
            d, f = r.imu_rates.gyro - ref.imu_rates.gyro, ref.imu_rates.accel
        else:
            d, f = r.imu.dtheta_b - ref.imu.dtheta_b, ref.imu.dvel_b
        assert np.abs(d - f @ g.T).max() < 1e-15 * np.abs(f @ g.T).max() + 1e-20
        scale = 0.01 if output == "increments" else 1.0          # the interval
        assert np.abs(np.abs(d[:, 2]) / scale - 0.12 * DEG * np.abs(f[:, 2]) / scale / G0).max() < 1e-9 * DEG  # 0.12 deg/s at 1 g


def test_vibration_rectification_is_k2_times_the_mean_square():
    """A z-axis vibration of RMS a on top of gravity: the accelerometer's K2 adds ``K2 f_z^2`` to each rate
    sample and, in the increments, ``K2 int f_z^2 dt``, whose mean is ``K2 (g^2 + a^2)``: the rectified
    ``K2 a^2``, which squares of the interval means would underestimate (by a third for 20-40 Hz lines at
    100 Hz)."""
    k2 = 4000.0                                    # micro-g per g^2
    vib = _vib(accel_rms=[0.0, 0.0, 3.0])
    k2_si = k2 * 1e-6 / G0
    ref = simulate(_sc({"output": "rates"}, vibration=vib))
    r = simulate(_sc({"output": "rates", "vibration_rectification": [0, 0, k2]}, vibration=vib))
    f = ref.imu_rates.accel[:, 2]
    assert np.abs(r.imu_rates.accel[:, 2] - f - k2_si * f * f).max() < 1e-15 * 10
    assert np.array_equal(r.imu_rates.accel[:, :2], ref.imu_rates.accel[:, :2])
    ref = simulate(_sc(vibration=vib))
    r = simulate(_sc({"vibration_rectification": k2}, vibration=vib))
    t = 20.0
    mean_rect = (r.imu.dvel_b[:, 2] - ref.imu.dvel_b[:, 2]).sum() / t
    g = np.abs(ref.imu.dvel_b[:, 2].sum() / t)
    assert mean_rect == pytest.approx(k2_si * (g * g + 9.0), rel=2e-3)
    naive = k2_si * np.sum(ref.imu.dvel_b[:, 2] ** 2 / 0.01) / t - k2_si * g * g   # from the interval means
    assert naive < 0.8 * k2_si * 9.0


def test_temperature_drift_follows_the_profile():
    """Rates: ``c dT(t)`` with ``dT = rise (1 - e^(-t/tau)) + swing sin(2 pi t/period)`` (0 at the start);
    increments: their sum is ``c`` times the profile's integral, to rounding."""
    temp = {"rise": 12.0, "tau": 5.0, "swing": 2.0, "period": 7.0, "gyro": [0.02, -0.01, 0.015], "accel": [0.3, -0.2, 0.5]}
    t = np.arange(2001) * 0.01
    dT = 12.0 * (1 - np.exp(-t / 5.0)) + 2.0 * np.sin(2 * np.pi * t / 7.0)
    it = 12.0 * (t - 5.0 * (1 - np.exp(-t / 5.0))) + 2.0 * 7.0 / (2 * np.pi) * (1 - np.cos(2 * np.pi * t / 7.0))
    ref = simulate(_sc({"output": "rates"}))
    r = simulate(_sc({"output": "rates"}, temperature=temp))
    assert np.allclose(r.imu_rates.gyro - ref.imu_rates.gyro, np.outer(dT, temp["gyro"]) * DEG, rtol=0, atol=1e-15)
    assert np.allclose(r.imu_rates.accel - ref.imu_rates.accel, np.outer(dT, temp["accel"]) * MG, rtol=0, atol=1e-14)
    assert np.all(r.imu_rates.gyro[0] == ref.imu_rates.gyro[0])
    ref = simulate(_sc())
    r = simulate(_sc(temperature=temp))
    s = np.cumsum(r.imu.dtheta_b - ref.imu.dtheta_b, axis=0)
    assert np.allclose(s, np.outer(it[1:], temp["gyro"]) * DEG, rtol=1e-12, atol=1e-15)
    s = np.cumsum(r.imu.dvel_b - ref.imu.dvel_b, axis=0)
    assert np.allclose(s, np.outer(it[1:], temp["accel"]) * MG, rtol=1e-12, atol=1e-14)


# ---- mount flex ------------------------------------------------------------------------------------------

def test_flex_low_pass_is_exact_for_a_held_input():
    """A constant target from t = 0: ``theta = U (1 - e^(-t/tau))``, ``theta' = U e^(-t/tau) / tau``; a ramp
    ``u = s t``: ``theta = s (t - tau (1 - e^(-t/tau)))``; between the instants the Hermite derivative is the
    derivative of its value (central differences)."""
    fl = Flex(np.array([1.0, 1.0, 1.0]), 0.3)
    t = np.arange(301) * 0.01
    u = np.tile([0.2, -0.1, 0.05], (t.size, 1))
    u[0] = 0.0                                     # first-order hold: a 10 ms ramp to U, then U
    th, dth = flex_knots(fl, t, u)
    # exact for the held ramp then the constant: theta(t) = U [1 - tau/h (e^{-(t-h)/tau} - e^{-t/tau})] for t >= h
    h, tau = 0.01, 0.3
    exact = u[1] * (1 - tau / h * (np.exp(-(t[1:] - h) / tau) - np.exp(-t[1:] / tau)))[:, None]
    assert np.abs(th[1:] - exact).max() < 1e-15
    assert np.abs(dth[1:] - (u[1] - exact) / tau).max() < 1e-13
    ramp = np.outer(t, [0.5, 0.0, -0.2])
    th, dth = flex_knots(fl, t, ramp)
    assert np.abs(th - np.outer(t - tau * (1 - np.exp(-t / tau)), [0.5, 0.0, -0.2])).max() < 1e-15
    k = np.full(99, 150)
    s = np.linspace(0.0005, 0.0095, 99)
    _, d = flex_between(th, dth, np.diff(t), k, s)
    vp, _ = flex_between(th, dth, np.diff(t), k, s + 1e-7)
    vm, _ = flex_between(th, dth, np.diff(t), k, s - 1e-7)
    assert np.abs((vp - vm) / 2e-7 - d).max() < 1e-7 * np.abs(d).max()
    v0, d0 = flex_between(th, dth, np.diff(t), k, np.zeros(99))
    assert np.array_equal(v0, th[k]) and np.allclose(d0, dth[k], rtol=1e-14, atol=0)


def test_flex_is_what_the_gyro_sees_and_not_in_the_truth():
    """Accelerating along a straight line with a pitch flex: the gyro's y increments exceed the rigid car's
    by the flex angle's change (summed: the angle itself, to second order in the angles), the peak angle is
    the gain times the peak acceleration (to the lag), and the truth is the rigid car's (equal to the run
    without flex)."""
    segs = [{"type": "rest", "duration": 2}, {"type": "accelerate", "speed": 15, "duration": 5},
            {"type": "cruise", "duration": 5}]
    base = _sc(segments=segs)
    ref = simulate(base, perfect=True)
    r = simulate(dict(base, mount_flex={"pitch": 0.5, "tau": 0.2}), perfect=True)
    assert np.array_equal(r.truth.lat, ref.truth.lat) and np.array_equal(r.truth.Cbn, ref.truth.Cbn)
    angle = np.cumsum(r.imu.dtheta_b[:, 1] - ref.imu.dtheta_b[:, 1])
    a_x = np.diff(np.linalg.norm(ref.truth.vel_n, axis=1)) / 0.01
    peak = 0.5 * DEG * a_x.max()
    assert np.abs(angle).max() == pytest.approx(peak, rel=0.05)
    assert angle[np.argmax(np.abs(angle))] < 0                 # the nose lifts (-y rotation) while accelerating
    rec = r.record["mount_flex"]
    assert rec["max_angle_deg"][1] == pytest.approx(np.degrees(np.abs(angle).max()), rel=1e-6)
    assert abs(angle[-1]) < 1e-9                               # back on the body at constant speed


# ---- sideslip --------------------------------------------------------------------------------------------

def test_sideslip_in_a_steady_turn():
    """A steady right turn at 10 m/s and 10 deg/s (bank none) with a slip gradient K: the truth's lateral
    body velocity is ``K a_lat V``, ``a_lat = -V psi'`` (out of the turn for K < 0); straight, it is 0; the
    truth and the increments agree (a perfect run navigates to the algorithm's level)."""
    k = -3.0                                                   # deg/g
    segs = [{"type": "rest", "duration": 1}, {"type": "accelerate", "speed": 10, "duration": 4},
            {"type": "cruise", "duration": 2}, {"type": "turn", "rate": 10, "duration": 3, "bank": "none"},
            {"type": "cruise", "duration": 6}]
    r = simulate(_sc(segments=segs, vehicle={"sideslip": k}), perfect=True)
    v_b = np.einsum("nji,nj->ni", r.truth.Cbn, r.truth.vel_n)
    t = r.truth.time - r.truth.time[0]
    steady = t > 10.5
    psi_dot = 10 * DEG
    expect = (k * DEG / G0) * (-v_b[steady, 0] * psi_dot) * v_b[steady, 0]
    assert np.abs(v_b[steady, 1] - expect).max() < 1e-6 * np.abs(expect).max()
    assert expect.min() > 0.09                                 # 0.093 m/s to the left in a right turn (0.53 deg)
    assert np.abs(v_b[(t > 1) & (t < 7), 1]).max() < 1e-12
    nav = navigate(r.imu, r.init, NavOptions())
    e = compare_trajectories(r.truth, nav)
    assert np.abs(e.pos_enu_m).max() < 1e-3
    assert r.record["vehicle"]["max_lateral_velocity_m_s"] == pytest.approx(np.abs(v_b[:, 1]).max())


# ---- dropped rows ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("output", ["rates", "increments"])
def test_dropped_rows_fraction_runs_and_the_kept_rows_unchanged(output):
    sc = _sc({"output": output, "sensor": "consumer", "stamp_jitter": 0.001}, segments=[{"type": "rest", "duration": 100}])
    ref = simulate(sc, seed=2)
    sc["imu"]["dropped"] = {"fraction": 0.02, "run": [2, 4]}
    r = simulate(sc, seed=2)
    n = 10000
    drop = r.imu_dropped
    runs = runs_of(drop)
    assert runs.size == round(0.02 * (n - 1) / 3) and runs.min() >= 2 and runs.max() <= 4
    assert set(runs.tolist()) == {2, 3, 4}
    assert drop.size == runs.sum() and 0.017 < drop.size / (n - 1) < 0.023
    assert drop.min() > 0 and drop.max() < n
    keep = np.ones(n + 1, bool)
    keep[drop] = False
    assert np.array_equal(r.imu_stamps, ref.imu_stamps[keep])
    if output == "rates":
        assert np.array_equal(r.imu_rates.gyro, ref.imu_rates.gyro[keep])
        assert np.array_equal(r.imu_rates.time, ref.imu_rates.time[keep])
    else:
        assert np.array_equal(r.imu.dtheta_b, ref.imu.dtheta_b[keep[1:]]) and len(r.imu) == n - drop.size
    assert r.record["imu"]["dropped"]["rows"] == drop.size


# ---- RTK float and wrong fixes ---------------------------------------------------------------------------

def test_rtk_float_and_wrong_fixes(tmp_path):
    """Float: from the window's first fix a straight drift of +-drift per axis (walk 0), the written std the
    float's; wrong fix: exactly the offset, the written std the fixed one; velocity untouched; elsewhere the
    fixes are those of the run without them."""
    gnss = {"rate": 4, "pos_noise": [0.015, 0.015, 0.03], "pos_tau": 30, "vel_noise": 0.02}
    segs = [{"type": "rest", "duration": 2}, {"type": "accelerate", "speed": 10, "duration": 6}, {"type": "cruise", "duration": 52}]
    ref = simulate(_sc(segments=segs, gnss=gnss), seed=4)
    fl = {"windows": [[10, 30]], "sigma": [0.2, 0.2, 0.3], "walk": 0.0, "drift": [0.01, 0.02, 0.03], "reported": [0.3, 0.3, 0.5]}
    jumps = [{"start": 40, "duration": 5, "offset": [0.6, -0.4, 0.3]}]
    r = simulate(_sc(segments=segs, gnss=dict(gnss, float=fl, jumps=jumps)), seed=4)
    g, g0 = r.gnss, ref.gnss
    e = -enu_offset(np.radians(g0.lat), np.radians(g0.lon), g0.height, np.radians(g.lat), np.radians(g.lon), g.height)
    t = g.time - r.truth.time[0]
    fw = (t >= 10) & (t < 30)
    jw = (t >= 40) & (t < 45)
    assert np.abs(e[~fw & ~jw]).max() == 0.0
    assert np.abs(e[jw] - [0.6, -0.4, 0.3]).max() < 1e-6
    slope = np.diff(e[fw], axis=0) / 0.25
    assert np.allclose(np.abs(slope), [0.01, 0.02, 0.03], rtol=0, atol=1e-6)
    assert np.ptp(slope, axis=0).max() < 1e-6
    assert np.all(np.abs(e[fw][0]) < 1.5)                     # the float's start: decimetres
    assert np.array_equal(g.std_pos[fw], np.tile([0.3, 0.3, 0.5], (fw.sum(), 1)))
    assert np.array_equal(g.std_pos[~fw], g0.std_pos[~fw])
    assert np.array_equal(g.vel_n, g0.vel_n)
    out = tmp_path / "g"
    p = tmp_path / "g.yaml"
    p.write_text(yaml.safe_dump(_sc(segments=segs, gnss=dict(gnss, float=fl, jumps=jumps))))
    assert CliRunner().invoke(main, ["simulate", str(p), "-o", str(out), "-q", "--seed", "4"]).exit_code == 0
    back = read_gnss_csv(out / "gnss.csv")
    assert np.allclose(back.std_pos, g.std_pos) and np.allclose(back.lat, g.lat, rtol=0, atol=1e-11)


# ---- off by default, dropped by --perfect, refusals ------------------------------------------------------

def test_terms_at_zero_change_nothing():
    """Every key present with its off value gives the same bits as the keys absent."""
    sc = _sc({"output": "rates", "sensor": "consumer", "stamp_jitter": 0.001}, segments=_drive(),
             gnss={"rate": 4, "pos_noise": 0.02})
    ref = simulate(sc, seed=1)
    off = yaml.safe_load(yaml.safe_dump(sc))
    off["imu"].update(quantization={"gyro": 0, "accel": 0}, dropped={"fraction": 0, "run": 2})
    off.update(mount_flex={"roll": 0, "pitch": 0, "yaw": 0}, vehicle={"sideslip": 0}, temperature={})
    r = simulate(off, seed=1)
    for a, b in ((r.imu_rates.gyro, ref.imu_rates.gyro), (r.imu_rates.accel, ref.imu_rates.accel),
                 (r.imu_stamps, ref.imu_stamps), (r.truth.lat, ref.truth.lat), (r.gnss.lat, ref.gnss.lat)):
        assert np.array_equal(a, b)


def test_perfect_drops_the_error_terms_and_keeps_the_motion():
    sc = _sc({"output": "rates", "quantization": {"gyro": 0.01, "accel": 1}, "g_sensitivity": 0.1,
              "dropped": {"fraction": 0.01, "run": 2}}, segments=_drive(),
             temperature={"rise": 5, "gyro": 0.01}, mount_flex={"roll": 0.1}, vehicle={"sideslip": -2})
    p = simulate(sc, perfect=True)
    plain = simulate(dict(sc, imu={"rate": 100, "output": "rates"}, temperature=None), perfect=True)
    assert np.array_equal(p.imu_rates.gyro, plain.imu_rates.gyro) and p.imu_dropped is None
    assert "quantization" not in p.record["imu"] and "temperature" not in p.record
    assert p.record["mount_flex"]["max_angle_deg"][0] > 0.01 and p.record["vehicle"]["max_lateral_velocity_m_s"] > 0.01


BAD = [
    ({"imu": {"quantization": {"gyro": -0.01}}}, "imu.quantization.gyro", ">= 0"),
    ({"imu": {"quantization": {"accl": 1}}}, "imu.quantization.accl", "unknown key"),
    ({"imu": {"dropped": {"fraction": 1.0}}}, "imu.dropped.fraction", "[0, 1)"),
    ({"imu": {"dropped": {"fraction": -0.1}}}, "imu.dropped.fraction", "[0, 1)"),
    ({"imu": {"dropped": {"fraction": 0.1, "run": [3, 1]}}}, "imu.dropped.run", "at least min"),
    ({"imu": {"dropped": {"fraction": 0.9, "run": 4}}}, "imu.dropped", "leaves no kept sample"),
    ({"imu": {"g_sensitivity": [[0.1, 0, 0], [0, 0.1, 0]]}}, "imu.g_sensitivity", "3x3"),
    ({"imu": {"vibration_rectification": "big"}}, "imu.vibration_rectification", "expected"),
    ({"temperature": {"rise": 5, "tau": 0}}, "temperature.tau", "> 0"),
    ({"temperature": {"swing": -1}}, "temperature.swing", ">= 0"),
    ({"mount_flex": {"roll": 0.1, "tau": -1}}, "mount_flex.tau", "> 0"),
    ({"mount_flex": {"roll": 50}}, "mount_flex", "+-5"),
    ({"vehicle": {"sideslip": 100}}, "vehicle.sideslip", "+-30"),
    ({"gnss": {"pos_noise": 0.02, "float": {"windows": [[20, 10]]}}}, "gnss.float.windows[0]", "after start"),
    ({"gnss": {"pos_noise": 0.02, "float": {"windows": [[1, 5]], "sigma": 0}}}, "gnss.float.sigma", "> 0"),
    ({"gnss": {"float": {"windows": [[1, 5]]}}}, "gnss.float", "fixed epochs"),
    ({"gnss": {"pos_noise": 0.02, "jumps": [{"start": 3, "duration": 2}]}}, "gnss.jumps[0].offset", "required"),
]


@pytest.mark.parametrize("extra,key,words", BAD, ids=[b[1] + ":" + b[2] for b in BAD])
def test_bad_values_refused_in_one_line(tmp_path, extra, key, words):
    sc = _sc()
    for sec, v in extra.items():
        sc[sec] = dict(sc.get(sec) or {}, **v) if sec == "imu" else v
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(sc))
    res = CliRunner().invoke(main, ["simulate", str(p), "-o", str(tmp_path / "o"), "-q"])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("sins: error:") and "bad.yaml" in lines[0], res.output
    assert f"key {key}" in lines[0] and words in lines[0], lines[0]
    assert not (tmp_path / "o").exists()
