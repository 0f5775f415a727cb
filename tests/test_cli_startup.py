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
