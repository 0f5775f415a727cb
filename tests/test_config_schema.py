"""The one config schema (issue 23, section 3): typed, frozen sections built once from the YAML by one validator
family (``sinscli.schema``) with one message style, ``FILE: key a.b: expected ..., got ...``; command-line
overrides through ``dataclasses.replace``; the choices of click and of the schema the same tuples."""
import dataclasses
import subprocess
import sys
from pathlib import Path

import click
import pytest

from sinscli import conventions as cv
from sinscli.config import (DEFAULTS, SCHEMA, Config, ImuSection, Limits, NavigationSection, build_config,
                            load_config, override)
from sinscli.errors import SinsError
from sinscli.fusion.options import FUSION_DEFAULTS, build_fusion_options

ROOT = Path(__file__).resolve().parents[1]


def _refused(data, src="nav.yaml"):
    with pytest.raises(SinsError) as e:
        build_config(data, src)
    text = str(e.value)
    assert "\n" not in text
    return text


def test_the_shipped_file_is_the_defaults():
    """configs/navigation.yaml (every key documented) builds the same config as no file at all."""
    shipped = load_config(ROOT / "configs" / "navigation.yaml")
    default = load_config()
    for name in SCHEMA:
        assert getattr(shipped, name) == getattr(default, name), name
    assert default.limits == Limits() and default.navigation == NavigationSection()
    # every key of the schema is a field of its section and the other way round
    for name, keys in SCHEMA.items():
        assert [f.name for f in dataclasses.fields(getattr(default, name))] == list(keys), name


@pytest.mark.parametrize("data, message", [
    ({"imu": {"colour": 1}}, "nav.yaml: key imu.colour: unknown key; expected one of body, columns, "),
    ({"navigation": {"colour": 1}}, "nav.yaml: key navigation.colour: unknown key"),
    ({"sensors": {}}, "nav.yaml: key sensors: unknown section; expected one of align, fusion, gnss, imu"),
    ({"imu": {"units": {"speed": "m/s"}}}, "nav.yaml: key imu.units.speed: unknown key; expected one of accel, "),
])
def test_unknown_key(data, message):
    assert _refused(data).startswith(message)


@pytest.mark.parametrize("data, message", [
    ({"navigation": {"subsamples": "2"}}, "nav.yaml: key navigation.subsamples: expected a whole number from 1 to "
                                          "2147483647, got '2'"),
    ({"navigation": {"allow_gaps": "yes"}}, "nav.yaml: key navigation.allow_gaps: expected true or false, got 'yes'"),
    ({"gnss": {"lever_arm": 0.5}}, "nav.yaml: key gnss.lever_arm: expected a list of 3 numbers, got 0.5"),
    ({"gnss": {"lever_arm": [0, "a", 0]}}, "nav.yaml: key gnss.lever_arm[1]: expected a number in [-1000, 1000], "
                                           "got 'a'"),
    ({"imu": {"columns": []}}, "nav.yaml: key imu.columns: expected a mapping of keys, got []"),
    ({"imu": "flu"}, "nav.yaml: key imu: expected a mapping of keys, got 'flu'"),
    ({"ros": {"imu_topic": 5}}, "nav.yaml: key ros.imu_topic: expected a name (text) or null, got 5"),
])
def test_wrong_type(data, message):
    assert _refused(data) == message


@pytest.mark.parametrize("data, message", [
    ({"navigation": {"singularity_threshold": 1.5}}, "key navigation.singularity_threshold: expected a number in "
                                                     "(0, 1), got 1.5"),
    ({"navigation": {"every": 0}}, "key navigation.every: expected a whole number from 1 to 2147483647, got 0"),
    ({"limits": {"speed": 0}}, "key limits.speed: expected a number > 0, got 0"),
    ({"limits": {"height_min": 10.0, "height_max": 5.0}}, "key limits.height_min: expected a number below "
                                                          "limits.height_max (5.0), got 10.0"),
    ({"gnss": {"time_offset": 2e10}}, "key gnss.time_offset: expected a number of seconds within +-1e+10 (the "
                                      "config's limits.time), got 20000000000.0"),
    ({"gnss": {"lever_arm": [0, 0, 1001]}}, "key gnss.lever_arm[2]: expected a number in [-1000, 1000], got 1001"),
])
def test_out_of_range(data, message):
    assert _refused(data) == f"nav.yaml: {message}"


@pytest.mark.parametrize("data, message", [
    ({"navigation": {"coning": 5}}, "key navigation.coning: expected one of 1, 2, 3, 4, got 5"),
    ({"navigation": {"attitude": "rk45"}}, "key navigation.attitude: expected one of dcm, quat, krylov, euler, "
                                           "got 'rk45'"),
    ({"imu": {"body": "nwu"}}, "key imu.body: expected one of flu, rfu, frd, got 'nwu'"),
    ({"imu": {"units": {"gyro": "rpm"}}}, "key imu.units.gyro: expected one of rad/s, deg/s, deg/h, got 'rpm'"),
    ({"gnss": {"frame": "ecef"}}, "key gnss.frame: expected one of enu, ned, got 'ecef'"),
    ({"odometry": {"frame": "world"}}, "key odometry.frame: expected one of auto, body, vehicle, sensor, got 'world'"),
])
def test_choice_not_in_list(data, message):
    assert _refused(data) == f"nav.yaml: {message}"


def test_choices_are_case_insensitive_and_typed():
    cfg = build_config({"navigation": {"attitude": "DCM"}, "imu": {"body": "FRD"}, "gnss": {"lever_arm": [1, 2, 3]}})
    assert cfg.navigation.attitude == "dcm" and cfg.imu.body == "frd"
    assert cfg.gnss.lever_arm == (1.0, 2.0, 3.0) and all(type(x) is float for x in cfg.gnss.lever_arm)


def test_fusion_section_speaks_the_same_style():
    def refused(section):
        with pytest.raises(SinsError) as e:
            build_fusion_options(section, "nav.yaml")
        return str(e.value)
    assert refused({"zupt": {"sigma": 0}}) == "nav.yaml: key fusion.zupt.sigma: expected a number in (0, 10000], got 0"
    assert refused({"states": 18}) == "nav.yaml: key fusion.states: expected one of 15, 21, got 18"
    assert refused({"bias_model": "gm"}) == "nav.yaml: key fusion.bias_model: expected one of gm-noise, gm-decay, got 'gm'"
    assert refused({"zupt": {"colour": 1}}).startswith("nav.yaml: key fusion.zupt.colour: unknown key; expected one of ")
    assert refused({"adapt": {"window": 1}}) == ("nav.yaml: key fusion.adapt.window: expected a whole number from 2 "
                                                 "to 2147483647, got 1")
    with pytest.raises(SinsError, match=r"^command line: key fusion.vehicle: expected one of none, car, robot, "):
        build_fusion_options(None, "nav.yaml", vehicle="boat")
    assert set(FUSION_DEFAULTS) >= {"zupt", "states", "bias_model"}


def test_sections_are_frozen():
    cfg = load_config()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.navigation.coning = 4
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.imu = ImuSection()
    with pytest.raises(TypeError):                  # a mapping field is a read-only view
        cfg.imu.units["gyro"] = "deg/s"
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.limits.rate = 1.0
    fopts = build_fusion_options(None, "x")
    with pytest.raises(dataclasses.FrozenInstanceError):
        fopts.zupt = True


def test_override_by_replace_checks_like_the_yaml():
    cfg = build_config({"navigation": {"coning": 3}, "imu": {"body": "rfu"}}, "nav.yaml")
    new = override(cfg, "navigation", attitude="dcm", coning=None, every=4)
    # a new config: the original unchanged, the keys not given (None) kept, the other sections the same objects
    assert (cfg.navigation.attitude, cfg.navigation.every) == ("quat", 1)
    assert (new.navigation.attitude, new.navigation.coning, new.navigation.every) == ("dcm", 3, 4)
    assert new.imu is cfg.imu and new.limits is cfg.limits and isinstance(new, Config)
    assert new.navigation == dataclasses.replace(cfg.navigation, attitude="dcm", every=4)
    assert override(cfg, "navigation") is cfg
    with pytest.raises(SinsError, match=r"^command line: key navigation.every: expected a whole number from 1 to "):
        override(cfg, "navigation", every=0)
    with pytest.raises(SinsError, match=r"^command line: key gnss.time_offset: expected a number of seconds within "):
        override(cfg, "gnss", time_offset=1e11)         # against the config's limits.time
    with pytest.raises(SinsError, match=r"^command line: key navigation.colour: unknown key"):
        override(cfg, "navigation", colour="red")


def test_click_and_the_schema_share_the_choices():
    """The choices of the navigate and align options are the schema's tuples (sinscli.conventions)."""
    from sinscli.cli.align import align_cmd
    from sinscli.cli.navigate import navigate_cmd
    opts = {p.name: p for p in navigate_cmd.params}
    pairs = {"attitude": cv.ATTITUDES, "dcm_variant": cv.DCM_VARIANTS, "euler_integrator": cv.EULER_INTEGRATORS,
             "on_singularity": cv.ON_SINGULARITY, "frame": cv.NAV_FRAMES}
    for name, choices in pairs.items():
        assert isinstance(opts[name].type, click.Choice)
        assert tuple(opts[name].type.choices) == choices
        # and the schema's check refuses what click would refuse
        with pytest.raises(SinsError):
            SCHEMA["navigation"][name][1]("x", name, "nope")
        assert SCHEMA["navigation"][name][0] in choices
    assert tuple(opts["align_method"].type.choices) == cv.ALIGN_METHODS
    assert tuple(opts["vehicle"].type.choices) == cv.VEHICLES
    assert set(opts["body"].type.choices) == set(cv.BODY_NAMES) == set(cv.BODY_CONVENTIONS)
    assert tuple({p.name: p for p in align_cmd.params}["method"].type.choices) == cv.ALIGN_METHODS


def test_defaults_table_matches_the_sections():
    assert DEFAULTS["navigation"]["coning"] == NavigationSection().coning
    assert DEFAULTS["limits"] == dataclasses.asdict(Limits())


def test_bad_config_from_the_command_line_is_one_line_exit_2(tmp_path):
    (tmp_path / "c.yaml").write_text("navigation:\n  coning: 7\n")
    r = subprocess.run([sys.executable, "-c", "import sys; from sinscli.cli import main; main(sys.argv[1:], "
                        "prog_name='sins')", "navigate", str(ROOT / "sample_data" / "imu.csv"),
                        "--init", str(ROOT / "sample_data" / "init.yaml"), "--config", "c.yaml", "-o", "n.csv"],
                       cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr == "sins: error: c.yaml: key navigation.coning: expected one of 1, 2, 3, 4, " \
                                             "got 7\n"
    assert not (tmp_path / "n.csv").exists()


def test_a_config_pickles_and_its_mappings_are_read_only():
    """A config travels to a batch's workers: it pickles back equal; its mapping fields refuse changes."""
    import pickle
    cfg = build_config({"imu": {"columns": {"time": "t"}, "units": {"gyro": "deg/s"}},
                        "navigation": {"launch": {"lat": 30, "lon": 114, "height": 0, "azimuth": 90}}})
    assert pickle.loads(pickle.dumps(cfg)) == cfg
    for m in (cfg.imu.columns, cfg.imu.units, cfg.navigation.launch):
        with pytest.raises(TypeError):
            m.update(x=1)
        with pytest.raises(TypeError):
            m.pop(next(iter(m)))
    assert dict(cfg.imu.units) == {"gyro": "deg/s", "accel": "m/s^2", "dtheta": "rad", "dvel": "m/s"}


def test_the_sensor_description_is_read_once_into_a_typed_value(tmp_path):
    """fusion.sensor is read when the options are built (a bad one refused there, before any log is read), into
    a frozen SensorDescription whose values are the preset's in SI units; the filter takes that value."""
    import pickle
    import numpy as np
    from sinscli.fusion.pipeline import filter_model
    from sinscli.sensors import SensorDescription, load_sensor, read_sensor
    fopts = build_fusion_options({"sensor": "tactical"}, "nav.yaml")
    assert isinstance(fopts.sensor, SensorDescription) and fopts.sensor.source == "<preset tactical>"
    ref = load_sensor("tactical", None, "x", tmp_path)
    for which in ("gyro", "accel"):
        assert set(getattr(fopts.sensor, which)) == set(ref[which])
        for k, v in ref[which].items():
            assert np.array_equal(getattr(fopts.sensor, which)[k], v)
    with pytest.raises(ValueError):                 # read-only arrays
        fopts.sensor.gyro["arw"][0] = 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        fopts.sensor.source = "x"
    assert pickle.loads(pickle.dumps(fopts)).sensor.source == "<preset tactical>"
    m = filter_model(fopts.sensor, 15, "nav.yaml")
    assert np.allclose(m.arw2, ref["gyro"]["arw"] ** 2) and m.source == "<preset tactical>" and not m.default
    assert filter_model(None, 15, "nav.yaml").default
    (tmp_path / "imu.yaml").write_text("gyro: {arw: 0.1, bias_sigma: 10, bias_instability: 1, bias_tau: 100}\n"
                                       "accel: {vrw: 50, bias_sigma: 100, bias_instability: 10, bias_tau: 100}\n")
    own = build_fusion_options({"sensor": "imu.yaml"}, "nav.yaml", base_dir=tmp_path).sensor
    again = read_sensor("imu.yaml", "x", tmp_path)
    assert own.source == again.source == "imu.yaml"
    assert all(np.array_equal(own.gyro[k], again.gyro[k]) for k in again.gyro) and own.gyro["arw"][0] > 0
    with pytest.raises(SinsError, match=r"^nav.yaml: key fusion.sensor: no sensor preset or file 'nope.yaml'"):
        build_fusion_options({"sensor": "nope.yaml"}, "nav.yaml", base_dir=tmp_path)
