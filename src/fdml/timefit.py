"""Time-domain output-error fit, the cross-check of the frequency-domain estimate.

The same model is simulated in the time domain by :func:`fdml.simulate.simulate`
and fitted to the measured time histories by ``scipy.optimize.least_squares`` (:mod:`fdml.lsq`):
the classical output-error method (Maine and Iliff; SIDPAC ``oe``), with a
diagonal measurement-noise covariance re-estimated between passes (the
relaxation algorithm).  Standard errors are the Cramer-Rao bounds
``(J^T J)^-1`` of the weighted residuals for white noise.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from .channels import OUTPUTS
from .errors import RecordError
from .fit_options import known_outputs
from .lsq import relaxed_least_squares
from .models.base import Model
from .record import Record
from .results import ByName, frozen

__all__ = ["TimeFitResult", "fit_time_domain"]


@dataclass(frozen=True)
class TimeFitResult(ByName):
    """Outcome of :func:`fit_time_domain`.

    Parameters
    ----------
    names : tuple of str
        Estimated parameters (model parameters, then output biases).
    values, stderr : ndarray
        Estimates and their standard errors, in ``names`` order, each in the parameter's unit.
    sigma : ndarray
        Estimated noise standard deviation per fitted output.
    outputs : tuple of str
        The fitted outputs.
    nfev : int
        Model simulations used.
    converged : bool
        Whether the last pass converged.
    message : str
        The optimiser's message.
    elapsed : float
        Wall-clock seconds.
    model : Model
        The model at the estimate.
    """

    names: tuple
    values: np.ndarray
    stderr: np.ndarray
    sigma: np.ndarray
    outputs: tuple
    nfev: int
    converged: bool
    message: str
    elapsed: float
    model: Model

    def __post_init__(self) -> None:
        for f in fields(self):  # a result is a record: its arrays are read-only
            object.__setattr__(self, f.name, frozen(getattr(self, f.name)))

    def __getitem__(self, name: str) -> float:
        return self.params[name]

    def summary(self) -> str:
        """Text table of the estimates.

        Returns
        -------
        str
            A header line and one line per estimate with its standard error.
        """
        lines = [
            f"time-domain output-error fit: {self.model.describe()}; outputs {', '.join(self.outputs)}",
            f"{'converged' if self.converged else 'NOT converged'} ({self.message}); {self.nfev} simulations",
            f"{'parameter':<16s}{'value':>14s}{'std err':>12s}",
        ]
        lines += [f"{n:<16s}{v:>14.6g}{s:>12.4g}" for n, v, s in zip(self.names, self.values, self.stderr)]
        return "\n".join(lines)


def fit_time_domain(
    record: Record,
    model: Model,
    *,
    outputs: Sequence[str] | str | None = None,
    trim: str = "first",
    biases: bool = True,
    free: Sequence[str] | None = None,
    fix=None,
    passes: int = 4,
    max_nfev: int = 400,
) -> TimeFitResult:
    """Fit ``model`` to ``record`` by time-domain output error.

    Parameters
    ----------
    record : Record
        The flight record.
    model : Model
        Starting values and free parameters (as for :func:`fdml.fit`).
    outputs : sequence of str or str, optional
        Outputs in the fit (default alpha, q, az; ``theta`` and ``qdot`` too).
    trim : {"first", "mean", "none"}, optional
        Trim removal, as in :func:`fdml.spectral.spectra`.
    biases : bool, optional
        Estimate a constant output bias per fitted output (default True).
    free, fix : optional
        As for :func:`fdml.fit`.
    passes : int, optional
        Relaxation passes: fit the parameters with the noise weights fixed,
        then re-estimate the weights from the residuals.
    max_nfev : int, optional
        Simulation budget per pass.

    Returns
    -------
    TimeFitResult
        The estimates, standard errors and noise levels.
    """
    from .simulate import simulate

    t_start = time.perf_counter()
    if not isinstance(record, Record):
        raise RecordError(f"expected an fdml Record, got {type(record).__name__}")
    if isinstance(outputs, str):
        outputs = [o.strip() for o in outputs.split(",") if o.strip()]
    outputs = known_outputs(outputs or OUTPUTS)
    model = model.with_outputs(outputs)  # the simulator returns them
    params = model.parameters.fix(fix or ()).free(free or ())
    model = model.with_parameters(params)
    rec = record.remove_trim(trim)
    # the simulator needs an exactly uniform grid; records are uniform to 1e-3 of dt
    t_sim = rec.t[0] + rec.dt * np.arange(rec.n)
    if model.gust and not rec.has("alpha_w"):
        raise RecordError(f"record {rec.name!r} has no alpha_w column but the model has a gust input")
    inputs = {k: rec[k] for k in model.inputs}
    zmeas = np.column_stack([rec[o] for o in outputs])
    names = list(params.free_model_names)
    theta0 = np.array([params[n].value for n in names])
    nb = len(outputs) if biases else 0
    x0 = np.concatenate([theta0, np.zeros(nb)])
    lo = np.concatenate([[params[n].lower for n in names], np.full(nb, -np.inf)])
    hi = np.concatenate([[params[n].upper for n in names], np.full(nb, np.inf)])
    base = {**params.values, **{f"bias_{o}": 0.0 for o in model.outputs}}  # biases are handled here, per fitted output

    def predict(x):
        vals = dict(base, **dict(zip(names, x[: len(names)])))
        sim = simulate(model, t_sim, inputs, vals)
        y = np.column_stack([sim[o] for o in outputs])
        return y + (x[len(names) :] if nb else 0.0)

    fit = relaxed_least_squares(
        lambda x: (zmeas - predict(x)).T,
        x0,
        (lo, hi),
        np.std(zmeas, axis=0) + 1e-300,
        passes=passes,
        tol=1e-3,
        floor=1e-300,
        max_nfev=max_nfev,
    )
    x = fit.x
    with np.errstate(invalid="ignore"):
        cov = np.linalg.pinv(fit.J.T @ fit.J)
    se = np.sqrt(np.abs(np.diag(cov)))
    allnames = tuple(names) + tuple(f"bias_{o}" for o in outputs[:nb])
    est_model = model.with_values(dict(zip(names, x[: len(names)])))
    return TimeFitResult(
        names=allnames,
        values=x,
        stderr=se,
        sigma=fit.sigma,
        outputs=outputs,
        nfev=fit.nfev,
        converged=fit.success,
        message=fit.message,
        elapsed=time.perf_counter() - t_start,
        model=est_model,
    )
