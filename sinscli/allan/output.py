"""Writers of ``sins allan``: ``sensor.yaml``, ``allan.csv``, ``fit.csv`` and ``allan.png`` (each atomically,
every number through the writer guard :func:`sinscli.io.atomic.check_finite`)."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..io.atomic import atomic_path, check_finite
from ..sensors import ACCEL_UNITS, GYRO_UNITS
from .fit import GM_PEAK_RATIO, GM_PEAK_X, gm_avar
from .pipeline import AXES, AllanResult, sensor_values

_DEG_H = GYRO_UNITS["bias_instability"]       # rad/s per deg/h
_UG = ACCEL_UNITS["bias_instability"]         # m/s^2 per micro-g


def _r(x) -> str:
    return repr(float(x))


def _scalar(text: str) -> str:
    """``text`` as a YAML scalar that reads back as the same string (quoted where plain would not)."""
    try:
        plain = yaml.safe_load(text) == text and "\n" not in text and "#" not in text
    except yaml.YAMLError:
        plain = False
    return text if plain else json.dumps(text)


def _list(v) -> str:
    return "[" + ", ".join(f"{float(x):.6g}" for x in v) + "]"


def sensor_yaml_text(res: AllanResult, name: str) -> str:
    """The sensor description in the schema and units of ``sinscli/data/sensors/*.yaml``, with comments."""
    v = sensor_values(res.fits)
    lines = [f"# Sensor description measured by sins allan from {res.source}",
             f"# ({res.n} samples at {1.0 / res.tau0:.6g} Hz, {res.duration / 3600.0:.4g} h from t = {res.t_start:.6g} s).",
             "# Units: gyro deg/h, deg/sqrt(h), rad; accel micro-g, micro-g/sqrt(Hz), m/s (as the shipped presets).",
             "# bias_instability/bias_tau: the first-order Gauss-Markov bias of the simulator, fitted to the whole",
             f"# Allan curve; its deviation peaks at tau = {GM_PEAK_X:.4f} bias_tau with {GM_PEAK_RATIO:.4f} bias_instability.",
             f"name: {_scalar(name)}",
             f"description: measured by sins allan ({res.duration / 3600.0:.3g} h static log)"]
    for which, white_key, white_unit in (("gyro", "arw", "deg/sqrt(h)"), ("accel", "vrw", "micro-g/sqrt(Hz)")):
        d = v[which]
        unit = "deg/h" if which == "gyro" else "micro-g"
        qunit = "rad" if which == "gyro" else "m/s"
        lines.append(f"{which}:")
        lines.append(f"  {white_key}: {_list(d[white_key])}   # {white_unit}, x y z")
        lines.append(f"  bias_instability: {_list(d['bias_instability'])}   # {unit}, Gauss-Markov steady-state sigma")
        lines.append(f"  bias_tau: {_list(d['bias_tau'])}   # s, Gauss-Markov correlation time")
        if "quantization" in d:
            lines.append(f"  quantization: {_list(d['quantization'])}   # {qunit} per count")
        lines.append("  bias_sigma: 0   # turn-on bias (run-to-run): a single static log cannot observe it")
        for note in v[f"{which}_notes"]:
            lines.append(f"  # {note}")
        rrw, ok = v[f"{which}_rrw"]
        lines.append(f"  # rate random walk (no key in the schema): {_list(rrw)} {unit}/sqrt(h); identified: "
                     + ", ".join("xyz"[i] for i in range(3) if ok[i]) if any(ok) else
                     f"  # rate random walk (no key in the schema): not identifiable from this log "
                     f"(fit {_list(rrw)} {unit}/sqrt(h))")
    return "\n".join(lines) + "\n"


def write_sensor_yaml(path, res: AllanResult, name: str) -> None:
    v = sensor_values(res.fits)
    for which in ("gyro", "accel"):
        check_finite(path, {f"{which}.{k}": np.asarray(x, dtype=np.float64) for k, x in v[which].items()})
    with atomic_path(path, suffix=".yaml") as tmp:
        Path(tmp).write_text(sensor_yaml_text(res, name), encoding="utf-8")


def write_allan_csv(path, res: AllanResult) -> None:
    """``tau_s, m, clusters``, then per axis the deviation, its 1-sigma and the fitted model (rad/s or m/s^2)."""
    header = ["tau_s", "m", "clusters"]
    for a in AXES:
        u = "rad_s" if a.startswith("gyro") else "m_s2"
        header += [f"{a}_adev_{u}", f"{a}_sigma_{u}", f"{a}_fit_{u}"]
    check_finite(path, {"tau_s": res.tau, "adev": res.adev, "sigma": res.adev * res.rel_sigma[:, None],
                        "fit": np.column_stack([f.model_avar for f in res.fits])})
    with atomic_path(path, suffix=".csv") as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for k in range(res.tau.shape[0]):
            row = [_r(res.tau[k]), str(int(res.m[k])), _r(res.n / res.m[k])]
            for c in range(6):
                row += [_r(res.adev[k, c]), _r(res.adev[k, c] * res.rel_sigma[k]),
                        _r(math.sqrt(max(res.fits[c].model_avar[k], 0.0)))]
            w.writerow(row)


FIT_COLUMNS = ["axis", "white", "white_unit", "bias_instability", "bias_tau_s", "bias_unit", "gm_peak_tau_s",
               "gm_peak_adev", "flicker_b", "tau_at_min_adev_s", "rrw", "rrw_unit", "quantization", "quantization_unit",
               "identified"]


def write_fit_csv(path, res: AllanResult) -> None:
    """One row per axis: every fitted term in the units of the sensor YAML, and what is identified."""
    check_finite(path, {c: np.array([getattr(f, c) for f in res.fits], dtype=np.float64)
                        for c in ("white", "gm_sigma", "flicker_b", "tau_min_adev", "rrw", "quantization")})
    check_finite(path, {"gm_peak_adev": np.array([f.gm_peak[1] for f in res.fits], dtype=np.float64)})
    with atomic_path(path, suffix=".csv") as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(FIT_COLUMNS)
        for a, f in zip(AXES, res.fits):
            gyro = a.startswith("gyro")
            units = GYRO_UNITS if gyro else ACCEL_UNITS
            wk = "arw" if gyro else "vrw"
            b = units["bias_instability"]
            tp, ap = f.gm_peak
            w.writerow([a, _r(f.white / units[wk]), "deg/sqrt(h)" if gyro else "micro-g/sqrt(Hz)",
                        _r(f.gm_sigma / b), _r(f.gm_tau) if np.isfinite(f.gm_tau) else "",
                        "deg/h" if gyro else "micro-g", _r(tp) if np.isfinite(tp) else "", _r(ap / b),
                        _r(f.flicker_b / b), _r(f.tau_min_adev), _r(f.rrw * 60.0 / b),
                        "deg/h/sqrt(h)" if gyro else "micro-g/sqrt(h)", _r(f.quantization),
                        "rad" if gyro else "m/s",
                        " ".join(k for k, ok in f.identified.items() if ok)])


def plot_allan(path, res: AllanResult, title: str) -> None:
    """Two log-log panels (gyro deg/h, accelerometer micro-g): every axis with its 1-sigma band and fit,
    and the characteristic slopes through the mean fit: -1 (quantization), -1/2 (random walk),
    0 (bias instability at the Gauss-Markov peak), +1/2 (rate random walk), and the Gauss-Markov hump."""
    fig = Figure(figsize=(9, 9))
    axes = fig.subplots(2, 1)
    tau = res.tau
    for p, (ax, sl, scale, unit, wname) in enumerate(zip(
            axes, (slice(0, 3), slice(3, 6)), (_DEG_H, _UG), ("deg/h", "micro-g"), ("ARW", "VRW"))):
        for k, c in enumerate(range(sl.start, sl.stop)):
            y = res.adev[:, c] / scale
            line, = ax.loglog(tau, y, lw=1.2, label=AXES[c])
            ax.fill_between(tau, y * (1 - res.rel_sigma), y * (1 + res.rel_sigma), color=line.get_color(),
                            alpha=0.15, lw=0)
            ax.loglog(tau, np.sqrt(np.maximum(res.fits[c].model_avar, 0)) / scale, ls=":", lw=1.0,
                      color=line.get_color())
        fits = res.fits[sl]
        ylo, yhi = np.nanmin(res.adev[:, sl]) / scale / 3, np.nanmax(res.adev[:, sl]) / scale * 3
        mean = lambda attr: float(np.mean([getattr(f, attr) for f in fits]))   # noqa: E731
        slopes = []
        n_w, q, k_r = mean("white"), mean("quantization"), mean("rrw")
        wval = n_w * (math.degrees(1.0) * 60.0 if p == 0 else 1.0 / _UG)
        wunit = "deg/sqrt(h)" if p == 0 else "micro-g/sqrt(Hz)"
        if n_w > 0:
            slopes.append((n_w / np.sqrt(tau), f"-1/2: {wname} {wval:.3g} {wunit} (at tau = 1 s)", 0.15))
        if q > 0 and any(f.identified["quantization"] for f in fits):
            slopes.append((np.sqrt(3.0) * q / tau, "-1: quantization", 0.05))
        if k_r > 0 and any(f.identified["rate_random_walk"] for f in fits):
            slopes.append((k_r * np.sqrt(tau / 3.0), "+1/2: rate random walk", 0.8))
        gm = [f for f in fits if f.identified["gauss_markov"]]
        if gm:
            sig = float(np.mean([f.gm_sigma for f in gm]))
            T = float(np.mean([f.gm_tau for f in gm]))
            slopes.append((sig * np.sqrt(gm_avar(tau, T)), "Gauss-Markov bias", 0.9))
            slopes.append((np.full_like(tau, GM_PEAK_RATIO * sig),
                           f"0: bias instability, peak {GM_PEAK_RATIO * sig / scale:.3g} {unit} at "
                           f"{GM_PEAK_X * T:.3g} s (sigma {sig / scale:.3g}, tau {T:.3g} s)", 0.02))
        for y, lab, where in slopes:
            ax.loglog(tau, y / scale, color="0.5", lw=0.8, ls="--")
            k = min(int(where * len(tau)), len(tau) - 1)
            ax.annotate(lab, (tau[k], y[k] / scale), fontsize=7, color="0.3", xytext=(3, 3),
                        textcoords="offset points")
        ax.set_ylim(ylo, yhi)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_ylabel(f"Allan deviation ({unit})")
        ax.legend(fontsize=8, loc="upper right")
        ax.set_title(("Gyroscopes" if p == 0 else "Accelerometers")
                     + " (band: 1-sigma; dotted: fit; dashed: slopes of the mean fit)", fontsize=9)
    axes[-1].set_xlabel("cluster time tau (s)")
    fig.suptitle(title if len(title) <= 90 else title[:87] + "...", fontsize=10)
    fig.tight_layout()
    FigureCanvasAgg(fig)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
