"""Start-up of the command line (issue 14, section 3): help texts without numpy, numba or the simulator.

Deterministic checks on the modules a fresh interpreter loads (the timing itself is
``benchmarks/bench_startup.py``), and the listing of ``sins --help`` against the one click makes
from the commands themselves.
"""
import json
import subprocess
import sys
from pathlib import Path

import pytest

HEAVY = ("numpy", "numba", "pandas", "pyarrow", "yaml", "sinscli.sim", "sinscli.nav", "sinscli.io")

_PROBE = """
import json, sys
from sinscli.cli import main
try:
    main(sys.argv[1:], prog_name="sins")
except SystemExit as e:
    code = e.code
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def _probe(*args):
    r = subprocess.run([sys.executable, "-c", _PROBE, *args], capture_output=True, text=True, check=True)
    lines = r.stdout.strip().splitlines()
    return "\n".join(lines[:-1]), json.loads(lines[-1])


@pytest.mark.parametrize("args", [["--help"], ["navigate", "--help"], ["simulate", "--help"],
                                  ["compare", "--help"], ["allan", "--help"], ["info", "--help"]], ids=" ".join)
def test_help_loads_no_heavy_module(args):
    text, res = _probe(*args)
    assert res["code"] == 0 and "Usage: sins" in text
    loaded = [m for m in res["modules"] if any(m == h or m.startswith(h + ".") for h in HEAVY)]
    assert loaded == [], loaded


def test_import_of_the_command_line_loads_no_heavy_module():
    r = subprocess.run([sys.executable, "-c", "import sys, sinscli.cli; print('\\n'.join(sys.modules))"],
                       capture_output=True, text=True, check=True)
    mods = set(r.stdout.split())
    assert "click" in mods and not mods & {"numpy", "numba", "sinscli.nav", "sinscli.sim"}


def test_listing_equals_the_one_click_makes_from_the_commands():
    """SHORT_HELP cannot drift from the commands' docstrings: compare with every command imported."""
    fast, _ = _probe("--help")
    code = ("import importlib, click\n"
            "from sinscli.cli import base\n"
            "for m in base.COMMANDS.values():\n"
            "    importlib.import_module('sinscli.cli.' + m)\n"
            "base.main.format_commands = click.Group.format_commands.__get__(base.main)\n"
            "base.main(['--help'], prog_name='sins')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert fast == r.stdout.strip()
    from sinscli.cli.base import COMMANDS, SHORT_HELP
    assert set(SHORT_HELP) == set(COMMANDS)
    for name in COMMANDS:
        assert f"\n  {name} " in fast


def test_installed_console_script_help(tmp_path):
    exe = Path(sys.executable).parent / "sins"
    if not exe.exists():
        pytest.skip("no installed sins console script next to this interpreter")
    r = subprocess.run([str(exe), "--help"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0 and "navigate  Navigate IMU increments" in r.stdout
    r = subprocess.run([str(exe), "navigate", "--help"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0 and "[flu|frd|rfu]" in r.stdout


@pytest.mark.parametrize("module, heavy", [
    ("sinscli", ["numba", "numpy"]),                                     # _numba_cache: numba's event on demand
    ("sinscli.report.report", ["pandas", "scipy.stats", "sinscli.fusion.pipeline"]),   # compare_page, tables
    ("sinscli.batch.exec", ["distributed", "psutil"]),                  # the optional Dask extra
    ("sinscli.config", ["scipy.spatial"]),                                # Rotation only for a mounting
], ids=lambda x: x if isinstance(x, str) else "")
def test_function_local_imports_keep_their_modules_out(module, heavy):
    """What the function-local imports (each with its reason, tests/test_layers.py) save: importing the
    module does not load these (the time saved: python -X importtime, benchmarks/bench_startup.py)."""
    r = subprocess.run([sys.executable, "-c", f"import sys, {module}; print('\\n'.join(sys.modules))"],
                       capture_output=True, text=True, check=True)
    assert not set(r.stdout.split()) & set(heavy)


@pytest.mark.parametrize("command", ["align", "convert"])
def test_help_of_the_reader_commands_loads_no_stage(command):
    """``align`` and ``convert`` import their readers at module level (numpy, numba); their stages, the plots and
    the batch machinery load only when they run (the function-local imports of cli/align.py, cli/convert.py)."""
    text, res = _probe(command, "--help")
    assert res["code"] == 0 and "Usage: sins" in text
    stages = ("matplotlib", "pandas", "sinscli.align", "sinscli.batch", "sinscli.report", "sinscli.sim",
              "sinscli.fusion")
    assert [m for m in res["modules"] if any(m == h or m.startswith(h + ".") for h in stages)] == []


def test_plain_navigate_loads_no_scipy(tmp_path):
    """Issue 21: a plain `sins navigate` (kernels compiled or loaded from the cache, CSV and Parquet out) never
    imports SciPy.  numba would (its version check at import, and ``scipy.linalg`` from the CPU target's
    BLAS probe when it loads a cached kernel: 0.2 s); ``sinscli._numba_cache.lean_numba`` keeps both out."""
    root = Path(__file__).resolve().parent.parent
    code = ("import sys\nfrom sinscli.cli.base import main\n"
            "try:\n    main(sys.argv[1:], prog_name='sins')\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
            "print(sorted(m for m in sys.modules if (m == 'scipy' or m.startswith('scipy.')) and sys.modules[m]))\n")
    for out in ("nav.csv", "nav.parquet"):
        r = subprocess.run([sys.executable, "-c", code, "navigate", str(root / "sample_data" / "imu.csv"), "--init",
                            str(root / "sample_data" / "init.yaml"), "-o", out, "-q"],
                           cwd=tmp_path, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        assert r.stdout.strip().splitlines()[-1] == "[]", r.stdout
        assert (tmp_path / out).stat().st_size > 0


def test_lean_numba_keeps_linear_algebra_working():
    """With numba imported through ``sinscli`` (SciPy hidden at its import), a kernel that calls LAPACK still
    compiles and gives numpy's answer; SciPy is imported then, by numba, for that kernel only."""
    code = """if True:
        import sys, sinscli, numpy as np
        from numba import njit
        assert 'scipy.linalg' not in sys.modules
        f = njit(lambda a: np.linalg.solve(a, np.ones(3)))
        a = np.array([[4.0, 1, 0], [1, 3, 1], [0, 1, 2]])
        assert np.allclose(f(a), np.linalg.solve(a, np.ones(3)), rtol=0, atol=1e-15)
        print('scipy.linalg' in sys.modules)
    """
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "True"


def test_commands_run_one_blas_thread_unless_the_user_says():
    """Issue 21: OpenBLAS's threads spin on vectors of ~10,000 (25x the CPU of one thread under load); the command
    line sets one thread before numpy loads, and a user's OPENBLAS_NUM_THREADS is kept."""
    import os
    code = "import sinscli.cli, os, numpy; print(os.environ['OPENBLAS_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert r.stdout.strip() == "1"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(env, OPENBLAS_NUM_THREADS="3"),
                       check=True)
    assert r.stdout.strip() == "3"
