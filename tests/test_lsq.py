"""fdml.lsq: the one least-squares engine of the time-domain fit and the compatibility check (issue 22)."""

import numpy as np
import pytest

from fdml.errors import FdmlError
from fdml.lsq import relaxed_least_squares

#: Two outputs of one straight line, measured with noise levels ten times apart.
T = np.linspace(0.0, 10.0, 201)
X = [np.column_stack([np.ones_like(T), T]), np.column_stack([np.ones_like(T), -0.5 * T])]
TRUE = np.array([0.3, -1.2])
NOISE = (0.01, 0.1)


def _data(seed=0):
    rng = np.random.default_rng(seed)
    return [x @ TRUE + s * rng.standard_normal(T.size) for x, s in zip(X, NOISE)]


def _closed_form(y):
    """The relaxation's fixed point by weighted linear least squares (numpy's lstsq), iterated to 1e-14."""
    sigma = np.ones(2)
    for _ in range(200):
        A = np.vstack([x / s for x, s in zip(X, sigma)])
        b = np.concatenate([yk / s for yk, s in zip(y, sigma)])
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        new = np.array([np.sqrt(np.mean((yk - xk @ x) ** 2)) for yk, xk in zip(y, X)])
        if np.max(np.abs(new / sigma - 1)) < 1e-14:
            break
        sigma = new
    return x, new


def test_the_relaxation_finds_the_weighted_least_squares_fixed_point():
    y = _data()
    fit = relaxed_least_squares(
        lambda x: np.array([yk - xk @ x for yk, xk in zip(y, X)]),
        [0.0, 0.0],
        (np.full(2, -np.inf), np.full(2, np.inf)),
        np.ones(2),
        passes=50,
        tol=1e-10,
    )
    x, sigma = _closed_form(y)
    assert fit.settled and fit.success
    # the solver stops at ftol = 1e-8 of the cost; on a linear problem that is 1e-8 of x or better
    np.testing.assert_allclose(fit.x, x, rtol=1e-7)
    np.testing.assert_allclose(fit.sigma, sigma, rtol=1e-7)
    # each weight is its output's error RMS: about its noise level
    np.testing.assert_allclose(fit.sigma, NOISE, rtol=0.15)
    # the residuals and the Jacobian are those at the settled weights: (y - X x) / sigma and -X / sigma
    # (the forward-difference Jacobian of a linear model is exact to rounding: 1e-6 of its entries)
    r = np.concatenate([(yk - xk @ fit.x) / s for yk, xk, s in zip(y, X, fit.sigma)])
    np.testing.assert_allclose(fit.r, r, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(fit.J, -np.vstack([xk / s for xk, s in zip(X, fit.sigma)]), rtol=1e-6, atol=1e-6)


def test_bounds_floor_and_unsettled_weights():
    y = _data(1)
    errors = lambda x: np.array([yk - xk @ x for yk, xk in zip(y, X)])  # noqa: E731
    fit = relaxed_least_squares(errors, [0.0, 0.0], ([-np.inf, -1.0], [np.inf, np.inf]), np.ones(2), passes=4, tol=1e-3)
    assert fit.x[1] == pytest.approx(-1.0)  # the slope -1.2 lies beyond its bound
    floored = relaxed_least_squares(errors, [0.0, 0.0], ([-9, -9], [9, 9]), np.ones(2), passes=4, tol=1e-3, floor=0.5)
    assert np.all(floored.sigma == 0.5)  # both error RMS lie below the floor
    one = relaxed_least_squares(errors, [0.0, 0.0], ([-9, -9], [9, 9]), np.ones(2), passes=1, tol=1e-3)
    assert not one.settled  # from unit weights to 0.01 and 0.1: one pass cannot settle them


def test_a_simulation_that_diverges():
    hits = []

    def errors(x):
        if x[0] > 1.0:
            hits.append(x[0])
            raise FloatingPointError("diverged")
        return np.array([np.full(3, np.tanh(5 * (x[0] - 0.5))), np.full(3, x[1])])

    bounds = ([-9, -9], [9, 9])
    fit = relaxed_least_squares(errors, [0.0, 5.0], bounds, np.ones(2), passes=3, tol=1e-3, floor=1e-12, x_scale=1.0)
    # Gauss-Newton from 0 on the flat tanh steps to 7.6 and the first trust region is |x0| = 5 wide: the
    # solver meets the divergence and steps back
    assert hits and fit.x[0] == pytest.approx(0.5, abs=1e-6)
    with pytest.raises(FdmlError, match="diverges at the start values: diverged"):
        relaxed_least_squares(errors, [2.0, 0.0], bounds, np.ones(2), passes=1, tol=1e-3)
