"""The first run a newcomer sees (issue 21): a fresh venv, ``pip install .``, every cache empty, then the README's
first command, cold, then once more warm (the baseline, in the same process).

    python benchmarks/bench_first_run.py [--keep DIR] [--pip-cache]

Prints the install's wall and CPU time and the venv's size, then for each command of the README's first
command line (``sins navigate ... --smooth`` and ``sins compare``) wall and CPU time cold and warm, whether it
compiled anything at run time (its compile note), with the load average beside every figure.  Caches cleared:
a new venv (no numba cache but the one the wheel ships), ``XDG_CACHE_HOME`` and ``NUMBA_CACHE_DIR`` unset to an
empty folder, pip's cache off unless ``--pip-cache`` (the local package index stays: it is the registry here).

Targets (issue 21): the README's first command <= 15 s wall on an idle 2-core machine, nothing compiled at run time.
"""
from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def readme_first_command() -> tuple[str, list[list[str]]]:
    """The README's first ``bash`` block: its install step and its ``sins`` commands (argument lists)."""
    text = (ROOT / "README.md").read_text()
    block = re.search(r"```bash\n(.*?)```", text, re.S).group(1).replace("\\\n", " ")
    steps = [s.strip() for s in block.split("&&")]
    install = next(s for s in steps if s.startswith("pip install"))
    return install, [shlex.split(s) for s in steps if s.startswith("sins ")]


def _timed(cmd, cwd, env):
    """(exit status, stderr, wall s, CPU s of the process and its children)."""
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=err)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return p.returncode, err.read().decode(errors="replace"), wall, ru.ru_utime + ru.ru_stime


def _load() -> str:
    return f"load {os.getloadavg()[0]:.1f}"


def _du(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink())


def run(work: Path, pip_cache: bool = False, echo=print) -> dict:
    """Install into ``work/venv`` and run the README's first command there twice; returns the figures."""
    install, commands = readme_first_command()
    venv = work / "venv"
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("NUMBA_", "VIRTUAL_ENV", "PYTHON", "SINS_NO_PRECOMPILE"))}   # the README's install
    env["XDG_CACHE_HOME"] = str(work / "xdg-cache")            # empty: no user-wide numba or pip cache
    if not pip_cache:
        env["PIP_NO_CACHE_DIR"] = "1"
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    res = {"install_cmd": install}
    echo(f"fresh venv, then `{install}` ({_load()})")
    code, err, wall, cpu = _timed([sys.executable, "-m", "venv", str(venv)], work, env)
    assert code == 0, err
    args = shlex.split(install)
    args = [str(venv / "bin" / "pip"), *args[1:-1], "--quiet", str(ROOT) if args[-1] == "." else args[-1]]
    code, err, wall2, cpu2 = _timed(args, work, env)
    if code != 0:
        raise RuntimeError(f"install failed: {err[-2000:]}")
    res.update(install_wall=wall + wall2, install_cpu=cpu + cpu2, venv_bytes=_du(venv),
               shipped_kernels=sum(1 for _ in (venv / "lib").rglob("sinscli/**/*.nbi")))
    echo(f"  install: {res['install_wall']:.0f} s wall, {res['install_cpu']:.0f} s CPU, venv {res['venv_bytes'] / 1e9:.2f} GB, "
         f"{res['shipped_kernels']} kernel indexes shipped ({_load()})")
    data = work / "run"
    data.mkdir()
    for name in ("sample_data", "configs"):
        shutil.copytree(ROOT / name, data / name)
    for label in ("cold", "warm"):
        total_wall = total_cpu = 0.0
        for cmd in commands:
            code, err, wall, cpu = _timed([str(venv / "bin" / cmd[0]), *cmd[1:]], data, env)
            if code != 0:
                raise RuntimeError(f"{' '.join(cmd[:2])} failed: {err[-2000:]}")
            compiled = "compiling" in err
            res[f"{label}:{cmd[1]}"] = (wall, cpu, compiled)
            total_wall += wall
            total_cpu += cpu
            echo(f"  {label} sins {cmd[1]:9s} {wall:6.2f} s wall {cpu:6.2f} s CPU  "
                 f"{'COMPILED at run time' if compiled else 'nothing compiled'} ({_load()})")
        res[f"{label}:total"] = (total_wall, total_cpu)
        echo(f"  {label} README first command: {total_wall:.2f} s wall, {total_cpu:.2f} s CPU ({_load()})")
    res["ratio"] = res["cold:total"][0] / res["warm:total"][0]
    echo(f"  cold / warm: {res['ratio']:.2f}x wall  (target: cold <= 15 s wall idle)")
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=Path, help="work folder to keep (default: a temporary one, removed)")
    ap.add_argument("--pip-cache", action="store_true", help="let pip use its cache (faster, less fresh)")
    a = ap.parse_args()
    if a.keep:
        a.keep.mkdir(parents=True, exist_ok=True)
        run(a.keep, a.pip_cache)
    else:
        with tempfile.TemporaryDirectory(prefix="sins-first-run-") as d:
            run(Path(d), a.pip_cache)


if __name__ == "__main__":
    main()
