"""Will this input tell the models apart?  Expected likelihood-ratio statistics and detection power.

Steady against unsteady (Wells-Keskar)
    Under the unsteady truth the expected likelihood-ratio statistic is its
    non-centrality ``lambda``: the steady model is fitted (Gauss-Newton on
    Eq. 20 with R held at the noise covariance, Eq. 23) to the noise-free
    unsteady response, and ``lambda`` is the noise-weighted energy of what it
    cannot match, ``2 kappa sum_i d_i^H S^-1 d_i`` over the band, with ``S``
    the frequency-domain covariance of white noise of the given stds (Eq. 19)
    and ``kappa = d omega T / (2 pi)`` converting the fit's grid into
    independent frequencies (Parseval: it equals the time-domain
    ``sum_n d_n^T Sigma^-1 d_n`` of the band-limited discrepancy).

    Degrees of freedom.  The two models are not nested and have equal
    parameter counts, so Wilks's theorem gives no degrees of freedom.  The
    approximation used is the comprehensive model (Cox; Atkinson): the steady
    model extended by one parameter along the discrepancy direction ``d``
    contains both, and testing the steady model inside it is a nested test
    with **one** degree of freedom, whose statistic under the unsteady truth
    is ``(sqrt(lambda) + Z)^2``, a non-central chi-square ``ncx2(1, lambda)``
    (to first order: the two models' tangent spaces, which share every
    parameter's role, absorb the same noise).  The detection probability at
    level ``alpha`` is ``P{ncx2(1, lambda) > chi2_1(1 - alpha)}``.  For a
    Vuong-type comparison of the two fits the same approximation gives
    ``LR ~ N(lambda, 4 lambda)``, so Vuong's ``z ~ N(sqrt(lambda) / 2, 1)``:
    P(the unsteady fit is the better one) = Phi(sqrt(lambda) / 2), and
    P(``fdml compare`` favours the unsteady model) = P(z > z_(1-alpha/2)) =
    Phi(sqrt(lambda) / 2 - z_(1-alpha/2)), its two-sided test at level alpha
    (:func:`fdml.compare.vuong_test`); both are reported.

Effects of the library
    A model with an effect is the base model plus the effect's parameters at
    their null: the models are nested, the test has as many degrees of
    freedom as the effect has parameters, and locally ``lambda = delta^2 /
    var(delta_hat)`` with the predicted variance of :func:`fdml.design.predict`.
    The minimum detectable value (probability ``power`` at level ``alpha``) is
    ``sqrt(lambda_req) * stderr``, ``lambda_req`` solving ``P{ncx2(1,
    lambda_req) > chi2_1(1 - alpha)} = power`` for each parameter alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from ..channels import OUTPUTS
from ..compare import span_of
from ..errors import FdmlError, ParameterError
from ..estimate import Problem, information, prepare
from ..jsoncodec import Codec, integer, number_map
from ..models.effects import with_effects
from .inputs import DesignInput
from .prediction import noise_stds, predict, response

__all__ = ["Discrimination", "discriminate", "detection_probability", "minimum_detectable", "noncentrality"]

#: Gauss-Newton passes of the steady fit to the noise-free unsteady response.
_GN_PASSES = 30


@dataclass(frozen=True)
class Discrimination(Codec):
    """Expected steady-versus-unsteady statistic for one input.

    Parameters
    ----------
    noncentrality : float
        Expected likelihood-ratio statistic lambda under the unsteady truth.
    level : float
        Test level alpha.
    probability : float
        Detection probability, P{ncx2(1, lambda) > chi2_1(1 - alpha)}.
    favoured : float
        P(the unsteady model fits better), Phi(sqrt(lambda) / 2).
    vuong : float
        P(``fdml compare`` favours the unsteady model: Vuong's two-sided test
        at level alpha, z > z_(1-alpha/2)), Phi(sqrt(lambda)/2 - z_(1-alpha/2)).
    steady_values : dict
        The steady model's best match to the unsteady response.
    df : int
        Degrees of freedom of the approximation (1: see the module docstring).
    """

    noncentrality: float
    level: float
    probability: float
    favoured: float
    vuong: float
    steady_values: dict
    df: int = 1

    json_source = "discrimination"
    json_fields = {"steady_values": number_map(), "df": integer(1)}


def detection_probability(lam: float, level: float = 0.05, df: int = 1) -> float:
    """P{ncx2(df, lam) > chi2_df(1 - level)} (scipy.stats.ncx2).

    Parameters
    ----------
    lam : float
        Noncentrality lambda (the expected likelihood-ratio statistic).
    level : float, optional
        Test level alpha.
    df : int, optional
        Degrees of freedom.

    Returns
    -------
    float
        The detection probability.
    """
    _check_level(level)
    crit = stats.chi2.isf(level, df)
    return float(stats.ncx2.sf(crit, df, max(lam, 1e-300)))


def _check_level(level: float) -> None:
    if not (isinstance(level, (int, float)) and 0 < level < 1):
        raise ParameterError(f"test level must be in (0, 1), got {level!r}")


def required_noncentrality(power: float = 0.9, level: float = 0.05, df: int = 1) -> float:
    """The lambda whose detection probability at ``level`` is ``power``.

    Parameters
    ----------
    power : float, optional
        Required detection probability, in (level, 1).
    level : float, optional
        Test level alpha.
    df : int, optional
        Degrees of freedom.

    Returns
    -------
    float
        The noncentrality lambda.
    """
    _check_level(level)
    if not (level < power < 1):
        raise ParameterError(f"power must be in (level, 1) = ({level}, 1), got {power!r}")
    f = lambda lam: detection_probability(lam, level, df) - power  # noqa: E731
    hi = 1.0
    while f(hi) < 0:
        hi *= 2.0
    return float(optimize.brentq(f, 1e-9, hi, xtol=1e-10))


def _band_weights(prob: Problem) -> np.ndarray:
    """kappa_i = d omega_i T / (2 pi) per stacked frequency: grid points -> independent frequencies."""
    return np.concatenate([np.gradient(d.omega) * d.T / (2.0 * math.pi) for d in prob.data])


def noncentrality(prob: Problem, theta: np.ndarray, S_inv: np.ndarray) -> float:
    """2 sum_i kappa_i v_i^H S^-1 v_i of the residuals at theta (S: per-frequency noise covariance).

    Parameters
    ----------
    prob : fdml.estimate.Problem
        The fit problem set up on the noise-free response.
    theta : numpy.ndarray
        Estimate vector of the problem.
    S_inv : numpy.ndarray
        Inverse noise covariance per frequency, shape (n_out, n_out).

    Returns
    -------
    float
        The noncentrality lambda.
    """
    V = prob.residuals(theta)
    q = np.real(np.einsum("ij,jk,ik->i", V.conj(), S_inv, V))
    return float(2.0 * np.sum(_band_weights(prob) * q))


def compare_power(lam: float, level: float, extra: int, prob: Problem) -> float:
    """P(``fdml compare`` favours the unsteady model) under the unsteady truth.

    Vuong's statistic (:func:`fdml.compare.vuong_test`) is the log-likelihood
    difference, mean ``lambda / 2`` and variance ``lambda`` to first order, plus
    Schwarz's correction ``extra / 2 * ln(n_eff)`` for the steady model's
    ``extra`` more free parameters (1 for the six derivatives against the
    unsteady model's five), over its standard deviation; it favours the
    unsteady model when above ``z_(1 - level / 2)``.

    Parameters
    ----------
    lam : float
        The non-centrality (expected likelihood-ratio statistic).
    level : float
        The comparison's two-sided level.
    extra : int
        Free model parameters of the steady model less those of the unsteady one.
    prob : Problem
        The steady model's problem (its frequencies and record lengths give n_eff).

    Returns
    -------
    float
        The probability, between 0 and 1.
    """
    n_eff = sum(d.omega.size / span_of(d.omega, d.T) for d in prob.data)
    root = math.sqrt(max(lam, 1e-300))
    mean = root / 2.0 + 0.5 * extra * math.log(max(n_eff, 1.0)) / root
    return float(stats.norm.cdf(mean - stats.norm.isf(level / 2.0)))


def _best_match(prob: Problem, S_inv: np.ndarray) -> np.ndarray:
    """Gauss-Newton (Eq. 23 with R held at the noise covariance) from the model's values, step halving."""
    theta = prob.initial()
    lam = noncentrality(prob, theta, S_inv)
    for _ in range(_GN_PASSES):
        V = prob.residuals(theta)
        A = prob.sensitivities(theta)
        M = information(A, S_inv)
        g = np.real(np.einsum("nip,ij,nj->p", A.conj(), S_inv, V))
        d = np.sqrt(np.abs(np.diag(M)))
        d[d == 0] = 1.0
        step = np.linalg.lstsq(M / np.outer(d, d), g / d, rcond=1e-12)[0] / d
        for _ in range(30):
            new = noncentrality(prob, theta + step, S_inv)
            if new <= lam:
                break
            step = 0.5 * step
        else:
            break
        done = lam - new <= 1e-10 * max(lam, 1e-300)
        theta, lam = theta + step, new
        if done:
            break
    return theta


def discriminate(
    unsteady,
    steady,
    inp: DesignInput,
    *,
    noise=0.05,
    level: float = 0.05,
    band=None,
    outputs=None,
) -> Discrimination:
    """Expected steady-versus-unsteady likelihood-ratio statistic and detection probability.

    Parameters
    ----------
    unsteady : Model
        The truth (Wells-Keskar unsteady, at its true values).
    steady : Model
        The steady model fitted to it (``steady`` or ``derivatives``).
    inp : DesignInput
        The input history.
    noise : float or mapping, optional
        A fraction of each output's RMS in the unsteady response, or stds.
    level : float, optional
        Test level alpha (default 0.05).
    band : tuple or str, optional
        Fit band ``(lo, hi, step)`` rad/s or ``"LO:HI:STEP"``, as for :func:`fdml.fit`.
    outputs : sequence of str or str, optional
        Outputs that enter the fit (default ``alpha, q, az``).

    Returns
    -------
    Discrimination
        The expected statistic and the probabilities of telling the models apart.
    """
    _check_level(level)
    rec = response(unsteady, inp)
    stds = noise_stds(rec, noise)
    prob = prepare(rec, steady, band=band, outputs=outputs)
    sig = np.array([stds[k] for k in OUTPUTS])[prob.out_idx]
    if np.any(sig <= 0):
        raise ParameterError("the noise of a fitted output is zero: any discrepancy is detected with certainty")
    gains = np.concatenate([d.noise_gain(include_trim=False) for d in prob.data])
    S_inv = np.diag(1.0 / (sig**2 * float(np.mean(gains))))  # Eq. 19's R for white noise of these stds
    theta = _best_match(prob, S_inv)
    lam = noncentrality(prob, theta, S_inv)
    root = math.sqrt(max(lam, 0.0))
    return Discrimination(
        noncentrality=lam,
        level=level,
        probability=detection_probability(lam, level),
        favoured=float(stats.norm.cdf(root / 2.0)),
        vuong=compare_power(
            lam, level, len(steady.parameters.free_model_names) - len(unsteady.parameters.free_model_names), prob
        ),
        steady_values={prob.names[i]: float(theta[i]) for i in prob.model_slots},
    )


@dataclass(frozen=True)
class Detectable(Codec):
    """Smallest value of an effect parameter this input detects.

    Parameters
    ----------
    effect : str
        The library effect.
    parameter : str
        The parameter it adds.
    stderr : float
        Predicted standard error of the parameter at its null, in its unit.
    minimum : float
        The value detected with probability ``power`` at ``level``, in its unit.
    power : float
        Detection probability.
    level : float
        Test level alpha.
    unit : str, optional
        The parameter's unit (``"s"`` for a delay, ``"m"`` for a sensor offset).
    """

    effect: str
    parameter: str
    stderr: float
    minimum: float
    power: float
    level: float
    unit: str = ""

    json_source = "detectable effect"


def minimum_detectable(
    model, effect: str, inp: DesignInput, *, noise=0.05, power: float = 0.9, level: float = 0.05, **kw
) -> list[Detectable]:
    """Minimum detectable value of each parameter of a library effect with this input.

    ``model`` is the base model (at its truth); ``effect`` a library name
    (``"time_delay:alpha"``, ``"actuator_lag"``, ``"sensor_offset@az"``...).
    The effect's parameters sit at their null; each one's predicted standard
    error (with all other parameters estimated) times ``sqrt(lambda_req)``
    is the value detected with probability ``power`` at ``level``.

    Parameters
    ----------
    model : fdml.models.Model
        The base model, at its true values.
    effect : str
        A library effect (``name[:channel]``).
    inp : DesignInput
        The input history.
    noise : float or mapping, optional
        As for :func:`fdml.design.predict.predict`.
    power : float, optional
        Required detection probability.
    level : float, optional
        Test level alpha.
    **kw
        Further options of :func:`fdml.design.predict.predict`.

    Returns
    -------
    list of Detectable
        One per parameter the effect adds, its minimum detectable value in the parameter's unit.
    """
    with_effect = with_effects(model, [effect])
    new = [n for n in with_effect.parameters.free_names if n not in model.parameters.free_names]
    if not new:
        raise FdmlError(f"effect {effect!r} adds no free parameter to the {model.kind} model: nothing to detect")
    se = predict(with_effect, inp, noise=noise, **kw).stderr
    root = math.sqrt(required_noncentrality(power, level, 1))
    units = with_effect.parameters
    return [Detectable(effect, n, se[n], root * se[n], power, level, units[n].unit) for n in new]
