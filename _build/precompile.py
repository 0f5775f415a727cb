"""Compile the numba kernels of a freshly built package into its own ``__pycache__`` folders (issue 21).

Run by ``setup.py``'s ``build_py`` (``pip install .``) as ``python _build/precompile.py BUILD_LIB``: the
package copy under ``BUILD_LIB`` runs the commands a user runs first, on the shipped sample data, so that
numba writes every kernel a command needs (``@njit(cache=True)``) beside its source in ``BUILD_LIB``.
The wheel carries those cache files; installed, numba's in-tree locator finds them at run time (its
source stamp is the source file's content hash, so the new modification times of an install do not
matter; the index also names the numba version, the Python byte code of each kernel and the CPU).

Nothing here is needed at run time: a kernel missing from the shipped cache (another numba, another CPU,
an input type no workload below met) is compiled on first use as before, with its progress line.

Workloads run as separate processes, two at a time (the kernels they share are written atomically by
numba; a second compile of the same kernel only wastes time).  Each prints one line with its time.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent          # the source tree (sample_data/, configs/)
S = str(SRC / "sample_data")
IMU, GNSS, INIT, TRUTH = f"{S}/imu.csv", f"{S}/gnss.csv", f"{S}/init.yaml", f"{S}/truth.csv"

# Lanes run in parallel; each lane's steps run in order (a later step may read an earlier one's output).
# Lane 1 is the README's first command (navigate fused and smoothed, then compare), the longest compile.
LANES = [
    [["navigate", IMU, "--gnss", GNSS, "--init", INIT, "--config", str(SRC / "configs/fusion/sample.yaml"),
      "--vehicle", "car", "--smooth", "-o", "fused.csv"],
     ["compare", "--truth", TRUTH, "fused.csv", "-o", "report"],
     ["navigate", IMU, "--gnss", GNSS, "--init", INIT, "-o", "fused_plain.parquet"]],
    [["navigate", IMU, "--init", INIT, "-o", "nav.csv"],
     ["navigate", IMU, "--init", INIT, "-o", "nav.parquet"],
     ["navigate", IMU, "--init", INIT, "--attitude", "dcm", "-o", "dcm.csv"],
     ["navigate", IMU, "--init", INIT, "--attitude", "dcm", "--dcm-variant", "seed000", "-o", "dcm0.csv"],
     ["navigate", IMU, "--init", INIT, "--attitude", "krylov", "-o", "krylov.csv"],
     ["navigate", IMU, "--init", INIT, "--attitude", "euler", "-o", "euler.csv"],
     ["navigate", IMU, "--init", INIT, "--attitude", "euler", "--euler-integrator", "euler", "-o", "euler1.csv"],
     ["navigate", IMU, "--init", INIT, "--frame", "launch-inertial", "-o", "li.csv"],
     ["align", IMU, "--method", "static", "--duration", "50", "--position", "30,114,50", "--heading", "30", "-o", "a_static.yaml"],
     ["align", IMU, "--method", "inertial", "--duration", "50", "--position", "30,114,50", "--heading", "30", "-o", "a_inertial.yaml"],
     ["align", IMU, "--method", "kf", "--duration", "50", "--position", "30,114,50", "--heading", "30", "-o", "a_kf.yaml"],
     ["align", IMU, "--gnss", GNSS, "--method", "gnss-inertial", "-o", "a_gi.yaml"],
     ["allan", IMU, "--end", "60", "-o", "allan"],
     ["simulate", str(SRC / "configs/scenarios/vehicle_drive.yaml"), "--duration", "30", "--raw-gnss",
      str(SRC / "configs/raw_gnss/urban.yaml"), "-o", "sim"],
     ["gnss", "spp", "sim/obs.rnx", "--nav", "sim/nav.rnx", "-o", "spp.csv"],
     ["convert", str(SRC / "_build/receiver_sample.nmea"), "-o", "nmea.csv"]],     # the NMEA kernels
]


def _run(args, work: Path, env: dict):
    """One command, its exit status, stderr and CPU seconds (user + system, from wait4)."""
    with tempfile.TemporaryFile() as err:
        p = subprocess.Popen([sys.executable, "-c", "from sinscli.cli.base import main; main()", *args, "-q"],
                             cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=err)
        _, status, ru = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return p.returncode, err.read().decode(errors="replace"), ru.ru_utime + ru.ru_stime


def _run_lane(lane, work: Path, env: dict) -> None:
    for args in lane:
        t0 = time.perf_counter()
        code, err, cpu = _run(args, work, env)
        what = " ".join(a if not a.startswith(str(SRC)) else Path(a).name for a in args[:4])
        status = "ok" if code == 0 else f"exit {code}: {err.strip().splitlines()[-1:]}"
        print(f"  {time.perf_counter() - t0:6.1f} s wall {cpu:6.1f} s CPU  sins {what} ... {status}", flush=True)


def main(build_lib: str) -> int:
    pkg = Path(build_lib) / "sinscli"
    if not pkg.is_dir():
        print(f"precompile: no package at {pkg}", file=sys.stderr)
        return 1
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}   # the in-tree locator
    env["PYTHONPATH"] = os.pathsep.join([str(Path(build_lib).resolve()), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PYTHONDONTWRITEBYTECODE"] = "1"          # only numba's files go into the build tree
    env["MPLBACKEND"] = "Agg"
    t0 = time.perf_counter()
    print(f"precompile: compiling the kernels into {pkg} (two lanes; minutes on a loaded machine)", flush=True)
    work = Path(tempfile.mkdtemp(prefix="sins-precompile-"))
    try:
        lanes = []
        for i, lane in enumerate(LANES):
            d = work / f"lane{i}"
            d.mkdir()
            lanes.append((lane, d))
        with ThreadPoolExecutor(len(lanes)) as pool:
            list(pool.map(lambda ld: _run_lane(ld[0], ld[1], env), lanes))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    n = sum(1 for _ in pkg.rglob("*.nbi"))
    load = os.getloadavg()[0]
    print(f"precompile: {n} kernel indexes in {time.perf_counter() - t0:.0f} s (load average {load:.1f})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
