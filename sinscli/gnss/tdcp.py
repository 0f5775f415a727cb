"""Receiver displacement and velocity from time-differenced carrier phase without an IMU (``sins gnss spp --tdcp``;
numba kernel over plain arrays, no I/O; docs/raw_gnss.md, "TDCP without an IMU").

For a pair of epochs a < b and the satellites tracked without a slip between them (:mod:`sinscli.gnss.phase`),
the corrected carrier changes ``z_s = Delta Phi_c,s`` are, with ``r_a`` the receiver at epoch a (its single-point
fix: metres of error change the lines of sight by 1e-7) and ``D`` its displacement,

    z_s = rho_s,b(r_a + D) - rho_s,a(r_a) + Delta b + noise

(van Graas & Soloviev 2004, NAVIGATION 51(4), eq. 4-6: the satellites' motion along the line of sight is in
``rho_s,b(r_a) - rho_s,a(r_a)``).  ``D`` and the clock change ``Delta b`` follow by iterated weighted least
squares (weights the carrier variances), with Baarda's data snooping on the residuals (the standardized
``w_i = v_i / sqrt((R - H N^-1 H^T)_ii)``, the largest over the threshold excluded while at least two redundant
satellites remain): a slip the receiver did not flag.

The velocity at epoch k is the central difference ``D(k-1 -> k+1) / (t_k+1 - t_k-1)``, solved directly from the
carrier changes over both intervals (their noise independent across satellites; second-order accurate in time:
the error is the jerk times ``dt^2 / 6``); where only one interval exists (the ends of a stretch) the mean
velocity over it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .model import geo_range
from .orbits import earth_rate
from .phase import carrier_pairs, slip_counts
from .signals import N_SYS
from .spp import IONO_OFF, O_IONO, O_TROPO
from .tc import tc_records

MIN_PAIRS = 4                  # displacement (3) and clock change (1)


@njit(cache=True)
def _solve4(N, b, out):
    """``out = N^-1 b`` and N replaced by its inverse (4 x 4, symmetric positive definite; Gauss-Jordan).
    False when N is singular."""
    n = 4
    A = np.zeros((n, 2 * n))
    for i in range(n):
        for j in range(n):
            A[i, j] = N[i, j]
        A[i, n + i] = 1.0
    for c in range(n):
        p = c
        for i in range(c + 1, n):
            if abs(A[i, c]) > abs(A[p, c]):
                p = i
        if abs(A[p, c]) < 1e-300:
            return False
        if p != c:
            for j in range(2 * n):
                A[c, j], A[p, j] = A[p, j], A[c, j]
        d = A[c, c]
        for j in range(2 * n):
            A[c, j] /= d
        for i in range(n):
            if i != c:
                f = A[i, c]
                if f != 0.0:
                    for j in range(2 * n):
                        A[i, j] -= f * A[c, j]
    for i in range(n):
        for j in range(n):
            N[i, j] = A[i, n + j]
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += N[i, j] * b[j]
        out[i] = s
    return True


@njit(cache=True)
def displacements(gstart, r_cur, r_prev, z, var, sx, rsys, base, w_thr):
    """Per group g of pairs ``gstart[g]:gstart[g+1]`` (one pair of epochs; per pair the records ``r_cur`` of the
    later and ``r_prev`` of the earlier epoch, the corrected delta range ``z`` (m) and its variance ``var``
    (m^2); ``sx (R, 6)`` the satellites at transmission per record, ``rsys`` their systems; ``base[g]`` the
    receiver's ECEF position at the earlier epoch): the displacement ``D (G, 3)`` (ECEF, m), the clock change
    ``db (G,)`` (m), their covariance ``cov (G, 4, 4)`` (m^2), ``n (G,)`` pairs used, ``vwv (G,)`` the weighted
    residual square sum (for the unit variance), ``excl (P,)`` True for pairs excluded, ``wres (P,)`` each used
    pair's standardized residual (NaN: excluded or no solution).  Groups with fewer than
    :data:`MIN_PAIRS` pairs left give NaN."""
    ng = gstart.shape[0] - 1
    npair = z.shape[0]
    D = np.full((ng, 3), np.nan)
    db = np.full(ng, np.nan)
    cov = np.full((ng, 4, 4), np.nan)
    nused = np.zeros(ng, np.int64)
    vwv = np.zeros(ng)
    excl = np.zeros(npair, np.bool_)
    wres = np.full(npair, np.nan)
    N = np.zeros((4, 4))
    b = np.zeros(4)
    dx = np.zeros(4)
    for g in range(ng):
        a0, a1 = gstart[g], gstart[g + 1]
        m = a1 - a0
        if m < MIN_PAIRS:
            continue
        H = np.zeros((m, 4))
        v = np.zeros(m)
        act = np.ones(m, np.bool_)
        ok = False
        while True:
            x = np.zeros(4)
            ok = False
            for it in range(6):
                for i in range(4):
                    b[i] = 0.0
                    for j in range(4):
                        N[i, j] = 0.0
                for i in range(m):
                    q = a0 + i
                    rc, rp = r_cur[q], r_prev[q]
                    omge = earth_rate(int(rsys[rc]))
                    rho_c, ex, ey, ez = geo_range(sx[rc, 0], sx[rc, 1], sx[rc, 2], base[g, 0] + x[0],
                                                  base[g, 1] + x[1], base[g, 2] + x[2], omge)
                    rho_p, _, _, _ = geo_range(sx[rp, 0], sx[rp, 1], sx[rp, 2], base[g, 0], base[g, 1], base[g, 2],
                                               omge)
                    H[i, 0], H[i, 1], H[i, 2], H[i, 3] = -ex, -ey, -ez, 1.0
                    v[i] = z[q] - (rho_c - rho_p + x[3])
                    if act[i]:
                        w = 1.0 / var[q]
                        for j in range(4):
                            b[j] += H[i, j] * w * v[i]
                            for k in range(4):
                                N[j, k] += H[i, j] * w * H[i, k]
                if not _solve4(N, b, dx):
                    break
                for j in range(4):
                    x[j] += dx[j]
                ok = True
                if dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2] < 1e-12:
                    break
            if not ok:
                break
            # residuals at the solution and the standardized w of each active pair (N holds N^-1)
            na = 0
            worst, w_worst = -1, 0.0
            s2 = 0.0
            for i in range(m):
                if not act[i]:
                    continue
                na += 1
                q = a0 + i
                rc, rp = r_cur[q], r_prev[q]
                omge = earth_rate(int(rsys[rc]))
                rho_c, ex, ey, ez = geo_range(sx[rc, 0], sx[rc, 1], sx[rc, 2], base[g, 0] + x[0], base[g, 1] + x[1],
                                              base[g, 2] + x[2], omge)
                rho_p, _, _, _ = geo_range(sx[rp, 0], sx[rp, 1], sx[rp, 2], base[g, 0], base[g, 1], base[g, 2],
                                           omge)
                vi = z[q] - (rho_c - rho_p + x[3])
                s2 += vi * vi / var[q]
                hq = 0.0
                for j in range(4):
                    for k in range(4):
                        hq += H[i, j] * N[j, k] * H[i, k]
                qv = var[q] - hq
                if qv > 1e-30:
                    w = vi / math.sqrt(qv)
                    wres[q] = w
                    if abs(w) > abs(w_worst):
                        worst, w_worst = i, w
            if na - 4 >= 2 and worst >= 0 and abs(w_worst) > w_thr:
                act[worst] = False
                excl[a0 + worst] = True
                wres[a0 + worst] = np.nan
                if na - 1 < MIN_PAIRS:
                    ok = False
                    break
                continue
            if na >= MIN_PAIRS:
                for j in range(3):
                    D[g, j] = x[j]
                db[g] = x[3]
                for j in range(4):
                    for k in range(4):
                        cov[g, j, k] = N[j, k]
                nused[g] = na
                vwv[g] = s2
            break
    for g in range(ng):
        if nused[g] < MIN_PAIRS:
            for q in range(gstart[g], gstart[g + 1]):
                wres[q] = np.nan
    return D, db, cov, nused, vwv, excl, wres


def _robust_scale(gs, cur, prev, z, var, sx, rsys, base):
    """The noise's scale from the data (>= 1): ``(1.4826 median |w|)^2`` of every pair's standardized residual,
    nothing excluded (robust to the few slips).  Over long intervals the atmosphere's and the satellite clocks'
    changes add to the carrier's own noise: 30 s on a CORS station gives about 50."""
    w0 = displacements(gs, cur, prev, z, var, sx, rsys, base, np.inf)[6]
    w0 = w0[np.isfinite(w0)]
    return max(1.0, (1.4826 * float(np.median(np.abs(w0)))) ** 2) if len(w0) else 1.0


def _approx_positions(res):
    """Per epoch the single-point fix (ECEF), interpolated across epochs without one."""
    ok = res.fix
    t = res.time
    return np.column_stack([np.interp(t, t[ok], res.pos[ok, i]) for i in range(3)])


def _groups(epoch_of_pair):
    """``(order, gstart, group epochs)`` of pairs grouped by an epoch index."""
    order = np.argsort(epoch_of_pair, kind="stable")
    e = epoch_of_pair[order]
    keys, first = np.unique(e, return_index=True)
    return order, np.append(first, len(e)).astype(np.int64), keys


def tdcp_velocity(res, nav, opts, carrier_sigma=0.003, slip_doppler=1.0, slip_gf=0.05, w_thr=5.0, max_gap=2.5,
                  iono_free=True):
    """TDCP velocities of the epochs of a single-point solution ``res`` (:class:`sinscli.gnss.pipeline.SppResult`:
    its observations, signals and fixes; ``opts`` its options vector): a dict with ``vel (E, 3)`` and ``cov (E, 3, 3)`` (ECEF, m/s), ``kind (E,)``
    (2 central difference, 1 one interval, 0 none), ``disp (E, 3)`` the one-interval displacements (ECEF, m; NaN
    where none), the unit variance ``s0sq`` applied (>= 1), and counts: ``carriers``, ``pairs``, ``slips`` per test
    before the solution, ``excluded`` by its data snooping."""
    obs, sig = res.obs, res.signals
    ne = len(obs)
    out = {"vel": np.full((ne, 3), np.nan), "cov": np.full((ne, 3, 3), np.nan), "kind": np.zeros(ne, np.int8),
           "disp": np.full((ne, 3), np.nan), "s0sq": 1.0, "carriers": 0, "pairs": 0, "slips": {}, "excluded": 0}
    if not res.fix.any() or ne < 2:
        return out
    pos0 = np.ascontiguousarray(_approx_positions(res))
    sys_on = np.zeros(N_SYS, dtype=np.bool_)
    sys_on[list(res.systems)] = True
    ion = nav.ion_gps if nav.ion_gps is not None else nav.ion_bds
    ion = np.zeros(8) if ion is None else np.asarray(ion, dtype=np.float64)
    rsys, rprn = obs.sys.astype(np.int64), obs.prn.astype(np.int64)
    (ok, sx, _, _, _, var_rate, el, az, cdts, _, _, _) = tc_records(
        nav.eph, ion, opts, sys_on, obs.time, obs.start, rsys, rprn, sig.p1, sig.p2, sig.b1, sig.b2, sig.f1, sig.f2,
        sig.cn0, sig.dop, pos0, np.full((ne, 3), np.nan))
    step = float(np.median(np.diff(obs.time)))
    prev, dz, shape, status, own = carrier_pairs(
        opts, ion, obs.time, obs.start, rsys, rprn, ok, sig.l1, sig.lli1, sig.f1, sig.l2, sig.lli2, sig.f2, sig.dop,
        var_rate, sig.cn0, el, az, cdts, pos0, opts[O_IONO] != IONO_OFF, opts[O_TROPO] > 0.0, max_gap * step, 6.0,
        slip_doppler, slip_gf, iono_free and opts[O_IONO] != IONO_OFF)
    out["carriers"] = int(np.count_nonzero(status >= 0))
    out["slips"] = slip_counts(status)
    ep = obs.epoch_of_record()
    s2 = carrier_sigma ** 2
    # one interval: pairs (k-1, k), grouped by k
    cur = np.nonzero(prev >= 0)[0]
    out["pairs"] = len(cur)
    if len(cur) == 0:
        return out
    order, gs, ek = _groups(ep[cur])
    c1 = cur[order]
    base1 = np.ascontiguousarray(pos0[ek - 1])
    # the noise's scale from the data first (robust: the median |w| of every pair, no exclusion): over long
    # intervals the atmosphere's and the satellite clocks' changes add to the carrier's noise
    s0sq1 = _robust_scale(gs, c1, prev[c1], dz[c1], s2 * shape[c1], sx, rsys, base1)
    D1, _, cov1, n1, vwv1, ex1, _ = displacements(gs, c1, prev[c1], dz[c1], s2 * s0sq1 * shape[c1], sx, rsys, base1,
                                                  w_thr)
    # two intervals: pairs (k-1, k+1) through k, grouped by k
    two = cur[prev[prev[cur]] >= 0]
    mid = prev[two]
    first = prev[mid]
    order2, gs2, ek2 = _groups(ep[mid])
    two, mid, first = two[order2], mid[order2], first[order2]
    base2 = np.ascontiguousarray(pos0[ek2 - 1])
    z2, var2 = dz[two] + dz[mid], s2 * (own[two] + own[first])
    s0sq2 = _robust_scale(gs2, two, first, z2, var2, sx, rsys, base2) if len(two) else 1.0
    D2, _, cov2, n2, vwv2, ex2, _ = displacements(gs2, two, first, z2, var2 * s0sq2, sx, rsys, base2, w_thr)
    out["excluded"] = int(ex1.sum() + ex2.sum())
    dof = np.concatenate([n1 - 4, n2 - 4])
    v = np.concatenate([vwv1, vwv2])
    good = dof > 0
    post = max(1.0, float(v[good].sum() / dof[good].sum())) if good.any() else 1.0
    out["s0sq"] = s0sq1 * post
    s0sq = post
    t = obs.time
    have1 = n1 >= MIN_PAIRS
    out["disp"][ek[have1]] = D1[have1]
    # one-sided velocities first (the interval ending at k, else the one starting at k), then the central ones
    idx = ek[have1]
    dt = (t[ek] - t[ek - 1])[have1]
    out["vel"][idx] = D1[have1] / dt[:, None]
    out["cov"][idx] = cov1[have1, :3, :3] * s0sq / dt[:, None, None] ** 2
    out["kind"][idx] = 1
    start_of = np.zeros(ne, bool)
    start_of[ek[have1] - 1] = True
    fill = start_of & (out["kind"] == 0)
    if fill.any():
        nxt = {int(k) - 1: i for i, k in enumerate(ek) if have1[i]}
        for k in np.nonzero(fill)[0]:
            i = nxt[int(k)]
            dt = t[k + 1] - t[k]
            out["vel"][k] = D1[i] / dt
            out["cov"][k] = cov1[i, :3, :3] * s0sq / dt ** 2
            out["kind"][k] = 1
    have2 = n2 >= MIN_PAIRS
    k2 = ek2[have2]
    dt2 = t[k2 + 1] - t[k2 - 1]
    out["vel"][k2] = D2[have2] / dt2[:, None]
    out["cov"][k2] = cov2[have2, :3, :3] * s0sq / dt2[:, None, None] ** 2
    out["kind"][k2] = 2
    return out


__all__ = ["displacements", "tdcp_velocity", "MIN_PAIRS"]
