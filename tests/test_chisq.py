"""The chi-square quantiles of the fusion filter's gates without SciPy (sinscli/nav/chisq.py, issue 21), against
``scipy.stats.chi2.ppf`` (the outside oracle) over the degrees of freedom and probabilities the gates use and
beyond, and against closed forms."""
import math

import pytest
from scipy.stats import chi2

from sinscli.nav.chisq import chi2_quantile

PROBS = [1e-12, 1e-8, 1e-4, 1e-3, 0.01, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.95, 0.99, 0.999, 0.9999,
         1 - 1e-6, 1 - 1e-9, 1 - 1e-12]


@pytest.mark.parametrize("k", list(range(1, 31)) + [60, 100])
def test_quantiles_equal_scipy(k):
    for p in PROBS:
        ours, ref = chi2_quantile(p, k), float(chi2.ppf(p, k))
        assert abs(ours - ref) <= 1e-12 * ref, (k, p, ours, ref)


def test_closed_forms():
    # k = 2: Q(x) = exp(-x/2), so x = -2 ln(1 - p); k = 1: x = (Phi^-1((1 + p)/2))^2, with erf: erf(sqrt(x/2)) = p
    for p in (1e-6, 0.25, 0.9973, 1 - 1e-10):
        assert math.isclose(chi2_quantile(p, 2), -2.0 * math.log1p(-p), rel_tol=1e-13)
        x = chi2_quantile(p, 1)
        assert math.isclose(math.erf(math.sqrt(x / 2.0)), p, rel_tol=1e-13)


def test_refuses_what_is_not_a_quantile():
    for p, k in ((0.0, 3), (1.0, 3), (0.5, 0), (float("nan"), 2)):
        with pytest.raises(ValueError):
            chi2_quantile(p, k)
