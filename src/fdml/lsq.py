"""Output error by nonlinear least squares, with each output's noise weight relaxed between passes.

fdml's one least-squares engine outside the frequency-domain estimator: the
time-domain fit (:mod:`fdml.timefit`) and the compatibility check
(:mod:`fdml.flightpath`) both minimise

    sum_k sum_i (e_ki(x) / sigma_k)^2

over bounded parameters x with :func:`scipy.optimize.least_squares` (its
trust-region reflective method and its forward-difference Jacobian, the only
one these fits use), then re-estimate each output's weight sigma_k as the RMS
of its errors and fit again until the weights settle: the relaxation
algorithm (Maine and Iliff; SIDPAC ``oe``), maximum likelihood with a
diagonal noise covariance.

The errors enter the residuals linearly in 1/sigma_k, so the residuals and
the Jacobian at the settled weights are those of the last pass rescaled per
output: no finite-difference sweep is repeated for them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .errors import FdmlError

__all__ = ["RelaxedFit", "relaxed_least_squares"]

#: Options of :func:`scipy.optimize.least_squares` (the caller's are added): trust-region reflective,
#: each unknown scaled by its Jacobian column.
_OPTIONS = {"method": "trf", "x_scale": "jac"}
#: Residual of a simulation that diverged: large and finite, so that the solver steps back
#: (a non-finite one would spoil a Jacobian column).
DIVERGED = 1e6


@dataclass(frozen=True)
class RelaxedFit:
    """Outcome of :func:`relaxed_least_squares`.

    Parameters
    ----------
    x : numpy.ndarray
        The estimate, shape (p,).
    sigma : numpy.ndarray
        The settled weights: each output's error RMS at ``x`` (floored), shape (m,).
    r : numpy.ndarray
        The weighted residuals e_ki(x) / sigma_k at ``x``, output by output, shape (m n,).
    J : numpy.ndarray
        Their Jacobian (forward differences), shape (m n, p).
    settled : bool
        Whether the weights changed by less than the tolerance in the last pass.
    success : bool
        Whether the last pass's least-squares solve met its convergence test.
    message : str
        The last pass's termination message.
    nfev : int
        Error evaluations over all passes (Jacobian columns included).
    """

    x: np.ndarray
    sigma: np.ndarray
    r: np.ndarray
    J: np.ndarray
    settled: bool
    success: bool
    message: str
    nfev: int


def relaxed_least_squares(
    errors: Callable[[np.ndarray], np.ndarray],
    x0,
    bounds: tuple,
    sigma,
    *,
    passes: int,
    tol: float,
    floor=0.0,
    **options,
) -> RelaxedFit:
    """Minimise the weighted output errors, re-estimating the weights between passes.

    Parameters
    ----------
    errors : callable
        ``errors(x) -> E``, the unweighted output errors, shape (m, n): one row
        per output, in the outputs' units.  A simulation that diverges may raise
        ``FloatingPointError``, ``ZeroDivisionError`` or ``OverflowError``: its
        residuals are then :data:`DIVERGED`, so the solver steps back.
    x0 : array_like
        Start, shape (p,); clipped into the bounds.
    bounds : tuple of array_like
        ``(lower, upper)`` bounds of x, each shape (p,) (``-inf``/``inf`` for none).
    sigma : array_like
        Weights of the first pass, one per output, shape (m,), in the outputs' units.
    passes : int
        Largest number of passes (least-squares solves).
    tol : float
        The weights have settled when none changed by more than this fraction.
    floor : float or array_like, optional
        Smallest weight per output (e.g. the quantisation noise), shape (m,) or scalar.
    **options
        Passed to :func:`scipy.optimize.least_squares` (``ftol``, ``max_nfev`` ...; default
        ``method="trf"``, ``x_scale="jac"``).

    Returns
    -------
    RelaxedFit
        The estimate, the settled weights, the residuals and Jacobian at them.

    Raises
    ------
    FdmlError
        If the simulation diverges at the start values.
    """
    sigma = np.asarray(sigma, dtype=float)
    floor = np.broadcast_to(np.asarray(floor, dtype=float), sigma.shape)
    lo, hi = (np.asarray(b, dtype=float) for b in bounds)
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    size: list[int] = []  # residuals per evaluation, from the first that succeeds

    def weighted(z: np.ndarray, w: np.ndarray) -> np.ndarray:
        try:
            e = np.asarray(errors(z), dtype=float)
        except (FloatingPointError, ZeroDivisionError, OverflowError) as exc:
            if not size:
                raise FdmlError(f"the simulation diverges at the start values: {exc}") from None
            return np.full(size[0], DIVERGED)
        size[:] = [e.size]
        return (e * w).ravel()

    nfev, settled = 0, False
    for _ in range(passes):
        w = 1.0 / sigma[:, None]
        res = optimize.least_squares(weighted, x, bounds=(lo, hi), args=(w,), **{**_OPTIONS, **options})
        x, nfev = res.x, nfev + res.nfev + res.njev * x.size
        e = res.fun.reshape(sigma.size, -1) * sigma[:, None]
        new = np.maximum(np.sqrt(np.mean(e**2, axis=1)), floor)
        settled = bool(np.max(np.abs(new / sigma - 1.0)) < tol)
        rescale = np.repeat(sigma / new, e.shape[1])  # the residuals are linear in 1/sigma
        sigma = new
        if settled:
            break
    return RelaxedFit(
        x=x,
        sigma=sigma,
        r=res.fun * rescale,
        J=res.jac * rescale[:, None],
        settled=settled,
        success=bool(res.success),
        message=str(res.message).rstrip("."),
        nfev=int(nfev),
    )
