"""A fit's parameters fixed at values known only to a standard error: their uncertainty carried in.

A sensor effect settled by the kinematics (:mod:`fdml.kinematics`) enters a model fixed at its
kinematic estimate ``psi`` with standard error ``s``.  The estimates then depend on ``psi``:
``theta_hat(psi)``.  To first order their covariance grows by ``J s^2 J^T`` with
``J = d theta_hat / d psi``, taken here as the central difference of two refits at ``psi +- s``
(exact for the first-order term, and it follows the estimator wherever it is nonlinear in
``psi`` over the range that matters).  The result says so in ``options["known_uncertainty"]``.
"""

from __future__ import annotations

from dataclasses import replace
from types import MappingProxyType

import numpy as np

__all__ = ["with_known_uncertainty"]


def with_known_uncertainty(result, refit, known: dict):
    """``result`` with the uncertainty of its fixed parameters ``known`` added to its covariance.

    Parameters
    ----------
    result : FitResult
        The fit with every parameter of ``known`` fixed at its value.
    refit : callable
        ``refit(values) -> FitResult``: the same fit with the fixed parameters set to ``values``
        (a dict by name).
    known : dict
        ``{name: standard error}`` of fixed model parameters, each in its unit.

    Returns
    -------
    FitResult
        A copy whose ``cov``, ``stderr`` and ``corr`` include the known parameters' share;
        ``options["known_uncertainty"]`` lists, per parameter, its standard error and the
        estimates' shifts per standard error.
    """
    if not known:
        return result
    base = result.model.parameters.values
    cov = np.array(result.cov, float)
    shifts = {}
    for name, se in known.items():
        if not (se > 0 and np.isfinite(se)):
            continue
        up = refit({name: base[name] + se})
        down = refit({name: base[name] - se})
        d = np.array([(up.params.get(n, np.nan) - down.params.get(n, np.nan)) / 2 for n in result.names])
        d = np.where(np.isfinite(d), d, 0.0)
        cov = cov + np.outer(d, d)
        shifts[name] = {"stderr": float(se), "shift_per_se": dict(zip(result.names, d.tolist()))}
    cov.setflags(write=False)
    options = MappingProxyType({**dict(result.options), "known_uncertainty": shifts})
    return replace(result, cov=cov, options=options)  # stderr, corr and derived follow from cov
