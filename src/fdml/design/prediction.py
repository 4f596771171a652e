"""Predicted covariance of the estimates for a planned input (docs/theory.md Eqs. 20-26).

The prediction is the estimator's own bound, reached through its own code:
the noise-free response to the input is transformed and set up exactly as
:func:`fdml.fit` sets up a record (:func:`fdml.estimate.prepare`: the band,
boundary terms, output biases, trim removal), the sensitivities are the fit's
(analytic or Eq. 26), and the covariance is the fit's ``white`` sandwich
(:func:`fdml.estimate.white_covariance`) with R the residual covariance the
fit would estimate (Eq. 24) for white measurement noise of the given
standard deviations.  A Monte Carlo of the time-domain simulator and
:func:`fdml.fit` confirms it (``benchmarks/design_validation.py``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..channels import OUTPUTS
from ..errors import FdmlError, ParameterError
from ..estimate import Problem, information, prepare, white_covariance
from ..jsoncodec import Fields
from ..record import Record
from ..record import noise_stds as record_noise_stds
from ..simulate import simulate
from .inputs import DesignInput

__all__ = ["Prediction", "predict", "noise_stds", "response"]

#: Settling tolerance of Eq. 26 sensitivities behind the bound (as the fit's final covariance).
_SETTLE_FINAL = 1e-10


@dataclass(frozen=True)
class Prediction:
    """Predicted standard errors of one input.

    Parameters
    ----------
    names : tuple of str
        Estimated quantities, in the fit's order (model parameters, then
        output biases and boundary values).
    values : dict
        Their true values.
    cov : ndarray, shape (p, p)
        Predicted covariance of the estimates (the fit's ``white`` bound).
    noise : dict
        Measurement-noise standard deviations per output (rad, rad/s, g).
    information : ndarray, shape (p, p)
        ``2 Re sum A^H R^-1 A`` (the naive information, Eq. 23's matrix).
    input : DesignInput or None
        The input the prediction is for (None when read back without it: :meth:`from_dict`).
    """

    names: tuple
    values: dict
    cov: np.ndarray = field(repr=False)
    noise: dict
    information: np.ndarray = field(repr=False)
    input: DesignInput | None = field(repr=False)

    @property
    def stderr(self) -> dict[str, float]:
        """Predicted standard error per estimated quantity."""
        return dict(zip(self.names, np.sqrt(np.diag(self.cov)).tolist()))

    def relative(self, name: str) -> float:
        """Predicted standard error of ``name`` over |its value|.

        Parameters
        ----------
        name : str
            An estimated quantity.

        Returns
        -------
        float
            The relative standard error (inf when the true value is 0).
        """
        return self.stderr[name] / abs(self.values[name]) if self.values[name] else math.inf

    def model_cov(self) -> np.ndarray:
        """Predicted covariance of the model parameters (nuisance terms left out).

        Returns
        -------
        numpy.ndarray
            Shape (p_model, p_model), in the order of the model parameters in ``names``.
        """
        idx = [i for i, n in enumerate(self.names) if not _nuisance(n)]
        return self.cov[np.ix_(idx, idx)]

    def cov_of(self, names) -> list[float]:
        """Predicted variances of the named estimates.

        Parameters
        ----------
        names : sequence of str
            Estimated quantities.

        Returns
        -------
        list of float
            Their variances, in the square of each quantity's unit.
        """
        se = self.stderr
        return [se[n] ** 2 for n in names]

    def to_dict(self, model_only: bool = True) -> dict:
        """``{name: {"value": v, "stderr": s}}`` (model parameters only by default).

        Parameters
        ----------
        model_only : bool, optional
            Leave out the output biases and boundary values.

        Returns
        -------
        dict
            True value and predicted standard error per quantity.
        """
        se = self.stderr
        keep = [n for n in self.names if not model_only or not _nuisance(n)]
        return {n: {"value": self.values[n], "stderr": se[n]} for n in keep}

    @classmethod
    def from_dict(cls, d, *, noise=None, input: DesignInput | None = None, source: str = "prediction") -> Prediction:
        """Inverse of :meth:`to_dict`, as far as it goes; a bad key raises a one-line FdmlError naming ``source``.

        :meth:`to_dict` keeps each quantity's value and standard error, so the
        prediction read back has those quantities (the model parameters alone
        when it was written with ``model_only``), a diagonal ``cov`` of the
        squared standard errors (the correlations are not written) and an
        ``information`` of NaN; ``noise`` and ``input`` are what is passed here.
        So :attr:`stderr`, :meth:`relative` and ``to_dict`` of the prediction
        read back are the original's.

        Parameters
        ----------
        d : dict
            As written by :meth:`to_dict`.
        noise : mapping, optional
            Measurement-noise standard deviations per output (rad, rad/s, g); default none.
        input : DesignInput, optional
            The input the prediction is for.
        source : str, optional
            What ``d`` came from, for the message.

        Returns
        -------
        Prediction
            The predicted standard errors.
        """
        f = Fields(d, source)
        names = tuple(f.doc)
        entries = [f.sub(n) for n in names]
        se = np.array([e.number("stderr") for e in entries], float)
        return cls(
            names=names,
            values={n: e.number("value") for n, e in zip(names, entries)},
            cov=np.diag(se**2),
            noise=dict(noise or {}),
            information=np.full((se.size, se.size), np.nan),
            input=input,
        )


def _nuisance(name: str) -> bool:
    return name.startswith(("bias_", "x0_", "xT_"))


def response(model, inp: DesignInput, values: Mapping | None = None) -> Record:
    """The noise-free response of ``model`` to the input (:func:`fdml.simulate.simulate`).

    Parameters
    ----------
    model : fdml.models.Model
        The model (a gust model gets alpha_w = 0 when the input has none).
    inp : DesignInput
        The input history.
    values : mapping, optional
        Parameter values overriding the model's.

    Returns
    -------
    Record
        The simulated record, named after the input.
    """
    signals = dict(inp.signals)
    if model.gust and "alpha_w" not in signals:
        signals["alpha_w"] = np.zeros_like(inp.t)
    if not model.gust:
        signals.pop("alpha_w", None)
    return simulate(model, inp.t, signals, values, name=inp.name)


def noise_stds(rec: Record, noise) -> dict[str, float]:
    """Noise standard deviations per output from a fraction of each output's RMS or a mapping.

    A number is a fraction of each output's RMS about its mean in the
    noise-free record, as :func:`fdml.record.add_noise` with ``relative=True``
    (``fdml simulate --noise``).

    Parameters
    ----------
    rec : Record
        The noise-free response.
    noise : float or mapping
        A fraction of each output's RMS, or ``{"alpha": rad, "q": rad/s, "az": g}``
        (missing outputs get 0).

    Returns
    -------
    dict of str to float
        Standard deviation per output: alpha rad, q rad/s, az g.
    """
    return record_noise_stds(rec, noise, relative=not isinstance(noise, Mapping))


def expected_R(prob: Problem, stds: Mapping[str, float]) -> np.ndarray:
    """The residual covariance (Eq. 24) a fit would estimate for white noise of these stds.

    White noise of per-sample covariance Sigma gives E R = Sigma mean_i ||F_i||^2
    less the fraction the p estimated parameters absorb, (N_real - p) / N_real
    (the inverse of the scaling in :func:`fdml.estimate._white_cov_g`).

    Parameters
    ----------
    prob : fdml.estimate.Problem
        The fit problem on the noise-free response.
    stds : mapping
        Noise standard deviation per output (alpha rad, q rad/s, az g).

    Returns
    -------
    numpy.ndarray
        Diagonal, shape (n_out, n_out), for the fitted outputs: the squared
        units of their transforms.
    """
    sig = np.array([stds[OUTPUTS[k]] for k in prob.out_idx])
    if np.any(sig <= 0):
        zero = [OUTPUTS[k] for k, s in zip(prob.out_idx, sig) if s <= 0]
        raise ParameterError(f"noise of the fitted output(s) {', '.join(zero)} is zero: the bounds would be zero")
    gains = np.concatenate([d.noise_gain(include_trim=False) for d in prob.data])
    n_real = 2 * prob.n_out * sum(d.independent_frequencies() for d in prob.data)
    dof = n_real / max(n_real - len(prob.slots), 1.0)
    return np.diag(sig**2) * float(np.mean(gains)) / dof


def predict(
    model,
    inp: DesignInput,
    *,
    noise=0.05,
    values: Mapping | None = None,
    band=None,
    outputs=None,
    free=None,
    fix=None,
    boundary: str = "estimated",
    biases="auto",
) -> Prediction:
    """Predicted covariance of the estimates of ``model`` from a record flown with ``inp``.

    Parameters
    ----------
    model : fdml.models.Model
        The model fitted, at its true parameter values (``values`` override).
    inp : DesignInput
        The input history (:mod:`fdml.design.inputs`).
    noise : float or mapping, optional
        White measurement noise: a fraction of each output's RMS in the
        noise-free response (default 0.05), or ``{"alpha": rad, "q": rad/s,
        "az": g}``.
    values : mapping, optional
        Parameter values overriding the model's.
    band : tuple or str, optional
        Fit band ``(lo, hi, step)`` rad/s or ``"LO:HI:STEP"``, as for :func:`fdml.fit`.
    outputs : sequence of str or str, optional
        Outputs that enter the fit (default ``alpha, q, az``).
    free, fix : sequence of str, optional
        Names to free and to fix (``fix`` may be a ``{name: value}`` mapping), as for :func:`fdml.fit`.
    boundary : {"estimated", "measured", "none"}, optional
        Boundary terms, as for :func:`fdml.fit`.
    biases : {"auto", True, False}, optional
        Output biases, as for :func:`fdml.fit`.

    Returns
    -------
    Prediction
        The predicted covariance of every estimated quantity.
    """
    if values:
        model.parameters.check_names(values)
        model = model.with_values(values)
    rec = response(model, inp)
    stds = noise_stds(rec, noise)
    prob = prepare(rec, model, band=band, outputs=outputs, free=free, fix=fix, boundary=boundary, biases=biases)
    theta = prob.initial()  # noise-free: the truth, with x(0), x(T) and the biases exact
    A = prob.sensitivities(theta, tol=_SETTLE_FINAL)
    R = expected_R(prob, stds)
    W = np.linalg.inv(R)
    M = information(A, W)
    Minv = _inverse(M, prob.names)
    cov = white_covariance(prob, A, R, Minv, None, W)  # the fit's white bound (Eqs. 23-24 sandwich)
    return Prediction(
        names=prob.names,
        values=dict(zip(prob.names, theta.tolist())),
        cov=cov,
        noise=stds,
        information=2.0 * M,
        input=inp,
    )


def _inverse(M: np.ndarray, names) -> np.ndarray:
    """M^-1, or a one-line error naming what this input cannot identify."""
    d = np.sqrt(np.abs(np.diag(M)))
    dead = [n for n, x in zip(names, d) if x == 0]
    if dead:
        raise FdmlError(f"this input does not excite {', '.join(dead)}: it cannot be identified from it")
    Mn = M / np.outer(d, d)
    w, U = np.linalg.eigh(Mn)
    if w[0] <= 1e-12 * w[-1]:
        top = [names[j] for j in np.argsort(np.abs(U[:, 0]))[::-1][:3]]
        raise FdmlError(f"with this input the combination of {', '.join(top)} cannot be identified")
    return np.linalg.inv(Mn) / np.outer(d, d)
