"""Tests of fdml.fourier: the finite Fourier transform (THEORY.md Eq. 11)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdml import fourier
from fdml.errors import BandError, FdmlError, RecordError
from fdml.fourier import (
    _choose_method,
    _end_weights,
    _moments,
    finite_fourier_transform,
    fourier_adjoint,
    is_evenly_spaced,
    omega_band,
    transform_weights,
)

EPS = np.finfo(float).eps
END_CORRECTIONS = ["cubic", "trapezoid", "none"]
METHODS = ["direct", "czt"]
# Cubic Lagrange interpolation error |x - p| <= C dt^4 max|x''''| with
# C = max|(u+1)u(u-1)(u-2)|/4! = (9/16)/24 = 3/128 on centred stencils and
# max|u(u-1)(u-2)(u-3)|/4! = 1/24 on the one-sided first and last interval.
C_INTERIOR, C_END = 3.0 / 128.0, 1.0 / 24.0


def cubic_bound(dt, T, d4max):
    """Bound on |X - X_exact| for the cubic rule: integral of |x - p| over [0, T]."""
    return (T * C_INTERIOR + 2 * dt * C_END) * dt**4 * d4max


def phi(c, T):
    """integral_0^T exp(1j c t) dt, stable for every real c (including 0)."""
    return T * np.exp(0.5j * c * T) * np.sinc(c * T / (2 * np.pi))


def grid(T, dt):
    n = int(round(T / dt)) + 1
    return np.arange(n) * dt, n


def unsorted_omega(rng, wmax, m=37):
    return np.r_[rng.uniform(-wmax, wmax, m - 2), 0.0, 1e-7]


PAPER = omega_band()


# ----------------------------------------------------------------- omega_band
def test_omega_band_paper_grid():
    w = omega_band()
    assert w.size == 100
    assert w[0] == 0.1
    assert abs(w[-1] - 10.0) < 1e-14  # lo + 99 * step: a few roundings of 10
    assert is_evenly_spaced(w)


def test_omega_band_endpoint_rounding():
    # (0.3 - 0.1) / 0.1 = 1.9999999999999998 in floats: hi must still be included.
    assert omega_band(0.1, 0.3, 0.1).size == 3
    # hi off the grid: stop at the last point below it.
    np.testing.assert_allclose(omega_band(0.0, 1.0, 0.3), [0.0, 0.3, 0.6, 0.9], rtol=0, atol=1e-15)
    assert omega_band(2.0, 2.0, 0.5).tolist() == [2.0]


@pytest.mark.parametrize(
    "args, word",
    [
        ((-0.1, 1.0, 0.1), "negative"),
        ((0.1, 1.0, 0.0), "positive"),
        ((0.1, 1.0, -1.0), "positive"),
        ((2.0, 1.0, 0.1), "below"),
        ((0.1, np.nan, 0.1), "finite"),
        ((0.1, np.inf, 0.1), "finite"),
    ],
)
def test_omega_band_errors(args, word):
    with pytest.raises(BandError, match=word):
        omega_band(*args)


def test_is_evenly_spaced():
    assert is_evenly_spaced(np.linspace(-3, 7, 51))
    assert is_evenly_spaced(np.linspace(7, -3, 51))  # descending is fine
    w = np.linspace(0, 1, 11)
    w[5] += 1e-6
    assert not is_evenly_spaced(w)
    assert not is_evenly_spaced(np.zeros(5))  # zero step
    assert not is_evenly_spaced([0.0, 1.0, np.nan])


# ----------------------------------------------------------------- closed forms
@pytest.mark.parametrize(
    "method, where", [("direct", "paper"), ("czt", "paper"), ("direct", "unsorted"), ("auto", "unsorted")]
)
def test_exponential_decay(method, where):
    a, T, dt = 1.5, 5.0, 0.01
    t, n = grid(T, dt)
    rng = np.random.default_rng(1)
    w = PAPER if where == "paper" else unsorted_omega(rng, 40.0)
    X = finite_fourier_transform(np.exp(-a * t), dt, w, method=method)
    s = a + 1j * w
    exact = -np.expm1(-s * T) / s
    # Interpolation error bound with max|x''''| = a^4, plus rounding ~n eps.
    tol = cubic_bound(dt, T, a**4) + 100 * n * EPS * T
    assert np.max(np.abs(X - exact)) < tol


@pytest.mark.parametrize("where", ["paper", "unsorted"])
def test_sinusoid_whole_periods(where):
    w0, periods, dt = 2.0, 3, 0.005
    T = periods * 2 * np.pi / w0
    n = int(round(T / dt))
    dt = T / n  # a whole number of periods exactly
    t = np.arange(n + 1) * dt
    rng = np.random.default_rng(2)
    w = PAPER if where == "paper" else unsorted_omega(rng, 30.0)
    X = finite_fourier_transform(np.sin(w0 * t), dt, w)
    exact = (phi(w0 - w, T) - phi(-w0 - w, T)) / 2j
    # Interpolation error with max|x''''| = w0^4, plus rounding.
    tol = cubic_bound(dt, T, w0**4) + 100 * n * EPS * T
    assert np.max(np.abs(X - exact)) < tol
    # On the paper grid w = 2 rad/s is the line itself: X = T / (2j).
    if where == "paper":
        i = np.argmin(np.abs(PAPER - w0))
        assert abs(X[i] - T / 2j) < tol


@pytest.mark.parametrize("method", METHODS)
def test_unit_step_is_exact(method):
    dt, n = 0.02, 301
    T = (n - 1) * dt
    rng = np.random.default_rng(8)
    w = np.r_[PAPER, unsorted_omega(rng, np.pi / dt)] if method == "direct" else PAPER
    X = finite_fourier_transform(np.ones(n), dt, w, method=method)
    # The cubic rule integrates x = 1 times exp(-j w t) exactly (Filon); the
    # remaining error is phase rounding, ~n eps relative to integral|x| = T.
    assert np.max(np.abs(X - phi(-w, T))) < 100 * n * EPS * T


def _gauss_transform(f, T, w, panels):
    """integral_0^T f(t) exp(-1j w t) dt by composite 16-point Gauss-Legendre.

    With |w| T / panels <= pi the integrand is a smooth, at most half-period
    oscillation per panel, integrated to ~eps (error ~ (pi/2)^32 / 32!).
    """
    u, g = np.polynomial.legendre.leggauss(16)
    h = T / panels
    t = (np.arange(panels)[:, None] + 0.5 * (u + 1)).ravel() * h
    weights = np.tile(0.5 * h * g, panels)
    return np.exp(-1j * np.outer(w, t)) @ (weights * f(t))


@pytest.mark.parametrize("n", [4, 5, 9, 151])
def test_cubic_polynomial_is_exact(n):
    rng = np.random.default_rng(n)
    coef = rng.standard_normal(4)
    poly = np.polynomial.Polynomial(coef)
    dt = 3.0 / (n - 1)
    T = (n - 1) * dt
    t = np.arange(n) * dt
    nyquist = np.pi / dt
    w = np.r_[PAPER[PAPER <= nyquist][::9], rng.uniform(-nyquist, nyquist, 5), nyquist, 0.0, 1e-6]
    X = finite_fourier_transform(poly(t), dt, w)
    exact = _gauss_transform(poly, T, w, n - 1)
    scale = _gauss_transform(lambda s: np.abs(poly(s)), T, np.zeros(1), 4 * n)[0].real
    # The piecewise cubic interpolant is the polynomial itself: only rounding
    # (float weights, phases ~n eps) in both computations remains.
    assert np.max(np.abs(X - exact)) < 1e-12 * scale


# ------------------------------------------------------------ convergence order
def _smooth_error(dt, end_correction, T=4.0):
    t, n = grid(T, dt)
    a, b = 0.8, 3.0
    x = np.exp(-a * t) * np.cos(b * t)
    w = np.array([0.0, 0.5, 2.0, 3.0, 7.0, 10.0])
    X = finite_fourier_transform(x, dt, w, end_correction=end_correction)
    exact = 0.5 * (phi(b - w + 1j * a, T) + phi(-b - w + 1j * a, T))
    return np.max(np.abs(X - exact))


def test_cubic_converges_at_fourth_order():
    errors = [_smooth_error(dt, "cubic") for dt in (0.08, 0.04, 0.02)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # Error ~ C dt^4; at dt = 0.02 it is ~1e-7, far above rounding (~1e-13).
    assert np.all(orders > 3.5), orders


def test_trapezoid_converges_at_second_order():
    errors = [_smooth_error(dt, "trapezoid") for dt in (0.08, 0.04, 0.02)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # Euler-Maclaurin: leading error dt^2/12 [f'(T) - f'(0)] != 0 here, so order 2.
    assert np.all((orders > 1.8) & (orders < 2.2)), orders


# ----------------------------------------------------------------- numpy.fft
@pytest.mark.parametrize("method", METHODS)
def test_rectangle_sum_equals_fft_at_bins(method):
    rng = np.random.default_rng(3)
    n, dt = 96, 0.05
    x = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    k = np.arange(n // 2 + 1)
    w = 2 * np.pi * k / (n * dt)  # the last bin is exactly Nyquist
    X = finite_fourier_transform(x, dt, w, method=method, end_correction="none")
    ref = dt * np.fft.fft(x)[k]
    # Same sum, different rounding: phase errors ~ n eps * |x| per term.
    assert np.max(np.abs(X - ref)) < 1e-12 * np.max(np.abs(ref))


# ------------------------------------------------------------- czt vs direct
@pytest.mark.parametrize("end_correction", END_CORRECTIONS)
@pytest.mark.parametrize(
    "w", [PAPER, PAPER[::-1], np.linspace(-150, 150, 31)], ids=["paper", "descending", "two-sided"]
)
def test_czt_agrees_with_direct(end_correction, w):
    rng = np.random.default_rng(4)
    n, dt = 2003, 0.02
    x = rng.standard_normal((n, 3))
    a = finite_fourier_transform(x, dt, w, method="direct", end_correction=end_correction)
    b = finite_fourier_transform(x, dt, w, method="czt", end_correction=end_correction)
    assert a.shape == b.shape == (w.size, 3)
    # Rounded phases: direct theta*j up to 3 * 2003 rad, czt chirps up to 2e3 rad;
    # each costs ~eps * phase, i.e. a few 1e-13 relative at most.
    assert np.max(np.abs(a - b)) < 1e-12 * np.max(np.abs(a))


def test_auto_method_choice():
    assert _choose_method(3000, PAPER, "auto") == "czt"
    assert _choose_method(20, PAPER[:10], "auto") == "direct"  # too small to pay
    uneven = np.r_[PAPER[:50], PAPER[50:] + 0.01]
    assert _choose_method(3000, uneven, "auto") == "direct"
    assert _choose_method(3000, PAPER[:1], "czt") == "direct"  # one frequency
    with pytest.raises(BandError, match="evenly spaced"):
        _choose_method(3000, uneven, "czt")


# ----------------------------------------------------------- linear map, adjoint
@pytest.mark.parametrize("end_correction", END_CORRECTIONS)
@pytest.mark.parametrize("n", [4, 7, 257])
def test_weights_match_transform(end_correction, n):
    rng = np.random.default_rng(5 + n)
    dt = 0.1
    w = np.r_[omega_band(0.1, 10.0, 0.3), -2.5, 0.0]
    x = rng.standard_normal((n, 2)) + 1j * rng.standard_normal((n, 2))
    F = transform_weights(n, dt, w, end_correction=end_correction)
    assert F.shape == (w.size, n)
    X = finite_fourier_transform(x, dt, w, end_correction=end_correction)
    # Same weights, different summation order: rounding ~ n eps.
    assert np.max(np.abs(F @ x - X)) < 1e-13 * np.max(np.abs(X))


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("end_correction", END_CORRECTIONS)
@pytest.mark.parametrize("n", [5, 1500])
def test_adjoint_identity(method, end_correction, n):
    rng = np.random.default_rng(6 + n)
    dt = 0.02
    w = PAPER
    x = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    y = rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)
    Fx = finite_fourier_transform(x, dt, w, method=method, end_correction=end_correction)
    Fhy = fourier_adjoint(y, n, dt, w, method=method, end_correction=end_correction)
    assert Fhy.shape == (n,)
    lhs, rhs = np.vdot(Fx, y), np.vdot(x, Fhy)
    # Cauchy-Schwarz scale; rounding of both maps ~ n eps.
    assert abs(lhs - rhs) < 1e-12 * np.linalg.norm(Fx) * np.linalg.norm(y)
    F = transform_weights(n, dt, w, end_correction=end_correction)
    Y = rng.standard_normal((w.size, 2))
    # czt rounds chirp phases of up to 2e3 rad (~2e-13), direct ones of max|theta| n.
    assert np.max(
        np.abs(fourier_adjoint(Y, n, dt, w, method=method, end_correction=end_correction) - F.conj().T @ Y)
    ) < 1e-12 * np.max(np.abs(F.conj().T @ Y))


def test_adjoint_long_record_without_matrix():
    # 100 minutes at 50 Hz: F would be 300000 x 100 complex (480 MB); the czt
    # adjoint must agree with the forward map column by column, <F e_j, y>.
    n, dt = 300_000, 0.02
    rng = np.random.default_rng(7)
    y = rng.standard_normal(PAPER.size) + 1j * rng.standard_normal(PAPER.size)
    assert _choose_method(n, PAPER, "auto") == "czt"
    r = fourier_adjoint(y, n, dt, PAPER)
    # Phases theta*j reach max|theta| n = 6e4 rad; rounding them costs ~eps each.
    tol = 4 * EPS * (PAPER.max() * dt) * n * np.abs(r).max()
    for j in (0, 2, 150_001, n - 1):
        e = np.zeros(n)
        e[j] = 1.0
        assert abs(np.vdot(finite_fourier_transform(e, dt, PAPER), y) - r[j]) < tol


# ------------------------------------------------------------- small theta
def test_end_weights_known_values():
    W, alpha = _end_weights(np.array([0.0, 1e-5]), "cubic")
    # Endpoint weights 1/3, 31/24, 5/6, 25/24 of the cubic rule, minus the 1 in W.
    expected = np.array([-2 / 3, 7 / 24, -1 / 6, 1 / 24])
    assert W[0] == 1.0 and abs(W[1] - (1 - 11e-20 / 720)) < 2 * EPS  # W = 1 - 11 theta^4/720
    assert np.max(np.abs(alpha[0] - expected)) < 4 * EPS
    # a_k(theta) = a_k(0) + O(theta): nothing blows up as theta -> 0.
    assert np.max(np.abs(alpha[1] - expected)) < 1e-5
    t = np.linspace(0.3, np.pi, 50)
    W, _ = _end_weights(t, "cubic")
    closed = (6 + t**2) * (3 - 4 * np.cos(t) + np.cos(2 * t)) / (3 * t**4)
    # The closed form itself cancels (error ~10 eps / theta^4) on top of ~1 ulp.
    assert np.all(np.abs(W - closed) < 4 * EPS + 10 * EPS / t**4)


def test_moments_continuous_at_series_switch():
    below = np.nextafter(1.0, 0.0)
    mu = _moments(np.array([below, 1.0, -below, -1.0]))
    # Series (20 terms, remainder < 1/20!) and recursion (error <= 6 eps) meet;
    # |d mu / d theta| <= 1/2, so the 1 ulp step in theta adds nothing visible.
    assert np.max(np.abs(mu[0] - mu[1])) < 20 * EPS
    assert np.max(np.abs(mu[2] - mu[3])) < 20 * EPS


@pytest.mark.parametrize("method", METHODS)
def test_tiny_and_zero_frequency(method):
    dt, n = 0.01, 501
    T = (n - 1) * dt
    t = np.arange(n) * dt
    w = np.array([-1e-6, 0.0, 1e-9, 1e-6, 2e-6]) if method == "direct" else np.linspace(0, 4e-6, 5)
    poly = np.polynomial.Polynomial([0.3, -1.0, 0.5, 0.2])
    X = finite_fourier_transform(poly(t), dt, w, method=method)
    # exact moments of t^p times exp(-1j w t), series in w (|w T| <= 2e-5)
    exact = np.zeros(w.size, dtype=complex)
    for s in range(6):
        antider = (poly * np.polynomial.Polynomial([0, 1]) ** s).integ()
        exact += (-1j * w) ** s / math.factorial(s) * (antider(T) - antider(0))
    # Exact for cubics: rounding only, ~1e-14 relative to integral|x|.
    assert np.max(np.abs(X - exact)) < 1e-12 * np.abs(exact[0])
    a = 0.9
    X = finite_fourier_transform(np.exp(-a * t), dt, w, method=method)
    s = a + 1j * w
    assert np.max(np.abs(X - (-np.expm1(-s * T) / s))) < cubic_bound(dt, T, a**4) + 100 * n * EPS


# ------------------------------------------------------------------ bad input
def test_nan_in_x():
    x = np.ones((50, 2))
    x[17, 1] = np.nan
    x[30, 0] = np.inf
    with pytest.raises(RecordError, match=r"2 NaN.*sample 17.*column 1"):
        finite_fourier_transform(x, 0.1, PAPER)


def test_above_nyquist():
    with pytest.raises(BandError, match=r"Nyquist.*15\.70"):
        finite_fourier_transform(np.ones(100), 0.2, np.array([1.0, 20.0]))
    with pytest.raises(BandError, match="Nyquist"):
        fourier_adjoint(np.ones(2), 100, 0.2, np.array([1.0, -20.0]))


@pytest.mark.parametrize("dt", [0.0, -0.01, np.nan, np.inf])
def test_bad_dt(dt):
    with pytest.raises(RecordError, match="dt"):
        finite_fourier_transform(np.ones(100), dt, PAPER)


def test_too_short_for_cubic():
    with pytest.raises(RecordError, match="at least 4"):
        finite_fourier_transform(np.ones(3), 0.01, PAPER)
    # the other rules accept it
    X = finite_fourier_transform(np.ones(3), 0.01, PAPER, end_correction="trapezoid")
    assert X.shape == (100,)


@pytest.mark.parametrize("omega", [np.array([]), np.array([1.0, np.nan])])
def test_bad_omega(omega):
    with pytest.raises(BandError, match="non-empty|NaN"):
        finite_fourier_transform(np.ones(100), 0.01, omega)


def test_bad_options_and_shapes():
    with pytest.raises(FdmlError, match="method"):
        finite_fourier_transform(np.ones(10), 0.1, PAPER[:5], method="fft")
    with pytest.raises(FdmlError, match="end_correction"):
        finite_fourier_transform(np.ones(10), 0.1, PAPER[:5], end_correction="simpson")
    with pytest.raises(BandError, match="shape"):
        fourier_adjoint(np.ones(4), 10, 0.1, PAPER[:5])
    with pytest.raises(RecordError, match="integer"):
        transform_weights(10.0, 0.1, PAPER[:5])


@pytest.mark.parametrize("n", [16, 17, 376, 3001])
@pytest.mark.parametrize("grid", ["even", "uneven"])
def test_gram_matrices_match_explicit_weights(n, grid):
    # closed-form Dirichlet sums plus end columns against W W^H built from transform_weights;
    # both are sums of ~n terms of size dt^2: rounding ~ n eps relative
    om = np.linspace(0.3, 9.0, 40) if grid == "even" else np.r_[np.linspace(0.3, 9.0, 30), -2.0, 0.0]
    for ec in ("cubic", "trapezoid", "none"):
        F = fourier.transform_weights(n, 0.02, om, end_correction=ec)
        GH, GT = fourier.gram(n, 0.02, om, end_correction=ec)
        for got, ref in ((GH, F @ F.conj().T), (GT, F @ F.T)):
            assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()


def test_leading_transform_matches_full_transform():
    om = np.linspace(0.3, 9.0, 40)
    for L in (1, 3, 25):
        w = np.arange(1.0, L + 1)
        x = np.zeros(500)
        x[:L] = w
        ref = fourier.finite_fourier_transform(x, 0.02, om)
        got = fourier.leading_transform(w, 500, 0.02, om)
        assert np.allclose(got, ref, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("om", [np.array([2.5]), np.array([0.7, 4.1]), np.array([-3.0]), np.array([0.0, 1.3])])
def test_gram_of_one_and_two_frequencies_matches_explicit_weights(om):
    # the closed form on the smallest grids (no Toeplitz path) against W W^H: sums of ~n terms of
    # size dt^2, so rounding ~ n eps relative
    for n, ec in ((16, "cubic"), (9, "cubic"), (301, "trapezoid"), (2, "none"), (301, "none")):
        F = fourier.transform_weights(n, 0.02, om, end_correction=ec)
        GH, GT = fourier.gram(n, 0.02, om, end_correction=ec)
        for got, ref in ((GH, F @ F.conj().T), (GT, F @ F.T)):
            assert got.shape == (om.size, om.size)
            assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()


def test_gram_of_a_record_without_interior_uses_the_explicit_weights():
    # fewer than 2K + 1 samples: the Dirichlet sum has no interior to sum; gram_form says so
    om = np.linspace(0.5, 20.0, 7)
    assert fourier.gram_form(8, "cubic") == "direct sum" and fourier.gram_form(9, "cubic") == "closed form"
    assert fourier.gram_form(2, "trapezoid") == "direct sum" and fourier.gram_form(3, "trapezoid") == "closed form"
    for n in (4, 8, 9):
        F = fourier.transform_weights(n, 0.05, om)
        GH, _ = fourier.gram(n, 0.05, om)
        assert np.abs(GH - F @ F.conj().T).max() <= 1e-14 * np.abs(GH).max()


def test_gram_is_kept_per_grid_and_read_only():
    om = np.linspace(0.3, 9.0, 40)
    first = fourier.gram(500, 0.02, om)
    again = fourier.gram(500, 0.02, om.copy())  # an equal grid, another array
    assert all(a is b for a, b in zip(first, again))
    assert not first[0].flags.writeable and not first[1].flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        first[0][0, 0] = 0.0
    # another record length, interval, grid or end correction is another Gram matrix
    for other in (
        fourier.gram(501, 0.02, om),
        fourier.gram(500, 0.025, om),
        fourier.gram(500, 0.02, om * 1.01),
        fourier.gram(500, 0.02, om, end_correction="trapezoid"),
    ):
        assert np.abs(other[0] - first[0]).max() > 1e-6 * np.abs(first[0]).max()
    # a grid too large to keep is still exact, and read-only like the kept ones
    big = np.linspace(0.1, 60.0, 401)
    F = fourier.transform_weights(700, 0.05, big)
    GH, GT = fourier.gram(700, 0.05, big)
    assert not GH.flags.writeable and fourier.gram(700, 0.05, big)[0] is not GH
    assert np.abs(GH - F @ F.conj().T).max() <= 1e-12 * np.abs(GH).max()


def test_transform_columns_are_columns_of_the_weights():
    om = np.r_[np.linspace(0.3, 9.0, 30), -2.0, 0.0]
    for n, ec in ((5, "cubic"), (8, "cubic"), (300, "cubic"), (300, "trapezoid"), (300, "none")):
        F = fourier.transform_weights(n, 0.02, om, end_correction=ec)
        cols = np.unique(np.r_[0, 1, 2, 3, n // 2, n - 4, n - 2, n - 1])
        got = fourier.transform_columns(n, 0.02, om, cols, end_correction=ec)
        # phases theta j up to ~n theta: rounding ~ n eps relative
        assert np.abs(got - F[:, cols]).max() <= 1e-13 * np.abs(F).max()
    with pytest.raises(RecordError, match="sample indices"):
        fourier.transform_columns(10, 0.02, om, [10])
