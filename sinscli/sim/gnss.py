"""GNSS fixes from the exact truth: antenna point, noise, outages.

The antenna sits at the lever arm ``l^b`` from the IMU; its position and
velocity are the truth *at the antenna*, exactly:

    r_a^e = r^e + C_n^e Cbn l^b
    v_a^n = v^n + Cbn (w_eb^b x l^b),   w_eb^b = w_nb^b + C_n^b w_en^n

with the velocity turned into the antenna's own ENU frame.  Noise is white,
Gaussian, per axis E/N/U (metres turned into latitude/longitude with the
local radii), or first-order Gauss-Markov with correlation times ``pos_tau``,
``vel_tau`` (the same unit draws, steady state from the first fix, exact
across outages).  Outages drop the fixes in ``[start, end)`` (s since the
start).  The ``std_*`` columns carry ``reported_*_sigma`` when given (a
receiver whose claim differs from its noise), else the true sigma; the
stamps are the true times plus ``time_offset``.  RTK float windows and wrong
fixes (:mod:`.rtk`) add their errors to the position, and the float epochs
their larger sigma to ``std_*``.
"""
from __future__ import annotations

import numpy as np

from ..nav.earth import ecef_to_lla, enu_rotation, lla_to_ecef, radii_py
from ..types import GnssLog
from . import pinned as pm
from .errors import gauss_markov_times
from .imu_synth import transport_rate_many


def gnss_times(duration: float, rate: float, outages, t0: float = 0.0) -> np.ndarray:
    """Fix times (s since start) ``fl(t0 + k/rate) - t0`` for ``k >= 0`` up to ``duration``, less the outages."""
    tau = (t0 + np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate) - t0
    keep = np.ones(tau.size, dtype=bool)
    for a, b in outages:
        keep &= ~((tau >= a) & (tau < b))
    return tau[keep]


def antenna_truth(lat, lon, h, vel_n, cbn, w_nb_b, lever_b):
    """Exact position (rad, rad, m) and ENU velocity (m/s) of the antenna at ``lever_b`` (body, m)."""
    lever_b = np.asarray(lever_b, dtype=float)
    if not np.any(lever_b):
        return lat, lon, h, vel_n
    c_en = enu_rotation(lat, lon, m=pm)                          # C_e^n (n, 3, 3)
    l_n = pm.matmul(cbn, lever_b)
    r_a = lla_to_ecef(lat, lon, h, m=pm) + np.einsum("nij,ni->nj", c_en, l_n)   # C_n^e = (C_e^n)^T
    lat_a, lon_a, h_a = ecef_to_lla(r_a, m=pm)
    w_en = transport_rate_many(lat, h, vel_n)
    w_eb = w_nb_b + np.einsum("nji,nj->ni", cbn, w_en)          # C_n^b w_en^n
    v_a_n = vel_n + np.einsum("nij,nj->ni", cbn, np.cross(w_eb, lever_b))
    v_a_e = np.einsum("nij,ni->nj", c_en, v_a_n)
    v_a = np.einsum("nij,nj->ni", enu_rotation(lat_a, lon_a, m=pm), v_a_e)
    return lat_a, lon_a, h_a, v_a


def make_gnss(tau, t0, lat, lon, h, vel_n, cfg: dict, rng: np.random.Generator | None, source: str,
              rtk=None) -> GnssLog:
    """A :class:`GnssLog` (degrees) from antenna truth, with noise drawn from ``rng`` (None: none) and the
    RTK float and wrong-fix errors ``rtk`` (:class:`sinscli.sim.rtk.RtkErrors`, with ``rng`` only)."""
    n = tau.size
    pos_sig = np.asarray(cfg["pos_noise"], dtype=float)
    vel_sig = np.asarray(cfg["vel_noise"], dtype=float)
    lat, lon, h, vel = lat.copy(), lon.copy(), h.copy(), vel_n.copy()
    if rng is not None:
        e_pos = _noise(rng.standard_normal((n, 3)), tau, pos_sig, cfg.get("pos_tau"))
        e_vel = _noise(rng.standard_normal((n, 3)), tau, vel_sig, cfg.get("vel_tau"))
        if rtk is not None:
            e_pos = e_pos + rtk.error
        rm, rn = radii_py(pm.sin(lat))
        lat += e_pos[:, 1] / (rm + h)
        lon += e_pos[:, 0] / ((rn + h) * pm.cos(lat))
        h += e_pos[:, 2]
        vel += e_vel
    rep_pos, rep_vel = cfg.get("reported_pos_sigma"), cfg.get("reported_vel_sigma")
    std_pos = std_vel = None
    if rng is not None:
        if rep_pos is not None or np.any(pos_sig > 0):
            std_pos = np.tile(pos_sig if rep_pos is None else rep_pos, (n, 1))
        if cfg["velocity"] and (rep_vel is not None or np.any(vel_sig > 0)):
            std_vel = np.tile(vel_sig if rep_vel is None else rep_vel, (n, 1))
        if rtk is not None and rtk.reported is not None:
            std_pos[rtk.floating] = rtk.reported            # a float solution says so; a wrong fix does not
    offset = cfg.get("time_offset", 0.0) if rng is not None else 0.0
    return GnssLog(time=(t0 + tau) + offset, lat=np.degrees(lat), lon=np.degrees(lon), height=h,
                   vel_n=vel if cfg["velocity"] else None, std_pos=std_pos, std_vel=std_vel, source=source)


def _noise(w, tau, sigma, tc):
    """White ``sigma w`` or, with correlation times ``tc`` > 0, Gauss-Markov noise from the same draws."""
    if tc is None or not np.any(np.asarray(tc) > 0):
        return w * sigma
    return gauss_markov_times(tau, np.asarray(sigma, float), np.asarray(tc, float), w)
