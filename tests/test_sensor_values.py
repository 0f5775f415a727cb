"""Sensor descriptions with a bad value (sinscli/sensors.py): a zero, negative or non-finite sigma was
taken as it was.  Now: one line naming the file and the key, exit 2, nothing written.  Which terms may be
0: ``bias_sigma`` (``sins allan`` writes it so: unknown), ``scale_factor_sigma`` and ``misalignment_sigma``
(perfect axes), ``quantization`` (none); the white noise (``arw``, ``vrw``) and ``bias_instability`` may not."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from test_contract import refused

from sinscli.sensors import load_sensor, preset_text

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"


def _description(which, key, value):
    d = yaml.safe_load(preset_text("mems"))
    d[which][key] = value
    return yaml.safe_dump(d).replace("'.nan'", ".nan").replace("'.inf'", ".inf").replace("'-.inf'", "-.inf")


@pytest.mark.parametrize("which, key, value, expect", [
    ("gyro", "arw", 0, "expected numbers > 0 (white noise"),
    ("gyro", "arw", -0.3, "expected numbers > 0 (white noise"),
    ("accel", "vrw", ".nan", "'.nan' is not a finite number"),
    ("accel", "vrw", ".inf", "'.inf' is not a finite number"),
    ("gyro", "bias_instability", 0, "expected numbers > 0 (every sensor's bias wanders"),
    ("accel", "bias_instability", "-.inf", "'-.inf' is not a finite number"),
    ("gyro", "bias_sigma", -360, "expected numbers >= 0, got -360"),
    ("accel", "scale_factor_sigma", ".nan", "'.nan' is not a finite number"),
    ("gyro", "misalignment_sigma", -1, "expected numbers >= 0, got -1"),
    ("gyro", "quantization", ".inf", "'.inf' is not a finite number"),
])
def test_a_bad_sigma_is_refused_naming_file_and_key(tmp_path, which, key, value, expect):
    path = tmp_path / "imu_model.yaml"
    path.write_text(_description(which, key, value))
    out = tmp_path / "out"
    out.mkdir()
    where = "line" if "finite" in expect else "key"     # the YAML reader names the line of a .nan or .inf
    line = refused(["navigate", SAMPLE / "imu.csv", "--gnss", SAMPLE / "gnss.csv", "--init", SAMPLE / "init.yaml",
                    "--sensor", path, "-o", out / "f.csv"], f"imu_model.yaml: {where}", f"{which}.{key}", expect)
    assert list(out.iterdir()) == [], line


@pytest.mark.parametrize("value", [float("nan"), float("inf"), 0.0, -1.0])
def test_an_inline_description_is_checked_the_same(value):
    """A mapping (a config's fusion.sensor, a scenario's imu.sensor) goes through the same checks."""
    from sinscli.errors import SinsError
    d = yaml.safe_load(preset_text("mems"))
    d["accel"]["vrw"] = value
    with pytest.raises(SinsError, match=r"^cfg.yaml: key accel\.vrw: expected (finite numbers|numbers > 0)"):
        load_sensor(d, None, "cfg.yaml", ROOT)


def test_the_zeros_that_mean_something_are_accepted():
    d = yaml.safe_load(preset_text("mems"))
    for which in ("gyro", "accel"):
        d[which].update(bias_sigma=0, scale_factor_sigma=0, misalignment_sigma=0, quantization=0)
    s = load_sensor(d, None, "t", ROOT)
    assert float(s["gyro"]["bias_sigma"].max()) == 0.0 and float(s["accel"]["quantization"].max()) == 0.0
    assert float(s["gyro"]["arw"].min()) > 0.0
