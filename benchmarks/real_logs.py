"""The fused filter on the real recordings that ship in tests/data, under every sensor description a user may
give (the shipped presets, none, the consumer preset 10x optimistic and 10x pessimistic in every sigma):

* the comma2k19 minute (phone IMU with its raw gyro, turn-on biases up to 3.9 deg/s; 10 Hz u-blox fixes,
  position only at 1 m; `--vehicle car`) with 5 s and 10 s outages cut in: the horizontal RMS inside the
  outages against the recording's reference pose, and the share of outage rows inside 3 sigma;
* the Husky bag as the README runs it (`configs/fusion/husky.yaml --vehicle robot --align gnss-inertial`):
  no truth, so the filter against itself: the fixes' mean NIS (3 degrees of freedom), the share of filtered
  rows whose 3 sigma covers the smoothed track (per axis and all three), fixes rejected, the largest step of
  the smoothed track beyond what its speed allows over one row.

    python benchmarks/real_logs.py [--only comma|husky] [--keep DIR]

The reference pose is the camera's (comma.ai's own optimizer): its lever arm and its clock against the IMU
are not given, so a constant offset in the car's forward and right axes and a constant time shift are fitted
outside the outages and removed (the figures are errors of the fused track's shape against the reference,
not of the camera's mounting).  The fixes are stamped at their epoch (`tests/realdata.py`); the GNSS-IMU
offset, +0.05 s, is what `fusion.estimate: [time_offset]` finds on the whole minute.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from realdata import HUSKY_BAG, comma2k19_csvs  # noqa: E402
from sinscli.io.trajectory import read_trajectory  # noqa: E402
from sinscli.sensors import preset_text  # noqa: E402

SIGMA_TERMS = ("arw", "vrw", "bias_sigma", "bias_instability", "scale_factor_sigma", "misalignment_sigma")
DESCRIPTIONS = ("none", "consumer", "mems", "tactical", "consumer_opt10", "consumer_pes10")
OUTAGES = {"5 s": [(15.0, 20.0), (30.0, 35.0), (45.0, 50.0)], "10 s": [(20.0, 30.0), (40.0, 50.0)]}
COMMA_TIME_OFFSET = 0.05          # s: gnss.time_offset, as the tool estimates it on the whole minute


def _sensor_file(d: Path, name: str):
    if name == "none":
        return None
    if name in ("consumer", "mems", "tactical"):
        return name
    f = 10.0 if name.endswith("opt10") else 0.1
    base = yaml.safe_load(preset_text("consumer"))
    desc = {w: {k: (v / f if k in SIGMA_TERMS else v) for k, v in base[w].items()} for w in ("gyro", "accel")}
    p = d / f"{name}.yaml"
    p.write_text(yaml.safe_dump(desc))
    return str(p)


def _sins(args, cwd):
    r = subprocess.run(["sins", *args], cwd=cwd, capture_output=True, text=True)
    return r.returncode, r.stderr


def _enu(lat0, lon0, lat, lon, h):
    a = 6378137.0
    return np.column_stack([(lon - lon0) * a * np.cos(lat0), (lat - lat0) * a, h])


def comma_errors(nav: Path, truth, outages, t0):
    """(outage horizontal RMS, share of outage rows inside 3 sigma E and N) against the reference."""
    tr = read_trajectory(nav)
    best = None
    inside_all = None
    for shift in np.arange(-0.3, 0.31, 0.01):                  # the reference's clock against the IMU's
        t = tr.time
        m = (t + shift >= truth.time[0]) & (t + shift <= truth.time[-1])
        tt = t[m] + shift
        lat = np.interp(tt, truth.time, truth.lat)
        lon = np.interp(tt, truth.time, np.unwrap(truth.lon))
        h = np.interp(tt, truth.time, truth.height)
        hd = np.arctan2(np.interp(tt, truth.time, truth.vel_n[:, 0]), np.interp(tt, truth.time, truth.vel_n[:, 1]))
        d = _enu(truth.lat[0], truth.lon[0], tr.lat[m], tr.lon[m], tr.height[m]) - \
            _enu(truth.lat[0], truth.lon[0], lat, lon, h)
        inside = np.zeros(len(tt), dtype=bool)
        for a, b in outages:
            inside |= (t[m] >= t0 + a) & (t[m] < t0 + b)
        # d_en = R(heading) [forward, right] + noise: the camera's constant offset in the car's axes
        A = np.zeros((2 * len(tt), 2))
        A[0::2, 0], A[0::2, 1] = np.sin(hd), np.cos(hd)
        A[1::2, 0], A[1::2, 1] = np.cos(hd), -np.sin(hd)
        y = d[:, :2].reshape(-1)
        w = np.repeat(~inside, 2)
        x = np.linalg.lstsq(A[w], y[w], rcond=None)[0]
        r = (y - A @ x).reshape(-1, 2)
        cost = float(np.mean(r[~inside] ** 2))
        if best is None or cost < best[0]:
            best = (cost, r, m)
            inside_all = inside
    _, r, m = best
    se, sn = tr.extra["pos_e_std"][m], tr.extra["pos_n_std"][m]
    ins = inside_all
    rms = float(np.sqrt(np.mean(r[ins, 0] ** 2 + r[ins, 1] ** 2)))
    cov = float(np.mean((np.abs(r[ins, 0]) <= 3 * se[ins]) & (np.abs(r[ins, 1]) <= 3 * sn[ins])))
    return rms, cov


def run_comma(work: Path):
    print("\ncomma2k19 minute, outages cut in, horizontal RMS inside them against the reference (m) "
          "[share of outage rows inside 3 sigma, E and N]")
    print(f"{'description':18s}" + "".join(f"{k:>22s}" for k in OUTAGES))
    rows = {}
    for label, outs in OUTAGES.items():
        d = work / f"comma_{label.replace(' ', '')}"
        paths = comma2k19_csvs(d, outages=outs)
        truth = read_trajectory(paths["truth"])
        t0 = float(np.loadtxt(paths["imu"], delimiter=",", skiprows=1, max_rows=1)[0])
        # the init: the reference's state at the IMU's first sample (the camera's attitude: the phone's axes)
        k = int(np.searchsorted(truth.time, t0))
        from sinscli.nav.rotation import dcm_to_euler
        rpy = np.degrees(dcm_to_euler(truth.Cbn[k], truth.body))
        init = {"time": float(t0), "lat": float(np.degrees(truth.lat[k])), "lon": float(np.degrees(truth.lon[k])),
                "height": float(truth.height[k]), "vel_e": float(truth.vel_n[k, 0]),
                "vel_n": float(truth.vel_n[k, 1]), "vel_u": float(truth.vel_n[k, 2]),
                "roll": float(rpy[0]), "pitch": float(rpy[1]), "heading": float(rpy[2] % 360.0)}
        (d / "init.yaml").write_text(yaml.safe_dump(init))
        for name in DESCRIPTIONS:
            cfg = {"imu": {"body": "frd"}, "gnss": {"time_offset": COMMA_TIME_OFFSET},
                   "fusion": {"gnss_pos_sigma": [1.0, 1.0, 2.0]}}
            sens = _sensor_file(d, name)
            if sens:
                cfg["fusion"]["sensor"] = sens
            (d / f"c_{name}.yaml").write_text(yaml.safe_dump(cfg))
            code, err = _sins(["navigate", "imu.csv", "--gnss", "gnss.csv", "--init", "init.yaml", "--config",
                               f"c_{name}.yaml", "--vehicle", "car", "-o", f"n_{name}.csv", "-q"], d)
            rows.setdefault(name, {})[label] = ("FAILED: " + err.strip().splitlines()[-1]) if code else \
                comma_errors(d / f"n_{name}.csv", truth, outs, t0)
    for name in DESCRIPTIONS:
        cells = []
        for label in OUTAGES:
            v = rows[name][label]
            cells.append(f"{v:>22s}" if isinstance(v, str) else f"{v[0]:>12.2f} [{100 * v[1]:4.0f} %]  ")
        print(f"{name:18s}" + "".join(cells))


def run_husky(work: Path):
    print("\nHusky bag as the README runs it: fixes' mean NIS (3 dof; target <= 6), filtered rows whose 3 sigma "
          "covers the smoothed track E/N/U/all (target 90 %), fixes rejected, largest smoothed step beyond the "
          "speed over one row (m)")
    d = work / "husky"
    d.mkdir(parents=True, exist_ok=True)
    bag = str(HUSKY_BAG)
    from sinscli.io.innovations import read_innovations
    for name in DESCRIPTIONS:
        sens = _sensor_file(d, name)
        extra = ["--sensor", sens] if sens else []
        cfg = str(ROOT / "configs/fusion/husky.yaml")
        base = ["navigate", bag, "--gnss", bag, "--config", cfg, "--vehicle", "robot", "--align", "gnss-inertial"]
        c1, e1 = _sins([*base, *extra, "-o", f"f_{name}.csv", "--innovations", f"i_{name}.csv"], d)
        c2, e2 = _sins([*base, *extra, "--smooth", "-o", f"s_{name}.csv"], d)
        if c1 or c2:
            print(f"{name:18s} FAILED: {(e1 if c1 else e2).strip().splitlines()[-1]}")
            continue
        f = read_trajectory(d / f"f_{name}.csv")
        s = read_trajectory(d / f"s_{name}.csv")
        rec = read_innovations(d / f"i_{name}.csv")
        g = rec[rec["type"] == "gnss_pos"]
        nis = float(np.mean(g["nis"][0::3]))
        rej = int((~g["accepted"]).sum()) // 3
        a = 6378137.0
        de = (f.lon - s.lon) * a * np.cos(f.lat[0])
        dn = (f.lat - s.lat) * a
        du = f.height - s.height
        c = [np.abs(x) <= 3 * f.extra[k] for x, k in ((de, "pos_e_std"), (dn, "pos_n_std"), (du, "pos_u_std"))]
        cov = [float(np.mean(x)) for x in c] + [float(np.mean(c[0] & c[1] & c[2]))]
        e = (s.lon - s.lon[0]) * a * np.cos(s.lat[0])
        n = (s.lat - s.lat[0]) * a
        step = np.hypot(np.diff(e), np.diff(n)) - np.hypot(s.vel_n[1:, 0], s.vel_n[1:, 1]) * np.diff(s.time)
        print(f"{name:18s} NIS {nis:5.2f}  cover {' / '.join(f'{100 * x:3.0f}' for x in cov)} %  rejected {rej:3d}  "
              f"step {float(step.max()):6.2f} m")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", choices=("comma", "husky"))
    ap.add_argument("--keep", type=Path, help="keep the runs in this folder")
    a = ap.parse_args()
    work = a.keep or Path(tempfile.mkdtemp(prefix="sins_real_"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        if a.only in (None, "comma"):
            run_comma(work)
        if a.only in (None, "husky"):
            run_husky(work)
    finally:
        if a.keep is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
