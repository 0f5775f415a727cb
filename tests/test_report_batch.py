"""Batch YAML validation (``sins compare BATCH.yaml``): each bad key is named, exit 2, nothing written."""
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.batch.compare import count_jobs, default_method_name, load_batch

REPO = Path(__file__).resolve().parents[1]


def write_batch(tmp_path, data) -> Path:
    for name in ("imu.csv", "truth.csv", "init.yaml", "scen.yaml"):
        (tmp_path / name).write_text("x\n")
    p = tmp_path / "batch.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


GOOD = {
    "title": "t",
    "datasets": [{"scenario": "scen.yaml", "perfect": True},
                 {"name": "files", "imu": "imu.csv", "truth": "truth.csv", "init": "init.yaml"}],
    "methods": [{"name": "quat", "attitude": "quat", "coning": 2},
                {"attitude": "dcm", "dcm_variant": "seed000", "coning": 1}],
    "seeds": 3,
}


def test_good_batch_loads(tmp_path):
    spec = load_batch(write_batch(tmp_path, GOOD))
    assert [d.name for d in spec.datasets] == ["scen", "files"]
    assert spec.datasets[0].scenario == tmp_path / "scen.yaml" and spec.datasets[0].perfect
    assert spec.datasets[1].truth == tmp_path / "truth.csv"
    assert [m.name for m in spec.methods] == ["quat", "dcm-seed000-c1"]
    assert spec.methods[1].navigation["dcm_variant"] == "seed000"
    assert spec.methods[1].navigation["subsamples"] == 1          # defaults filled in
    assert spec.seeds == [0, 1, 2]
    # 3 seeds of the scenario + 1 files dataset, each navigated with 2 methods; 2 reports, 1 summary.
    assert count_jobs(spec) == 4 * 2 + 2 + 1


def test_default_method_names():
    base = {"attitude": "quat", "dcm_variant": "exact", "coning": 2, "subsamples": 1, "frame": "enu"}
    assert default_method_name(base) == "quat-c2"
    assert default_method_name(dict(base, attitude="dcm", dcm_variant="seed000", coning=1)) == "dcm-seed000-c1"
    assert default_method_name(dict(base, subsamples=4, frame="launch-inertial")) == "quat-c2-s4-launch-inertial"


@pytest.mark.parametrize("change, pattern", [
    (lambda d: d.update(colour="red"), r"batch\.yaml: colour: unknown key"),
    (lambda d: d.update(methods=[]), r"batch\.yaml: methods: expected a non-empty list"),
    (lambda d: d["methods"][1].update(coning=5), r"batch\.yaml: methods\[1\]\.coning: expected one of 1, 2, 3, 4"),
    (lambda d: d["methods"][0].update(atitude="quat"), r"methods\[0\]\.atitude: unknown key"),
    (lambda d: d["methods"][0].update(subsamples=0), r"methods\[0\]\.subsamples: expected a whole number"),
    (lambda d: d["methods"][1].update(name="quat"), r"methods\[1\]\.name: duplicate name 'quat'"),
    (lambda d: d["datasets"][0].update(scenario="nope.yaml"), r"datasets\[0\]\.scenario: file not found"),
    (lambda d: d["datasets"][0].update(perfect="yes"), r"datasets\[0\]\.perfect: expected true or false"),
    (lambda d: d["datasets"][1].pop("init"), r"datasets\[1\]\.init: missing"),
    (lambda d: d["datasets"][1].update(gnss="g.csv"), r"datasets\[1\]\.gnss: unknown key"),
    (lambda d: d["datasets"][1].update(name="a/b"), r"datasets\[1\]\.name: expected a name"),
    (lambda d: d.update(seeds=[1, 1]), r"batch\.yaml: seeds: expected a count"),
    (lambda d: d.update(seeds=0), r"batch\.yaml: seeds: expected a count >= 1"),
    (lambda d: d.update(epoch="end"), r"batch\.yaml: epoch: expected a time"),
    (lambda d: d.update(timeseries_every=0), r"timeseries_every: expected a whole number"),
])
def test_bad_batch_names_the_key(tmp_path, change, pattern):
    import copy
    data = copy.deepcopy(GOOD)
    change(data)
    path = write_batch(tmp_path, data)
    with pytest.raises(SinsError, match=pattern):
        load_batch(path)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["compare", str(path), "-o", str(out), "-q"])
    assert r.exit_code == 2, r.output
    assert "sins: error:" in r.output and "batch.yaml" in r.output
    assert not out.exists()


def test_batch_cli_refuses_single_mode_options(tmp_path):
    path = write_batch(tmp_path, GOOD)
    r = CliRunner().invoke(main, ["compare", str(path), "--epoch", "3", "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--epoch: not used with a batch file" in r.output


def test_shipped_batches_are_valid():
    for name in ("seed000.yaml", "methods.yaml"):
        path = REPO / "configs" / "batch" / name
        spec = load_batch(path)
        assert spec.datasets and spec.methods
        for d in spec.datasets:
            assert d.scenario is not None and d.scenario.exists()


def test_monte_carlo_table_rms_and_max():
    import pandas as pd

    from sinscli.batch.compare_report import mc_table
    from sinscli.evaluate.errors import ROW_UNITS, ROWS
    from sinscli.evaluate.stats import row_statistics
    vals = np.zeros((len(ROWS), 4))
    pos_e, max_att = ROWS.index("pos_E"), ROWS.index("max_att_deg")
    vals[pos_e] = [3.0, -4.0, 1.0, 1.0]          # a#s0, a#s1, b#s0, b#s1
    vals[max_att] = [0.1, 0.3, 0.2, 0.05]
    frame = pd.DataFrame({"method": ["a", "a", "b", "b"], **{r: vals[i] for i, r in enumerate(ROWS)}})
    mc = mc_table(row_statistics(frame, "method", ROWS, ROW_UNITS), 1.0)
    assert mc.methods == ["a", "b"]
    np.testing.assert_allclose(mc.values[pos_e], [np.sqrt(12.5), 1.0], rtol=1e-15)
    np.testing.assert_allclose(mc.values[max_att], [0.3, 0.2], rtol=0)
