"""Single-point positioning and Doppler velocity (numba kernels over plain arrays, no I/O).

Per epoch: satellite states at transmission (:mod:`orbits`, :mod:`model`), Klobuchar or the
ionosphere-free combination, Saastamoinen troposphere, elevation and C/N0 weights, one receiver clock per
system, iterated weighted least squares, chi-square fault detection excluding one satellite at a time, the
covariance of the solution (scaled up by the unit-weight variance pooled over recent epochs when that exceeds
1: the chi-square test uses the same scale, so a noise model that is too optimistic neither excludes good
satellites nor gives optimistic sigmas), DOPs, then
weighted least squares on the Doppler range rates for velocity and clock drift.  Equations: docs/raw_gnss.md.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.stats import chi2

from ..nav.linalg import cholesky_inverse
from .corrections import klobuchar, mapping_mops, tropo_delay
from .ephemeris import URA, max_age, select_ephemeris
from .model import azel, ecef_to_geodetic, geo_range, group_delay, range_rate, transmit_state
from .orbits import earth_rate
from .signals import C_LIGHT, N_SYS, SYS_GAL

# options vector (spp_options builds it)
(O_ELMASK, O_IONO, O_TROPO, O_CODE_A, O_CODE_B, O_CN0_REF, O_DOP_SIGMA, O_IONO_VAR, O_TROPO_SIGMA, O_URA,
 O_FDE, O_MAXITER, O_MAX_EXCL, O_VARFACTOR) = range(14)
N_OPT = 14
IONO_OFF, IONO_KLOBUCHAR, IONO_IFLC = 0, 1, 2

# record status codes
USED, NO_OBS, NO_EPH, BELOW_MASK, EXCLUDED, SYSTEM_OFF, NO_SOLUTION = 0, 1, 2, 3, 4, 5, 6
# epoch status codes
FIX, TOO_FEW, NO_CONVERGENCE, CHI2_FAILED = 0, 1, 2, 3

MAX_SAT = 128


def chi2_quantile(p: float, dof: int) -> float:
    """Quantile of the chi-square distribution (scipy.stats, as the fusion filter's gates)."""
    return float(chi2.ppf(p, dof))


def chi2_table(alpha: float, n: int = MAX_SAT) -> np.ndarray:
    """``table[dof]`` = the (1 - alpha) chi-square quantile, dof = 0..n-1 (table[0] = inf)."""
    t = np.full(n, np.inf)
    for k in range(1, n):
        t[k] = chi2_quantile(1.0 - alpha, k)
    return t


@njit(cache=True)
def code_variance(opts, el, cn0):
    """Pseudorange noise variance (m^2): ``(a^2 + b^2 / sin^2 el) * max(1, 10^((C/N0_ref - C/N0)/10))``:
    the elevation model of RTKLIB's ``varerr`` times the inverse C/N0 law of a delay-lock loop's thermal
    noise (C/N0 in dB-Hz; NaN or 0: no C/N0 term)."""
    s = math.sin(el)
    v = opts[O_CODE_A] ** 2 + opts[O_CODE_B] ** 2 / (s * s)
    if cn0 == cn0 and cn0 > 0.0 and opts[O_CN0_REF] > 0.0:
        f = 10.0 ** ((opts[O_CN0_REF] - cn0) / 10.0)
        if f > 1.0:
            v *= f
    return v


@njit(cache=True)
def doppler_variance(opts, el, cn0):
    """Range-rate noise variance ((m/s)^2): ``sigma_d^2`` times the same elevation and C/N0 shape as
    :func:`code_variance`, normalized to 1 at the zenith and at the reference C/N0."""
    a2 = opts[O_CODE_A] ** 2
    b2 = opts[O_CODE_B] ** 2
    shape = code_variance(opts, el, cn0) / (a2 + b2) if a2 + b2 > 0.0 else 1.0
    return opts[O_DOP_SIGMA] ** 2 * shape


@njit(cache=True)
def _solve_normal(h, w, v, n, m):
    """Weighted least squares over the first n rows: ``(dx, Q = (H^T W H)^-1, ok)``."""
    nmat = np.zeros((m, m))
    rhs = np.zeros(m)
    for i in range(n):
        for a in range(m):
            ha = h[i, a] * w[i]
            if ha == 0.0:
                continue
            rhs[a] += ha * v[i]
            for b in range(m):
                nmat[a, b] += ha * h[i, b]
    for a in range(m):
        if nmat[a, a] <= 0.0:
            return rhs, nmat, False
    linv, _ = cholesky_inverse(nmat)
    for a in range(m):
        if not (abs(linv[a, a]) < 1e6):          # singular geometry (a clock without a satellite, ...)
            return rhs, nmat, False
    q = np.zeros((m, m))                        # Q = L^-T L^-1 and dx = Q rhs by loops: numba's @ needs scipy
    for a in range(m):
        for b in range(a, m):
            acc = 0.0
            for k in range(b, m):
                acc += linv[k, a] * linv[k, b]
            q[a, b] = acc
            q[b, a] = acc
    dx = np.zeros(m)
    for a in range(m):
        acc = 0.0
        for b in range(m):
            acc += q[a, b] * rhs[b]
        dx[a] = acc
    return dx, q, True


@njit(cache=True)
def _pseudorange_rows(eph, ion, opts, t_rx, x, clk_of, rows, nsat, p1, p2, b1, b2, f1, f2, cn0, sysv, kk,
                      sx, dts, use, iono_used, h, w, v, el, az):
    """Fill design rows, weights and residuals of the satellites ``use`` (receiver at ``x``, clocks
    ``x[3:]`` indexed by ``clk_of[sys]``).  Returns the number of rows; per satellite its elevation and
    azimuth."""
    known = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > 1e12
    lat, lon, hgt = 0.0, 0.0, 0.0
    if known:
        lat, lon, hgt = ecef_to_geodetic(x[0], x[1], x[2])
    n = 0
    tow = t_rx - math.floor(t_rx / 604800.0) * 604800.0
    for i in range(nsat):
        if not use[i]:
            continue
        k = kk[i]
        s = sysv[i]
        omge = earth_rate(s)
        rho, ex, ey, ez = geo_range(sx[i, 0], sx[i, 1], sx[i, 2], x[0], x[1], x[2], omge)
        if known:
            a_, e_ = azel(lat, lon, ex, ey, ez)
        else:
            a_, e_ = 0.0, math.pi / 2.0
        az[i] = a_
        el[i] = e_
        if known and e_ < opts[O_ELMASK]:
            use[i] = False
            continue
        iono = 0.0
        var = 0.0
        if iono_used[i]:
            fa = f1[i] * f1[i]
            fb = f2[i] * f2[i]
            pr = (fa * p1[i] - fb * p2[i]) / (fa - fb)
            gd = (fa * group_delay(eph, k, b1[i], f1[i]) - fb * group_delay(eph, k, b2[i], f2[i])) / (fa - fb)
            var = code_variance(opts, e_, cn0[i]) * (fa * fa + fb * fb) / ((fa - fb) * (fa - fb))
        else:
            pr = p1[i]
            gd = group_delay(eph, k, b1[i], f1[i])
            var = code_variance(opts, e_, cn0[i])
            if opts[O_IONO] != IONO_OFF and known:
                iono = klobuchar(ion, lat, lon, a_, e_, tow) * (1575.42e6 / f1[i]) ** 2
                var += (opts[O_IONO_VAR] * iono) ** 2
        trop = 0.0
        if opts[O_TROPO] > 0.0 and known:
            trop = tropo_delay(lat, hgt, e_)
            var += (opts[O_TROPO_SIGMA] * mapping_mops(e_)) ** 2
        if opts[O_URA] > 0.0:
            var += eph[k, URA] ** 2
        c = clk_of[s]
        pred = rho + x[3 + c] - C_LIGHT * (dts[i] - gd) + iono + trop
        for a in range(h.shape[1]):
            h[n, a] = 0.0
        h[n, 0] = -ex
        h[n, 1] = -ey
        h[n, 2] = -ez
        h[n, 3 + c] = 1.0
        w[n] = 1.0 / var
        v[n] = pr - pred
        rows[n] = i
        n += 1
    return n


@njit(cache=True)
def _clock_map(use, sysv, nsat, clk_of):
    """Clock column per system among the satellites in use; returns the number of clocks."""
    for s in range(N_SYS):
        clk_of[s] = -1
    nc = 0
    for i in range(nsat):
        if use[i] and clk_of[sysv[i]] < 0:
            clk_of[sysv[i]] = nc
            nc += 1
    return nc


@njit(cache=True)
def _lsq_position(eph, ion, opts, t_rx, x, rows, nsat, p1, p2, b1, b2, f1, f2, cn0, sysv, kk, sx, dts, use,
                  iono_used, el, az, q_out, clk_of):
    """Iterated weighted least squares from ``x`` (updated in place).  Returns ``(ok, n, m, chi2)``."""
    m_max = 3 + N_SYS
    h = np.zeros((nsat, m_max))
    w = np.zeros(nsat)
    v = np.zeros(nsat)
    ok = False
    n = 0
    m = 0
    chi2 = 0.0
    for it in range(int(opts[O_MAXITER])):
        nc = _clock_map(use, sysv, nsat, clk_of)
        # clocks of systems that came or went: the state keeps one slot per system present
        m = 3 + nc
        n = _pseudorange_rows(eph, ion, opts, t_rx, x, clk_of, rows, nsat, p1, p2, b1, b2, f1, f2, cn0, sysv,
                              kk, sx, dts, use, iono_used, h, w, v, el, az)
        nc2 = _clock_map(use, sysv, nsat, clk_of)
        if nc2 != nc:                    # the elevation mask removed a whole system: redo the rows
            m = 3 + nc2
            n = _pseudorange_rows(eph, ion, opts, t_rx, x, clk_of, rows, nsat, p1, p2, b1, b2, f1, f2, cn0,
                                  sysv, kk, sx, dts, use, iono_used, h, w, v, el, az)
        if n < m:
            return False, n, m, 0.0
        dx, q, good = _solve_normal(h[:, :m], w, v, n, m)
        if not good:
            return False, n, m, 0.0
        for a in range(m):
            x[a] += dx[a]
        step = math.sqrt(dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2)
        if step < 1e-4:
            # residuals at the solution
            n = _pseudorange_rows(eph, ion, opts, t_rx, x, clk_of, rows, nsat, p1, p2, b1, b2, f1, f2, cn0,
                                  sysv, kk, sx, dts, use, iono_used, h, w, v, el, az)
            if n < m or _clock_map(use, sysv, nsat, clk_of) != m - 3:
                continue
            chi2 = 0.0
            for i in range(n):
                chi2 += v[i] * v[i] * w[i]
            dx, q, good = _solve_normal(h[:, :m], w, v, n, m)
            if not good:
                return False, n, m, 0.0
            for a in range(m):
                for b in range(m):
                    q_out[a, b] = q[a, b]
            ok = True
            break
    return ok, n, m, chi2


@njit(cache=True)
def _dops(x, el, az, use, sysv, nsat, clk_of, m):
    """PDOP, HDOP, VDOP of the unweighted geometry (one clock column per system)."""
    lat, lon, _ = ecef_to_geodetic(x[0], x[1], x[2])
    g = np.zeros((nsat, m))
    n = 0
    for i in range(nsat):
        if not use[i]:
            continue
        ce = math.cos(el[i])
        g[n, 0] = ce * math.sin(az[i])
        g[n, 1] = ce * math.cos(az[i])
        g[n, 2] = math.sin(el[i])
        g[n, 3 + clk_of[sysv[i]]] = 1.0
        n += 1
    ones = np.ones(n)
    dx, q, ok = _solve_normal(g, ones, ones, n, m)
    if not ok:
        return np.nan, np.nan, np.nan
    return math.sqrt(q[0, 0] + q[1, 1] + q[2, 2]), math.sqrt(q[0, 0] + q[1, 1]), math.sqrt(q[2, 2])


@njit(cache=True)
def epoch_arrays(nsat):
    """The per-satellite arrays of one epoch that :func:`epoch_satellites` and :func:`_pseudorange_rows` fill:
    ``(sysv, kk, sx, dts, ddts, use, iono_used, el, az, rows)``."""
    return (np.empty(nsat, np.int64), np.full(nsat, -1, np.int64), np.zeros((nsat, 6)), np.zeros(nsat),
            np.zeros(nsat), np.zeros(nsat, np.bool_), np.zeros(nsat, np.bool_), np.full(nsat, np.nan),
            np.full(nsat, np.nan), np.zeros(nsat, np.int64))


@njit(cache=True)
def epoch_satellites(eph, opts, sys_on, t, a0, nsat, rsys, rprn, p1, p2, b1, f1, f2, sysv, kk, sx, dts, ddts, use,
                     iono_used, rec_status):
    """The satellites of one epoch (records ``a0 .. a0 + nsat`` received at ``t``, receiver clock time): per
    satellite its system ``sysv``, ephemeris row ``kk`` (:func:`select_ephemeris`; Galileo I/NAV for E1/E5b,
    F/NAV for E5a), state at transmission ``sx`` (ECEF position, velocity), clock ``dts`` and drift ``ddts``
    (:func:`transmit_state`), ``use`` and ``iono_used`` (the ionosphere-free combination, only for a system all
    of whose satellites in the epoch have two frequencies: a receiver's inter-frequency code bias would otherwise
    enter as a per-satellite error); ``rec_status`` of the records left out.  Shared by single-point positioning
    and the tightly coupled filter's measurement rows (:mod:`sinscli.gnss.tc`)."""
    for i in range(nsat):
        r = a0 + i
        s = int(rsys[r])
        sysv[i] = s
        if s < 0 or not sys_on[s]:
            rec_status[r] = SYSTEM_OFF
            continue
        if not (p1[r] == p1[r]) or f1[r] <= 0.0:
            rec_status[r] = NO_OBS
            continue
        pref = 0
        if s == SYS_GAL:
            pref = 0b010 if b1[r] == 5 else 0b101
        k = select_ephemeris(eph, s, int(rprn[r]), t, max_age(s), pref)
        if k < 0:
            rec_status[r] = NO_EPH
            continue
        kk[i] = k
        t_tx, xs, ys, zs, vxs, vys, vzs, dt_s, ddt_s = transmit_state(eph, k, t, p1[r])
        sx[i, 0], sx[i, 1], sx[i, 2] = xs, ys, zs
        sx[i, 3], sx[i, 4], sx[i, 5] = vxs, vys, vzs
        dts[i] = dt_s
        ddts[i] = ddt_s
        use[i] = True
        iono_used[i] = opts[O_IONO] == IONO_IFLC and p2[r] == p2[r] and f2[r] > 0.0 and f2[r] != f1[r]
    for s in range(N_SYS):
        all_two = True
        for i in range(nsat):
            if use[i] and sysv[i] == s and not iono_used[i]:
                all_two = False
        if not all_two:
            for i in range(nsat):
                if sysv[i] == s:
                    iono_used[i] = False


@njit(cache=True)
def solve_epochs(eph, ion, opts, chi2_tab, sys_on, t_rx, start, rsys, rprn, p1, p2, b1, b2, f1, f2, cn0, dop,
                 x_init):
    """Single-point position and Doppler velocity of every epoch.

    Per record r: ``p1`` primary pseudorange (m), ``p2`` second-frequency pseudorange (NaN: none), ``b1``,
    ``b2`` their RINEX bands, ``f1``, ``f2`` carrier frequencies (Hz), ``cn0`` (dB-Hz) and ``dop`` the
    primary Doppler (Hz, NaN: none).  ``sys_on[s]`` selects systems; ``x_init`` (3,) a starting position
    (zeros: the Earth's centre).

    Returns per epoch ``status, pos (E,3) ECEF, cov (E,3,3), clk (E,N_SYS) m (NaN: system absent), vel
    (E,3), cov_vel (E,3,3), drift (E,) m/s, nsat, pdop, hdop, vdop, chi2, dof, vel_ok`` and per record
    ``rec_status, resid (m), el (rad), az (rad)``.
    """
    ne = t_rx.shape[0]
    nr = rsys.shape[0]
    status = np.full(ne, TOO_FEW, np.int8)
    pos = np.full((ne, 3), np.nan)
    cov = np.full((ne, 3, 3), np.nan)
    clk = np.full((ne, N_SYS), np.nan)
    vel = np.full((ne, 3), np.nan)
    cov_vel = np.full((ne, 3, 3), np.nan)
    drift = np.full(ne, np.nan)
    nsat_used = np.zeros(ne, np.int32)
    pdop = np.full(ne, np.nan)
    hdop = np.full(ne, np.nan)
    vdop = np.full(ne, np.nan)
    chi2_out = np.full(ne, np.nan)
    dof_out = np.zeros(ne, np.int32)
    vel_ok = np.zeros(ne, np.bool_)
    rec_status = np.full(nr, NO_OBS, np.int8)
    resid = np.full(nr, np.nan)
    rel = np.full(nr, np.nan)
    raz = np.full(nr, np.nan)
    x = np.zeros(3 + N_SYS)
    x_prev = np.zeros(3)
    x_prev[:] = x_init
    have_prev = x_init[0] ** 2 + x_init[1] ** 2 + x_init[2] ** 2 > 1e12
    clk_of = np.full(N_SYS, -1, np.int64)
    q = np.zeros((3 + N_SYS, 3 + N_SYS))
    # unit-weight variance pooled over recent epochs (forgetting factor 0.98, ~50 epochs): the measurement
    # noise model's scale as the data show it, for the chi-square test and the covariance
    pool_t = 0.0
    pool_d = 0.0
    pool_tv = 0.0
    pool_dv = 0.0
    for e in range(ne):
        a0 = start[e]
        nsat = start[e + 1] - a0
        if nsat <= 0:
            continue
        sysv, kk, sx, dts, ddts, use, iono_used, el, az, rows = epoch_arrays(nsat)
        pp1 = p1[a0:a0 + nsat]
        pp2 = p2[a0:a0 + nsat]
        bb1 = b1[a0:a0 + nsat]
        bb2 = b2[a0:a0 + nsat]
        ff1 = f1[a0:a0 + nsat]
        ff2 = f2[a0:a0 + nsat]
        cc = cn0[a0:a0 + nsat]
        t = t_rx[e]
        epoch_satellites(eph, opts, sys_on, t, a0, nsat, rsys, rprn, p1, p2, b1, f1, f2, sysv, kk, sx, dts, ddts,
                         use, iono_used, rec_status)
        cand = use.copy()
        for a in range(3 + N_SYS):
            x[a] = 0.0
        if have_prev:
            x[0] = x_prev[0]
            x[1] = x_prev[1]
            x[2] = x_prev[2]
        ok, n, m, chi2 = _lsq_position(eph, ion, opts, t, x, rows, nsat, pp1, pp2, bb1, bb2, ff1, ff2, cc, sysv,
                                       kk, sx, dts, use, iono_used, el, az, q, clk_of)
        if not ok and have_prev:          # a bad start (a jump): again from the Earth's centre
            use[:] = cand
            for a in range(3 + N_SYS):
                x[a] = 0.0
            ok, n, m, chi2 = _lsq_position(eph, ion, opts, t, x, rows, nsat, pp1, pp2, bb1, bb2, ff1, ff2, cc,
                                           sysv, kk, sx, dts, use, iono_used, el, az, q, clk_of)
        for i in range(nsat):
            if cand[i] and not use[i]:
                rec_status[a0 + i] = BELOW_MASK
            rel[a0 + i] = el[i]
            raz[a0 + i] = az[i]
        if not ok:
            status[e] = TOO_FEW if n < m else NO_CONVERGENCE
            for i in range(nsat):
                if use[i]:
                    rec_status[a0 + i] = NO_SOLUTION
            continue
        # chi-square test; exclude one satellite at a time while it fails
        excluded = np.zeros(nsat, np.bool_)
        n_excl = 0
        lam = 1.0
        if opts[O_VARFACTOR] > 0.0 and pool_d > 0.0 and pool_t / pool_d > 1.0:
            lam = pool_t / pool_d
        passed = n - m < 1 or chi2 / lam <= chi2_tab[min(n - m, chi2_tab.shape[0] - 1)]
        while not passed and opts[O_FDE] > 0.0 and n_excl < opts[O_MAX_EXCL] and n - m >= 2:
            best_i = -1
            best_t = np.inf
            xb = x.copy()
            for i in range(nsat):
                if not use[i]:
                    continue
                trial = use.copy()
                trial[i] = False
                xt = x.copy()
                qt = np.zeros_like(q)
                clk_t = clk_of.copy()
                elt = el.copy()
                azt = az.copy()
                okt, nt, mt, c2 = _lsq_position(eph, ion, opts, t, xt, rows, nsat, pp1, pp2, bb1, bb2, ff1, ff2,
                                                cc, sysv, kk, sx, dts, trial, iono_used, elt, azt, qt, clk_t)
                if okt and nt - mt >= 1:
                    score = c2 / lam / chi2_tab[min(nt - mt, chi2_tab.shape[0] - 1)]
                    if score < best_t:
                        best_t = score
                        best_i = i
                        xb = xt
            if best_i < 0:
                break
            use[best_i] = False
            excluded[best_i] = True
            n_excl += 1
            x[:] = xb
            ok, n, m, chi2 = _lsq_position(eph, ion, opts, t, x, rows, nsat, pp1, pp2, bb1, bb2, ff1, ff2, cc,
                                           sysv, kk, sx, dts, use, iono_used, el, az, q, clk_of)
            if not ok:
                break
            passed = chi2 / lam <= chi2_tab[min(n - m, chi2_tab.shape[0] - 1)]
        if not ok:
            status[e] = NO_CONVERGENCE
            continue
        dof = n - m
        if dof >= 1 and passed:
            pool_t = 0.98 * pool_t + chi2
            pool_d = 0.98 * pool_d + dof
        scale = 1.0
        if opts[O_VARFACTOR] > 0.0 and pool_d > 0.0 and pool_t / pool_d > 1.0:
            scale = pool_t / pool_d
        status[e] = FIX if passed else CHI2_FAILED
        for a in range(3):
            pos[e, a] = x[a]
            for b in range(3):
                cov[e, a, b] = q[a, b] * scale
        for s in range(N_SYS):
            if clk_of[s] >= 0:
                clk[e, s] = x[3 + clk_of[s]]
        nsat_used[e] = n
        chi2_out[e] = chi2
        dof_out[e] = dof
        pdop[e], hdop[e], vdop[e] = _dops(x, el, az, use, sysv, nsat, clk_of, m)
        # residuals and record status
        hh = np.zeros((nsat, 3 + N_SYS))
        ww = np.zeros(nsat)
        vv = np.zeros(nsat)
        nn = _pseudorange_rows(eph, ion, opts, t, x, clk_of, rows, nsat, pp1, pp2, bb1, bb2, ff1, ff2, cc, sysv,
                               kk, sx, dts, use, iono_used, hh, ww, vv, el, az)
        for j in range(nn):
            resid[a0 + rows[j]] = vv[j]
        for i in range(nsat):
            if use[i]:
                rec_status[a0 + i] = USED
            elif excluded[i]:
                rec_status[a0 + i] = EXCLUDED
        x_prev[0] = x[0]
        x_prev[1] = x[1]
        x_prev[2] = x[2]
        have_prev = True
        # Doppler velocity and clock drift
        vx = np.zeros(4)
        hd = np.zeros((nsat, 4))
        wd = np.zeros(nsat)
        vd = np.zeros(nsat)
        okv = False
        qd = np.zeros((4, 4))
        nd = 0
        for it in range(4):
            nd = 0
            for i in range(nsat):
                r = a0 + i
                if not use[i] or not (dop[r] == dop[r]):
                    continue
                rho, ex, ey, ez = geo_range(sx[i, 0], sx[i, 1], sx[i, 2], x[0], x[1], x[2], earth_rate(sysv[i]))
                rate = range_rate(sx[i, 0], sx[i, 1], sx[i, 2], sx[i, 3], sx[i, 4], sx[i, 5], x[0], x[1], x[2],
                                  vx[0], vx[1], vx[2], ex, ey, ez, earth_rate(sysv[i]))
                obs = -C_LIGHT / ff1[i] * dop[r]
                hd[nd, 0] = -ex
                hd[nd, 1] = -ey
                hd[nd, 2] = -ez
                hd[nd, 3] = 1.0
                wd[nd] = 1.0 / doppler_variance(opts, el[i], cc[i])
                vd[nd] = obs - (rate + vx[3] - C_LIGHT * ddts[i])
                nd += 1
            if nd < 4:
                break
            dxv, qd, good = _solve_normal(hd, wd, vd, nd, 4)
            if not good:
                break
            for a in range(4):
                vx[a] += dxv[a]
            if math.sqrt(dxv[0] ** 2 + dxv[1] ** 2 + dxv[2] ** 2) < 1e-6:
                okv = True
                break
        if okv:
            c2 = 0.0
            for j in range(nd):
                c2 += vd[j] * vd[j] * wd[j]
            if nd > 4:
                pool_tv = 0.98 * pool_tv + c2
                pool_dv = 0.98 * pool_dv + (nd - 4)
            sc = 1.0
            if opts[O_VARFACTOR] > 0.0 and pool_dv > 0.0 and pool_tv / pool_dv > 1.0:
                sc = pool_tv / pool_dv
            vel_ok[e] = True
            drift[e] = vx[3]
            for a in range(3):
                vel[e, a] = vx[a]
                for b in range(3):
                    cov_vel[e, a, b] = qd[a, b] * sc
    return (status, pos, cov, clk, vel, cov_vel, drift, nsat_used, pdop, hdop, vdop, chi2_out, dof_out, vel_ok,
            rec_status, resid, rel, raz)


def spp_options(elev_mask_deg=15.0, iono="auto", tropo=True, code_a=0.3, code_b=0.3, cn0_ref=45.0,
                doppler_sigma=0.1, iono_var=0.5, tropo_sigma=0.1, use_ura=True, fde=True, max_iter=12,
                max_exclude=3, variance_factor=True) -> np.ndarray:
    """The options vector of :func:`solve_epochs` (see docs/raw_gnss.md for each)."""
    o = np.zeros(N_OPT)
    o[O_ELMASK] = math.radians(elev_mask_deg)
    o[O_IONO] = {"off": IONO_OFF, "klobuchar": IONO_KLOBUCHAR, "iflc": IONO_IFLC, "auto": IONO_IFLC}[iono]
    o[O_TROPO] = 1.0 if tropo else 0.0
    o[O_CODE_A], o[O_CODE_B], o[O_CN0_REF] = code_a, code_b, cn0_ref
    o[O_DOP_SIGMA] = doppler_sigma
    o[O_IONO_VAR], o[O_TROPO_SIGMA] = iono_var, tropo_sigma
    o[O_URA] = 1.0 if use_ura else 0.0
    o[O_FDE] = 1.0 if fde else 0.0
    o[O_MAXITER], o[O_MAX_EXCL] = max_iter, max_exclude
    o[O_VARFACTOR] = 1.0 if variance_factor else 0.0
    return o


__all__ = ["solve_epochs", "spp_options", "chi2_table", "code_variance", "doppler_variance", "hatch_smooth"]


@njit(cache=True)
def hatch_smooth(t, start, rsys, rprn, pr, carrier, lli, wavelength, n_max, max_gap, max_jump):
    """Carrier-smoothed pseudoranges (Hatch filter; RTCA DO-229 J.2.2): per satellite
    ``P_s,k = P_k / n + (n-1)/n (P_s,k-1 + lambda (L_k - L_k-1))`` with ``n = min(k, n_max)``, restarted at a
    loss-of-lock flag, a gap over ``max_gap`` s, a missing carrier, or when the raw pseudorange is more than
    ``max_jump`` m from the smoothed prediction (a cycle slip the receiver missed).  Returns the smoothed
    pseudoranges (R,) (the raw value where no carrier)."""
    out = pr.copy()
    key_n = 8 * 1024
    last_t = np.full(key_n, -1e300)
    last_p = np.zeros(key_n)
    last_l = np.zeros(key_n)
    count = np.zeros(key_n, np.int64)
    for e in range(t.shape[0]):
        for r in range(start[e], start[e + 1]):
            k = int(rsys[r]) * 1024 + int(rprn[r])
            if k < 0 or k >= key_n:
                continue
            p = pr[r]
            l = carrier[r]
            if not (p == p):
                count[k] = 0
                continue
            if not (l == l) or wavelength[r] <= 0.0:
                count[k] = 0
                continue
            restart = count[k] == 0 or (lli[r] & 1) != 0 or t[e] - last_t[k] > max_gap
            pred = 0.0
            if not restart:
                pred = last_p[k] + wavelength[r] * (l - last_l[k])
                if abs(p - pred) > max_jump:
                    restart = True
            if restart:
                count[k] = 1
                ps = p
            else:
                n = min(count[k] + 1, n_max)
                count[k] = n
                ps = p / n + (n - 1.0) / n * pred
            out[r] = ps
            last_p[k] = ps
            last_l[k] = l
            last_t[k] = t[e]
    return out
