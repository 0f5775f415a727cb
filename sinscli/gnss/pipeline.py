"""Single-point positioning of an observation table with a navigation table: signal selection (Python, once
per file), the kernel (:func:`sinscli.gnss.spp.solve_epochs`), and the fixes in geodetic/ENU form."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SinsError
from ..nav.earth import ecef_to_lla, enu_rotation
from . import spp as S
from .ephemeris import NavData
from .observations import ObsData
from .signals import (C_LIGHT, KEPLER_SYSTEMS, N_SYS, PRIMARY_CODES, SECONDARY_CODES, SYS_BDS, SYS_CHARS, SYS_GAL,
                      SYS_GPS, SYS_QZS, frequency, sat_name, sys_index)


@dataclass
class SignalArrays:
    """Per-record inputs of the kernel: the chosen pseudoranges, their bands and frequencies, C/N0, Doppler."""
    p1: np.ndarray
    p2: np.ndarray
    b1: np.ndarray
    b2: np.ndarray
    f1: np.ndarray
    f2: np.ndarray
    cn0: np.ndarray
    dop: np.ndarray
    code1: dict = field(default_factory=dict)      # sys -> primary code chosen most often
    l1: np.ndarray | None = None                   # carrier (cycles) and its LLI of the primary signal
    lli1: np.ndarray | None = None
    l2: np.ndarray | None = None                   # the same of the second-frequency signal
    lli2: np.ndarray | None = None
    code2: dict = field(default_factory=dict)


def _band(sys: int, code: str) -> int:
    b = int(code[1])
    return 2 if sys == SYS_BDS and b == 1 and code[2] == "I" else b


def select_signals(obs: ObsData) -> SignalArrays:
    """For each record: the first primary and secondary code present (signals.PRIMARY_CODES,
    SECONDARY_CODES), the C/N0 (``S``) and Doppler (``D``) of the primary signal."""
    n = obs.n_records
    out = SignalArrays(*(np.full(n, np.nan) for _ in range(2)), np.zeros(n, np.int64), np.zeros(n, np.int64),
                       np.zeros(n), np.zeros(n), np.full(n, np.nan), np.full(n, np.nan),
                       l1=np.full(n, np.nan), lli1=np.zeros(n, np.int64), l2=np.full(n, np.nan),
                       lli2=np.zeros(n, np.int64))
    for s in KEPLER_SYSTEMS:
        if s not in obs.types:
            continue
        types = obs.types[s]
        for codes, pv, bv, fv, key in ((PRIMARY_CODES[s], out.p1, out.b1, out.f1, "code1"),
                                       (SECONDARY_CODES[s], out.p2, out.b2, out.f2, "code2")):
            vals, which = obs.column(codes, s)
            take = which >= 0
            pv[take] = vals[take]
            counts = np.bincount(which[take], minlength=len(codes)) if take.any() else np.zeros(len(codes), int)
            if take.any():
                getattr(out, key)[s] = codes[int(np.argmax(counts))]
            for i, code in enumerate(codes):
                sel = which == i
                if not sel.any():
                    continue
                bv[sel] = _band(s, code)
                fv[sel] = frequency(s, code)
                first = key == "code1"
                lv, llv = (out.l1, out.lli1) if first else (out.l2, out.lli2)
                for kind, dst in ((("S", out.cn0), ("D", out.dop), ("L", lv)) if first else (("L", lv),)):
                    other = kind + code[1:]
                    if other in types:
                        dst[sel] = obs.values[sel, types.index(other)]
                        if kind == "L":
                            llv[sel] = obs.lli[sel, types.index(other)]
    # a second frequency equal to the first (C1C with C1W) is no combination
    same = out.f2 == out.f1
    out.p2[same] = np.nan
    return out


@dataclass
class SppResult:
    time: np.ndarray            # (E,) receiver epoch time tags (GPS s)
    status: np.ndarray
    pos: np.ndarray             # (E,3) ECEF m
    cov: np.ndarray             # (E,3,3) ECEF m^2
    clk: np.ndarray             # (E,N_SYS) m
    vel: np.ndarray
    cov_vel: np.ndarray
    drift: np.ndarray           # m/s
    nsat: np.ndarray
    pdop: np.ndarray
    hdop: np.ndarray
    vdop: np.ndarray
    chi2: np.ndarray
    dof: np.ndarray
    vel_ok: np.ndarray
    rec_status: np.ndarray
    resid: np.ndarray
    el: np.ndarray
    az: np.ndarray
    obs: ObsData
    signals: SignalArrays
    systems: list

    @property
    def fix(self) -> np.ndarray:
        return self.status == S.FIX

    def solution_time(self) -> np.ndarray:
        """GPS time of each solution: the epoch tag less the receiver clock offset of the first system solved
        (G, E, C, J order), as RTKLIB does."""
        t = self.time.copy()
        clk = np.full(t.shape, np.nan)
        for s in (SYS_GPS, SYS_GAL, SYS_BDS, SYS_QZS):
            take = np.isnan(clk) & ~np.isnan(self.clk[:, s])
            clk[take] = self.clk[take, s]
        ok = ~np.isnan(clk)
        t[ok] -= clk[ok] / C_LIGHT
        return t

    def excluded_text(self) -> list[str]:
        """Per epoch the satellites excluded by the chi-square test, ``'G05 E11'``."""
        out = [""] * len(self.time)
        ex = np.nonzero(self.rec_status == S.EXCLUDED)[0]
        if ex.size:
            ep = self.obs.epoch_of_record()
            for r in ex:
                e = int(ep[r])
                name = sat_name(int(self.obs.sys[r]), int(self.obs.prn[r]))
                out[e] = f"{out[e]} {name}".strip()
        return out

    def enu(self):
        """``(lat, lon, height, vel_enu, std_enu, std_vel_enu)`` of every epoch (degrees, m, m/s)."""
        lat, lon, h = ecef_to_lla(self.pos)
        rot = enu_rotation(lat, lon)                          # (E,3,3) rows E, N, U
        cov_enu = rot @ self.cov @ np.swapaxes(rot, 1, 2)
        vel = np.einsum("eij,ej->ei", rot, self.vel)
        cov_v = rot @ self.cov_vel @ np.swapaxes(rot, 1, 2)
        std = np.sqrt(np.einsum("eii->ei", cov_enu))
        std_v = np.sqrt(np.einsum("eii->ei", cov_v))
        return np.degrees(lat), np.degrees(lon), h, vel, std, std_v


def parse_systems(text: str | None, obs: ObsData | None = None) -> list[int]:
    """``'GEC'`` -> system numbers (only Keplerian systems); None: every such system."""
    if text is None:
        return list(KEPLER_SYSTEMS)
    out = []
    for c in text.upper():
        s = sys_index(c)
        if s < 0:
            raise SinsError(f"--systems: unknown system letter {c!r}; expected letters of {SYS_CHARS}")
        if s not in KEPLER_SYSTEMS:
            raise SinsError(f"--systems: {c} (GLONASS/SBAS/NavIC) is not positioned; expected letters of GECJ")
        out.append(s)
    return out


def smooth_signals(obs: ObsData, sig: SignalArrays, window: float) -> None:
    """Replace the pseudoranges of both frequencies by carrier-smoothed ones (:func:`sinscli.gnss.spp.hatch_smooth`,
    each with its own carrier) over ``window`` seconds."""
    if window <= 0.0 or len(obs) < 2:
        return
    step = float(np.median(np.diff(obs.time)))
    n_max = max(1, int(round(window / step)))
    for p, l, lli, f in ((sig.p1, sig.l1, sig.lli1, sig.f1), (sig.p2, sig.l2, sig.lli2, sig.f2)):
        lam = np.where(f > 0, C_LIGHT / np.where(f > 0, f, 1.0), 0.0)
        p[:] = S.hatch_smooth(obs.time, obs.start, obs.sys.astype(np.int64), obs.prn.astype(np.int64), p, l,
                              lli, lam, n_max, 2.5 * step, 30.0)


def run_spp(obs: ObsData, nav: NavData, systems=None, options=None, fde_alpha: float = 1e-3,
            x_init=None, smooth: float = 0.0) -> SppResult:
    """Single-point positioning of every epoch of ``obs`` with the ephemerides of ``nav`` (``smooth``: the
    Hatch filter's window, s; 0 none)."""
    systems = list(KEPLER_SYSTEMS) if systems is None else list(systems)
    opts = S.spp_options() if options is None else options
    sig = select_signals(obs)
    smooth_signals(obs, sig, smooth)
    sys_on = np.zeros(N_SYS, dtype=np.bool_)
    sys_on[systems] = True
    ion = nav.ion_gps if nav.ion_gps is not None else nav.ion_bds
    ion = np.zeros(8) if ion is None else np.asarray(ion, dtype=np.float64)
    x0 = np.zeros(3) if x_init is None else np.asarray(x_init, dtype=np.float64)
    res = S.solve_epochs(nav.eph, ion, opts, S.chi2_table(fde_alpha), sys_on, obs.time, obs.start,
                         obs.sys.astype(np.int64), obs.prn.astype(np.int64), sig.p1, sig.p2, sig.b1, sig.b2,
                         sig.f1, sig.f2, sig.cn0, sig.dop, x0)
    return SppResult(obs.time, *res, obs=obs, signals=sig, systems=systems)


def run_spp_chunks(obs: ObsData, nav: NavData, systems, options, fde_alpha: float = 1e-3, progress=None,
                   chunk: int = 2000, smooth: float = 0.0) -> SppResult:
    """:func:`run_spp` in chunks of epochs (``progress(n)`` after each), each starting from the last fix."""
    if progress is None or len(obs) <= chunk:
        res = run_spp(obs, nav, systems, options, fde_alpha, smooth=smooth)
        if progress is not None:
            progress(len(obs))
        return res
    sig = select_signals(obs)
    smooth_signals(obs, sig, smooth)
    sys_on = np.zeros(N_SYS, dtype=np.bool_)
    sys_on[list(systems)] = True
    ion = nav.ion_gps if nav.ion_gps is not None else nav.ion_bds
    ion = np.zeros(8) if ion is None else np.asarray(ion, dtype=np.float64)
    tab = S.chi2_table(fde_alpha)
    parts = []
    x0 = np.zeros(3)
    sysr = obs.sys.astype(np.int64)
    prnr = obs.prn.astype(np.int64)
    for a in range(0, len(obs), chunk):
        b = min(a + chunk, len(obs))
        ra, rb = int(obs.start[a]), int(obs.start[b])
        st = obs.start[a:b + 1] - ra
        res = S.solve_epochs(nav.eph, ion, options, tab, sys_on, obs.time[a:b], st, sysr[ra:rb], prnr[ra:rb],
                             sig.p1[ra:rb], sig.p2[ra:rb], sig.b1[ra:rb], sig.b2[ra:rb], sig.f1[ra:rb],
                             sig.f2[ra:rb], sig.cn0[ra:rb], sig.dop[ra:rb], x0)
        parts.append(res)
        fixes = np.nonzero(res[0] == S.FIX)[0]
        if fixes.size:
            x0 = res[1][fixes[-1]].copy()
        progress(b - a)
    joined = [np.concatenate([p[i] for p in parts]) for i in range(len(parts[0]))]
    return SppResult(obs.time, *joined, obs=obs, signals=sig, systems=list(systems))
