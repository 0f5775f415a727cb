"""The sensor noise the log itself shows at standstill, and how it corrects a sensor description.

:class:`RestNoise` holds what the standstill windows of a log tell (computed by
:func:`sinscli.allan.rest.noise_from_rest`: the Allan variance of each axis inside the windows, fitted
with white noise plus a ``1/tau^2`` term that takes an engine's vibration and quantization):

* the white-noise densities ``N`` of the gyros (ARW, rad/sqrt(s)) and accelerometers (VRW, m/s/sqrt(s)),
  with per axis whether the fit told them apart from the other terms, and the floor the log's own
  resolution sets (a white noise is never taken below it);
* the ``1/tau^2`` coefficient ``Q`` (vibration at 20-40 Hz averages out as ``1/tau^2`` once a window holds
  a few of its periods: it is motion of the mount, bounded, not a random walk); a rest whose gyro ``Q``
  (the RMS rotation of that motion) is under a few hundredths of a degree is a true rest;
* the mean rate and specific force at rest (a bias magnitude, earth rate and gravity included).

:func:`apply_data_noise` puts them in the filter model (docs/fusion.md).  A description is the user's
claim: the data may widen a term it proves wrong, never narrow one; without a description the data's
white noise replaces the default preset's.  No I/O.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..nav.earth import OMEGA_IE
from ..units import DEG, UG_DECIMAL

FACTOR = 2.0            # a description's white noise under the data's by more than this yields to the data
MIN_REST_FIT = 10.0     # s at rest a noise fit needs (sinscli.allan.rest.MIN_REST)
CREDIBILITY = 3.0       # under it by more than this (at a true rest): the description's other terms are widened too


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
    gyro_separated: np.ndarray = field(default_factory=lambda: np.ones(3, bool))    # (3,) the fit told N apart
    accel_separated: np.ndarray = field(default_factory=lambda: np.ones(3, bool))
    gyro_floor: float = 0.0     # rad/sqrt(s): the white noise the log's resolution sets (0: not known)
    accel_floor: float = 0.0    # m/s/sqrt(s)
    true_rest: bool = True      # the sensor did not turn at rest beyond a mount's vibration
    fitted: bool = True         # False: the windows were too short to fit (only rest_seconds holds)

    def rate_mean_var(self, span):
        """Variance (rad/s)^2 of the mean rate over a window of ``span`` s at rest, per axis: the Allan
        variance's terms at tau = span (white noise and the vibration/quantization term)."""
        span = np.asarray(span, dtype=float)[..., None]
        white = np.maximum(self.gyro_white, self.gyro_floor)
        return white ** 2 / span + 3.0 * self.gyro_q ** 2 / span ** 2

    def white(self, which: str):
        """``(N, floor)`` of ``which`` ("gyro" | "accel"): the largest white noise among the axes the fit told
        apart, raised to the resolution's floor; N is None when no axis was told apart."""
        n, sep, floor = ((self.gyro_white, self.gyro_separated, self.gyro_floor) if which == "gyro"
                         else (self.accel_white, self.accel_separated, self.accel_floor))
        if not np.any(sep):
            return None, floor
        return max(float(np.max(n[sep])), floor), floor


def _deg_h(x) -> str:
    return f"{x * 3600.0 / DEG:.3g} deg/h"


def apply_data_noise(model, dn: RestNoise, g: float, handheld: bool = False):
    """The filter model (:class:`sinscli.fusion.pipeline.FilterModel`) corrected by the rest noise
    (``g`` the local gravity, m/s^2; ``handheld``: the platform is a pedestrian's device, whose rest is never
    a true rest); returns ``(model, notes)``.

    * White noise: where the fit told it apart (:meth:`RestNoise.white`), raised to the log's resolution
      floor, it replaces the default preset's when no description was given, and raises a description's
      that is more than :data:`FACTOR` under it; it never lowers a description's.  Where the fit could not
      tell it apart from vibration or quantization, the description's (or the preset's) value is kept, said
      in one line.
    * A description whose white noise is more than :data:`CREDIBILITY` under the data's at a true rest (not
      handheld, the sensor not turning beyond a mount's vibration) is not this sensor's: its terms no static
      log can check (bias instability, scale factor, misalignment, turn-on bias) are widened by as much.
      Never narrowed.
    * Bias magnitudes: the turn-on gyro bias variance is raised to the rest's mean rate (less the earth
      rate), the accelerometer's along the vertical to ``| |f| - g |``; never lowered.
    """
    if not dn.fitted:
        return model, [f"the log's rest windows hold {dn.rest_seconds:.1f} s, under the {MIN_REST_FIT:g} s a noise "
                       f"fit needs: the " + ("default preset's" if model.default else "description's") +
                       " values kept"]
    notes = []
    arw2, vrw2 = model.arw2.copy(), model.vrw2.copy()
    k2 = {}                     # data / description, in variance, where the data raised the description
    for which, key, name, cur, unit, scale in (("gyro", "gyro", "gyro white noise (ARW)", arw2, "deg/sqrt(h)",
                                                60.0 / DEG),
                                               ("accelerometer", "accel", "accelerometer white noise (VRW)", vrw2,
                                                "ug/sqrt(Hz)", 1.0 / UG_DECIMAL)):
        n, floor = dn.white(key)
        was = "no description: the default preset's" if model.default else "the description's"
        if n is None:
            notes.append(f"{name}: the fit of {dn.rest_seconds:.0f} s at rest could not tell white noise apart "
                         f"from vibration and quantization: {was} {math.sqrt(cur.max()) * scale:.3g} {unit} kept")
            continue
        data = n * n
        r = math.sqrt(data / max(float(cur.max()), 1e-300))
        # the sensor's own white noise, less what the log's resolution adds (a rounding error on every sample
        # is white too): only that part says whether the description is this sensor's
        own = math.sqrt(max(n * n - floor * floor, 0.0) / max(float(cur.max()), 1e-300))
        if model.default or r > FACTOR:
            note = (f"{name} {n * scale:.3g} {unit} from {dn.rest_seconds:.0f} s at rest ({was} "
                    f"{math.sqrt(cur.max()) * scale:.3g})")
            if n == floor and floor > 0.0:
                note += ": the floor of the log's resolution"
            notes.append(note)
            if not model.default:
                k2[which] = own * own
            cur[:] = data
    upd = {}
    if not model.default and dn.true_rest and not handheld:
        kg, ka = k2.get("gyro", 1.0), k2.get("accelerometer", 1.0)
        if kg > CREDIBILITY ** 2:
            upd.update(q_bg=model.q_bg * kg, sfmis_g=model.sfmis_g * kg, p0_bg=model.p0_bg * kg,
                       p0_sg=model.p0_sg * kg)
            notes.append(f"the description's gyro white noise is {math.sqrt(kg):.2g}x under the log's at a true "
                         f"rest: its bias, instability, scale factor and misalignment widened {math.sqrt(kg):.2g}x "
                         f"too")
        if ka > CREDIBILITY ** 2:
            upd.update(q_ba=model.q_ba * ka, sfmis_a=model.sfmis_a * ka, p0_ba=model.p0_ba * ka,
                       p0_sa=model.p0_sa * ka)
            notes.append(f"the description's accelerometer white noise is {math.sqrt(ka):.2g}x under the log's "
                         f"at a true rest: its bias, instability, scale factor and misalignment widened "
                         f"{math.sqrt(ka):.2g}x too")
    elif max(k2.values(), default=1.0) > CREDIBILITY ** 2 and not model.default:
        notes.append("the rest was not a true rest (" + ("a handheld device" if handheld else
                     "the mount's motion or vibration dominates the fit where white noise is read") + "): the "
                     "description's bias, instability, scale factor and misalignment kept")
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
        notes.append(f"accelerometer bias variance raised to the rest's |f| - g ({db / UG_DECIMAL:.3g} ug)")
        p0_ba[k] = max(p0_ba[k], db ** 2)
    return replace(model, arw2=arw2, vrw2=vrw2, p0_bg=p0_bg, p0_ba=p0_ba), notes
