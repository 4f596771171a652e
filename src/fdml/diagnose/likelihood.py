"""Fits under a band-wise noise model, and the likelihood ratio between nested fits.

fdml's default likelihood concentrates one residual covariance R over the
whole band (Eq. 24), i.e. it assumes noise that is white across frequency.
Coloured sensor noise or turbulence breaks that, and a likelihood-ratio test
with the wrong weighting is miscalibrated (docs/diagnosis_method.md 2.1 and 2.6 rule 1: a
flat, residual-based noise estimate gave 87 % false turbulence calls on
coloured noise in the prototype).  So every diagnosis fit is :func:`fdml.fit`
with the band-wise noise model (:class:`fdml.estimate.NoiseModel`), whose cost is

    -log L = sum_b N_b ln det R_b(theta) + const,
    R_b = (1/N_b) sum_{i in b} v_i v_i^H            (Eq. 24 per band)

over a few frequency bands of equal size (each with >= ``min_independent``
independent frequencies, so each 3x3 R_b is well estimated); its standard
errors are fdml's coloured-residual sandwich at that estimate.

The likelihood-ratio statistic of nested fits is ``LR = 2 (C0 - C1) / K``
with ``C = sum_b N_b ln det R_b`` over the K-times oversampled grid (complex
Gaussian bins: -2 log L = 2 C + const; /K counts independent frequencies).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import FdmlError
from ..estimate import NoiseModel, Problem, _cov_R, _logdet, prepare
from ..estimate import fit as fdml_fit
from ..models.base import Model
from ..results import FitResult
from ..warning_log import merged, recording
from .data import AnalysisData

__all__ = ["DiagFit", "band_cost", "fit_model", "likelihood_ratio", "noise_bands"]


def noise_bands(data: AnalysisData, *, mode: str = "band", min_independent: int = 20, max_bands: int = 4) -> NoiseModel:
    """Equal-count noise bands over the stacked analysis frequencies.

    ``mode="white"`` gives one band (fdml's own white-noise likelihood).

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    mode : {"band", "white"}, optional
        Band-wise or one band.
    min_independent : int, optional
        Fewest independent frequencies per band.
    max_bands : int, optional
        Most bands.

    Returns
    -------
    NoiseModel
        The band edges, rad/s.
    """
    om = np.sort(data.stacked_omega())
    lo, hi = om[0] * (1 - 1e-9), om[-1] * (1 + 1e-9)
    if mode not in ("band", "white"):
        raise FdmlError(f"noise must be 'band' or 'white', got {mode!r}")
    nb = int(max(1, min(max_bands, data.n_dft // max(min_independent, 1))))
    if mode == "white" or nb == 1:
        return NoiseModel((lo, hi))
    q = np.quantile(om, np.linspace(0, 1, nb + 1)[1:-1])
    return NoiseModel(tuple(np.concatenate([[lo], q, [hi]])))


def band_cost(V: np.ndarray, rows: np.ndarray, nb: int):
    """``sum_b N_b ln det R_b`` and the R_b (Eq. 24 per band, fdml.estimate's floor), as a list of nb.

    Parameters
    ----------
    V : numpy.ndarray
        Residuals, shape (N, n_out), complex.
    rows : numpy.ndarray of int
        Noise band of each row, shape (N,).
    nb : int
        Number of bands (a band without rows gets R = I).

    Returns
    -------
    cost : float
        The cost ``sum_b N_b ln det R_b``.
    Rs : list of numpy.ndarray
        The nb band covariances, shape (n_out, n_out) each.
    """
    Rs = list(_cov_R(V, rows))
    Rs += [np.eye(V.shape[1])] * (nb - len(Rs))  # trailing bands without rows
    return float(V.shape[0] * _logdet(np.stack(Rs), rows)), Rs


@dataclass
class DiagFit:
    """A model fitted for the diagnosis (fdml.fit under the band-wise noise model).

    Parameters
    ----------
    model : Model
        With its parameters at the estimates.
    names : tuple of str
        Estimated quantities (model parameters then nuisance terms).
    theta : ndarray
        The estimates, in ``names`` order.
    stderr : dict
        Standard errors (fdml's coloured-residual covariance at ``theta``) by name.
    V : ndarray, shape (N, n_out)
        Residuals on the analysis grid (records stacked).
    cost : float
        ``sum_b N_b ln det R_b`` over the analysis grid.
    Rs : list of ndarray
        Band residual covariances.
    converged : bool
        Whether fdml's fit converged.
    message : str
        The optimiser's message.
    prob : Problem
        The fdml problem for this model and data.
    result : FitResult
        The fdml result (derived values and their standard errors at ``theta``).
    warnings : tuple of RecordedWarning
        Every warning raised while fitting it (the diagnosis shows none on the
        screen: they are kept here and in the report).
    """

    model: Model
    names: tuple
    theta: np.ndarray
    stderr: dict
    V: np.ndarray
    cost: float
    Rs: list
    converged: bool
    message: str
    prob: Problem = field(repr=False)
    result: FitResult | None = field(default=None, repr=False)
    warnings: tuple = ()

    @property
    def params(self) -> dict:
        """Estimated parameter values by name."""
        return dict(zip(self.names, self.theta.tolist()))

    def model_values(self) -> dict:
        """All model parameter values with the estimates in place.

        Returns
        -------
        dict of str to float
            Values by parameter name, each in its unit.
        """
        return self.prob.model_values(self.theta)

    def full_residual(self) -> np.ndarray:
        """Residuals of all three outputs on the stacked analysis rows, shape (N, 3).

        Returns
        -------
        numpy.ndarray
            Complex: alpha (rad s), q (rad), az (g s), fitted or not.
        """
        ys = self.prob.predict(self.theta)
        return np.concatenate([d.z - y for d, y in zip(self.prob.data, ys)])


def fit_model(
    data: AnalysisData,
    model: Model,
    bands: NoiseModel,
    *,
    outputs=None,
    boundary: str = "estimated",
    biases="auto",
    input_edges: str = "none",
    start: dict | None = None,
) -> DiagFit:
    """Fit ``model`` to ``data`` by :func:`fdml.fit` under the band-wise noise model ``bands``.

    ``start`` overrides start values by name (model parameters only).  Estimates, standard errors
    (coloured-residual sandwich) and derived values all belong to the same, final estimate.

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    model : Model
        The model, with its start values and free parameters.
    bands : NoiseModel
        The noise bands.
    outputs : sequence of str or str, optional
        Outputs that enter the fit (default ``alpha, q, az``).
    boundary : {"estimated", "measured", "none"}, optional
        Boundary terms, as for :func:`fdml.fit`.
    biases : {"auto", True, False}, optional
        Output biases, as for :func:`fdml.fit`.
    input_edges : {"none", "estimated", "auto"}, optional
        The elevator steps' timing terms, as for :func:`fdml.fit`.
    start : dict, optional
        Start values by parameter name (clipped to the bounds).

    Returns
    -------
    DiagFit
        The fit, its band-wise cost and the warnings it raised.
    """
    if start:
        pars = model.parameters
        ok = {k: float(v) for k, v in start.items() if k in pars and math.isfinite(v)}
        model = model.with_values({k: min(max(v, pars[k].lower), pars[k].upper) for k, v in ok.items()})
    with recording(reemit=False) as log:
        # the diagnosis checks its records once (core._data_findings); no adequacy check inside its own fits
        # "analytic": closed forms where the model has them, else central differences of the model
        # response (2 evaluations a parameter; Eq. 26's settled forward differences take 4 and more)
        res = fdml_fit(
            list(data.spectra),
            model,
            outputs=outputs,
            boundary=boundary,
            biases=biases,
            input_edges=input_edges,
            cov_type="colored",
            noise=bands,
            sensitivity="analytic",
            check=False,
            adequacy=False,
        )
    stderr = dict(zip(res.names, np.asarray(res.stderr, float).tolist()))
    return diag_fit(res, data, bands, stderr, log, outputs=outputs, boundary=boundary, biases=biases)  # edges: res's


def diag_fit(res, data: AnalysisData, bands: NoiseModel, stderr: dict, warned=(), **options) -> DiagFit:
    """A :class:`DiagFit` of the fit ``res``: its problem rebuilt with ``options``, band-wise cost.

    ``warned``: the warnings recorded while ``res`` was fitted; kept in the DiagFit with the
    result's own and those of rebuilding the problem.

    Parameters
    ----------
    res : FitResult
        The fit.
    data : AnalysisData
        The records' spectra it was fitted to.
    bands : NoiseModel
        The noise bands of the cost.
    stderr : dict
        Standard errors by name.
    warned : iterable, optional
        Warnings recorded while ``res`` was fitted.
    **options
        Fit options (``outputs``, ``boundary``, ``biases``) to rebuild the problem with; the
        elevator steps' timing terms are the fit's own (``input_edges`` as it resolved them).

    Returns
    -------
    DiagFit
        The fit with its residuals and band-wise cost.
    """
    with recording(reemit=False) as log:
        prob = prepare(
            list(data.spectra), res.model, **{**options, "input_edges": res.options.get("input_edges", "none")}
        )
    theta = np.array([res.params[n] for n in prob.names], float)
    V = prob.residuals(theta)
    C, Rs = band_cost(V, bands.assign(data.stacked_omega()), bands.n)
    return DiagFit(
        model=res.model,
        names=tuple(prob.names),
        theta=theta,
        stderr=stderr,
        V=V,
        cost=C,
        Rs=Rs,
        converged=bool(res.converged),
        message=res.message,
        prob=prob,
        result=res,
        warnings=merged(warned, res.warnings, log),
    )


def likelihood_ratio(c0: float, c1: float, oversample: int) -> float:
    """``2 (C0 - C1) / K`` (>= 0 up to optimiser noise; clipped at 0).

    Parameters
    ----------
    c0, c1 : float
        Costs of the null and the alternative fit.
    oversample : int
        K, the analysis grid's oversampling.

    Returns
    -------
    float
        The likelihood-ratio statistic.
    """
    return max(2.0 * (c0 - c1) / oversample, 0.0)
