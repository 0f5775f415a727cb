"""The sensor noise the log itself shows at standstill, and how it corrects a sensor description.

:class:`RestNoise` holds what the standstill windows of a log tell (computed by
:func:`sinscli.allan.rest.noise_from_rest`: the Allan variance of each axis inside the windows, fitted
with white noise plus a ``1/tau^2`` term that takes an engine's vibration and quantization):

* the white-noise densities ``N`` of the gyros (ARW, rad/sqrt(s)) and accelerometers (VRW, m/s/sqrt(s));
* the ``1/tau^2`` coefficient ``Q`` (vibration at 20-40 Hz averages out as ``1/tau^2`` once a window holds
  a few of its periods: it is motion of the mount, bounded, not a random walk);
* the mean rate and specific force at rest (a bias magnitude, earth rate and gravity included).

:func:`apply_data_noise` puts them in the filter model (docs/fusion.md): the white noise replaces the
description's where it is missing or off by more than 2x either way, the bias variances are raised to
the magnitudes the rest shows, and every change is a note for the summary.  No I/O.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..nav.earth import OMEGA_IE

DEG = math.pi / 180.0
FACTOR = 2.0            # a description's white noise off by more than this (either way) yields to the data
CREDIBILITY = 3.0       # off by more than this, the description's other terms are taken off by as much


@dataclass(frozen=True)
class RestNoise:
    """Noise terms from the standstill windows of a log (SI, per body axis)."""
    rest_seconds: float         # s at rest used
    windows: int                # standstill intervals used
    gyro_white: np.ndarray      # (3,) N, rad/sqrt(s)
    accel_white: np.ndarray     # (3,) N, m/s/sqrt(s)
    gyro_q: np.ndarray          # (3,) Q of the 3 Q^2 / tau^2 term, rad
    accel_q: np.ndarray         # (3,) m/s
    gyro_mean: np.ndarray       # (3,) mean rate at rest, rad/s (bias + earth rate)
    accel_mean: np.ndarray      # (3,) mean specific force at rest, m/s^2 (bias + gravity)

    def rate_mean_var(self, span):
        """Variance (rad/s)^2 of the mean rate over a window of ``span`` s at rest, per axis: the Allan
        variance's terms at tau = span (white noise and the vibration/quantization term)."""
        span = np.asarray(span, dtype=float)[..., None]
        return self.gyro_white ** 2 / span + 3.0 * self.gyro_q ** 2 / span ** 2


def _deg_h(x) -> str:
    return f"{x * 3600.0 / DEG:.3g} deg/h"


def apply_data_noise(model, dn: RestNoise, g: float):
    """The filter model (:class:`sinscli.fusion.pipeline.FilterModel`) corrected by the rest noise
    (``g`` the local gravity, m/s^2); returns ``(model, notes)``."""
    notes = []
    arw2, vrw2 = model.arw2.copy(), model.vrw2.copy()
    k2 = {}                     # the description's credibility: data / description, in variance
    for which, name, cur, data, unit, scale in (("gyro", "gyro white noise (ARW)", arw2, dn.gyro_white ** 2,
                                                 "deg/sqrt(h)", 60.0 / DEG),
                                                ("accelerometer", "accelerometer white noise (VRW)", vrw2,
                                                 dn.accel_white ** 2, "ug/sqrt(Hz)", 1.0 / 9.80665e-6)):
        # the largest axis for all three: a fit may give one axis no white noise at all (its variance all in
        # the vibration and flicker terms), which no filter should believe
        data = np.full(3, data.max())
        r = np.sqrt(data / np.maximum(cur, 1e-300))
        k2[which] = float(r.max() ** 2) if r.max() > 1.0 else float(r.min() ** 2)
        if model.default or np.any(r > FACTOR) or np.any(r < 1.0 / FACTOR):
            was = "no description" if model.default else f"the description's {np.sqrt(cur.max()) * scale:.3g}"
            notes.append(f"{name} {np.sqrt(data.max()) * scale:.3g} {unit} from {dn.rest_seconds:.0f} s at rest "
                         f"({was})")
            cur[:] = data
    # a description whose white noise is off by more than CREDIBILITY (3x) in sigma is not this sensor's: its
    # terms no static log can check (bias instability, scale factor, misalignment, turn-on bias) are taken
    # off by as much (a vendor states them alike; a description 10x optimistic in one is so in all)
    upd = {}
    if not model.default:
        kg, ka = k2["gyro"], k2["accelerometer"]
        if not 1.0 / CREDIBILITY ** 2 <= kg <= CREDIBILITY ** 2:
            upd.update(q_bg=model.q_bg * kg, sfmis_g=model.sfmis_g * kg, p0_bg=model.p0_bg * kg,
                       p0_sg=model.p0_sg * kg)
            notes.append(f"the description's gyro white noise is {math.sqrt(kg):.2g}x off the log's: its bias, "
                         f"instability, scale factor and misalignment taken {math.sqrt(kg):.2g}x too")
        if not 1.0 / CREDIBILITY ** 2 <= ka <= CREDIBILITY ** 2:
            upd.update(q_ba=model.q_ba * ka, sfmis_a=model.sfmis_a * ka, p0_ba=model.p0_ba * ka,
                       p0_sa=model.p0_sa * ka)
            notes.append(f"the description's accelerometer white noise is {math.sqrt(ka):.2g}x off the log's: its "
                         f"bias, instability, scale factor and misalignment taken {math.sqrt(ka):.2g}x too")
    model = replace(model, **upd)
    # bias magnitudes: the mean rate at rest is the bias plus the earth rate's projection (<= 15 deg/h)
    p0_bg = model.p0_bg.copy()
    b2 = np.maximum(np.abs(dn.gyro_mean) - OMEGA_IE, 0.0) ** 2
    if np.any(b2 > 4.0 * p0_bg):
        notes.append(f"gyro bias variance raised to the rest's mean rate (up to {_deg_h(np.sqrt(b2.max()))}, "
                     f"the description's 1-sigma {_deg_h(np.sqrt(p0_bg.max()))})")
        p0_bg = np.maximum(p0_bg, b2)
    p0_ba = model.p0_ba.copy()
    k = int(np.argmax(np.abs(dn.accel_mean)))          # the axis nearest the vertical
    db = abs(float(np.linalg.norm(dn.accel_mean)) - g)
    if db ** 2 > 4.0 * p0_ba[k]:
        notes.append(f"accelerometer bias variance raised to the rest's |f| - g ({db / 9.80665e-6:.3g} ug)")
        p0_ba[k] = max(p0_ba[k], db ** 2)
    return replace(model, arw2=arw2, vrw2=vrw2, p0_bg=p0_bg, p0_ba=p0_ba), notes
