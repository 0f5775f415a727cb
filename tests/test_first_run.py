"""The first `sins navigate` of a package without numba's cache (a source copy; `pip install .` ships the
cache, `_build/precompile.py`): it says it compiles, once, and the second run is silent about compiling and
costs less than half the first.  How long the compile takes is a property of the machine: the test prints it
and does not assert it (the first command of an installed package, which ships the cache, is
`tests/test_first_run_install.py`'s).

The figure is CPU time (user + system) of the `sins navigate` process: numba compiles on one thread, so on
an idle machine its wall time is the same, while on the shared 2-core machine (other jobs running) the wall
time measures the other jobs.  Both are printed (``pytest -s``), with the load.
"""
import compileall
import os
import resource
import shutil
import site
import subprocess
import sys
import time

import pytest
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _run(args, cwd, env):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-S", "-c", "from sinscli.cli.base import main; main()", *args], cwd=cwd,
                       env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return r, wall, cpu


@pytest.mark.slow
def test_first_navigate_compiles_once_and_says_so(tmp_path):
    pkg = tmp_path / "install"
    shutil.copytree(ROOT / "sinscli", pkg / "sinscli", ignore=shutil.ignore_patterns("__pycache__", "*.nb[ic]"))
    # byte-compiled as pip does on install (no numba cache files: those come only from a run)
    assert compileall.compile_dir(pkg / "sinscli", quiet=1)
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    # -S: no .pth files, so an editable install of the source tree does not shadow the copy; the
    # dependencies come from site-packages on PYTHONPATH after it
    env.update(PYTHONPATH=os.pathsep.join([str(pkg), *site.getsitepackages()]), NUMBA_CACHE_DIR=str(cache))
    args = ["navigate", str(ROOT / "sample_data" / "imu.csv"), "--init", str(ROOT / "sample_data" / "init.yaml"),
            "-o", "nav.csv"]
    load = os.getloadavg()[0]
    r, wall, cpu = _run(args, tmp_path, env)
    assert r.returncode == 0, r.stderr
    import_check = subprocess.run([sys.executable, "-S", "-c", "import sinscli; print(sinscli.__file__)"], env=env, cwd=tmp_path,
                                  capture_output=True, text=True, check=True)
    assert import_check.stdout.strip().startswith(str(pkg))          # the copy ran, not the source tree
    lines = r.stderr.strip().splitlines()
    assert lines[0].startswith("sins: compiling navigation kernels (first run only, about "), r.stderr
    assert sum("compiling" in ln for ln in lines) == 1, r.stderr     # the generic note is not added to it
    assert lines[-1].startswith("sins: navigated ") and "wrote 18,001 rows" in lines[-1], r.stderr
    assert any(cache.rglob("*.nbi"))                                   # compiled into the empty cache
    figure = (f"first sins navigate (fresh copy, empty cache): {cpu:.1f} s CPU, {wall:.1f} s wall, "
              f"load average {load:.1f} on {os.cpu_count()} CPUs")
    print("\n" + figure)

    r2, wall2, cpu2 = _run(args, tmp_path, env)
    assert r2.returncode == 0, r2.stderr
    assert "compiling" not in r2.stderr                                # warm cache: no message
    assert r2.stderr.strip().splitlines()[-1] == lines[-1]
    print(f"second run (warm cache): {cpu2:.1f} s CPU, {wall2:.1f} s wall")
    assert cpu2 < cpu / 2
