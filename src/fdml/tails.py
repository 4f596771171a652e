"""Tail probabilities of the chi-square, F and non-central chi-square laws, for whole degrees of freedom.

Every test fdml runs on a fit has whole degrees of freedom: chi-square with q = 1, 2, ... tested
parameters, Bartlett's statistic on k - 1 bands, and F(2q, 2(n - q)) for the multiple coherence of
complex residuals.  For those the tails have closed forms (Abramowitz and Stegun 26.4.4-26.4.5 and
26.6.4): finite sums of exponentials and one complementary error function, exact to rounding and
cheap.  They are written here rather than taken from :mod:`scipy.special` because importing that
costs 0.3 s with scipy 1.17 (its array-API layer), more than a whole fit (issue 20); the tests
check them against :mod:`scipy.stats` to 1e-12.

* chi-square, ``y = x/2``: even ``df = 2k``: ``Q = exp(-y) sum_{i<k} y^i / i!``; odd ``df = 2k+1``:
  ``Q = erfc(sqrt y) + exp(-y) sum_{i=1..k} y^(i-1/2) / Gamma(i + 1/2)``;
* F with even numerator degrees of freedom ``d1 = 2m``, ``t = d2/(d2 + d1 x)``:
  ``P(F > x) = t^(d2/2) sum_{i<m} [Gamma(d2/2 + i) / (Gamma(d2/2) i!)] (1 - t)^i``;
* non-central chi-square: the Poisson mixture ``sum_j Pois(j; lambda/2) Q(df + 2j, x)``.

Sums are formed in logarithms (``logsumexp``) so that the log tail stays finite where the tail
underflows.
"""

from __future__ import annotations

import math

__all__ = ["chi2_sf", "chi2_logsf", "f_sf", "ncx2_sf", "chi2_isf", "noncentrality"]


def _whole(df: float, what: str = "df") -> int:
    k = int(round(df))
    if k < 1 or abs(df - k) > 1e-9:
        raise ValueError(f"{what} must be a whole number >= 1, got {df!r}")
    return k


def _logsumexp(terms: list) -> float:
    m = max(terms)
    if m == -math.inf:
        return -math.inf
    return m + math.log(sum(math.exp(t - m) for t in terms))


def _log_erfc(z: float) -> float:
    """ln erfc(z), z >= 0, finite where erfc underflows (asymptotic series, A&S 7.1.23)."""
    if z < 25.0:
        return math.log(math.erfc(z))
    z2 = z * z
    series = 1.0 - 1.0 / (2 * z2) + 3.0 / (4 * z2 * z2) - 15.0 / (8 * z2**3)
    return -z2 - math.log(z * math.sqrt(math.pi)) + math.log(series)


def chi2_logsf(x: float, df: float) -> float:
    """The log tail ln P(chi2_df > x), whole ``df`` (module doc); 0 for x <= 0.

    Parameters
    ----------
    x : float
        The statistic.
    df : float
        Degrees of freedom (a whole number).

    Returns
    -------
    float
        The log tail probability.
    """
    k = _whole(df)
    if x <= 0:
        return 0.0
    y = 0.5 * x
    ly = math.log(y)
    if k % 2 == 0:
        terms = [-y + i * ly - math.lgamma(i + 1) for i in range(k // 2)]
    else:
        terms = [_log_erfc(math.sqrt(y))] + [-y + (i - 0.5) * ly - math.lgamma(i + 0.5) for i in range(1, k // 2 + 1)]
    return min(_logsumexp(terms), 0.0)


def chi2_sf(x: float, df: float) -> float:
    """P(chi2_df > x), whole ``df``; 1 for x <= 0.

    Parameters
    ----------
    x : float
        The statistic.
    df : float
        Degrees of freedom (a whole number).

    Returns
    -------
    float
        The tail probability.
    """
    return math.exp(chi2_logsf(x, df))


def f_sf(x: float, dfn: float, dfd: float) -> float:
    """P(F(dfn, dfd) > x) for an even ``dfn`` (module doc); 1 for x <= 0.

    Parameters
    ----------
    x : float
        The statistic.
    dfn, dfd : float
        Degrees of freedom of the numerator (even) and the denominator.

    Returns
    -------
    float
        The tail probability.
    """
    d1 = _whole(dfn, "dfn")
    if d1 % 2:
        raise ValueError(f"dfn must be even for the closed form, got {dfn!r}")
    if x <= 0:
        return 1.0
    h = 0.5 * float(dfd)
    t = float(dfd) / (float(dfd) + d1 * x)
    if t <= 0.0:
        return 0.0
    lt, l1t = math.log(t), math.log1p(-t) if t < 1.0 else -math.inf
    terms = [
        h * lt + math.lgamma(h + i) - math.lgamma(h) - math.lgamma(i + 1) + (i * l1t if i else 0.0)
        for i in range(d1 // 2)
    ]
    return min(math.exp(_logsumexp(terms)), 1.0)


def ncx2_sf(x: float, df: float, lam: float) -> float:
    """P(chi2_df(lambda) > x), the non-central tail: a Poisson mixture of central tails (module doc).

    Parameters
    ----------
    x : float
        The statistic.
    df : float
        Degrees of freedom (a whole number).
    lam : float
        Non-centrality, >= 0.

    Returns
    -------
    float
        The tail probability.
    """
    k = _whole(df)
    if lam <= 0.0:
        return chi2_sf(x, k)
    mu = 0.5 * lam
    hi = int(mu + 12.0 * math.sqrt(mu) + 30)  # the Poisson weights beyond are below 1e-25
    y = 0.5 * max(x, 0.0)
    ly = math.log(y) if y > 0 else -math.inf
    q = chi2_sf(x, k)  # Q(k/2 + j, y), raised term by term: Q(a + 1) = Q(a) + exp(-y) y^a / Gamma(a + 1)
    total = 0.0
    for j in range(hi + 1):
        a = 0.5 * k + j
        total += math.exp(-mu + j * math.log(mu) - math.lgamma(j + 1)) * q
        q = min(q + (math.exp(-y + a * ly - math.lgamma(a + 1)) if y > 0 else 0.0), 1.0)
    return min(total, 1.0)


def _bisect(f, lo: float, hi: float, tol: float = 1e-12) -> float:
    """The root of an increasing ``f`` in [lo, hi] (f(lo) < 0 < f(hi)), by bisection."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(mid) < 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= tol * max(1.0, abs(mid)):
            break
    return 0.5 * (lo + hi)


def chi2_isf(p: float, df: float) -> float:
    """The x with P(chi2_df > x) = p.

    Parameters
    ----------
    p : float
        Tail probability, in (0, 1).
    df : float
        Degrees of freedom (a whole number).

    Returns
    -------
    float
        The critical value.
    """
    k = _whole(df)
    lp = math.log(p)
    hi = 1.0
    while chi2_logsf(hi, k) > lp:
        hi *= 2.0
    return _bisect(lambda x: lp - chi2_logsf(x, k), 0.0, hi)


def noncentrality(level: float, df: int = 1, power: float = 0.8) -> float:
    """The non-centrality at which a chi-square(df) test at ``level`` has the given power.

    Parameters
    ----------
    level : float
        Test level, in (0, 1).
    df : int, optional
        Degrees of freedom.
    power : float, optional
        Wanted probability of rejection.

    Returns
    -------
    float
        The non-centrality lambda with ``ncx2_sf(chi2_isf(level, df), df, lambda) = power``.
    """
    crit = chi2_isf(level, df)
    hi = 1.0
    while ncx2_sf(crit, df, hi) < power:
        hi *= 2.0
    return _bisect(lambda lam: ncx2_sf(crit, df, lam) - power, 0.0, hi, tol=1e-10)  # ~40 halvings
