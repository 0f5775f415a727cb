"""Error budget of the consumer car: the fused filter's outage RMS with each realism term of the scenario alone.

Run: ``python benchmarks/sim_error_budget.py [--jobs N] [--seed N] [--keep DIR] [--terms a,b] [--upper]``
(about 10 minutes on one core).

``configs/scenarios/consumer_car.yaml`` is simulated (``sins simulate``'s library call) as shipped ("all"),
with every realism term of docs/simulate.md "As hard as real logs" taken out ("none": the scenario before
them: consumer preset, engine vibration, jittered rates, mounting, clock offset, correlated RTK, outages),
and with each term alone on top of "none"; ``--upper`` adds all the terms at the upper end of their
plausible ranges (:data:`UPPER`).  Each log is navigated as a user runs it and as
``tests/test_fusion_reallogs.py`` does (``sins navigate imu.csv --gnss gnss.csv --init init.yaml --config
cfg.yaml --vehicle car``, the config giving the mounting, the IMU clock offset and the lever arm) with the
true sensor description (``fusion.sensor: consumer``) and with none, and the horizontal RMS inside the
fifteen 15 s outages is printed as a Markdown table (m), with the machine, its load and the wall time.
"""
from __future__ import annotations

import argparse
import copy
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import yaml

from sinscli.evaluate.fusion import outage_rms
from sinscli.io.trajectory import read_trajectory
from sinscli.sim.run import simulate, write_sim

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "configs" / "scenarios" / "consumer_car.yaml"
SINS = shutil.which("sins", path=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", "")) or "sins"

# term -> the scenario keys (section, key or None for the whole section) that make it
TERMS = {
    "quantization": [("imu", "quantization")],
    "g-sensitivity": [("imu", "g_sensitivity")],
    "vibration rectification": [("imu", "vibration_rectification")],
    "temperature drift": [("temperature", None)],
    "mount flex": [("mount_flex", None)],
    "sideslip": [("vehicle", None)],
    "dropped samples": [("imu", "dropped")],
    "RTK float": [("gnss", "float")],
    "RTK wrong fixes": [("gnss", "jumps")],
}


# the upper end of each term's plausible range for a phone-class IMU in a car (``--upper``), against the
# shipped typical values: gyro zero-rate drift 0.05 deg/s/K and accelerometer 1 mg/K (the larger datasheet
# figures of phone-class parts), a 20 K warm-up (a sunlit roof box), a phone holder's flex, 4 deg/g of slip,
# 1 % of the rows dropped in runs of 1-3
UPPER = {("temperature", "gyro"): [0.05, -0.04, 0.03], ("temperature", "accel"): [1.0, -0.8, 1.0],
         ("temperature", "rise"): 20, ("mount_flex", "roll"): 0.2, ("mount_flex", "pitch"): 0.15,
         ("mount_flex", "yaw"): 0.1, ("vehicle", "sideslip"): -4.0,
         ("imu", "dropped"): {"fraction": 0.01, "run": [1, 3]}}


def upper(sc: dict) -> dict:
    """The scenario with :data:`UPPER`'s values."""
    out = copy.deepcopy(sc)
    for (sec, key), v in UPPER.items():
        out.setdefault(sec, {})[key] = copy.deepcopy(v)
    return out


def _without(sc: dict, keys) -> dict:
    out = copy.deepcopy(sc)
    for sec, key in keys:
        if key is None:
            out.pop(sec, None)
        elif isinstance(out.get(sec), dict):
            out[sec].pop(key, None)
    return out


def _with(base: dict, full: dict, keys) -> dict:
    out = copy.deepcopy(base)
    for sec, key in keys:
        if key is None:
            if sec in full:
                out[sec] = copy.deepcopy(full[sec])
        elif key in full.get(sec, {}):
            out.setdefault(sec, {})[key] = copy.deepcopy(full[sec][key])
    return out


def cases(names=None, with_upper: bool = False) -> dict:
    """``{case name: scenario mapping}``: none, each term alone, all (and all at the upper end)."""
    full = yaml.safe_load(SCENARIO.read_text())
    base = _without(full, [k for ks in TERMS.values() for k in ks])
    out = {"none (before the realism terms)": base}
    for name, keys in TERMS.items():
        if names is None or name in names:
            out[f"{name} alone"] = _with(base, full, keys)
    out["all (shipped consumer_car)"] = full
    if with_upper:
        out["all, upper end of the ranges"] = upper(full)
    return out


def run_case(name: str, sc: dict, seed: int | None, workdir: str) -> tuple[str, dict]:
    """Simulate, navigate with the true and no sensor description; ``(name, {"true": m, "none": m, "s": s})``."""
    t0 = time.perf_counter()
    d = Path(workdir) / name.split(" ")[0].replace("/", "_")
    d.mkdir(parents=True, exist_ok=True)
    write_sim(simulate(sc, seed=seed), d)
    st = yaml.safe_load((d / "sim_truth.yaml").read_text())
    truth = read_trajectory(d / "truth.csv")
    out = {}
    for label, sensor in (("true", "consumer"), ("none", None)):
        cfg = {"imu": {"mounting": st["imu"]["mounting"], "time_offset": -st["imu"]["time_offset"]},
               "gnss": {"lever_arm": st["gnss"]["lever_arm"]}, "fusion": {} if sensor is None else {"sensor": sensor}}
        (d / f"cfg_{label}.yaml").write_text(yaml.safe_dump(cfg))
        r = subprocess.run([SINS, "navigate", "imu.csv", "--gnss", "gnss.csv", "--init", "init.yaml", "--config",
                            f"cfg_{label}.yaml", "-o", f"{label}.csv", "--vehicle", "car", "-q"],
                           cwd=d, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"{name}: sins navigate failed: {r.stderr.strip()}")
        out[label] = outage_rms(read_trajectory(d / f"{label}.csv"), truth, st["gnss"]["outages"])
    out["s"] = time.perf_counter() - t0
    return name, out


def _machine() -> str:
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (default 1)")
    ap.add_argument("--seed", type=int, default=None, help="seed of every case (default: the scenario's)")
    ap.add_argument("--keep", default=None, help="keep the simulated logs and outputs in this directory")
    ap.add_argument("--terms", default=None, help="comma-separated subset of: " + ", ".join(TERMS))
    ap.add_argument("--upper", action="store_true", help="also all terms at the upper end of their ranges")
    a = ap.parse_args(argv)
    names = None if a.terms is None else [t.strip() for t in a.terms.split(",")]
    todo = cases(names, a.upper)
    work = a.keep or tempfile.mkdtemp(prefix="sins_budget_")
    load0, t0 = os.getloadavg(), time.perf_counter()
    print(f"machine: {_machine()}; load average at the start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}",
          flush=True)
    results = {}
    if a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            for name, res in ex.map(run_case, todo, todo.values(), [a.seed] * len(todo), [work] * len(todo)):
                results[name] = res
                print(f"  {name}: {res['true']:.3f} / {res['none']:.3f} m ({res['s']:.0f} s)", flush=True)
    else:
        for name, sc in todo.items():
            _, res = run_case(name, sc, a.seed, work)
            results[name] = res
            print(f"  {name}: {res['true']:.3f} / {res['none']:.3f} m ({res['s']:.0f} s)", flush=True)
    load1 = os.getloadavg()
    print()
    print("| case | outage RMS, true description (m) | outage RMS, no description (m) |")
    print("|---|---|---|")
    for name, res in results.items():
        print(f"| {name} | {res['true']:.2f} | {res['none']:.2f} |")
    print()
    print(f"wall time {time.perf_counter() - t0:.0f} s, {a.jobs} job(s); load average at the end "
          f"{load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    if a.keep is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
