"""Raw GNSS observations as measurement rows of the fusion filter (tightly coupled; no file I/O).

:func:`raw_measurements` turns an observation table and its ephemerides into

* the filter's rows (:data:`sinscli.fusion.kernel.ROW`): per epoch one clock row (``MT_CLOCK``: the epoch's
  receiver clock from its own pseudoranges, for the clock-jump check), then one pseudorange row
  (``MT_PR``) and one range-rate row (``MT_DOP``, where the receiver gave a Doppler) per satellite, and with
  ``fusion.raw.tdcp`` one time-differenced carrier-phase row (``MT_TDCP``, :mod:`sinscli.fusion.tdcp`) per
  satellite tracked without a slip since the epoch before (:func:`sinscli.gnss.phase.carrier_pairs`);
* the satellite table (:data:`sinscli.fusion.kernel.SAT`) the rows point into: each satellite's position
  and velocity at transmission (:func:`sinscli.gnss.tc.tc_records`);
* the initial receiver clock bias, drift and inter-system biases (from the first epochs' data);
* a GNSS log of the epochs' single-point fixes (:func:`sinscli.gnss.pipeline.run_spp`), for what the filter
  takes from fixes beside the measurements: the heading from motion, the standstill test, the summary's
  course check, ``--align``; and the approximate positions the ionosphere and troposphere are computed at
  (the SPP fix of the epoch, interpolated across epochs without one, the initial position before the first).

Time: the rows of an epoch tagged ``t_rx`` (receiver clock, GPS seconds) are at ``t_rx - dt_r + offset`` with
``dt_r`` the epoch's clock (the signals' true reception time) and ``offset`` the GNSS time offset
(``gnss.time_offset``, ``--time-offset``: GPS time to the IMU's clock).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import logging

import numpy as np

from ..errors import SinsError
from ..gnss.ephemeris import NavData
from ..gnss.observations import ObsData
from ..gnss.signals import C_LIGHT, KEPLER_SYSTEMS, N_SYS, SYS_CHARS, sat_name
from ..nav.earth import enu_rotation, lla_to_ecef
from ..types import GnssLog, NavState
from . import kernel as kn

SPREAD_FLOOR = 1.0          # m: the least 1-sigma of an epoch's clock from its pseudoranges
INIT_EPOCHS = 10            # epochs whose clocks give the initial inter-system biases
MAX_TDCP_GAP = 2.5          # nominal epoch intervals: epochs further apart give no carrier pair
DOPPLER_K = 6.0             # the Doppler slip test's bound in sigmas of the Dopplers' mean (and raw.slip_doppler)

log = logging.getLogger("sins")


@dataclass
class RawMeasurements:
    """Rows, satellite table and clock start of a raw log (see the module docstring)."""
    rows: np.ndarray                    # (N, kn.MW), time-sorted, on the IMU's clock
    sat: np.ndarray                     # (M, kn.SW)
    ref: int                            # the reference system (its clock is the bias state)
    isb_systems: list                   # the systems with an inter-system bias state, in state order
    t0: float                           # time of the first epoch (IMU clock)
    clock0: tuple                       # (bias m, drift m/s) at t0
    isb0: dict                          # system -> inter-system bias (m) at t0
    clock0_sigma: tuple                 # (m, m/s): 1-sigma of the data's first clock estimate
    epoch_time: np.ndarray              # (E,) epoch times (IMU clock)
    epoch_nsat: np.ndarray              # (E,) usable satellites per epoch (ephemeris, observation, mask)
    spp: GnssLog = None                 # the epochs' single-point fixes (time on the IMU's clock)
    obs_source: str = ""
    notes: list = field(default_factory=list)
    tdcp: bool = False                  # TDCP rows (the filter clones the antenna and the clock bias)
    tdcp_info: dict = field(default_factory=dict)   # pairs, slips per test, phases without a wavelength

    def sat_names(self) -> np.ndarray:
        """``G05`` per satellite-table row."""
        return np.array([sat_name(int(s), int(p)) for s, p in self.sat[:, [kn.SAT_SYS, kn.SAT_PRN]]]) \
            if len(self.sat) else np.zeros(0, dtype="U4")


def _systems(text):
    if text is None:
        return list(KEPLER_SYSTEMS)
    return [SYS_CHARS.index(c) for c in text]


def _approx_states(spp, obs_time, init: NavState):
    """Per epoch an approximate ECEF position and velocity: the SPP fix of the epoch, interpolated across
    epochs without one (the nearest fix outside their span); without any fix the initial state (time-tag
    order is enough: metres of error change the ionosphere and troposphere by millimetres)."""
    ne = len(obs_time)
    ok = spp.fix
    if ok.sum() >= 1:
        te = obs_time[ok]
        pos = np.column_stack([np.interp(obs_time, te, spp.pos[ok, i]) for i in range(3)])
        vok = ok & spp.vel_ok
        vel = np.column_stack([np.interp(obs_time, obs_time[vok], spp.vel[vok, i]) for i in range(3)]) \
            if vok.any() else np.zeros((ne, 3))
        return pos, vel
    p = lla_to_ecef(init.lat, init.lon, init.height)
    v = np.asarray(init.vel_n, float) @ enu_rotation(init.lat, init.lon)
    return np.tile(p, (ne, 1)), np.tile(v, (ne, 1))


def spp_log(spp, offset: float, source: str) -> GnssLog:
    """The SPP fixes as a GNSS log on the IMU's clock (time = solution time + ``offset``)."""
    ok = spp.fix
    lat, lon, h, vel, std, std_v = spp.enu()
    t = spp.solution_time() + offset
    vok = bool(spp.vel_ok[ok].all()) and ok.any()
    return GnssLog(t[ok], lat[ok], lon[ok], h[ok], vel[ok] if vok else None, std[ok], std_v[ok] if vok else None,
                   source=f"{source} (single-point fixes)")


def raw_spp(obs: ObsData, nav: NavData, fopts):
    """The single-point solution of every epoch (snapshot pseudoranges, the ``fusion.raw`` options)."""
    from ..gnss.pipeline import run_spp  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
    return run_spp(obs, nav, systems=_systems(fopts.raw_systems), options=fopts.spp_options())


def raw_measurements(obs: ObsData, nav: NavData, fopts, offset: float, init: NavState, spp=None) -> RawMeasurements:
    """The filter's raw GNSS rows of ``obs`` with ``nav`` (``fopts``: the ``fusion.raw`` and ``fusion.clock``
    options; ``offset``: GPS time -> IMU clock, s; ``init``: the initial state, the approximate position
    before the first fix; ``spp``: :func:`raw_spp` when already run)."""
    from ..gnss.pipeline import select_signals, smooth_signals  # --gnss-raw only
    from ..gnss.tc import tc_records  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
    if len(obs) == 0:
        raise SinsError(f"{obs.source}: no observation epochs")
    systems = _systems(fopts.raw_systems)
    opts = fopts.spp_options()
    spp = raw_spp(obs, nav, fopts) if spp is None else spp
    sig = select_signals(obs)
    smooth_signals(obs, sig, fopts.raw_smooth_code)
    pos0, vel0 = _approx_states(spp, obs.time, init)
    sys_on = np.zeros(N_SYS, dtype=np.bool_)
    sys_on[systems] = True
    ion = nav.ion_gps if nav.ion_gps is not None else nav.ion_bds
    ion = np.zeros(8) if ion is None else np.asarray(ion, dtype=np.float64)
    (ok, sx, prc, var_pr, ratec, var_rate, el, az, cdts, clk, drift,
     spread) = tc_records(nav.eph, ion, opts, sys_on, obs.time, obs.start, obs.sys.astype(np.int64),
                          obs.prn.astype(np.int64), sig.p1, sig.p2, sig.b1, sig.b2, sig.f1, sig.f2, sig.cn0, sig.dop,
                          np.ascontiguousarray(pos0), np.ascontiguousarray(vel0))
    if not ok.any():
        raise SinsError(f"{obs.source}: no usable satellite measurement (ephemerides of "
                        f"{', '.join(SYS_CHARS[s] for s in systems)} for the observed satellites, pseudoranges, "
                        f"elevation over fusion.raw.elevation_mask {fopts.raw_elevation_mask:g} deg)")
    ep = obs.epoch_of_record()
    present = [s for s in KEPLER_SYSTEMS if s in systems and np.any(ok & (obs.sys == s))]
    ref = present[0]
    isb_systems = present[1:]
    # the epochs' reference clock (m): from the reference system's satellites, else another system's less its
    # bias to the reference, else interpolated (time tags and the clock-jump check only)
    c_ref = clk[:, ref].copy()
    isb0 = {}
    for s in isb_systems:
        both = np.nonzero(~np.isnan(clk[:, s]) & ~np.isnan(c_ref))[0][:INIT_EPOCHS]
        isb0[s] = float(np.median(clk[both, s] - c_ref[both])) if len(both) else 0.0
        fill = np.isnan(c_ref) & ~np.isnan(clk[:, s])
        c_ref[fill] = clk[fill, s] - isb0[s]
    have = ~np.isnan(c_ref)
    if not have.all():
        k = np.nonzero(have)[0]
        c_ref = np.interp(np.arange(len(c_ref)), k, c_ref[k])
    t_epoch = obs.time - c_ref / C_LIGHT + offset
    nsat = np.bincount(ep[ok], minlength=len(obs))
    # the satellite table and the rows
    idx = np.nonzero(ok)[0]
    m = len(idx)
    sat = np.zeros((m, kn.SW))
    sat[:, kn.SAT_POS:kn.SAT_POS + 3] = sx[idx, :3]
    sat[:, kn.SAT_VEL:kn.SAT_VEL + 3] = sx[idx, 3:]
    sat[:, kn.SAT_SYS] = obs.sys[idx]
    sat[:, kn.SAT_PRN] = obs.prn[idx]
    sat[:, kn.SAT_EL] = el[idx]
    te = t_epoch[ep[idx]]
    zeros = np.zeros(m)
    pr_rows = np.column_stack([te, np.full(m, kn.MT_PR), prc[idx], zeros, zeros, np.sqrt(var_pr[idx]), zeros, zeros,
                               np.arange(m, dtype=float), obs.sys[idx].astype(float)])
    hd = ~np.isnan(ratec[idx])
    dop_rows = np.column_stack([te[hd], np.full(hd.sum(), kn.MT_DOP), ratec[idx][hd], zeros[hd], zeros[hd],
                                np.sqrt(var_rate[idx][hd]), zeros[hd], zeros[hd], np.arange(m, dtype=float)[hd],
                                obs.sys[idx][hd].astype(float)])
    ce = np.nonzero((nsat > 0) & ~np.isnan(clk[:, ref]))[0]
    ne = len(ce)
    clock_rows = np.column_stack([t_epoch[ce], np.full(ne, kn.MT_CLOCK), clk[ce, ref], np.nan_to_num(drift[ce]),
                                  np.zeros(ne), np.maximum(spread[ce], SPREAD_FLOOR), np.zeros((ne, 2)),
                                  np.full(ne, -1.0), np.full(ne, float(ref))])
    tdcp_rows, tdcp_info = np.zeros((0, kn.MW)), {}
    notes = []
    if fopts.raw_tdcp:
        tdcp_rows, tdcp_info = tdcp_rows_of(obs, sig, ok, idx, t_epoch, el, az, cdts, var_rate, pos0, ion, opts,
                                            fopts)
        if tdcp_info.get("carriers", 0) == 0:
            msg = (f"{obs.source}: no carrier-phase observation of the satellites used: TDCP off, the filter runs "
                   f"on the pseudoranges and Dopplers")
            log.warning("%s", msg)
            notes.append("no carrier phase: TDCP off")
    rows = np.vstack([clock_rows, pr_rows, dop_rows, tdcp_rows])
    order = {kn.MT_CLOCK: 0, kn.MT_PR: 1, kn.MT_DOP: 2, kn.MT_TDCP: 3}
    key = np.array([order[int(k)] for k in rows[:, 1]])
    rows = rows[np.lexsort((key, rows[:, 0]))]
    # the clock's start: the first epoch after the initial time with the reference system's satellites
    after = ce[t_epoch[ce] > init.time] if ne else ce
    if not len(after):
        raise SinsError(f"{obs.source}: no epoch with satellites after the initial time {init.time!r} s (epochs "
                        f"{float(t_epoch[0])!r} to {float(t_epoch[-1])!r} s on the IMU's clock; GNSS time offset "
                        f"{offset:g} s)")
    e0 = int(after[0])
    d0 = drift[e0] if not np.isnan(drift[e0]) else 0.0
    b_sig = max(SPREAD_FLOOR, float(spread[e0]))
    if not spp.fix.any():
        notes.append("no epoch had a single-point fix: the ionosphere and troposphere are computed at the initial "
                     "position, and there is no heading from motion or GNSS standstill test")
    return RawMeasurements(rows=rows, sat=sat, ref=ref, isb_systems=isb_systems, t0=float(t_epoch[e0]),
                           clock0=(float(c_ref[e0]), float(d0)), isb0=isb0, clock0_sigma=(b_sig, 0.0),
                           epoch_time=t_epoch, epoch_nsat=nsat, spp=spp_log(spp, offset, obs.source),
                           obs_source=obs.source, notes=notes, tdcp=bool(len(tdcp_rows)), tdcp_info=tdcp_info)


def tdcp_rows_of(obs, sig, ok, idx, t_epoch, el, az, cdts, var_rate, pos0, ion, opts, fopts):
    """The TDCP rows (:data:`sinscli.fusion.kernel.MT_TDCP`) of every satellite usable in two consecutive epochs
    with the primary signal's carrier in both and no slip found by :func:`sinscli.gnss.phase.carrier_pairs`:
    ``z = (Delta Phi_c, satellite-table row of the earlier epoch, its time)``, sigma ``carrier_sigma`` times the
    two carriers' elevation/C/N0 shape, ``aux = (satellite-table row, system)``.  Returns ``(rows, info)``, info
    the carriers seen, the pairs, the pairs left out per test and the phases of signals without a wavelength."""
    from ..gnss.phase import carrier_pairs, slip_counts, unknown_wavelength  # --gnss-raw --tdcp only
    from ..gnss.spp import IONO_OFF, O_IONO, O_TROPO  # --gnss-raw --tdcp only
    step = float(np.median(np.diff(obs.time))) if len(obs) > 1 else 1.0
    prev, dz, shape, status, _ = carrier_pairs(
        opts, ion, obs.time, obs.start, obs.sys.astype(np.int64), obs.prn.astype(np.int64), ok, sig.l1, sig.lli1,
        sig.f1, sig.l2, sig.lli2, sig.f2, sig.dop, var_rate, sig.cn0, el, az, cdts, np.ascontiguousarray(pos0),
        opts[O_IONO] != IONO_OFF, opts[O_TROPO] > 0.0, MAX_TDCP_GAP * step, DOPPLER_K, fopts.raw_slip_doppler,
        fopts.raw_slip_gf, False)
    ep = obs.epoch_of_record()
    cur = np.nonzero(prev >= 0)[0]
    pv = prev[cur]
    side = np.full(obs.n_records, -1.0)
    side[idx] = np.arange(len(idx), dtype=float)
    n = len(cur)
    zeros = np.zeros(n)
    rows = np.column_stack([t_epoch[ep[cur]], np.full(n, kn.MT_TDCP), dz[cur], side[pv], t_epoch[ep[pv]],
                            fopts.raw_carrier_sigma * np.sqrt(shape[cur]), zeros, zeros, side[cur],
                            obs.sys[cur].astype(float)])
    info = {"carriers": int(np.count_nonzero(status >= 0)), "pairs": n, "slips": slip_counts(status),
            "unknown": unknown_wavelength(obs)}
    return rows, info


def tdcp_notes(rec, events, info) -> list[str]:
    """The summary's TDCP lines (``fusion: raw GNSS: ...``): the carrier pairs the filter used and rejected, the
    slips its INS-aided test found (``events``: :data:`sinscli.fusion.kernel.EV_SLIP`), the pairs the tests
    before the filter left out, and the phases skipped for want of a wavelength."""
    m = rec["type"] == "tdcp"
    acc = rec["accepted"][m]
    slips = int(np.sum(events[:, 1] == kn.EV_SLIP)) if len(events) else 0
    rms = float(np.sqrt(np.mean(rec["innovation"][m][acc] ** 2))) if acc.any() else float("nan")
    pre = ", ".join(f"{k} {v}" for k, v in info["slips"].items())
    out = [f"TDCP: {info['pairs']} carrier pairs; in the filter {int(acc.sum())} used, {int((~acc).sum())} rejected "
           f"({slips} as cycle slips by the INS-aided test)" + (f", innovation RMS {rms * 1000:.3g} mm" if acc.any()
                                                                  else "")
           + f"; left out before the filter as slips: {pre}"]
    if info.get("unknown"):
        out.append("carrier phases of signals without a known wavelength skipped: "
                   + ", ".join(f"{k} {v}" for k, v in info["unknown"].items()))
    return out


def satellite_counts(letters, rec_type, accepted):
    """Per system letter (of each record's satellite) ``(pseudoranges used, rejected, range rates used,
    rejected)``."""
    out = {}
    for s in sorted(np.unique(letters), key=lambda c: SYS_CHARS.find(str(c))):
        m = letters == s
        c = []
        for t in ("pseudorange", "doppler"):
            k = m & (rec_type == t)
            c += [int((k & accepted).sum()), int((k & ~accepted).sum())]
        out[str(s)] = tuple(c)
    return out


__all__ = ["RawMeasurements", "raw_measurements", "raw_spp", "spp_log", "satellite_counts", "tdcp_rows_of", "tdcp_notes"]
