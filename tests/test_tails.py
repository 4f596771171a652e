"""fdml.tails: the closed-form tails for whole degrees of freedom against scipy.stats (independent
implementations: scipy evaluates incomplete gamma and beta functions by continued fractions and series)."""

import math

import pytest
from scipy import stats

from fdml import tails

# Each closed form sums a handful of exp(log-terms); a log-term of size L carries a rounding error of
# about L * 2.2e-16, and L reaches lgamma(dfd/2 + i) ~ 1e3 for the F law at dfd = 400, so 1e-12 relative
# is the accuracy the forms have (the chi-square ones, with L below 1e3 / 2 at x = 900, are checked the same).
REL = 1e-12
XS = (1e-6, 1e-3, 0.5, 1.0, 3.0, 10.0, 40.0, 200.0, 900.0)


@pytest.mark.parametrize("df", [1, 2, 3, 4, 5, 8, 11])
def test_chi2_tails_equal_scipy_stats(df):
    for x in XS:
        assert tails.chi2_logsf(x, df) == pytest.approx(float(stats.chi2.logsf(x, df)), rel=REL)
        assert tails.chi2_sf(x, df) == pytest.approx(float(stats.chi2.sf(x, df)), rel=REL, abs=1e-300)
    assert tails.chi2_sf(0.0, df) == 1.0 and tails.chi2_logsf(-1.0, df) == 0.0


def test_chi2_log_tail_stays_finite_where_the_tail_underflows():
    # P(chi2_1 > x) = erfc(z), z = sqrt(x/2); erfc(z) = e^(-z^2)/(z sqrt(pi)) (1 - 1/(2 z^2) + 3/(4 z^4) - ...):
    # at x = 1e4 the tail (e^-5000) underflows a double, its log does not; the series' next term is 4e-10
    z2 = 5000.0
    ref = -z2 - math.log(math.sqrt(z2 * math.pi)) + math.log1p(-1 / (2 * z2) + 3 / (4 * z2 * z2))
    assert tails.chi2_logsf(1e4, 1) == pytest.approx(ref, rel=1e-12)
    assert tails.chi2_sf(1e4, 1) == 0.0


@pytest.mark.parametrize("dfn,dfd", [(2, 30), (4, 30), (6, 400), (2, 2), (10, 58)])
def test_f_tail_equals_scipy_stats(dfn, dfd):
    for x in XS:
        assert tails.f_sf(x, dfn, dfd) == pytest.approx(float(stats.f.sf(x, dfn, dfd)), rel=REL, abs=1e-300)
    assert tails.f_sf(0.0, dfn, dfd) == 1.0


@pytest.mark.parametrize("df,lam", [(1, 0.5), (2, 7.85), (3, 30.0), (1, 200.0)])
def test_noncentral_tail_equals_scipy_stats(df, lam):
    # the Poisson mixture is cut where its weights fall below 1e-25: its error is rounding, not truncation
    for x in (0.1, 2.0, 10.0, 50.0, 300.0):
        assert tails.ncx2_sf(x, df, lam) == pytest.approx(float(stats.ncx2.sf(x, df, lam)), rel=1e-10, abs=1e-300)


@pytest.mark.parametrize("df", [1, 2, 5])
@pytest.mark.parametrize("p", [0.5, 0.01, 1e-6, 1e-12])
def test_chi2_isf_inverts_the_tail(df, p):
    # bisection to 1e-12 of the root
    assert tails.chi2_isf(p, df) == pytest.approx(float(stats.chi2.isf(p, df)), rel=1e-10)


def test_whole_degrees_of_freedom_only():
    with pytest.raises(ValueError, match="whole number"):
        tails.chi2_sf(1.0, 1.5)
    with pytest.raises(ValueError, match="even"):
        tails.f_sf(1.0, 3, 10)
