"""The installed package works from any directory: the ``sins`` console script of a non-editable install,
run from a temporary working directory outside the repository, on every shipped scenario, every batch
config (trimmed to seconds), the alignment scenarios, the README's commands and the sample-data recipe.

``python -m pytest`` from the repository root imports the source tree, so these tests run the console
script in a child process instead.  They need a non-editable install (``pip install ".[test]"``, as
``.ci/run`` does); with an editable one (a development venv) they are skipped with the reason printed
(``-rs`` is in the pytest options).  Under CI (``CI`` set) a missing install is a failure, not a skip.
"""
from __future__ import annotations

import filecmp
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
TRIM_S = 20.0            # batch scenarios are cut to their first 20 s


def _installed_sins() -> tuple[Path | None, str]:
    """The ``sins`` console script (beside this interpreter, else on PATH) when it runs a non-editable
    install, or why not.  Asked of the script's own interpreter from outside the repository: run from
    the repository root, Python would find the source tree (and the build's sinscli.egg-info) first."""
    found = Path(sys.executable).parent / "sins"
    script = found if found.is_file() else (Path(shutil.which("sins")) if shutil.which("sins") else None)
    if script is None:
        return None, "no sins console script beside this interpreter or on PATH (pip install '.[test]')"
    shebang = script.read_bytes().split(b"\n", 1)[0]
    python = shebang[2:].decode().strip() if shebang.startswith(b"#!") else sys.executable
    probe = ("import json, importlib.metadata as m, sinscli; d = m.distribution('sinscli'); "
             "print(json.dumps([sinscli.__file__, d.read_text('direct_url.json') or '{}']))")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    with tempfile.TemporaryDirectory() as cwd:
        p = subprocess.run([python, "-c", probe], cwd=cwd, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        return None, f"{script}: its interpreter cannot import sinscli ({p.stderr.strip()[-200:]})"
    file, direct = json.loads(p.stdout)
    if json.loads(direct).get("dir_info", {}).get("editable") or Path(file).resolve().parent == (ROOT / "sinscli").resolve():
        return None, f"{script} runs an editable install ({file}); these tests need pip install '.[test]'"
    return script, ""


@pytest.fixture(scope="module")
def sins():
    script, reason = _installed_sins()
    if script is None:
        if os.environ.get("CI"):
            pytest.fail(f"CI must run the installed-package tests: {reason}")
        pytest.skip(reason)
    return script


def run(sins: Path, args: list[str], cwd: Path, timeout: float = 600.0) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    p = subprocess.run([str(sins), *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                       stdin=subprocess.DEVNULL)
    assert p.returncode == 0, f"sins {' '.join(args)} (in {cwd}): exit {p.returncode}\n{p.stderr[-2000:]}"
    assert "Traceback" not in p.stderr
    return p


@pytest.fixture
def workdir(tmp_path):
    """A working directory outside the repository (pytest's temporary folders are)."""
    assert ROOT not in tmp_path.resolve().parents
    return tmp_path


def test_the_installed_package_is_used(sins, workdir):
    p = run(sins, ["--version"], workdir)
    assert "sins" in p.stdout


def test_readme_quick_start(sins, workdir):
    """The README's first command line, after its install step, in a fresh directory holding copies of
    sample_data/ and configs/ (the files the commands name)."""
    line = next(ln for ln in (ROOT / "README.md").read_text().splitlines() if "pip install" in ln and "sins " in ln)
    cmds = [c.strip() for c in line.split("&&") if c.strip().startswith("sins ")]
    assert len(cmds) == 2, cmds
    shutil.copytree(ROOT / "sample_data", workdir / "sample_data")
    shutil.copytree(ROOT / "configs", workdir / "configs")
    for c in cmds:
        run(sins, c.split()[1:], workdir)
    outputs = [c.split()[c.split().index("-o") + 1] for c in cmds]
    assert all((workdir / o).exists() for o in outputs) and (workdir / "report" / "index.html").is_file()
    table = (workdir / "report" / "errors.csv").read_text()
    assert "max_att_deg" in table


def test_sample_data_recipe_reproduces_the_shipped_files(sins, workdir):
    """sample_data/README.md's recipe, run by the installed script: the shipped files bit for bit."""
    recipe = re.search(r"^\s+(sins simulate .*)$", (ROOT / "sample_data" / "README.md").read_text(), re.M).group(1)
    args = recipe.split()[1:]
    args[1] = str(ROOT / args[1])                        # the scenario in the repository, output here
    run(sins, args + ["-q"], workdir)
    for name in ("imu.csv", "gnss.csv", "truth.csv", "init.yaml", "sim_truth.yaml"):
        assert filecmp.cmp(workdir / "sample_data" / name, ROOT / "sample_data" / name, shallow=False), name


@pytest.mark.parametrize("scenario", sorted(p.name for p in (ROOT / "configs" / "scenarios").glob("*.yaml")))
def test_every_shipped_scenario(sins, workdir, scenario):
    """Each scenario (its sensor preset read from the package data) simulated for 5 s and navigated."""
    run(sins, ["simulate", str(ROOT / "configs" / "scenarios" / scenario), "-o", "sim", "--duration", "5", "-q"],
        workdir)
    init = yaml.safe_load((workdir / "sim" / "init.yaml").read_text())
    frame = ["--frame", "launch-inertial"] if "j2" in (ROOT / "configs" / "scenarios" / scenario).read_text() else []
    run(sins, ["navigate", "sim/imu.csv", "--init", "sim/init.yaml", "-o", "nav.csv", "-q", *frame], workdir)
    run(sins, ["compare", "--truth", "sim/truth.csv", "nav.csv", "-o", "report", "-q"], workdir)
    assert (workdir / "report" / "index.html").is_file() and init["time"] is not None


def _trim_scenario(src: Path, dst: Path, seconds: float) -> None:
    data = yaml.safe_load(src.read_text())
    kept, total = [], 0.0
    for seg in data["segments"]:
        seg = dict(seg)
        d = float(seg.get("duration", 0.0))
        if total + d > seconds and "duration" in seg:
            seg["duration"] = max(seconds - total, 1.0)
            kept.append(seg)
            break
        kept.append(seg)
        total += d
    data["segments"] = kept
    if isinstance(data.get("gnss"), dict):
        data["gnss"].pop("outages", None)
    dst.write_text(yaml.safe_dump(data, sort_keys=False))


@pytest.mark.parametrize("batch", sorted(p.name for p in (ROOT / "configs" / "batch").glob("*.yaml")))
def test_every_batch_config(sins, workdir, batch):
    """Each batch config as shipped, with its scenarios cut to their first 20 s (same relative layout)."""
    (workdir / "configs" / "batch").mkdir(parents=True)
    (workdir / "configs" / "scenarios").mkdir()
    shutil.copy(ROOT / "configs" / "batch" / batch, workdir / "configs" / "batch" / batch)
    for sc in (ROOT / "configs" / "scenarios").glob("*.yaml"):
        _trim_scenario(sc, workdir / "configs" / "scenarios" / sc.name, TRIM_S)
    run(sins, ["compare", f"configs/batch/{batch}", "-o", "out", "--jobs", "2", "-q"], workdir)
    assert (workdir / "out" / "index.html").is_file() and (workdir / "out" / "summary.md").is_file()


@pytest.mark.parametrize("scenario", sorted(p.name for p in (ROOT / "configs" / "align").glob("seed001_*.yaml")))
def test_alignment_scenarios(sins, workdir, scenario):
    """The shipped alignment scenarios through the Monte Carlo command (2 runs)."""
    run(sins, ["align", "--monte-carlo", "2", "--scenario", str(ROOT / "configs" / "align" / scenario),
               "-o", "mc", "-q"], workdir)
    assert (workdir / "mc" / "summary.csv").is_file()
