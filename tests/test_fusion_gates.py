"""The filter's chi-square gates (``fusion.pipeline.chi2_gate``, scipy.stats) against closed forms and sampling."""
import math
from statistics import NormalDist

import numpy as np
import pytest

from sinscli.fusion.pipeline import chi2_gate


@pytest.mark.parametrize("p", [0.5, 0.95, 0.99, 0.9999, 0.99999])
def test_gate_matches_the_closed_forms(p):
    # chi2(1) = z^2: P(|z| <= sqrt(x)) = p;  chi2(2) is exponential with mean 2
    assert chi2_gate(p, 1) == pytest.approx(NormalDist().inv_cdf(0.5 + 0.5 * p) ** 2, rel=1e-9)
    assert chi2_gate(p, 2) == pytest.approx(-2.0 * math.log1p(-p), rel=1e-12)
    # chi2(4): CDF 1 - exp(-x/2) (1 + x/2)
    x = chi2_gate(p, 4)
    assert 1.0 - math.exp(-x / 2) * (1.0 + x / 2) == pytest.approx(p, abs=1e-12)


def test_gate_rejects_the_expected_fraction_of_true_innovations():
    """NIS of true 3-D innovations (sum of 3 squared unit normals): the 0.99 gate passes 99 % of them."""
    rng = np.random.default_rng(23)
    nis = (rng.standard_normal((1_000_000, 3)) ** 2).sum(axis=1)
    frac = float(np.mean(nis > chi2_gate(0.99, 3)))
    assert abs(frac - 0.01) < 5 * math.sqrt(0.01 * 0.99 / nis.size)        # 5 sigma of the binomial count


def test_adaptive_threshold_on_many_degrees_of_freedom():
    # the NIS window's mean per dof: chi2(m)/m -> 1 + z sqrt(2/m) (Wilson-Hilferty, 0.1 % at m = 150)
    m = 150
    wh = (1.0 - 2.0 / (9 * m) + NormalDist().inv_cdf(0.99999) * math.sqrt(2.0 / (9 * m))) ** 3
    assert chi2_gate(0.99999, m) / m == pytest.approx(wh, rel=2e-3)
