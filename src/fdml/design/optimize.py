"""Optimal multisine spectra: power per harmonic for a criterion, then phases for crest factor.

For a multisine whose harmonics are those of the record (2 pi k / T) the
information of the estimator (Eq. 23's ``Re sum A^H R^-1 A``) is, to within
the boundary and bias terms, a sum over harmonics of the power ``p_k`` put
into each times that harmonic's own information ``M_k = Re dG_k^H S^-1 dG_k``
(``dG_k`` the model's output sensitivities at omega_k, ``S`` the noise
covariance).  So the best allocation of a fixed power is a convex design
problem on the simplex, solved by the classic multiplicative iterations:

* ``d-optimal``: maximise ln det M(p) (Titterington's algorithm, p_k <- p_k
  tr(M^-1 M_k) / n);
* ``a-optimal``: minimise the summed variances of a named subset,
  tr(C M^-1 C^T) (p_k <- p_k sqrt(tr(M^-1 C^T C M^-1 M_k)), normalised);
* ``discriminate``: maximise the steady model's smallest weighted misfit to
  the unsteady response, min_theta sum_k p_k ||G_u(omega_k) - G_s(omega_k,
  theta)||^2_S (Atkinson-Fedorov T-optimality: refit theta, move power to
  where the misfit is largest, repeat).

The amplitudes ``sqrt(p_k)`` then get minimum-crest-factor phases
(:func:`fdml.maneuvers.min_crest_phases`) and the peak is scaled to the
amplitude limit; the result is judged by the full prediction, not the
surrogate.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

from .. import maneuvers as mv
from ..errors import FdmlError, ParameterError
from ..models.base import OUTPUTS
from .inputs import DesignInput, Limits, multisine_input

__all__ = ["CRITERIA", "optimal_input", "allocate", "harmonic_information", "model_parameters"]

CRITERIA = ("d-optimal", "a-optimal", "discriminate")
#: Multiplicative iterations of the allocation.
_ITERATIONS = 300
#: Power fractions below this share of the largest are dropped (fewer harmonics, lower crest factor).
_DROP = 1e-3
#: Harmonic groups whose power the full-criterion refinement adjusts.
_GROUPS = 6


def model_parameters(model) -> list[str]:
    """The free model parameters (output biases excluded).

    Parameters
    ----------
    model : fdml.models.Model
        The model.

    Returns
    -------
    list of str
        The names, in the model's order.
    """
    return list(model.parameters.free_model_names)  # by role: nuisance terms are not designed for


def _weights(stds, outputs) -> tuple[np.ndarray, np.ndarray]:
    idx = np.array([OUTPUTS.index(o) for o in outputs])
    sig = np.array([stds[o] for o in outputs])
    return idx, np.diag(1.0 / sig**2)


def harmonic_information(model, omega, names, stds, outputs=OUTPUTS) -> np.ndarray:
    """M_k = Re dG_k^H S^-1 dG_k per harmonic for a unit elevator amplitude, shape (K, p, p).

    Parameters
    ----------
    model : fdml.models.Model
        The model, at its parameter values.
    omega : numpy.ndarray, shape (K,)
        Harmonic frequencies, rad/s.
    names : sequence of str
        The p parameters.
    stds : mapping
        Noise standard deviation per output (alpha rad, q rad/s, az g).
    outputs : sequence of str, optional
        The outputs observed.

    Returns
    -------
    numpy.ndarray
        Shape (K, p, p), real: the information of each harmonic per unit power.
    """
    idx, S_inv = _weights(stds, outputs)
    _, dG, _, _ = model.sensitivity(omega, model.parameters.values, names, ("G",))
    a = np.transpose(dG[:, :, idx, 0], (1, 2, 0))  # (K, n_out, p)
    return np.real(np.conj(np.transpose(a, (0, 2, 1))) @ S_inv @ a)


def _multiplicative(Mk: np.ndarray, sel: list[int] | None) -> np.ndarray:
    """The d-optimal (``sel`` None) or a-optimal (variances of the parameters ``sel``) power fractions."""
    K, p, _ = Mk.shape
    w = np.full(K, 1.0 / K)
    C = np.eye(p)[sel or []]
    for _ in range(_ITERATIONS):
        Minv = np.linalg.inv(np.tensordot(w, Mk, axes=1))
        if sel is None:
            w = w * np.einsum("ij,kji->k", Minv, Mk) / p  # tr(M^-1 M_k)
        else:  # tr(M^-1 C^T C M^-1 M_k)
            w = w * np.sqrt(np.maximum(np.einsum("ij,kji->k", Minv @ C.T @ C @ Minv, Mk), 0.0))
        w /= w.sum()
    return w


def _discriminate(unsteady, steady, omega, stds, outputs) -> np.ndarray:
    """T-optimal power: refit the steady model in the p-weighted metric, move power to the misfit."""
    idx, S_inv = _weights(stds, outputs)
    Gu = unsteady.evaluate(omega, unsteady.parameters.values).G[:, idx, 0]
    names = model_parameters(steady)
    vals = dict(steady.parameters.values)
    K = omega.size
    w = np.full(K, 1.0 / K)
    for _ in range(60):
        for _ in range(5):  # Gauss-Newton on the weighted misfit
            resp, dG, _, _ = steady.sensitivity(omega, vals, names, ("G",))
            r = Gu - resp.G[:, idx, 0]
            a = np.transpose(dG[:, :, idx, 0], (1, 2, 0))
            M = np.real(np.einsum("k,kip,ij,kjq->pq", w, a.conj(), S_inv, a))
            g = np.real(np.einsum("k,kip,ij,kj->p", w, a.conj(), S_inv, r))
            step = np.linalg.lstsq(M, g, rcond=1e-12)[0]
            vals.update({n: vals[n] + s for n, s in zip(names, step)})
        r = Gu - steady.evaluate(omega, vals).G[:, idx, 0]
        d = np.real(np.einsum("ki,ij,kj->k", r.conj(), S_inv, r))
        w = w * d / np.dot(w, d)
        w /= w.sum()
    return w


def allocate(criterion: str, model, omega, stds, *, targets=(), steady=None, outputs=OUTPUTS) -> np.ndarray:
    """Power fractions per harmonic for the criterion (sum 1).

    Parameters
    ----------
    criterion : {"d-optimal", "a-optimal", "discriminate"}
        The design criterion (module docstring).
    model : fdml.models.Model
        The model, at its true values (the unsteady truth for ``discriminate``).
    omega : numpy.ndarray, shape (K,)
        Harmonic frequencies, rad/s.
    stds : mapping
        Noise standard deviation per output (alpha rad, q rad/s, az g).
    targets : sequence of str, optional
        Parameters whose summed variance ``a-optimal`` minimises.
    steady : fdml.models.Model, optional
        The steady model ``discriminate`` tells the truth from.
    outputs : sequence of str, optional
        The outputs observed.

    Returns
    -------
    numpy.ndarray
        Shape (K,): the power fraction of each harmonic.
    """
    names = model_parameters(model)
    if criterion == "d-optimal":
        return _multiplicative(harmonic_information(model, omega, names, stds, outputs), None)
    if criterion == "a-optimal":
        if not targets:
            raise ParameterError("the a-optimal criterion needs target parameters (e.g. --targets b1,y_w,G)")
        sel = [_target_index(model, names, t) for t in targets]
        return _multiplicative(harmonic_information(model, omega, names, stds, outputs), sel)
    if criterion == "discriminate":
        if model.kind != "unsteady" or steady is None:
            raise FdmlError(
                f"the discriminate criterion needs the unsteady model as the truth and a steady model to tell "
                f"it from; the {model.kind} model has no steady counterpart here (use --model unsteady)"
            )
        return _discriminate(model, steady, omega, stds, outputs)
    raise ParameterError(f"unknown criterion {criterion!r}; criteria: {', '.join(CRITERIA)}")


def _target_index(model, names: list[str], target: str) -> int:
    if target in names:
        return names.index(target)
    if target in model.parameters.names:
        raise ParameterError(
            f"target parameter {target} is fixed in the {model.kind} model; free it (--free {target}) to design for it"
        )
    raise ParameterError(f"target parameter {target!r} is not in the {model.kind} model; free: {', '.join(names)}")


#: Mixtures (1 - beta) w_opt + beta flat tried: the surrogate ignores the crest factor, the
#: peak limit and the boundary terms, so the full prediction picks among them.
_MIXTURES = (0.0, 0.25, 0.5, 1.0)


def optimal_input(
    criterion: str,
    model,
    lim: Limits,
    band,
    stds,
    *,
    targets=(),
    steady=None,
    outputs=OUTPUTS,
    score=None,
    refine: int = 40,
) -> DesignInput:
    """The optimised multisine: allocated power per harmonic, minimum-crest phases, peak at the limit.

    ``score(input) -> float`` (larger is better) judges the candidate mixtures of
    the optimal allocation with a flat spectrum by the full prediction, and
    ``refine`` full evaluations then adjust the power of a few harmonic groups
    (:func:`_refine`); without ``score`` the optimal allocation itself is returned.

    Parameters
    ----------
    criterion : {"d-optimal", "a-optimal", "discriminate"}
        The design criterion.
    model : fdml.models.Model
        The model, at its true values.
    lim : Limits
        Amplitude, rate, duration and sample interval.
    band : (lo, hi)
        Band of the harmonics, rad/s.
    stds : mapping
        Noise standard deviation per output (alpha rad, q rad/s, az g).
    targets : sequence of str, optional
        Parameters of the ``a-optimal`` criterion.
    steady : fdml.models.Model, optional
        The steady model of the ``discriminate`` criterion.
    outputs : sequence of str, optional
        The outputs observed.
    score : callable, optional
        ``score(input) -> float``, larger is better.
    refine : int, optional
        Full evaluations of the refinement (0: none).

    Returns
    -------
    DesignInput
        The multisine; its ``options["power"]`` holds the power fractions.
    """
    t = mv.time_vector(lim.duration, lim.dt)
    omega = mv.multisine_frequencies(t, *band)
    w_opt = allocate(criterion, model, omega, stds, targets=targets, steady=steady, outputs=outputs)

    def make(w):
        w = np.where(w < _DROP * w.max(), 0.0, w / w.sum())
        inp = multisine_input(lim, band, np.sqrt(w), phases="min-crest", name=f"{criterion} multisine")
        return DesignInput(inp.name, inp.t, inp.signals, {**inp.options, "power": w.tolist()}, lim)

    if score is None:
        return make(w_opt)
    cands = [(1.0 - beta) * w_opt + beta / w_opt.size for beta in _MIXTURES]
    scores = [score(make(w)) for w in cands]
    w0 = cands[int(np.argmax(scores))]
    return make(_refine(w0, lambda w: score(make(w)), refine)) if refine else make(w0)


def _refine(w0: np.ndarray, score, evaluations: int) -> np.ndarray:
    """Nelder-Mead on log power multipliers of a few harmonic groups, by the full criterion.

    The surrogate leaves out what the full prediction has (boundary terms and
    biases that absorb the lowest harmonics, the crest factor the peak limit
    turns into power); a few dozen full evaluations correct the allocation.
    """
    groups = np.array_split(np.arange(w0.size), min(_GROUPS, w0.size))
    which = np.concatenate([np.full(g.size, i) for i, g in enumerate(groups)])
    seen: dict = {}

    def cost(x):
        key = tuple(np.round(x, 6))
        if key not in seen:
            seen[key] = -score(w0 * np.exp(x)[which])
        return seen[key]

    x0 = np.zeros(len(groups))
    simplex = np.vstack([x0, x0 + 1.5 * np.eye(len(groups))])  # steps of e^1.5 ~ 4.5x in power
    res = optimize.minimize(cost, x0, method="Nelder-Mead", options={"maxfev": evaluations, "initial_simplex": simplex})
    x = res.x if res.fun < cost(x0) else x0
    return w0 * np.exp(x)[which]
