"""The estimator's named thresholds and iteration caps (:data:`SETTINGS`).

Kept below :mod:`fdml.estimate` so that what reads them (the estimator, the
summary's correlation table) needs no import of the estimator itself.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SETTINGS", "EstimatorSettings"]


@dataclass(frozen=True)
class EstimatorSettings:
    """The estimator's thresholds and iteration caps, named and documented in one place.

    :data:`SETTINGS` is the instance every fit uses; each number below is
    the one the estimator's code reads, none is written twice.

    Parameters
    ----------
    settle_tol : float
        Relative change at which the Eq. 26 sensitivities count as settled
        while iterating (docs/theory.md section 7).
    settle_tol_final : float
        The same for the sensitivities behind the final covariance, taken as
        central differences (error O(h^2)) halved until they settle, so that
        the bounds agree with the analytic sensitivities to six significant
        figures.
    fd_start : float
        First forward-difference step, as a fraction of ``max(|theta|, 1e-3)``
        (docs/theory.md section 7: 5 %).
    central_step : float
        Step of ``sensitivity="central"``, same scale.
    fd_max_halvings : int
        Most halvings of a difference step while it settles.
    tight_below : float
        Largest step (in standard errors) below which finite-difference fits
        switch to the tight final sensitivities.
    gn_max_halvings : int
        Most step halvings of a Gauss-Newton step (``method="gauss-newton"``)
        while the cost rises.
    shift_tries : int
        Most shifted-Newton trials per Levenberg-Marquardt step (the trust
        region quartered after each trial that does not lower the cost).
    shift_limit : float
        Shifted Newton only while the most negative curvature of the scaled
        concentrated Hessian is within this fraction of the largest one.
    fallback_halvings : int
        Most halvings of the Gauss-Newton fallback step of the
        Levenberg-Marquardt iteration.
    stall_factor : float
        A fit whose cost no step decreases counts as converged when its last
        step is below ``stall_factor * tol`` standard errors.
    paper_rel_change : float
        The paper's stop rule: relative change of J = det R (Eq. 25).
    singular_eig : float
        Eigenvalue of the scaled information matrix, relative to the
        largest, below which a combination of parameters is not identifiable.
    correlation_warn : float
        Correlation magnitude beyond which the fit raises an
        :class:`~fdml.errors.IdentifiabilityWarning`.
    correlation_listed : float
        Correlation magnitude at or above which the summary lists a pair
        (:func:`fdml.summary.fit_summary`); below ``correlation_warn`` so the
        table shows the pairs approaching it.
    gram_max : int
        Largest frequency count for the O(m^2) Gram-matrix covariance; above
        it the O(n log m) adjoint transform is cheaper in time and memory.
    end_offset_warn : float
        End offset (fraction of the peak) above which a record "ends far from
        trim" (with ``boundary="none"``).
    r_floor : float
        Relative floor added to the diagonal of R: noise-free (simulated) data
        can make R numerically singular, where the likelihood is unbounded;
        1e-12 of the largest variance changes nothing at any realistic noise
        level.
    edge_level : float
        With ``input_edges="auto"``, the step edges' timing terms enter a fit
        whose score test for them (chi-squared, one degree of freedom per
        edge; docs/theory.md section 7a) falls below this level: 1 in 100 records
        whose steps the interpolation does place right pays their variance.
    """

    settle_tol: float = 1e-4
    settle_tol_final: float = 1e-10
    fd_start: float = 0.05
    central_step: float = 1e-4
    fd_max_halvings: int = 60
    tight_below: float = 1e-2
    gn_max_halvings: int = 30
    shift_tries: int = 12
    shift_limit: float = 0.05
    fallback_halvings: int = 12
    stall_factor: float = 10.0
    paper_rel_change: float = 0.01
    singular_eig: float = 1e-10
    correlation_warn: float = 0.95
    correlation_listed: float = 0.9
    gram_max: int = 1500
    end_offset_warn: float = 0.1
    r_floor: float = 1e-12
    edge_level: float = 0.01


#: The settings every fit uses.
SETTINGS = EstimatorSettings()
