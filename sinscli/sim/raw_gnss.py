"""Simulated raw GNSS observations with exact truth: pseudorange, Doppler, carrier phase and C/N0 of every
satellite of a broadcast navigation file, for a receiver on a given trajectory.

The geometry is exact: the time of transmission solves ``t_tx = t - |R_z(w_e (t - t_tx)) r_s(t_tx) - r(t)|/c``
(the Earth's rotation during the flight in closed form, not the first-order Sagnac term of the solver), the
satellite orbit and clock are the broadcast ones (so they are the truth), the range rate is the central
difference of that exact range over +-1/16 s (exact in float64 GPS seconds; truncation < 1e-6 m/s).  The receiver clock is ``b0 + d0 (t - t0)`` plus a random walk of the drift
(``clock_walk``) and of the bias (``clock_bias_walk``, white frequency noise); epochs are
tagged with the receiver's clock time (``t + dt_r``), as a free-running receiver writes them.  Ionosphere =
Klobuchar x (1 + ``iono_error``), troposphere = Saastamoinen/DO-229 x (1 + ``tropo_error``); code noise
follows the solver's own elevation / C/N0 model (:func:`sinscli.gnss.spp.code_variance`) with C/N0 =
``cn0_horizon + (cn0_zenith - cn0_horizon) sin(el)``.  Blockages: an elevation mask, an elevation mask per
azimuth sector, and urban-canyon windows that keep only the N highest satellites (optionally with a larger code
noise there).  Carrier phase: ``(rho + c (dt_r - dt_sv) - I + T + multipath + noise) / lambda + N``, the integer
ambiguity ``N`` drawn per satellite and arc: a satellite that comes back after a blockage has lost lock (a new
``N``, LLI bit 0 at its first epoch back).  Multipath: a first-order Gauss-Markov error per satellite on the code
and on the carrier.  Cycle slips: at chosen epochs (whole or half cycles, flagged by LLI or not) and at random on
a share of the satellite-epochs; their truth is :attr:`RawSim.slips`.  See docs/raw_gnss.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
from numba import njit

from ..errors import SinsError
from ..gnss import spp as S
from ..gnss.corrections import klobuchar, tropo_delay
from ..gnss import ephemeris as E
from ..gnss.ephemeris import NavData, finish_table, max_age, select_ephemeris
from ..gnss.model import azel, ecef_to_geodetic, group_delay
from ..gnss.observations import ObsData
from ..gnss.orbits import earth_rate, sat_state
from ..gnss.phase import carrier_shape
from ..gnss.signals import C_LIGHT, SYS_BDS, SYS_CHARS, SYS_GAL, SYS_GPS, SYS_QZS, frequency, sys_index
from ..io.atomic import atomic_path
from ..io.csvcore import write_table_csv
from ..io.rinex import read_nav, write_nav, write_obs
from ..nav.earth import ecef_to_lla, enu_rotation, lla_to_ecef
from .gnss import antenna_truth

# signals written per system: (first frequency codes, second frequency codes), each C, L, D, S
SIGNALS = {SYS_GPS: ("1C", "2W"), SYS_QZS: ("1C", "2L"), SYS_GAL: ("1C", "5Q"), SYS_BDS: ("2I", "7I")}

DEFAULTS = {
    "nav": None,                 # RINEX navigation file (default: the shipped GPS file, sinscli/data/gnss)
    "systems": "GEC",
    "gps_start": None,           # GPS seconds of the scenario's first instant (default: first toe + 1 h)
    "rate": 1.0,                 # Hz
    "frequencies": 1,            # 1 or 2
    "code_sigma": 0.3,           # m: a = b of sigma^2 = a^2 + b^2 / sin^2 el (the solver's model)
    "doppler_sigma": 0.05,       # m/s at the zenith (range-rate noise, the solver's shape)
    "carrier_sigma": 0.003,      # m
    "cn0_zenith": 50.0,          # dB-Hz
    "cn0_horizon": 35.0,
    "clock_bias": 1.0e-4,        # s at the start
    "clock_drift": 2.0e-8,       # s/s
    "clock_walk": 0.0,           # random walk of the drift, (s/s)/sqrt(s)
    "clock_bias_walk": 0.0,      # random walk of the bias (white frequency noise), s/sqrt(s)
    "system_bias": {},           # receiver inter-system bias per system letter, s (e.g. {E: 5.0e-9})
    "iono_error": 0.0,           # relative error of the Klobuchar model (the residual the solver sees)
    "tropo_error": 0.0,
    "elevation_mask": 5.0,       # deg: below it no satellite is tracked
    "azimuth_mask": [],          # [[az_from, az_to, el_min], ...] deg
    "canyons": [],               # [{start: s, duration: s, keep: N[, code_sigma: m]}, ...] (s from the start)
    "multipath_code": 0.0,       # m: 1-sigma of a Gauss-Markov multipath error per satellite on the code
    "multipath_carrier": 0.0,    # m: the same on the carrier
    "multipath_tau": 10.0,       # s: their correlation time
    "lock_loss": True,           # a satellite back after a blockage: new ambiguity, LLI bit 0
    "cycle_slips": [],           # [{time: s, sat: G05, cycles: n (0.5: half a cycle)[, frequency: 1|2,
                                 #   flagged: false]}, ...] (s from the start)
    "slip_rate": 0.0,            # share of the satellite-epochs (after an arc's first) with a random slip
    "slip_cycles": [-3, -2, -1, -0.5, 0.5, 1, 2, 3],   # the random slips' sizes (cycles), drawn uniformly
    "slip_flagged": 0.0,         # share of the random slips the receiver flags (LLI bit 0)
}
SLIP_DTYPE = np.dtype([("epoch", "i8"), ("sys", "i8"), ("prn", "i8"), ("frequency", "i8"), ("cycles", "f8"),
                       ("flagged", "?")])


def shipped_nav() -> Path:
    """The broadcast navigation file shipped with the package (package data)."""
    return Path(str(resources.files("sinscli") / "data" / "gnss" / "brdc1350.20n"))


def check_config(cfg: dict | None, src: str = "raw_gnss") -> dict:
    """The raw-GNSS settings with defaults, each checked (SinsError naming the key)."""
    out = dict(DEFAULTS)
    for k, v in (cfg or {}).items():
        if k not in DEFAULTS:
            raise SinsError(f"{src}: {k}: unknown key; expected one of {', '.join(DEFAULTS)}")
        out[k] = v
    for k in ("rate", "code_sigma", "doppler_sigma", "carrier_sigma"):
        v = out[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise SinsError(f"{src}: {k}: expected a positive number; got {v!r}")
    for k in ("clock_bias", "clock_drift", "clock_walk", "clock_bias_walk", "iono_error", "tropo_error", "elevation_mask",
              "cn0_zenith", "cn0_horizon", "multipath_code", "multipath_carrier", "multipath_tau", "slip_rate",
              "slip_flagged"):
        v = out[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise SinsError(f"{src}: {k}: expected a number; got {v!r}")
    if not isinstance(out["system_bias"], dict) or any(
            k not in "GECJ" or isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            for k, v in out["system_bias"].items()):
        raise SinsError(f"{src}: system_bias: expected {{letter: seconds}} with letters of G, E, C, J")
    if out["frequencies"] not in (1, 2):
        raise SinsError(f"{src}: frequencies: expected 1 or 2; got {out['frequencies']!r}")
    for c in str(out["systems"]):
        if c not in "GECJ":
            raise SinsError(f"{src}: systems: {c!r} is not one of G, E, C, J")
    for i, m in enumerate(out["azimuth_mask"] or []):
        if not (isinstance(m, (list, tuple)) and len(m) == 3):
            raise SinsError(f"{src}: azimuth_mask[{i}]: expected [az_from, az_to, el_min] in degrees")
    for i, c in enumerate(out["canyons"] or []):
        if not isinstance(c, dict) or set(c) - {"start", "duration", "keep", "code_sigma"} or \
                not {"start", "duration", "keep"} <= set(c):
            raise SinsError(f"{src}: canyons[{i}]: expected {{start: s, duration: s, keep: N[, code_sigma: m]}}")
        if not (c["duration"] > 0 and int(c["keep"]) >= 0 and c.get("code_sigma", 1.0) > 0):
            raise SinsError(f"{src}: canyons[{i}]: duration and code_sigma must be > 0 and keep >= 0")
    for k in ("multipath_code", "multipath_carrier", "slip_flagged"):
        if out[k] < 0 or (k == "slip_flagged" and out[k] > 1):
            raise SinsError(f"{src}: {k}: expected {'0 to 1' if k == 'slip_flagged' else '>= 0'}; got {out[k]!r}")
    if not 0.0 <= out["slip_rate"] < 1.0:
        raise SinsError(f"{src}: slip_rate: expected a share in [0, 1); got {out['slip_rate']!r}")
    if out["multipath_tau"] <= 0:
        raise SinsError(f"{src}: multipath_tau: expected a positive number of seconds; got {out['multipath_tau']!r}")
    cyc = out["slip_cycles"]
    if not isinstance(cyc, (list, tuple)) or not cyc or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) or v == 0 or round(2 * v) != 2 * v for v in cyc):
        raise SinsError(f"{src}: slip_cycles: expected a list of non-zero whole or half cycles; got {cyc!r}")
    for i, c in enumerate(out["cycle_slips"] or []):
        if not isinstance(c, dict) or not {"time", "sat", "cycles"} <= set(c) or \
                set(c) - {"time", "sat", "cycles", "frequency", "flagged"}:
            raise SinsError(f"{src}: cycle_slips[{i}]: expected {{time: s, sat: G05, cycles: n[, frequency: 1|2, "
                            f"flagged: false]}}")
        sat = str(c["sat"])
        if len(sat) != 3 or sat[0] not in "GECJ" or not sat[1:].isdigit():
            raise SinsError(f"{src}: cycle_slips[{i}]: sat: expected a satellite like G05; got {sat!r}")
        v = c["cycles"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v == 0 or round(2 * v) != 2 * v:
            raise SinsError(f"{src}: cycle_slips[{i}]: cycles: expected a non-zero whole or half number; got {v!r}")
        if c.get("frequency", 1) not in (1, 2):
            raise SinsError(f"{src}: cycle_slips[{i}]: frequency: expected 1 or 2")
    return out


@njit(cache=True)
def _geometry(eph, ion, t, t_sel, pos, vel, sys_list, prn_list, freq, band):
    """Exact range, range rate and satellite terms of every (epoch, satellite): returns ``rho, rho_dot, el, az,
    dts, ddts, gd1, iono1, tropo, ok`` (E, S).  The ephemeris is the one nearest ``t_sel`` (the receiver's
    time tag, as the solver picks it)."""
    ne = t.shape[0]
    ns = sys_list.shape[0]
    rho = np.full((ne, ns), np.nan)
    rdot = np.full((ne, ns), np.nan)
    el = np.full((ne, ns), np.nan)
    az = np.full((ne, ns), np.nan)
    dts = np.zeros((ne, ns))
    ddts = np.zeros((ne, ns))
    gd1 = np.zeros((ne, ns))
    iono = np.zeros((ne, ns))
    trop = np.zeros((ne, ns))
    ok = np.zeros((ne, ns), np.bool_)
    for e in range(ne):
        lat, lon, hgt = ecef_to_geodetic(pos[e, 0], pos[e, 1], pos[e, 2])
        tow = t[e] - math.floor(t[e] / 604800.0) * 604800.0
        for j in range(ns):
            s = sys_list[j]
            k = select_ephemeris(eph, s, prn_list[j], t_sel[e], max_age(s), 0)
            if k < 0:
                continue
            omge = earth_rate(s)
            r_at = np.zeros(3)
            for q in range(3):
                h = (q - 1) * 0.0625                # -1/16 s, 0, +1/16 s: exact in float64 GPS seconds
                rx = pos[e, 0] + vel[e, 0] * h
                ry = pos[e, 1] + vel[e, 1] * h
                rz = pos[e, 2] + vel[e, 2] * h
                tt = t[e] + h
                tau = 0.075
                for _ in range(8):
                    x, y, z, vx, vy, vz, c0, c1 = sat_state(eph, k, tt - tau)
                    ang = omge * tau
                    xr = math.cos(ang) * x + math.sin(ang) * y
                    yr = -math.sin(ang) * x + math.cos(ang) * y
                    dist = math.sqrt((xr - rx) ** 2 + (yr - ry) ** 2 + (z - rz) ** 2)
                    tau = dist / C_LIGHT
                r_at[q] = dist
                if q == 1:
                    x, y, z, vx, vy, vz, c0, c1 = sat_state(eph, k, tt - tau)
                    dts[e, j] = c0
                    ddts[e, j] = c1
                    ang = omge * tau
                    xr = math.cos(ang) * x + math.sin(ang) * y
                    yr = -math.sin(ang) * x + math.cos(ang) * y
                    ex = (xr - rx) / dist
                    ey = (yr - ry) / dist
                    ez = (z - rz) / dist
                    a_, e_ = azel(lat, lon, ex, ey, ez)
                    el[e, j] = e_
                    az[e, j] = a_
                    gd1[e, j] = group_delay(eph, k, band[j], freq[j])
                    if e_ > 0.0:
                        iono[e, j] = klobuchar(ion, lat, lon, a_, e_, tow)
                        trop[e, j] = tropo_delay(lat, hgt, e_)
            rho[e, j] = r_at[1]
            rdot[e, j] = (r_at[2] - r_at[0]) / 0.125
            ok[e, j] = True
    return rho, rdot, el, az, dts, ddts, gd1, iono, trop, ok


@dataclass
class RawSim:
    obs: ObsData
    nav: NavData
    t_true: np.ndarray                 # (E,) GPS s
    pos: np.ndarray                    # (E,3) ECEF antenna
    vel: np.ndarray
    clock_bias: np.ndarray             # (E,) s
    clock_drift: np.ndarray            # (E,) s/s
    visible: np.ndarray                # (E,) satellites written per epoch
    config: dict = field(default_factory=dict)
    gps_offset: float = 0.0            # GPS time - scenario time (s)
    slips: np.ndarray = field(default_factory=lambda: np.zeros(0, SLIP_DTYPE))   # injected slips (SLIP_DTYPE)


def simulate_raw(t_true, pos, vel, nav: NavData, cfg: dict, seed: int = 0) -> RawSim:
    """Observations of a receiver at ECEF ``pos``/``vel`` (E,3) at true GPS times ``t_true`` (E,)."""
    cfg = check_config(cfg)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x52415747]))
    t_true = np.asarray(t_true, dtype=np.float64)
    ne = t_true.shape[0]
    systems = [sys_index(c) for c in str(cfg["systems"])]
    sats = sorted({(int(s), int(p)) for s, p in nav.eph[:, :2] if int(s) in systems})
    if not sats:
        raise SinsError(f"{nav.source}: no ephemeris of the systems {cfg['systems']} to simulate")
    sys_list = np.array([s for s, _ in sats], dtype=np.int64)
    prn_list = np.array([p for _, p in sats], dtype=np.int64)
    nfreq = int(cfg["frequencies"])
    codes = [[SIGNALS[s][f] for f in range(nfreq)] for s in sys_list]
    freqs = np.array([[frequency(s, "C" + c) for c in cs] for s, cs in zip(sys_list, codes)])
    bands = np.array([[int(c[0]) for c in cs] for cs in codes], dtype=np.int64)
    ion = nav.ion_gps if nav.ion_gps is not None else np.zeros(8)
    # receiver clock: bias and drift (random walk of the drift)
    dt = np.diff(t_true, prepend=t_true[0])
    drift = cfg["clock_drift"] + np.cumsum(rng.standard_normal(ne) * cfg["clock_walk"] * np.sqrt(dt))
    bias = cfg["clock_bias"] + np.concatenate([[0.0], np.cumsum(0.5 * (drift[1:] + drift[:-1]) * dt[1:])])
    if cfg["clock_bias_walk"]:                # drawn only when asked: the other draws stay those of a seed
        bias = bias + np.cumsum(rng.standard_normal(ne) * cfg["clock_bias_walk"] * np.sqrt(dt))
    geo = [_geometry(nav.eph, np.asarray(ion, dtype=np.float64), t_true, t_true + bias, pos, vel, sys_list, prn_list,
                     np.ascontiguousarray(freqs[:, f]), np.ascontiguousarray(bands[:, f])) for f in range(nfreq)]
    rho, rdot, el, az, dts, ddts, _, iono_l1, trop, ok = geo[0]
    visible = ok & (el > math.radians(cfg["elevation_mask"]))
    azd, eld = np.degrees(az), np.degrees(el)
    for a0, a1, emin in cfg["azimuth_mask"] or []:
        inside = ((azd - a0) % 360.0) <= ((a1 - a0) % 360.0)
        visible &= ~(inside & (eld < emin))
    t_rel = t_true - t_true[0]
    for c in cfg["canyons"] or []:
        win = (t_rel >= c["start"]) & (t_rel < c["start"] + c["duration"])
        for e in np.nonzero(win)[0]:
            order = np.argsort(np.where(visible[e], -el[e], np.inf))
            keep = order[:int(c["keep"])]
            m = np.zeros(visible.shape[1], bool)
            m[keep] = True
            visible[e] &= m
    cn0 = cfg["cn0_horizon"] + (cfg["cn0_zenith"] - cfg["cn0_horizon"]) * np.sin(np.clip(el, 0.0, None))
    opts = S.spp_options(code_a=cfg["code_sigma"], code_b=cfg["code_sigma"],
                         doppler_sigma=cfg["doppler_sigma"])
    var_code = np.full(el.shape, np.nan)
    var_dop = np.full(el.shape, np.nan)
    for e, j in zip(*np.nonzero(visible)):
        var_code[e, j] = S.code_variance(opts, el[e, j], cn0[e, j])
        var_dop[e, j] = S.doppler_variance(opts, el[e, j], cn0[e, j])
    for c in cfg["canyons"] or []:               # a canyon's own code noise (the variance scales with sigma^2)
        if "code_sigma" in c:
            win = (t_rel >= c["start"]) & (t_rel < c["start"] + c["duration"])
            var_code[win] *= (float(c["code_sigma"]) / cfg["code_sigma"]) ** 2
    # observations: per system the codes C, L, D, S of each frequency
    types = {}
    for s in sorted(set(sys_list.tolist())):
        cs = SIGNALS[s][:nfreq]
        types[s] = [k + c for c in cs for k in "CLDS"]
    ncol = max(len(v) for v in types.values())
    rows_e, rows_j = np.nonzero(visible)
    order = np.lexsort((rows_j, rows_e))
    rows_e, rows_j = rows_e[order], rows_j[order]
    nr = rows_e.size
    values = np.full((nr, ncol), np.nan)
    amb = rng.integers(-1000000, 1000000, size=(len(sats), nfreq)).astype(np.float64)
    lli = np.zeros(values.shape, np.int8)
    # arcs, multipath and slips: drawn from their own stream (the draws above stay those of a seed)
    extra = np.random.default_rng(np.random.SeedSequence([int(seed), 0x52415747, 1]))
    arc_amb, mp_code, mp_carr, slip_cyc, slips = _arcs_multipath_slips(cfg, extra, rows_e, rows_j, t_true, sys_list,
                                                                      prn_list, nfreq, lli)
    for f in range(nfreq):
        g = geo[f]
        gd = g[6][rows_e, rows_j]
        fr = freqs[rows_j, f]
        lam = C_LIGHT / fr
        scale_i = (1575.42e6 / fr) ** 2
        i_f = iono_l1[rows_e, rows_j] * scale_i * (1.0 + cfg["iono_error"])
        tr = trop[rows_e, rows_j] * (1.0 + cfg["tropo_error"])
        rr = rho[rows_e, rows_j]
        isb = np.array([float(cfg["system_bias"].get(SYS_CHARS[s], 0.0)) for s in sys_list])[rows_j]
        clock = C_LIGHT * (bias[rows_e] + isb - dts[rows_e, rows_j])
        code_noise = rng.standard_normal(nr) * np.sqrt(var_code[rows_e, rows_j])
        pr = rr + clock + C_LIGHT * gd + i_f + tr + code_noise + mp_code[:, f]
        # carrier noise: carrier_sigma times the filter's C/N0 law (gnss/phase.carrier_shape)
        carr_sd = cfg["carrier_sigma"] * np.sqrt([carrier_shape(opts, c) for c in cn0[rows_e, rows_j]])
        carrier = (rr + clock - i_f + tr + rng.standard_normal(nr) * carr_sd + mp_carr[:, f]) / lam \
            + amb[rows_j, f] + arc_amb[:, f] + slip_cyc[:, f]
        rate = rdot[rows_e, rows_j] + C_LIGHT * (drift[rows_e] - ddts[rows_e, rows_j]) \
            + rng.standard_normal(nr) * np.sqrt(var_dop[rows_e, rows_j])
        dop = -rate / lam
        for k, v in zip("CLDS", (pr, carrier, dop, cn0[rows_e, rows_j])):
            col = f * 4 + "CLDS".index(k)
            values[:, col] = v
    # columns of each system are in the same order (C L D S per frequency): no remapping needed
    counts = np.bincount(rows_e, minlength=ne)
    start = np.concatenate([[0], np.cumsum(counts)])
    t_tag = t_true + bias
    obs = ObsData(time=t_tag, start=start.astype(np.int64), sys=sys_list[rows_j].astype(np.int8),
                  prn=prn_list[rows_j].astype(np.int16), values=values, lli=lli,
                  types=types, flag=np.zeros(ne, np.int8),
                  header={"version": 3.04, "marker": "SIMULATED", "receiver": "sins simulate",
                          "approx_xyz": [float(v) for v in pos[0]], "interval": 1.0 / float(cfg["rate"])},
                  source="<simulated>")
    return RawSim(obs, nav, t_true, pos, vel, bias, drift, counts, cfg, slips=slips)


def _arcs_multipath_slips(cfg, rng, rows_e, rows_j, t_true, sys_list, prn_list, nfreq, lli):
    """Per observation row (epoch ``rows_e``, satellite ``rows_j``, in epoch order) and frequency: the ambiguity
    added at each new arc (an integer; 0 on the first), the code and carrier multipath (m; a first-order
    Gauss-Markov process per satellite, ``exp(-dt/tau)`` across its gaps too) and the cycles slipped so far; LLI
    bit 0 set in ``lli`` (the carrier columns, C L D S per frequency) at a new arc (``lock_loss``) and at a
    flagged slip.  Returns those arrays and the slips (:data:`SLIP_DTYPE`)."""
    nr = rows_e.size
    arc = np.zeros((nr, nfreq))
    mpc = np.zeros((nr, nfreq))
    mpl = np.zeros((nr, nfreq))
    cyc = np.zeros((nr, nfreq))
    t_rel = t_true - t_true[0]
    chosen = {}
    for c in cfg["cycle_slips"] or []:
        e = int(np.argmin(np.abs(t_rel - float(c["time"]))))
        chosen.setdefault((str(c["sat"]), e), []).append(c)
    out = []
    sizes = np.asarray(cfg["slip_cycles"], dtype=float)
    for j in np.unique(rows_j):
        idx = np.nonzero(rows_j == j)[0]
        ep = rows_e[idx]
        name = f"{SYS_CHARS[int(sys_list[j])]}{int(prn_list[j]):02d}"
        start = np.ones(idx.size, bool)
        start[1:] = ep[1:] != ep[:-1] + 1
        for f in range(nfreq):
            for sig, dst in ((cfg["multipath_code"], mpc), (cfg["multipath_carrier"], mpl)):
                if sig > 0:
                    a = np.exp(-np.diff(t_true[ep], prepend=t_true[ep[0]]) / cfg["multipath_tau"])
                    w = rng.standard_normal(idx.size) * sig * np.sqrt(1.0 - a * a)
                    w[0] = rng.standard_normal() * sig
                    m = np.empty(idx.size)
                    m[0] = w[0]
                    for i in range(1, idx.size):
                        m[i] = a[i] * m[i - 1] + w[i]
                    dst[idx, f] = m
        if cfg["lock_loss"]:
            for i in np.nonzero(start)[0][1:]:
                arc[idx[i:], :] += rng.integers(-1000, 1000, size=nfreq)
                lli[idx[i], [4 * f + 1 for f in range(nfreq)]] |= 1
        rand = rng.random(idx.size) < cfg["slip_rate"]
        draw = sizes[rng.integers(0, sizes.size, size=idx.size)]
        flag = rng.random(idx.size) < cfg["slip_flagged"]
        for i in range(idx.size):
            here = [(1, float(c["cycles"]), int(c.get("frequency", 1)), bool(c.get("flagged", False)))
                    for c in chosen.get((name, int(ep[i])), [])]
            if rand[i] and not start[i]:
                here.append((0, float(draw[i]), 1, bool(flag[i])))
            for _, n, f, flagged in here:
                if f > nfreq or start[i]:
                    continue
                cyc[idx[i:], f - 1] += n
                if flagged:
                    lli[idx[i], 4 * (f - 1) + 1] |= 1
                out.append((int(ep[i]), int(sys_list[j]), int(prn_list[j]), f, n, flagged))
    return arc, mpc, mpl, cyc, np.array(out, dtype=SLIP_DTYPE)


def with_second_constellation(nav: NavData, sys_letter: str = "E") -> NavData:
    """``nav`` plus a synthetic second Keplerian constellation for tests and benchmarks: its GPS orbits turned by
    60 deg in node and 1 rad in mean anomaly, labelled with ``sys_letter`` (Galileo I/NAV by default, group
    delays 2 and 3 ns), so that a receiver sees two systems with their own clock offsets."""
    other = nav.eph[nav.eph[:, E.SYS] == SYS_GPS].copy()
    other[:, E.SYS] = sys_index(sys_letter)
    other[:, E.SOURCE] = 513 if sys_index(sys_letter) == SYS_GAL else 0
    other[:, E.OMEGA0] += math.radians(60.0)
    other[:, E.M0] += 1.0
    other[:, E.TGD1], other[:, E.TGD2] = 2e-9, 3e-9
    return NavData(eph=finish_table(np.concatenate([nav.eph, other])), ion_gps=nav.ion_gps,
                   source=f"{nav.source} + synthetic {sys_letter}")


def load_nav_for_sim(cfg: dict) -> NavData:
    return read_nav(cfg["nav"] if cfg.get("nav") else shipped_nav())


def default_start(nav: NavData) -> float:
    """First toe of the file plus one hour (inside every ephemeris' validity)."""
    return float(np.min(nav.eph[:, 3])) + 3600.0


def static_receiver(lat_deg, lon_deg, height, duration, cfg: dict | None = None, seed: int = 0,
                    nav: NavData | None = None) -> RawSim:
    """A static receiver for ``duration`` s (tests, examples)."""
    cfg = check_config(cfg)
    nav = nav if nav is not None else load_nav_for_sim(cfg)
    t0 = float(cfg["gps_start"]) if cfg["gps_start"] is not None else default_start(nav)
    t = t0 + np.arange(0.0, float(duration), 1.0 / float(cfg["rate"]))
    p = lla_to_ecef(math.radians(lat_deg), math.radians(lon_deg), float(height))
    pos = np.tile(p, (t.size, 1))
    return simulate_raw(t, pos, np.zeros_like(pos), nav, cfg, seed)


def from_trajectory(time_rel, lat, lon, h, vel_enu, cfg: dict, seed: int = 0) -> RawSim:
    """Observations along a trajectory (scenario seconds ``time_rel``, radians, m, ENU m/s): epochs at the raw
    rate, the antenna state interpolated (cubic Hermite on ECEF position and velocity) at each true time."""
    cfg = check_config(cfg)
    nav = load_nav_for_sim(cfg)
    t0 = float(cfg["gps_start"]) if cfg["gps_start"] is not None else default_start(nav)
    xyz = lla_to_ecef(lat, lon, h)
    rot = enu_rotation(lat, lon)                              # rows E, N, U in ECEF axes
    v_ecef = np.einsum("nji,nj->ni", rot, vel_enu)
    step = 1.0 / float(cfg["rate"])
    tr = np.arange(time_rel[0], time_rel[-1] + 1e-9, step)
    idx = np.clip(np.searchsorted(time_rel, tr, side="right") - 1, 0, len(time_rel) - 2)
    ta, tb = time_rel[idx], time_rel[idx + 1]
    hh = (tb - ta)[:, None]
    s = ((tr - ta) / (tb - ta))[:, None]
    h00, h10, h01, h11 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    pos = h00 * xyz[idx] + h10 * hh * v_ecef[idx] + h01 * xyz[idx + 1] + h11 * hh * v_ecef[idx + 1]
    d00, d10, d01, d11 = 6 * s ** 2 - 6 * s, 3 * s ** 2 - 4 * s + 1, -6 * s ** 2 + 6 * s, 3 * s ** 2 - 2 * s
    vel = (d00 * xyz[idx] + d10 * hh * v_ecef[idx] + d01 * xyz[idx + 1] + d11 * hh * v_ecef[idx + 1]) / hh
    sim = simulate_raw(t0 + (tr - time_rel[0]), pos, vel, nav, cfg, seed)
    sim.gps_offset = t0 - float(time_rel[0])
    return sim


RAW_FILES = ("obs.rnx", "nav.rnx", "gnss_truth.csv")


def simulate_from_result(result, cfg: dict, seed: int = 0) -> RawSim:
    """Raw observations of the antenna of a ``sins simulate`` run (:class:`sinscli.sim.run.SimResult`): the
    antenna truth of its GNSS fixes' model (lever arm included) at the IMU times, resampled at the raw rate."""
    tr = result.truth
    lever = (result.scenario.gnss.get("lever_arm", [0.0, 0.0, 0.0]) if result.scenario is not None
             else [0.0, 0.0, 0.0])
    w = np.zeros((len(tr), 3))
    lat, lon, h, v = tr.lat, tr.lon, tr.height, tr.vel_n
    if np.any(np.asarray(lever, dtype=float)):
        # body rates from consecutive attitudes (the antenna's velocity term w x l is small; mm/s)
        dt = np.gradient(tr.time)
        c = tr.Cbn
        dc = np.gradient(c, axis=0) / dt[:, None, None]
        wx = np.einsum("nji,njk->nik", c, dc)
        w = np.stack([wx[:, 2, 1], wx[:, 0, 2], wx[:, 1, 0]], axis=1)
        lat, lon, h, v = antenna_truth(tr.lat, tr.lon, tr.height, tr.vel_n, tr.Cbn, w, lever)
    return from_trajectory(tr.time, lat, lon, h, v, cfg, seed)


def write_raw(sim: RawSim, outdir) -> list[Path]:
    """``obs.rnx``, ``nav.rnx`` (RINEX 3.04) and ``gnss_truth.csv`` (true GPS time, antenna lat/lon/height,
    ENU velocity, receiver clock bias m and drift m/s) into ``outdir`` (each written atomically); with injected
    cycle slips also ``gnss_slips.csv`` (true GPS time of the epoch, system number, PRN, frequency 1/2, cycles,
    flagged 0/1)."""
    outdir = Path(outdir)
    write_obs(outdir / "obs.rnx", sim.obs)
    write_nav(outdir / "nav.rnx", sim.nav)
    lat, lon, h = ecef_to_lla(sim.pos)
    v = np.einsum("nij,nj->ni", enu_rotation(lat, lon), sim.vel)
    data = {"time": sim.t_true, "lat": np.degrees(lat), "lon": np.degrees(lon), "height": h,
            "vel_e": v[:, 0], "vel_n": v[:, 1], "vel_u": v[:, 2], "clock_bias": sim.clock_bias * C_LIGHT,
            "clock_drift": sim.clock_drift * C_LIGHT, "satellites": sim.visible.astype(np.float64)}
    with atomic_path(outdir / "gnss_truth.csv") as tmp:
        write_table_csv(tmp, data)
    out = [outdir / "obs.rnx", outdir / "nav.rnx", outdir / "gnss_truth.csv"]
    if len(sim.slips):             # the injected cycle slips: epoch time (true GPS s), satellite, frequency, cycles
        sl = sim.slips
        with atomic_path(outdir / "gnss_slips.csv") as tmp:
            write_table_csv(tmp, {"time": sim.t_true[sl["epoch"]], "system": sl["sys"].astype(np.float64),
                                  "prn": sl["prn"].astype(np.float64), "frequency": sl["frequency"].astype(np.float64),
                                  "cycles": sl["cycles"], "flagged": sl["flagged"].astype(np.float64)})
        out.append(outdir / "gnss_slips.csv")
    return out


__all__ = ["simulate_raw", "static_receiver", "from_trajectory", "write_raw", "check_config", "SYS_CHARS",
           "with_second_constellation"]
