"""Carrier phase between consecutive epochs: corrected delta ranges and the cycle-slip tests that need no INS
(numba kernel over plain arrays, no I/O; docs/raw_gnss.md, "Carrier phase").

The carrier of satellite s (m, ``lambda L``) is modelled as ``Phi = rho + c (dt_r - dt_sv) - I + T + lambda N``
(the ionosphere advances the phase as much as it delays the code).  Over a stretch of continuous lock ``N`` is
constant, so the difference of two epochs,

    Delta Phi_c = lambda (L_k - L_k-1) + c (dt_sv,k - dt_sv,k-1) + (I_k - I_k-1) - (T_k - T_k-1)
                = rho_k - rho_k-1 + c (dt_r,k - dt_r,k-1) + noise,

measures the receiver's displacement along the line of sight and its clock change: the time-differenced
carrier phase (TDCP; van Graas & Soloviev 2004, "Precise velocity estimation using a stand-alone GPS receiver",
NAVIGATION 51(4), eq. 4).  ``I`` is Klobuchar scaled to the carrier's frequency, ``T`` Saastamoinen with the
DO-229 mapping, both at an approximate position (:mod:`sinscli.gnss.corrections`): over a second they change by
millimetres, and their models' errors change less.

A pair (k-1, k) of a satellite is not formed (the satellite restarts at k) when

* the receiver flags a loss of lock at k (RINEX LLI bit 0; a u-blox lock time reset or a change of the half
  cycle it subtracted, :mod:`sinscli.io.ubx`), or its half-cycle ambiguity flag (LLI bit 1) clears at k (the
  receiver may have moved the phase by half a cycle);
* with a Doppler in both epochs: the carrier's change differs from the Doppler's ``-lambda (D_k + D_k-1) dt / 2``
  (trapezoidal) by more than ``max(doppler_min, k sigma)``, sigma from the Dopplers' variances;
* with a second frequency in both epochs: the geometry-free combination ``lambda_1 L_1 - lambda_2 L_2`` changes
  by more than ``gf_min`` (geometry, clocks and troposphere cancel; the ionosphere moves it by millimetres per
  second; a slip of n_1, n_2 cycles moves it by ``lambda_1 n_1 - lambda_2 n_2``), ``gf_min`` at the reference
  C/N0 and growing with the carriers' noise below it (:func:`carrier_shape`).

Slips smaller than these tests see are the filter's business (:mod:`sinscli.fusion.tdcp`: the carrier change
against the INS-predicted displacement).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .corrections import F_L1, klobuchar, tropo_delay
from .model import ecef_to_geodetic
from .signals import C_LIGHT, KEPLER_SYSTEMS, frequency, sat_name
from .spp import O_CN0_REF

# per record: what became of its carrier (pair status of the pair that ends at the record)
PH_NONE, PH_PAIR, PH_START, PH_LLI, PH_HALF, PH_DOPPLER, PH_GF = -1, 0, 1, 2, 3, 4, 5
PH_NAMES = {PH_LLI: "receiver's loss-of-lock flag", PH_HALF: "half-cycle flag cleared", PH_DOPPLER: "Doppler",
            PH_GF: "geometry-free"}
KEY_N = 8 * 1024                       # satellite key sys * 1024 + prn


@njit(cache=True)
def carrier_shape(opts, cn0):
    """The carrier's noise variance relative to its value at the reference C/N0 (``opts``' ``cn0_ref``):
    ``max(1, 10^((C/N0_ref - C/N0)/10))``, the inverse C/N0 law of a phase-lock loop's thermal jitter
    (Kaplan & Hegarty 2006, "Understanding GPS", eq. 5.71: ``sigma^2 ~ B_n / (C/N0)``); 1 without a C/N0.  No
    elevation term: the code's ``1/sin^2 el`` is mostly its multipath, which the carrier sees a hundredth of."""
    if cn0 == cn0 and cn0 > 0.0 and opts[O_CN0_REF] > 0.0:
        return max(1.0, 10.0 ** ((opts[O_CN0_REF] - cn0) / 10.0))
    return 1.0


@njit(cache=True)
def _atmosphere(ion, lat, lon, hgt, t, az, el, f, iono_on, tropo_on):
    """``I - T`` (m) of a carrier at frequency ``f``: Klobuchar scaled by ``(f_L1/f)^2`` minus Saastamoinen/DO-229
    (:mod:`sinscli.gnss.corrections`), at the receiver ``lat, lon, hgt`` (rad, m) and GPS time ``t``."""
    v = 0.0
    if iono_on:
        v += klobuchar(ion, lat, lon, az, el, t - math.floor(t / 604800.0) * 604800.0) * (F_L1 / f) ** 2
    if tropo_on:
        v -= tropo_delay(lat, hgt, el)
    return v


@njit(cache=True)
def carrier_pairs(opts, ion, t_rx, start, rsys, rprn, ok, l1, lli1, f1, l2, lli2, f2, dop, var_dop, cn0, el, az,
                  cdts, pos0, iono_on, tropo_on, max_gap, doppler_k, doppler_min, gf_min, iono_free):
    """Per record r (epochs ``start[e]:start[e+1]``, receiver times ``t_rx``): ``prev[r]`` the record of the same
    satellite one epoch before whose pair with r is free of slips by the tests above (-1: none), ``dz[r]`` the
    corrected delta range of the pair (m, the module's ``Delta Phi_c``), ``shape[r]`` its variance relative to the
    reference C/N0 (the two carriers' :func:`carrier_shape`), ``status[r]`` (``PH_*``), ``own[r]`` the record's
    own :func:`carrier_shape`.  Records not ``ok`` (no ephemeris, below the mask:
    :func:`sinscli.gnss.tc.tc_records`) or without a carrier or a wavelength take no part.
    ``el``, ``az`` (rad) and ``cdts`` (m) per record from ``tc_records``; ``pos0 (E, 3)`` approximate ECEF
    positions; ``iono_on``/``tropo_on`` whether the Klobuchar and troposphere terms are applied; ``iono_free``:
    where both carriers are continuous, the ionosphere-free combination's change
    ``(f_1^2 Delta L_1 lambda_1 - f_2^2 Delta L_2 lambda_2) / (f_1^2 - f_2^2)`` instead of the first carrier's
    and Klobuchar (its noise ``(f_1^4 + f_2^4) / (f_1^2 - f_2^2)^2`` times larger: 6.7 for L1/L5).  Mixing it with
    single-frequency satellites is harmless here, unlike for the code: a receiver's inter-frequency bias is
    constant and cancels in the difference."""
    nr = rsys.shape[0]
    prev = np.full(nr, -1, np.int64)
    dz = np.full(nr, np.nan)
    shape = np.full(nr, np.nan)
    status = np.full(nr, PH_NONE, np.int8)
    own = np.full(nr, np.nan)
    last_r = np.full(KEY_N, -1, np.int64)
    last_e = np.full(KEY_N, -10, np.int64)
    for e in range(t_rx.shape[0]):
        # both epochs' atmosphere at this epoch's position: an approximate position that jumps by metres
        # between epochs (a single-point fix) would otherwise move a low satellite's troposphere by centimetres
        lat, lon, hgt = ecef_to_geodetic(pos0[e, 0], pos0[e, 1], pos0[e, 2])
        for r in range(start[e], start[e + 1]):
            k = int(rsys[r]) * 1024 + int(rprn[r])
            if not ok[r] or not (l1[r] == l1[r]) or f1[r] <= 0.0 or k < 0 or k >= KEY_N:
                continue
            lam = C_LIGHT / f1[r]
            own[r] = carrier_shape(opts, cn0[r])
            p = last_r[k]
            st = PH_START
            if p >= 0 and last_e[k] == e - 1 and t_rx[e] - t_rx[e - 1] <= max_gap and f1[p] == f1[r]:
                dt = t_rx[e] - t_rx[e - 1]
                dl = lam * (l1[r] - l1[p])
                st = PH_PAIR
                if (lli1[r] & 1) != 0:
                    st = PH_LLI
                elif (lli1[p] & 2) != 0 and (lli1[r] & 2) == 0:
                    st = PH_HALF
                elif dop[r] == dop[r] and dop[p] == dop[p]:
                    pred = -lam * 0.5 * (dop[r] + dop[p]) * dt
                    sd = 0.5 * dt * math.sqrt(var_dop[r] + var_dop[p]) if var_dop[r] == var_dop[r] and \
                        var_dop[p] == var_dop[p] else 0.0
                    if abs(dl - pred) > max(doppler_min, doppler_k * sd):
                        st = PH_DOPPLER
                dual = False
                if st == PH_PAIR and l2[r] == l2[r] and l2[p] == l2[p] and f2[r] > 0.0 and f2[r] == f2[p] \
                        and f2[r] != f1[r] and (lli2[r] & 1) == 0:
                    dl2 = C_LIGHT / f2[r] * (l2[r] - l2[p])
                    if abs(dl - dl2) > gf_min * math.sqrt(max(1.0, 0.5 * (own[r] + own[p]))):
                        st = PH_GF
                    dual = True
                if st == PH_PAIR:
                    prev[r] = p
                    shape[r] = own[r] + own[p]
                    if dual and iono_free:
                        a, b = f1[r] * f1[r], f2[r] * f2[r]
                        dz[r] = (a * dl - b * dl2) / (a - b) + cdts[r] - cdts[p] \
                            + _atmosphere(ion, lat, lon, hgt, t_rx[e], az[r], el[r], f1[r], False, tropo_on) \
                            - _atmosphere(ion, lat, lon, hgt, t_rx[e - 1], az[p], el[p], f1[p], False, tropo_on)
                        shape[r] *= (a * a + b * b) / ((a - b) * (a - b))
                    else:
                        dz[r] = dl + cdts[r] - cdts[p] \
                            + _atmosphere(ion, lat, lon, hgt, t_rx[e], az[r], el[r], f1[r], iono_on, tropo_on) \
                            - _atmosphere(ion, lat, lon, hgt, t_rx[e - 1], az[p], el[p], f1[p], iono_on, tropo_on)
            status[r] = st
            last_r[k] = r
            last_e[k] = e
    return prev, dz, shape, status, own


def unknown_wavelength(obs) -> dict:
    """Carrier-phase observations of the positioned systems whose signal has no known wavelength (a band that
    :func:`sinscli.gnss.signals.frequency` does not know): ``{"G L6X": count}`` (they are skipped)."""
    out = {}
    for s, codes in obs.types.items():
        if s not in KEPLER_SYSTEMS:
            continue
        mine = obs.sys == s
        for j, code in enumerate(codes):
            if code[0] == "L" and frequency(s, code) <= 0.0:
                n = int(np.count_nonzero(mine & ~np.isnan(obs.values[:, j])))
                if n:
                    out[f"{sat_name(s, 0)[0]} {code}"] = n
    return out


def slip_counts(status) -> dict:
    """``{reason: count}`` of the pairs left out by the tests of this module (``PH_NAMES``)."""
    return {name: int(np.count_nonzero(status == code)) for code, name in PH_NAMES.items()}


__all__ = ["carrier_pairs", "carrier_shape", "unknown_wavelength", "slip_counts", "PH_NONE", "PH_PAIR", "PH_START",
           "PH_LLI", "PH_HALF", "PH_DOPPLER", "PH_GF", "PH_NAMES"]
