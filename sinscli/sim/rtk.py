"""RTK float epochs and wrong fixes: the position errors of a carrier-phase receiver that loses its fix.

**Float windows** ``[a, b)`` (s since the start): the integer ambiguities are not resolved, and the
position error is decimetres and wanders (Teunissen & Montenbruck 2017, "Springer Handbook of Global
Navigation Satellite Systems", ch. 23 and 26: the float solution converges slowly from decimetres).  In
each window the error added to the fixed solution's is a biased random walk, per axis E, N, U:

    e_0 = sigma n_0,     e_k = e_k-1 + s drift dt_k + walk sqrt(dt_k) n_k

(``e_0`` at the window's first fix, ``dt_k`` the time since the previous fix) with a sign ``s = +-1`` per window and axis (the drift's direction) and unit normal draws ``n``; the
written sigma is ``reported`` (larger than the fixed one: the receiver says it is floating).

**Wrong fixes** (jumps): from ``start`` for ``duration`` s the fixes are off by ``offset`` (E, N, U, m), a
wrong integer fix, while the written sigma stays the fixed one: the receiver's claim is a lie the
filter must catch.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class RtkErrors:
    """Errors to add (n, 3) m ENU, and the epochs (n,) whose written sigma is ``reported`` (3,) m."""
    error: np.ndarray
    floating: np.ndarray
    reported: np.ndarray | None


def rtk_errors(tau: np.ndarray, cfg: dict, rng: np.random.Generator) -> RtkErrors:
    """The float and wrong-fix errors at the fix times ``tau`` (s since the start) of a validated ``gnss``
    section (``float``: windows, sigma, walk, drift, reported; ``jumps``: start, duration, offset)."""
    n = tau.size
    err = np.zeros((n, 3))
    floating = np.zeros(n, dtype=bool)
    fl = cfg.get("float")
    reported = None
    if fl is not None:
        reported = fl["reported"]
        for a, b in fl["windows"]:
            idx = np.nonzero((tau >= a) & (tau < b))[0]
            sign = np.where(rng.random(3) < 0.5, -1.0, 1.0)
            e0 = fl["sigma"] * rng.standard_normal(3)
            w = rng.standard_normal((idx.size, 3))
            if idx.size == 0:
                continue
            floating[idx] = True
            dt = np.diff(tau[idx], prepend=tau[idx[0]])[:, None]       # 0 at the window's first fix
            steps = sign * fl["drift"] * dt + fl["walk"] * np.sqrt(dt) * w
            err[idx] = e0 + np.cumsum(steps, axis=0)
    for j in cfg.get("jumps", []):
        sel = (tau >= j["start"]) & (tau < j["start"] + j["duration"])
        err[sel] += j["offset"]
    return RtkErrors(err, floating, reported)
