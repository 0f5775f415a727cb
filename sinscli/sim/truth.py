"""The exact-truth engine: analytic motion -> positions, attitude, velocity and exact increments.

Time runs as ``tau`` = seconds since the scenario start (``tau_k = k / rate``
exactly), so large epochs lose no precision.  The run is cut into
*sub-intervals* at every IMU time, GNSS time and primitive joint (and, for
fast motion, between IMU times), so that every quadrature sees one analytic
piece only.  On each sub-interval ``n``-point Gauss-Legendre nodes carry:

- the analytic attitude ``Cbn``, velocity ``v^n`` and their derivatives (jets);
- the position by collocation (Picard iteration of
  ``L' = v_N/(RM+h)``, ``lon' = v_E/((RN+h) cos L)``, ``h' = v_U``);
- the rates ``w_ib^b`` and specific force ``f^b`` (:mod:`.imu_synth`), whose
  Gauss-Legendre sums are the increments ``dtheta_b``, ``dvel_b``.

The work goes in chunks of sub-intervals (bounded memory, progress).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..nav.earth import radii_py
from . import pinned as pm
from .imu_synth import body_rate_nb, normal_gravity_n, sensor_outputs
from .quadrature import gauss_legendre
from .segments import Primitive
from .flex import Flex, flex_between, flex_knots, flex_target
from .vibration import Vibration, vibrate

CHUNK = 16384          # sub-intervals per chunk
PICARD_MAX = 60
VIB_STEP = 2.6         # rad: largest w h of a vibration line over a sub-interval (8 nodes: ~1e-15 relative)


@dataclass
class TruthData:
    """Exact truth at the boundary instants, and exact increments (FLU body, ENU)."""
    tau: np.ndarray        # (M+1,) s since start, all boundaries
    lat: np.ndarray        # (M+1,) rad
    lon: np.ndarray        # (M+1,) rad
    h: np.ndarray          # (M+1,) m
    vel_n: np.ndarray      # (M+1, 3) m/s
    cbn: np.ndarray        # (M+1, 3, 3)
    w_nb_b: np.ndarray     # (M+1, 3) rad/s
    imu_idx: np.ndarray    # (N+1,) boundary index of each IMU time (0 = start)
    dtheta_b: np.ndarray   # (N, 3) rad
    dvel_b: np.ndarray     # (N, 3) m/s
    w_imu: np.ndarray | None = None    # (N+1, 3) rad/s: sensor rate at each IMU instant (``rates=True``)
    f_imu: np.ndarray | None = None    # (N+1, 3) m/s^2: specific force at each IMU instant
    ff_b: np.ndarray | None = None     # (N, 6) m^2/s^3: int (fx^2, fy^2, fz^2, fx fy, fx fz, fy fz) dt (``moments``)
    flex_theta: np.ndarray | None = None   # (N+1, 3) rad: the mount's flex at each IMU instant (``flex``)


def boundaries(tau_imu: np.ndarray, extra: np.ndarray, subdiv: int):
    """All sub-interval boundaries: IMU times, ``extra`` times (snapped onto IMU times
    closer than 1e-9 s), and ``subdiv - 1`` equal splits of each IMU interval.

    Returns ``(b, imu_idx)``, with ``b[imu_idx] == tau_imu``.
    """
    pts = [tau_imu]
    if subdiv > 1:
        frac = np.arange(1, subdiv) / subdiv
        pts.append((tau_imu[:-1, None] + np.diff(tau_imu)[:, None] * frac[None, :]).ravel())
    extra = np.asarray(extra, dtype=float)
    extra = extra[(extra > tau_imu[0]) & (extra < tau_imu[-1])]
    if extra.size:
        j = np.clip(np.searchsorted(tau_imu, extra), 1, tau_imu.size - 1)
        near = np.where(np.abs(tau_imu[j] - extra) < np.abs(tau_imu[j - 1] - extra), j, j - 1)
        snap = np.abs(tau_imu[near] - extra) < 1e-9
        pts.append(extra[~snap])
    b = np.unique(np.concatenate(pts))
    imu_idx = np.searchsorted(b, tau_imu)
    return b, imu_idx


def evaluate(prims: list[Primitive], starts: np.ndarray, base: np.ndarray, off=None, side: str = "right"):
    """Attitude and velocity at times ``base + off`` (s since start): ``(Cbn, dCbn, vel_n, acc_n)``.

    ``base`` are exact instants (sub-interval starts) and ``off`` small offsets
    from them (Gauss nodes); each primitive gets ``(base - t_start) + off``,
    so rounding stays at the scale of the primitive, not of the run.  Each
    time takes the primitive that contains it (``side='right'``: a joint
    belongs to the later primitive; values agree there).
    """
    base = np.asarray(base, dtype=float)
    off = np.zeros_like(base) if off is None else np.asarray(off, dtype=float)
    n = base.shape[0]
    cbn = np.empty((n, 3, 3))
    dcbn = np.empty((n, 3, 3))
    vel = np.empty((n, 3))
    acc = np.empty((n, 3))
    which = np.clip(np.searchsorted(starts, base + off, side=side) - 1, 0, len(prims) - 1)
    for p in np.unique(which):
        sel = np.nonzero(which == p)[0]
        c, v, _ = prims[p].kinematics((base[sel] - starts[p]) + off[sel])
        cbn[sel], dcbn[sel] = c.c[0], c.c[1]
        vel[sel], acc[sel] = v.c[0], v.c[1]
    return cbn, dcbn, vel, acc


def _collocate(f, half, w, A, y0):
    """Integrate ``y' = f`` over consecutive sub-intervals from ``y0``.

    ``f`` (J, n) at the Gauss nodes, ``half`` (J,) half lengths.  Returns
    the node values (J, n) and the end values (J,) of ``y - y0`` offsets
    added to ``y0`` only at the end (small numbers keep their precision).
    """
    inc = half * pm.matmul(f, w)
    ends = np.cumsum(inc)
    starts = ends - inc
    nodes = starts[:, None] + half[:, None] * pm.matmul(f, A.T)
    return nodes, ends


def integrate_position(lat0, lon0, h0, half, vel_nodes, w, A):
    """Geodetic position at the nodes and the sub-interval ends from the node velocities.

    ``vel_nodes`` (J, n, 3) ENU.  ``h`` is a plain quadrature; latitude is a
    Picard iteration of the collocation equations until it stops changing
    (it contracts by ~ v T / R per sweep); longitude follows by quadrature.
    Returns ``(lat, lon, h)`` at nodes (J, n) and at ends (J,).
    """
    dh_n, dh_e = _collocate(vel_nodes[..., 2], half, w, A, h0)
    h_n = h0 + dh_n
    dl_n = np.zeros_like(h_n)
    for _ in range(PICARD_MAX):
        rm, _ = radii_py(pm.sin(lat0 + dl_n))
        new_n, dl_e = _collocate(vel_nodes[..., 1] / (rm + h_n), half, w, A, lat0)
        change = np.max(np.abs(new_n - dl_n)) if new_n.size else 0.0
        dl_n = new_n
        if change <= 2e-16 * max(np.max(np.abs(dl_n)), 1e-300) or change < 1e-22:
            break
    else:   # pragma: no cover - would mean an unphysical trajectory
        raise RuntimeError("latitude integration did not converge")
    lat_n = lat0 + dl_n
    _, rn = radii_py(pm.sin(lat_n))
    dlon_n, dlon_e = _collocate(vel_nodes[..., 0] / ((rn + h_n) * pm.cos(lat_n)), half, w, A, lon0)
    return (lat_n, lon0 + dlon_n, h_n), (lat0 + dl_e, lon0 + dlon_e, h0 + dh_e)


def sample_times(t0: float, rate: float, n: int) -> np.ndarray:
    """``tau_k = fl(t0 + k/rate) - t0``, k = 0..n: times since the start whose sums ``t0 + tau_k``
    are exactly the written time stamps, so that intervals of the file's times are those integrated."""
    return (t0 + np.arange(n + 1) / rate) - t0


def generate(prims: list[Primitive], lat0: float, lon0: float, h0: float, rate: float, n_imu: int,
             extra_times=(), nodes: int = 8, gravity=normal_gravity_n, progress=None,
             t0: float = 0.0, vibration: Vibration | None = None, rates: bool = False,
             flex: Flex | None = None, moments: bool = False) -> TruthData:
    """Exact truth and increments for ``n_imu`` IMU intervals at ``rate`` Hz from epoch ``t0``.

    ``extra_times`` (s since start, e.g. GNSS epochs) become boundaries too;
    ``gravity(lat, h)`` gives ``g^n`` (n, 3); ``progress(k)`` is called with
    the number of IMU intervals completed by each chunk.  ``vibration``: the
    mount's vibration (:mod:`.vibration`), in the increments and rates but not
    in the truth; ``rates``: also the sensor outputs at every IMU instant; ``flex``: the mount's flex under
    the body's acceleration (:mod:`.flex`), likewise in the sensor outputs only; ``moments``: also the
    integrals of the products of the specific force's components over each IMU interval.
    """
    tau_imu = sample_times(t0, rate, n_imu)
    starts = np.array([p.t_start for p in prims])
    joints = starts[1:]
    wmax = max(p.max_frequency() for p in prims)
    subdiv = max(1, int(np.ceil(wmax / rate)))          # omega * sub-interval <= 1 rad
    if vibration is not None:
        subdiv = max(subdiv, int(np.ceil(vibration.max_frequency() / (VIB_STEP * rate))))
    vib_end = [vibration.ramp] if vibration is not None and vibration.ramp > 0 else []   # its envelope's joint
    b, imu_idx = boundaries(tau_imu, np.concatenate([np.asarray(extra_times, float), joints, vib_end]), subdiv)
    x, w, A = gauss_legendre(nodes)
    M = b.size - 1
    owner = np.searchsorted(tau_imu, b[1:], side="left") - 1      # IMU interval of each sub-interval
    knots = None
    if flex is not None:
        acc_b = np.empty((n_imu + 1, 3))
        for k0 in range(0, n_imu + 1, CHUNK):
            k1 = min(k0 + CHUNK, n_imu + 1)
            cbn, _, _, acc = evaluate(prims, starts, tau_imu[k0:k1])
            acc_b[k0:k1] = pm.matmul(np.swapaxes(cbn, -1, -2), acc[:, :, None])[:, :, 0]     # C_n^b dv^n/dt
        knots = flex_knots(flex, tau_imu, flex_target(flex, acc_b))
        h_imu = np.diff(tau_imu)
    sub_ff = np.empty((M, 6)) if moments else None

    lat = np.empty(M + 1)
    lon = np.empty(M + 1)
    hgt = np.empty(M + 1)
    lat[0], lon[0], hgt[0] = lat0, lon0, h0
    sub_dth = np.empty((M, 3))
    sub_dv = np.empty((M, 3))
    cbn_b = np.empty((M + 1, 3, 3))
    vel_b = np.empty((M + 1, 3))
    w_b = np.empty((M + 1, 3))

    def at_boundaries(lo, hi):          # truth at boundaries lo..hi-1 (chunked: bounded memory)
        c_, dc_, v_, _ = evaluate(prims, starts, b[lo:hi])
        cbn_b[lo:hi], vel_b[lo:hi], w_b[lo:hi] = c_, v_, body_rate_nb(c_, dc_)

    at_boundaries(0, 1)
    done = 0
    for j0 in range(0, M, CHUNK):
        j1 = min(j0 + CHUNK, M)
        a, c = b[j0:j1], b[j0 + 1:j1 + 1]
        half = 0.5 * (c - a)
        J = j1 - j0
        base = np.repeat(a, nodes)
        off = (half[:, None] * (1.0 + x[None, :])).ravel()
        cbn, dcbn, vel, acc = evaluate(prims, starts, base, off)
        (lat_n, lon_n, h_n), (lat_e, lon_e, h_e) = integrate_position(
            lat[j0], lon[j0], hgt[j0], half, vel.reshape(J, nodes, 3), w, A)
        lat[j0 + 1:j1 + 1], lon[j0 + 1:j1 + 1], hgt[j0 + 1:j1 + 1] = lat_e, lon_e, h_e
        lat_f, h_f = lat_n.ravel(), h_n.ravel()
        w_ib, f_b = sensor_outputs(lat_f, h_f, vel, acc, cbn, body_rate_nb(cbn, dcbn), gravity(lat_f, h_f))
        extra = None
        if knots is not None:
            own = np.repeat(owner[j0:j1], nodes)
            extra = flex_between(knots[0], knots[1], h_imu, own, (base - tau_imu[own]) + off)
        w_ib, f_b = vibrate(vibration, base + off, w_ib, f_b, extra)
        if sub_ff is not None:
            fr = f_b.reshape(J, nodes, 3)
            for col, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
                sub_ff[j0:j1, col] = half * pm.matmul(fr[:, :, i] * fr[:, :, j], w)
        sub_dth[j0:j1] = half[:, None] * np.einsum("jnk,n->jk", w_ib.reshape(J, nodes, 3), w)
        sub_dv[j0:j1] = half[:, None] * np.einsum("jnk,n->jk", f_b.reshape(J, nodes, 3), w)
        at_boundaries(j0 + 1, j1 + 1)
        if progress is not None:
            now = int(owner[j1 - 1]) + 1 if j1 < M else n_imu
            progress(now - done)
            done = now
    dtheta = np.stack([np.bincount(owner, sub_dth[:, k], minlength=n_imu) for k in range(3)], axis=-1)
    dvel = np.stack([np.bincount(owner, sub_dv[:, k], minlength=n_imu) for k in range(3)], axis=-1)
    w_imu = f_imu = None
    if rates:
        w_imu, f_imu = np.empty((n_imu + 1, 3)), np.empty((n_imu + 1, 3))
        for k0 in range(0, n_imu + 1, CHUNK):
            k1 = min(k0 + CHUNK, n_imu + 1)
            cbn, dcbn, vel, acc = evaluate(prims, starts, tau_imu[k0:k1])
            la, hh = lat[imu_idx[k0:k1]], hgt[imu_idx[k0:k1]]
            w_ib, f_b = sensor_outputs(la, hh, vel, acc, cbn, body_rate_nb(cbn, dcbn), gravity(la, hh))
            extra = None if knots is None else (knots[0][k0:k1], knots[1][k0:k1])
            w_imu[k0:k1], f_imu[k0:k1] = vibrate(vibration, tau_imu[k0:k1], w_ib, f_b, extra)
    ff = None
    if sub_ff is not None:
        ff = np.stack([np.bincount(owner, sub_ff[:, k], minlength=n_imu) for k in range(6)], axis=-1)
    return TruthData(b, lat, lon, hgt, vel_b, cbn_b, w_b, imu_idx, dtheta, dvel, w_imu, f_imu, ff,
                     None if knots is None else knots[0])
