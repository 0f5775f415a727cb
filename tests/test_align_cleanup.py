"""The cleanup of issue 10 part 1: ``budget.allan_white`` on the project's one Allan variance
(``allan.adev.overlapping_avar``) gives what its own loop gave, within rounding."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sinscli.align import budget
from sinscli.align.budget import allan_white


def _allan_white_loop(inc, dt, max_frac=0.1):
    """The former implementation (its own overlapping Allan variance loop), kept as the reference."""
    inc = np.asarray(inc, dtype=float)[:budget.ALLAN_MAX]
    dt = np.asarray(dt, dtype=float)[:budget.ALLAN_MAX]
    n = inc.shape[0]
    step = float(np.median(dt))
    m_max = int(n * max_frac)
    ms = np.unique(np.round(np.logspace(0, math.log10(m_max), 24)).astype(int))
    theta = np.concatenate([np.zeros((1, 3)), np.cumsum(inc, axis=0)])
    best = None
    for i in range(3):
        tau = ms * step
        av = np.array([np.mean((theta[2 * m:, i] - 2.0 * theta[m:-m, i] + theta[:-2 * m, i]) ** 2)
                       for m in ms]) / (2.0 * tau ** 2)
        neff = np.maximum(n / ms - 1.0, 1.0)
        wsd = av * np.sqrt(2.0 / neff)
        A = np.stack([1.0 / tau, 3.0 / tau ** 2], axis=-1) / wsd[:, None]
        x, cov = budget._nnls2(A, av / wsd)
        if x is None:
            continue
        if best is None or x[0] > best[0]:
            best = (x[0], math.sqrt(max(cov[0, 0], 0.0)))
    return math.sqrt(best[0]), math.sqrt(best[0] + 2.5 * best[1])


@pytest.mark.parametrize("seed", range(4))
def test_allan_white_equals_the_former_loop(seed):
    rng = np.random.default_rng(seed)
    n = 20000
    inc = rng.normal(0.0, 1e-4, (n, 3)) + np.array([1e-5, 2e-5, -3e-6])
    if seed % 2:
        inc += np.round(rng.normal(0.0, 1.0, (n, 3))) * 1e-5               # quantization
    dt = np.full(n, 0.01)
    got, ref = allan_white(inc, dt), _allan_white_loop(inc, dt)
    assert got == pytest.approx(ref, rel=1e-12)
    # and the white noise it reports is the simulated one: 1e-4 rad per sqrt(0.01 s) = 1e-3 rad/sqrt(s)
    assert got[0] == pytest.approx(1e-3, rel=0.05)
