"""Per-satellite inputs of the tightly coupled GNSS/INS filter (numba kernel over plain arrays, no I/O).

For every satellite record of every epoch, the parts of the pseudorange and range-rate models that do not
depend on the receiver's state (docs/raw_gnss.md, "Tightly coupled"):

* the satellite's ECEF position and velocity at transmission (:func:`sinscli.gnss.spp.epoch_satellites`:
  ``select_ephemeris``, ``transmit_state``, IS-GPS-200 20.3.3.4.3);
* the corrected pseudorange ``P_c = P + c (dt_sv - T_gd) - I - T`` (:func:`sinscli.gnss.spp._pseudorange_rows`,
  the one implementation SPP uses: group delay, Klobuchar or the ionosphere-free combination, Saastamoinen
  troposphere, and the noise variance with the elevation/C/N0 model, the ionosphere and troposphere residuals
  and the URA), so that the filter predicts ``P_c = rho + c dt_r + ISB``;
* the corrected range rate ``-lambda D + c d(dt_sv)`` and its variance
  (:func:`sinscli.gnss.spp.doppler_variance`), the filter predicting ``d rho/dt + c d(dt_r)``;
* the satellite clock ``c dt_sv`` at transmission, which the carrier phase needs too
  (:mod:`sinscli.gnss.phase`).

The ionosphere and troposphere need the receiver's position: an approximate one per epoch (the epoch's SPP
fix, interpolated across epochs without one; metres of error change them by millimetres).  Per epoch also a
rough receiver clock per system (the median of ``P_c - rho`` at that position) and clock drift: the time
tag of the filter's rows, the filter's initial clock and its clock-jump check.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .model import geo_range, range_rate
from .orbits import earth_rate
from .signals import C_LIGHT, N_SYS
from .spp import _pseudorange_rows, doppler_variance, epoch_arrays, epoch_satellites

MAX_EPOCH_SAT = 128


@njit(cache=True)
def _median(a, n):
    b = np.sort(a[:n])
    return 0.5 * (b[(n - 1) // 2] + b[n // 2])


@njit(cache=True)
def tc_records(eph, ion, opts, sys_on, t_rx, start, rsys, rprn, p1, p2, b1, b2, f1, f2, cn0, dop, pos0, vel0):
    """Per record r: ``ok`` (usable: ephemeris, observation, above the mask), ``sx (R, 6)`` satellite ECEF
    position (m) and velocity (m/s) at transmission, ``prc`` corrected pseudorange (m), ``var_pr`` (m^2),
    ``ratec`` corrected range rate (m/s, NaN without Doppler), ``var_rate`` ((m/s)^2), ``el``, ``az`` (rad,
    at ``pos0``), ``cdts`` the satellite clock ``c dt_sv`` at transmission (m, relativistic term included).
    Per epoch e: ``clk (E, N_SYS)`` the median of ``P_c - rho`` of each system's satellites at the approximate
    ECEF position ``pos0[e]`` (m; NaN: none), ``drift (E,)`` the median of the range-rate residuals at
    ``pos0[e]``, ``vel0[e]`` (m/s, NaN: no Doppler), ``spread (E,)`` the largest deviation from the median among
    the satellites of the epoch's clocks (m).

    Arguments as :func:`sinscli.gnss.spp.solve_epochs` (per record the chosen signals, ``opts`` its options
    vector)."""
    ne = t_rx.shape[0]
    nr = rsys.shape[0]
    ok = np.zeros(nr, np.bool_)
    sx_out = np.zeros((nr, 6))
    prc = np.full(nr, np.nan)
    var_pr = np.full(nr, np.nan)
    ratec = np.full(nr, np.nan)
    var_rate = np.full(nr, np.nan)
    rel = np.full(nr, np.nan)
    raz = np.full(nr, np.nan)
    cdts = np.full(nr, np.nan)
    clk = np.full((ne, N_SYS), np.nan)
    drift = np.full(ne, np.nan)
    spread = np.zeros(ne)
    rec_status = np.zeros(nr, np.int8)
    clk_of = np.zeros(N_SYS, np.int64)          # every system on one clock column, x[3] = 0: v = P_c - rho
    x = np.zeros(4)
    res = np.zeros(MAX_EPOCH_SAT)
    for e in range(ne):
        a0 = start[e]
        nsat = min(start[e + 1] - a0, MAX_EPOCH_SAT)
        if nsat <= 0:
            continue
        sysv, kk, sx, dts, ddts, use, iono_used, el, az, rows = epoch_arrays(nsat)
        h = np.zeros((nsat, 4))
        w = np.zeros(nsat)
        v = np.zeros(nsat)
        t = t_rx[e]
        epoch_satellites(eph, opts, sys_on, t, a0, nsat, rsys, rprn, p1, p2, b1, f1, f2, sysv, kk, sx, dts, ddts,
                         use, iono_used, rec_status)
        x[0] = pos0[e, 0]
        x[1] = pos0[e, 1]
        x[2] = pos0[e, 2]
        x[3] = 0.0
        n = _pseudorange_rows(eph, ion, opts, t, x, clk_of, rows, nsat, p1[a0:a0 + nsat], p2[a0:a0 + nsat],
                              b1[a0:a0 + nsat], b2[a0:a0 + nsat], f1[a0:a0 + nsat], f2[a0:a0 + nsat],
                              cn0[a0:a0 + nsat], sysv, kk, sx, dts, use, iono_used, h, w, v, el, az)
        nd = 0
        for j in range(n):
            i = rows[j]
            r = a0 + i
            s = sysv[i]
            omge = earth_rate(s)
            rho, ex, ey, ez = geo_range(sx[i, 0], sx[i, 1], sx[i, 2], x[0], x[1], x[2], omge)
            ok[r] = True
            for a in range(6):
                sx_out[r, a] = sx[i, a]
            prc[r] = v[j] + rho
            var_pr[r] = 1.0 / w[j]
            rel[r] = el[i]
            raz[r] = az[i]
            cdts[r] = C_LIGHT * dts[i]
            d = dop[r]
            if d == d and vel0[e, 0] == vel0[e, 0]:
                ratec[r] = -C_LIGHT / f1[r] * d + C_LIGHT * ddts[i]
                var_rate[r] = doppler_variance(opts, el[i], cn0[r])
                rate = range_rate(sx[i, 0], sx[i, 1], sx[i, 2], sx[i, 3], sx[i, 4], sx[i, 5], x[0], x[1], x[2],
                                  vel0[e, 0], vel0[e, 1], vel0[e, 2], ex, ey, ez, omge)
                res[nd] = ratec[r] - rate
                nd += 1
            elif d == d:
                ratec[r] = -C_LIGHT / f1[r] * d + C_LIGHT * ddts[i]
                var_rate[r] = doppler_variance(opts, el[i], cn0[r])
        if nd > 0:
            drift[e] = _median(res, nd)
        worst = 0.0
        for s in range(N_SYS):
            m = 0
            for j in range(n):
                if sysv[rows[j]] == s:
                    res[m] = v[j]
                    m += 1
            if m > 0:
                c = _median(res, m)
                clk[e, s] = c
                for q in range(m):
                    worst = max(worst, abs(res[q] - c))
        spread[e] = worst
    return ok, sx_out, prc, var_pr, ratec, var_rate, rel, raz, cdts, clk, drift, spread


__all__ = ["tc_records"]
