"""The score-test core shared by every fit's adequacy check and the diagnosis.

One implementation of the statistics both run, importable without the
diagnosis package (:mod:`fdml.adequacy` runs after every fit):

* :func:`screen`, the score (Lagrange-multiplier) screen of a candidate
  effect from the current fit only, with :class:`ScreenContext` (whitened
  residual and base sensitivities) and :class:`ScreenResult`;
* the null distributions of a likelihood-ratio statistic (:func:`p_value`:
  chi2, chi-bar-square, Davies' bound; :func:`null_kind` picks one) and the
  profile variation Davies' bound needs (:func:`grid_variation`);
* the family-wise corrections :func:`holm` and :func:`bh`;
* :func:`whitener` of band covariances.

The screen
----------
At the current estimate theta_hat (null values eta_0 for the candidate), with
the band-whitened, real-stacked residual r and sensitivities J_theta (all
estimated quantities, nuisance terms included) and J_eta (the candidate's
parameters, by central differences):

    LM = 2 r' P r / K,   P = projection on (I - P_theta) J_eta

is the likelihood-ratio statistic of the linearised refit (Rao 1948); it needs
no refit.  From the same matrices:

* aliasing per parameter ``a_j = 1 - [J_eta'(I - P_theta) J_eta]_jj / [J_eta' J_eta]_jj``:
  the share of the effect's signature that the base parameters can mimic;
* the Fisher information in LR units ``I = 2 J_eta'(I - P_theta) J_eta / K``
  and the minimum detectable effect ``MDE_j = sqrt(lambda* [I^-1]_jj)``, the
  size that would be found with 80 % power at the family level (lambda* the
  non-centrality giving that power);
* the linearised estimate ``eta_lin``, used as the refit's start value.

For an effect whose parameter is not identified under the null (a structural
mode's frequency), the statistic is profiled over a grid of that parameter
(:meth:`ScreenContext.grid_sensitivities` gives the candidate sensitivities
at a block of grid values at once; the statistics of a block are one array
operation, and aliasing and the MDE are those of the best grid value).

Aliasing and the MDE describe the design and the noise, not the current
misfit, so they are computed with the gap map's noise floors (per channel and
band, diagonal; model error that is smooth across a band does not enter
them).  The residual covariance R_b of a biased base fit holds model error and
strong cross-channel correlation, and whitening with it made a 1.5 m
accelerometer offset look 99.8 % aliased; the LM statistic itself keeps the
likelihood's own weighting (R_b), which is what the refit's LR uses.

Null distributions
------------------
* interior null: chi2(q);
* one parameter whose null is on a bound (a delay, a lag, a lift-lag
  amplitude from 0): 0.5 chi2_0 + 0.5 chi2_1 (Chernoff 1954; Self and Liang
  1987);
* a parameter not identified under the null (structural-mode frequency):
  Davies' (1987) upper bound for the supremum of a chi2(q) process,
  ``P(chi2_q > u) + V u^((q-1)/2) e^(-u/2) 2^(-q/2) / Gamma(q/2)`` with V the
  total variation of sqrt(LM) along the frequency grid, capped by Bonferroni
  over the grid.

The chi-square and F tails are the closed forms for whole degrees of freedom in
:mod:`fdml.tails` (no scipy.special or scipy.stats import on the fit path, issue 20).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import FdmlError
from .models.base import Model
from .models.effects import Effect
from .tails import chi2_logsf, chi2_sf, noncentrality

__all__ = [
    "ALIAS_LIMIT",
    "LR_EQUAL",
    "equally",
    "ScreenContext",
    "ScreenResult",
    "bh",
    "davies_bound",
    "grid_variation",
    "holm",
    "null_kind",
    "p_value",
    "power_noncentrality",
    "screen",
    "screen_all",
    "whitener",
]

#: Aliasing above which a candidate is "not identifiable" (docs/diagnosis_method.md 2.3).
ALIAS_LIMIT = 0.99


# --- distributions (fdml.tails) -------------------------------------------------------------


@functools.lru_cache(maxsize=256)  # a root search of ncx2.sf: the same (level, df) for every candidate
def power_noncentrality(level: float, df: int = 1, power: float = 0.8) -> float:
    """Non-centrality lambda* of a chi-square(df) test at ``level`` with the given power.

    The root of ``ncx2.sf(chi2.isf(level, df), df, lambda) = power`` (:func:`fdml.tails.noncentrality`),
    cached: every candidate of a screen asks for the same (level, df).
    """
    return noncentrality(level, int(df), power)


def davies_bound(u: float, q: int, V: float) -> float:
    """Davies (1987): P(sup of a chi2(q) process > u) <= P(chi2_q > u) + V u^((q-1)/2) e^(-u/2) 2^(-q/2)/Gamma(q/2).

    Parameters
    ----------
    u : float
        The supremum of the likelihood-ratio statistic over the nuisance grid.
    q : int
        Degrees of freedom (parameters tested).
    V : float
        Total variation of sqrt(LR) along the grid (:func:`grid_variation`).

    Returns
    -------
    float
        The upper bound of the tail probability (may exceed 1); 1 for u <= 0.
    """
    if u <= 0:
        return 1.0
    log_term = (
        math.log(max(V, 1e-300))
        + 0.5 * (q - 1) * math.log(u)
        - 0.5 * u
        - 0.5 * q * math.log(2.0)
        - math.lgamma(0.5 * q)
    )
    return float(chi2_sf(u, q) + math.exp(log_term))


def p_value(lr: float, q: int, null: str, *, V: float = 0.0, n_grid: int = 1) -> tuple[float, float]:
    """(p, log p) of a likelihood-ratio statistic under the named null distribution (module doc).

    Parameters
    ----------
    lr : float
        The likelihood-ratio statistic (negative values count as 0).
    q : int
        Degrees of freedom (parameters tested).
    null : {"chi2", "chibar", "davies"}
        The null distribution (:func:`null_kind`).
    V : float, optional
        Total variation of sqrt(LR) along the nuisance grid, for ``"davies"``.
    n_grid : int, optional
        Number of grid values, for the Bonferroni bound of ``"davies"``.

    Returns
    -------
    p : float
        The p-value.
    log_p : float
        Its natural logarithm (finite where p underflows).
    """
    lr = max(float(lr), 0.0)
    if null == "chibar":
        lp = math.log(0.5) + chi2_logsf(lr, 1) if lr > 0 else 0.0
    elif null == "davies":
        lp_chi = chi2_logsf(lr, q)
        bonf = math.log(max(n_grid, 1)) + lp_chi
        dv = davies_bound(lr, q, V)
        lp = min(bonf, math.log(dv) if dv > 0 else lp_chi + math.log(max(V, 1.0) + 1.0), 0.0)
    else:
        lp = chi2_logsf(lr, q)
    return math.exp(lp), lp


#: Two hypotheses explain the data equally when their likelihood ratios differ by less than this:
#: (2 x 1.96)^2, the difference within 1.96 of its own sampling standard deviation (see :func:`equally`).
LR_EQUAL = (2 * 1.959964) ** 2


def equally(lr_best: float, lr_other: float) -> bool:
    """Whether two hypotheses explain the data equally: their LRs differ by less than :data:`LR_EQUAL`.

    Against a common null, the two likelihood ratios differ by ``dLR = 2 sum |d_i|^2 / v_i`` plus the
    noise's share ``4 sum Re(n_i^* d_i) / v_i`` (``d_i`` the difference of the two fits' predictions at
    frequency i, ``v_i`` the noise variance, a grid K times finer than 2 pi/T counted 1/K).  That share
    has standard deviation ``2 sqrt(dLR)`` whatever the grid, so the better one is told apart at the
    two-sided 5 % level only when ``dLR > 2 x 1.96 sqrt(dLR)``, i.e. ``dLR > (2 x 1.96)^2 = 15.4``.  The
    rule is a function of the two LRs alone, so a fit's adequacy check and the diagnosis apply it alike.
    With parameter counts that differ, pass Akaike-penalised values (``LR - 2 q``).

    Parameters
    ----------
    lr_best, lr_other : float
        Likelihood ratios of the two against a common null.

    Returns
    -------
    bool
        True when the data cannot tell them apart.
    """
    return lr_best - lr_other < LR_EQUAL


def null_kind(effect: Effect, model, screen_res: ScreenResult | None = None) -> tuple[str, int]:
    """(null distribution name, q) of ``effect`` on ``model``: ``davies``, ``chibar`` or ``chi2``.

    The bounds of a single parameter come from the augmented model (the
    screen's, ``screen_res.model``, when given).

    Parameters
    ----------
    effect : Effect
        The candidate effect.
    model : Model
        The model it augments.
    screen_res : ScreenResult, optional
        The effect's screen, whose augmented model gives the bounds.

    Returns
    -------
    null : str
        ``"davies"`` (nuisance grid), ``"chibar"`` (one parameter whose null is at a bound) or ``"chi2"``.
    q : int
        Degrees of freedom (parameters tested).
    """
    plist = [p for p in effect.param_list(model) if not p.nuisance]
    q = len(plist)
    if effect.nuisance_grid:
        return "davies", q
    if q == 1:
        p = plist[0]
        null = effect.nulls(model)[p.name]
        aug = screen_res.model if screen_res is not None and screen_res.model is not None else effect.augment(model)
        bounds = aug.parameters[p.name]  # every caller has augmented the model already
        if null <= bounds.lower or null >= bounds.upper:
            return "chibar", 1
    return "chi2", q


def grid_variation(scr: ScreenResult | None) -> tuple[float, int]:
    """(total variation of sqrt(LM) along the nuisance grid, grid size) for Davies' bound; (0, 1) without a grid.

    Parameters
    ----------
    scr : ScreenResult or None
        The screen of a nuisance-grid effect.

    Returns
    -------
    V : float
        Total variation of sqrt(LM) along the grid.
    n_grid : int
        Number of grid values.
    """
    if scr is None or not scr.grid:
        return 0.0, 1
    ((_, (grid, prof)),) = scr.grid.items()
    r = np.sqrt(np.maximum(prof, 0.0))
    return float(np.sum(np.abs(np.diff(r)))), int(grid.size)


# --- family-wise corrections ---------------------------------------------------------------------


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values (NaN stays NaN).

    Parameters
    ----------
    p : numpy.ndarray
        The p-values.

    Returns
    -------
    numpy.ndarray
        Adjusted p-values, same shape.
    """
    return _adjusted(p, lambda ps, m: np.maximum.accumulate(np.minimum(1.0, ps * (m - np.arange(m)))))


def bh(p: np.ndarray) -> np.ndarray:
    """Benjamini-Hochberg q-values (NaN stays NaN).

    Parameters
    ----------
    p : numpy.ndarray
        The p-values.

    Returns
    -------
    numpy.ndarray
        The q-values, same shape.
    """
    return _adjusted(p, lambda ps, m: np.minimum.accumulate(np.minimum(1.0, ps * m / np.arange(1, m + 1))[::-1])[::-1])


def _adjusted(p: np.ndarray, adjust) -> np.ndarray:
    """``adjust(sorted finite p-values, their count)`` put back in the order of ``p``; NaN stays NaN."""
    p = np.asarray(p, float)
    out = np.full_like(p, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    if ok.size:
        order = ok[np.argsort(p[ok])]
        out[order] = adjust(p[order], order.size)
    return out


def whitener(Rs) -> list[np.ndarray]:
    """Per band, ``L`` with ``v^H R^-1 v = ||L v||^2`` (L = C^H, C C^H = R^-1).

    Parameters
    ----------
    Rs : sequence of numpy.ndarray
        Residual covariance of each band, complex (n_out, n_out).

    Returns
    -------
    list of numpy.ndarray
        The whitening matrix L of each band, (n_out, n_out).
    """
    return [np.linalg.cholesky(0.5 * (W + W.conj().T)).conj().T for W in map(np.linalg.inv, Rs)]


# --- the screen ----------------------------------------------------------------------------------


@dataclass
class ScreenResult:
    """What the screen says about one candidate.

    ``model`` is the augmented model at the null values (for the bounds of
    its parameters); ``jacobian`` the (likelihood-whitened, floor-whitened)
    candidate sensitivities the statistic used (at the best grid value of a
    nuisance-grid effect).

    Parameters
    ----------
    key : str
        The effect's key.
    lm : float
        The score (LM) statistic, in likelihood-ratio units.
    eta_lin : dict
        Parameter name -> linearised estimate (null value plus one Gauss-Newton step), in its unit.
    aliasing : dict
        Parameter name -> share (0 to 1) of its signature the base parameters can mimic.
    mde : dict
        Parameter name -> minimum detectable effect (80 % power at the level divided by
        ``ctx.family_size``), in its unit.
    identifiable : bool
        Whether the data can test the candidate.
    reason : str or None, optional
        Why not, when not identifiable.
    grid : dict or None, optional
        Nuisance name -> (grid, LM profile) for a nuisance-grid effect.
    nuisance : dict, optional
        Nuisance name -> the grid value with the largest LM.
    model : Model or None, optional
        The augmented model at the null values.
    jacobian : tuple or None, optional
        (likelihood-whitened, floor-whitened) candidate sensitivities, each (M, q).
    """

    key: str
    lm: float
    eta_lin: dict
    aliasing: dict
    mde: dict
    identifiable: bool
    reason: str | None = None
    grid: dict | None = None  # {"omega_s": (grid, lm_profile)} for nuisance-grid effects
    nuisance: dict = field(default_factory=dict)  # best grid values
    model: Model | None = field(default=None, repr=False, compare=False)
    jacobian: tuple | None = field(default=None, repr=False, compare=False)


class ScreenContext:
    """Whitened residual and base sensitivities of the current fit (computed once per step).

    Parameters
    ----------
    fit : object
        The current fit: ``model``, ``theta``, ``params`` (by name), ``V``
        (residuals, (N, n_out)), ``Rs`` (band covariances), ``prob``
        (:class:`fdml.estimate.Problem`); e.g. a diagnosis
        :class:`~fdml.diagnose.likelihood.DiagFit`.
    rows : ndarray of int
        Band of each residual row.
    oversample : float
        K: grid points per independent frequency (LM = 2 r'Pr / K).
    spectra : sequence
        The fit's spectra (:func:`fdml.estimate.prepare` input).
    fit_options : dict
        ``prepare`` options of the candidate models.
    floor_weights : ndarray, shape (N, n_out), optional
        Diagonal noise-floor whitening for aliasing and the MDE.
    sensitivities : ndarray, shape (N, n_out, p), optional
        ``fit.prob.sensitivities(fit.theta)`` when the caller has it.
    prepare : callable, optional
        :func:`fdml.estimate.prepare`, which sets up a candidate's problem; given by the caller
        (this module sits below the estimator). Needed by :meth:`candidate_sensitivities` only.
    """

    #: Size of the screened family (the MDE's power is at level / family_size); callers set it per step.
    family_size: int = 1

    def __init__(
        self,
        fit,
        rows: np.ndarray,
        oversample: float,
        spectra,
        fit_options: dict,
        floor_weights: np.ndarray | None = None,
        sensitivities: np.ndarray | None = None,
        prepare=None,
    ):
        self.fit = fit
        self._prepare = prepare
        self.K = oversample
        self.spectra = list(spectra)
        self.options = fit_options
        self.L = np.stack(whitener(fit.Rs))[rows]  # (N, n, n)
        A = fit.prob.sensitivities(fit.theta) if sensitivities is None else sensitivities
        self.r = self.white(fit.V[:, :, None])[:, 0]
        self.Q = self._basis(self.white(A))
        # noise-floor metric (diagonal) for aliasing and MDE
        self.fw = np.ones(fit.V.shape) if floor_weights is None else np.asarray(floor_weights, float)
        self.Qf = self._basis(self.floor(A))

    @staticmethod
    def _basis(J):
        """Orthonormal basis of the columns of J (numerically dead directions dropped)."""
        U, s, _ = np.linalg.svd(J, full_matrices=False)
        keep = s > 1e-10 * (s[0] if s.size else 1.0)
        return U[:, keep]

    @staticmethod
    def _real_cols(A):
        N, n, p = A.shape
        M = A.reshape(N * n, p)
        return np.vstack([M.real, M.imag])

    def perp(self, X):
        """The part of ``X`` orthogonal to the base model's sensitivities (whitened).

        Parameters
        ----------
        X : numpy.ndarray
            Whitened, real-stacked columns, shape (M,) or (M, q).

        Returns
        -------
        numpy.ndarray
            ``X`` with the base sensitivities projected out, same shape.
        """
        return X - self.Q @ (self.Q.T @ X)

    def perp_floor(self, X):
        """The part of ``X`` orthogonal to the base sensitivities weighted by the noise floors.

        Parameters
        ----------
        X : numpy.ndarray
            Floor-whitened, real-stacked columns, shape (M,) or (M, q).

        Returns
        -------
        numpy.ndarray
            ``X`` with the base sensitivities projected out, same shape.
        """
        return X - self.Qf @ (self.Qf.T @ X)

    @functools.cached_property
    def r_perp(self) -> np.ndarray:
        """The whitened residual with the base sensitivities projected out (computed once)."""
        return self.perp(self.r)

    def white(self, A: np.ndarray) -> np.ndarray:
        """Likelihood-whitened, real-stacked columns of dy/d eta, A of shape (N, n_out, q): (M, q).

        Parameters
        ----------
        A : numpy.ndarray
            Sensitivities d(prediction)/d(eta), shape (N, n_out, q).

        Returns
        -------
        numpy.ndarray
            The columns, shape (M, q) with M = 2 N n_out.
        """
        return self._real_cols(self.L @ A)

    def floor(self, A: np.ndarray) -> np.ndarray:
        """Floor-whitened, real-stacked columns of dy/d eta (for aliasing and the MDE): (M, q).

        Parameters
        ----------
        A : numpy.ndarray
            Sensitivities d(prediction)/d(eta), shape (N, n_out, q).

        Returns
        -------
        numpy.ndarray
            The columns, shape (M, q) with M = 2 N n_out.
        """
        return self._real_cols(A * self.fw[:, :, None])  # row n, output j divided by its floor

    def candidate_sensitivities(self, model, names, steps, one_sided) -> np.ndarray:
        """Sensitivities d(prediction)/d(eta) at the model's values, by central (or forward) differences.

        Shape (N, n_out, q).

        Parameters
        ----------
        model : Model
            The augmented model at the candidate's null values.
        names : list of str
            The candidate parameters eta.
        steps : sequence of float
            Difference step of each parameter, in its unit.
        one_sided : sequence of bool
            Forward differences for each parameter whose null is at a bound.

        Returns
        -------
        numpy.ndarray
            The sensitivities, complex, shape (N, n_out, q).
        """
        if self._prepare is None:
            raise FdmlError("the screen was built without fdml.estimate.prepare: it cannot set up a candidate")
        prob = self._prepare(self.spectra, model, sensitivity="central", **self.options)
        theta = np.array([self.fit.params.get(n, model.parameters.values.get(n, 0.0)) for n in prob.names])
        cols = []
        for n, h, os_ in zip(names, steps, one_sided):
            i, tp, tm = prob.names.index(n), theta.copy(), theta.copy()
            tp[i] += h
            if not os_:  # a central difference; forward from a null on a bound
                tm[i] -= h
            cols.append((_stack(prob, tp) - _stack(prob, tm)) / (h if os_ else 2 * h))
        return np.stack(cols, axis=-1)

    def candidate_sensitivities_many(self, cands) -> list:
        """Compute :meth:`candidate_sensitivities` of each ``(model, names, steps, one_sided)``.

        An exception stands in place of a candidate that cannot be evaluated.  A subclass may
        take them together.

        Parameters
        ----------
        cands : sequence of tuple
            ``(model, names, steps, one_sided)`` of each candidate.

        Returns
        -------
        list
            Per candidate, its sensitivities (N, n_out, q) or the exception raised.
        """
        return [attempt(self.candidate_sensitivities, *args) for args in cands]

    def grid_sensitivities(self, model, names, steps, one_sided, gname: str, grid: np.ndarray) -> np.ndarray:
        """:meth:`candidate_sensitivities` at every value of the nuisance parameter ``gname`` on ``grid``.

        Returns shape (N, n_out, len(grid), q).  This one evaluates the grid
        values one by one; a subclass may evaluate them at once.

        Parameters
        ----------
        model : Model
            The augmented model at the candidate's null values.
        names : list of str
            The candidate parameters eta.
        steps : sequence of float
            Difference step of each parameter, in its unit.
        one_sided : sequence of bool
            Forward differences for each parameter whose null is at a bound.
        gname : str
            The nuisance parameter.
        grid : numpy.ndarray
            Its values, in its unit.

        Returns
        -------
        numpy.ndarray
            The sensitivities, complex, shape (N, n_out, len(grid), q).
        """
        return np.stack(
            [self.candidate_sensitivities(model.with_values({gname: float(w)}), names, steps, one_sided) for w in grid],
            axis=2,
        )


def _stack(prob, theta):
    return np.concatenate([y[:, prob.out_idx] for y in prob.predict(theta)])


def _score(ctx: ScreenContext, Je: np.ndarray) -> tuple:
    """LM statistic and linearised estimate (likelihood metric) of g candidates at once.

    ``Je`` of shape (M, g, q): g candidates (grid values) of q parameters
    each, projected at once.  Returns LM (g,) and eta (g, q).
    """
    M, g, q = Je.shape
    Jp = ctx.perp(Je.reshape(M, g * q))
    b = (ctx.r_perp @ Jp).reshape(g, q)
    Jp = Jp.reshape(M, g, q).transpose(1, 0, 2)  # (g, M, q)
    G = Jp.transpose(0, 2, 1) @ Jp
    try:
        eta = np.linalg.solve(G, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        eta = np.stack([_solve_or_lstsq(G[k], b[k]) for k in range(g)])
    lm = 2.0 * np.einsum("gi,gi->g", b, eta) / ctx.K
    return np.maximum(lm, 0.0), eta


def _floor_stats(ctx: ScreenContext, Jf: np.ndarray) -> tuple:
    """Information (g, q, q) and aliasing (g, q) in the floor metric of ``Jf`` (M, g, q)."""
    M, g, q = Jf.shape
    Jfp = ctx.perp_floor(Jf.reshape(M, g * q)).reshape(M, g, q).transpose(1, 0, 2)
    Gf = Jfp.transpose(0, 2, 1) @ Jfp
    full = np.einsum("mgi,mgi->gi", Jf, Jf)
    alias = 1.0 - np.diagonal(Gf, axis1=1, axis2=2) / np.where(full > 0, full, np.inf)
    return 2.0 * Gf / ctx.K, np.clip(alias, 0.0, 1.0)


def _solve_or_lstsq(G, b):
    try:
        return np.linalg.solve(G, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(G, b, rcond=1e-12)[0]


#: Candidate sensitivities per block of a nuisance grid, complex values (grid values x parameters x rows x
#: outputs, about 100 KB).  Larger temporaries are mapped fresh by the allocator on every call and cost a
#: page fault per 4 KB (725 faults, 1.5 ms per structural-mode screen of a 12 s record, measured); blocks
#: of this size reuse the heap.
BLOCK_VALUES = 6000


def _blocks(n: int, per_value: int) -> list:
    """Slices of ``range(n)`` with about :data:`BLOCK_VALUES` / ``per_value`` grid values each."""
    k = max(1, BLOCK_VALUES // max(per_value, 1))
    return [slice(i, min(i + k, n)) for i in range(0, n, k)]


def _steps(test, nulls, aug) -> tuple[list, list]:
    """Finite-difference steps (typical sizes) and one-sidedness (null on the lower bound) per tested parameter."""
    one_sided = [bool(nulls[p.name] <= p.lower or aug.parameters[p.name].lower >= nulls[p.name]) for p in test]
    return [p.typical() for p in test], one_sided


@dataclass(frozen=True)
class _Candidate:
    """A candidate set up for the screen: the augmented model at the null and the tested parameters."""

    effect: Effect
    aug: Model
    test: tuple
    nulls: dict
    steps: tuple
    one_sided: tuple

    @property
    def names(self) -> list:
        return [p.name for p in self.test]

    @property
    def args(self) -> tuple:
        """(model, names, steps, one_sided) of :meth:`ScreenContext.candidate_sensitivities`."""
        return self.aug, self.names, list(self.steps), list(self.one_sided)


def _candidate(ctx: ScreenContext, effect: Effect) -> _Candidate:
    cur = ctx.fit.model
    nulls = effect.nulls(cur)
    aug = effect.augment(cur)
    vals = aug.parameters.values
    if any(vals[k] != v for k, v in nulls.items()):  # augment leaves most effects at their nulls already
        aug = aug.with_values(nulls)
    test = tuple(p for p in effect.param_list(cur) if not p.nuisance)
    steps, one_sided = _steps(test, nulls, aug)
    return _Candidate(effect, aug, test, nulls, tuple(steps), tuple(one_sided))


def screen(ctx: ScreenContext, effect: Effect, *, level: float, band: tuple) -> ScreenResult:
    """Screen one candidate effect at the current fit (:func:`screen_all` of one).

    Parameters
    ----------
    ctx : ScreenContext
        The current fit's whitened residual and sensitivities.
    effect : Effect
        The candidate.
    level : float
        Test level (the MDE has 80 % power at level / ``ctx.family_size``).
    band : tuple of float
        The fit's band, ``(lo, hi, ...)`` rad/s (the nuisance grid spans lo to hi).

    Returns
    -------
    ScreenResult
        The screen of the candidate.
    """
    (res,) = screen_all(ctx, [effect], level=level, band=band)
    if isinstance(res, Exception):
        raise res
    return res


def screen_all(ctx: ScreenContext, effects, *, level: float, band: tuple) -> list:
    """:func:`screen` of every effect, in order; an effect that cannot be evaluated has its exception instead.

    The candidates without a nuisance grid are taken together: their
    sensitivities from :meth:`ScreenContext.candidate_sensitivities_many`,
    their statistics as one array operation per number of parameters.

    Parameters
    ----------
    ctx : ScreenContext
        The current fit's whitened residual and sensitivities.
    effects : sequence of Effect
        The candidates.
    level : float
        Test level (the MDE has 80 % power at level / ``ctx.family_size``).
    band : tuple of float
        The fit's band, ``(lo, hi, ...)`` rad/s (the nuisance grid spans lo to hi).

    Returns
    -------
    list
        Per effect, its :class:`ScreenResult` or the exception raised.
    """
    out: list = [attempt(_candidate, ctx, eff) for eff in effects]  # each candidate set up, or why not
    cands = {i: c for i, c in enumerate(out) if isinstance(c, _Candidate)}
    plain = [i for i, c in cands.items() if not c.effect.nuisance_grid]
    sens = dict(zip(plain, ctx.candidate_sensitivities_many([cands[i].args for i in plain])))
    stats: dict[int, tuple | Exception] = {i: A for i, A in sens.items() if isinstance(A, Exception)}
    good = [(i, A) for i, A in sens.items() if not isinstance(A, Exception)]
    for q in sorted({A.shape[-1] for _, A in good}):
        group = [(i, A) for i, A in good if A.shape[-1] == q]
        stacked = np.concatenate([A for _, A in group], axis=-1)
        Je, Jf = ctx.white(stacked).reshape(-1, len(group), q), ctx.floor(stacked).reshape(-1, len(group), q)
        lms, etas = _score(ctx, Je)
        infos, aliases = _floor_stats(ctx, Jf)
        for j, (i, _) in enumerate(group):
            stats[i] = (lms[j], etas[j], infos[j], aliases[j], (Je[:, j, :], Jf[:, j, :]), None, {})
    stats.update({i: attempt(_grid_stats, ctx, c, band) for i, c in cands.items() if c.effect.nuisance_grid})
    for i, st in stats.items():
        out[i] = st if isinstance(st, Exception) else attempt(_result, ctx, cands[i], st, level)
    return out


def attempt(f, *args):
    """``f(*args)``, or the exception it raised: a candidate that cannot be set up or evaluated is reported,
    never fatal."""
    try:
        return f(*args)
    except Exception as exc:  # noqa: BLE001 - reported in its place
        return exc


def _grid_stats(ctx: ScreenContext, c: _Candidate, band: tuple) -> tuple:
    """Statistics at the grid value of the nuisance parameter with the largest LM (blocks of the grid at once)."""
    assert c.effect.nuisance_grid is not None  # called for nuisance-grid effects only
    ((gname, gfun),) = c.effect.nuisance_grid.items()
    grid = np.asarray(gfun(max(band[0], band[1] / 5.0), band[1]))
    prof: list[np.ndarray] = []
    best: tuple | None = None
    model, names, steps, one_sided = c.args
    for blk in _blocks(grid.size, len(names) * ctx.fit.V.size):
        A = ctx.grid_sensitivities(model, names, steps, one_sided, gname, grid[blk])  # (N, n_out, g, q)
        N, n, g, q = A.shape
        Je = ctx.white(A.reshape(N, n, g * q)).reshape(-1, g, q)
        lms, etas = _score(ctx, Je)
        for j in range(g):  # the first grid value with the largest LM
            if best is None or lms[j] > best[0]:
                best = (lms[j], etas[j], blk.start + j, Je[:, j, :], A[:, :, j, :])
        prof.append(lms)
    assert best is not None  # the grid is not empty
    lm, eta, k, Je, A = best
    Jf = ctx.floor(A)  # the floor metric only matters at the chosen grid value
    infos, aliases = _floor_stats(ctx, Jf[:, None, :])
    return lm, eta, infos[0], aliases[0], (Je, Jf), {gname: (grid, np.concatenate(prof))}, {gname: float(grid[k])}


def _result(ctx: ScreenContext, c: _Candidate, stats: tuple, level: float) -> ScreenResult:
    """The screen's verdict on one candidate from its statistics (LM, eta, information, aliasing, ...)."""
    lm, eta, info, alias, jac, grid_out, best_nuis = stats
    names = c.names
    q = len(names)
    # one-sided nulls: a linearised step into the infeasible side means no evidence
    lm = 0.0 if q == 1 and c.one_sided[0] and eta[0] < 0 else float(lm)
    n_family = max(int(getattr(ctx, "family_size", 1)), 1)
    lam = power_noncentrality(level / n_family, q)
    try:
        Iinv = np.linalg.inv(info)
        mde = {n: float(math.sqrt(max(lam * Iinv[j, j], 0.0))) for j, n in enumerate(names)}
    except np.linalg.LinAlgError:
        mde = {n: math.inf for n in names}
    aliasing = {n: float(alias[j]) for j, n in enumerate(names)}
    reason = _unidentifiable(aliasing, mde, c.test, c.nulls, grid_out is not None)
    eta_lin = {n: float(c.nulls[n] + eta[j]) for j, n in enumerate(names)}
    return ScreenResult(
        c.effect.key, lm, eta_lin, aliasing, mde, reason is None, reason, grid_out, best_nuis, model=c.aug, jacobian=jac
    )


def _unidentifiable(aliasing: dict, mde: dict, test, nulls: dict, grid: bool) -> str | None:
    """Why these data cannot test the candidate (aliased, or an MDE beyond the plausible range), else None."""
    n_ = max(aliasing, key=aliasing.__getitem__, default=None)
    if n_ is not None and aliasing[n_] > ALIAS_LIMIT:
        return (
            f"aliased: {100 * aliasing[n_]:.1f} % of the {n_} signature is absorbed by the base parameters "
            "with these inputs"
        )
    if grid:
        return None
    for p in test:
        if p.plausible is not None and math.isfinite(mde[p.name]):
            span = max(abs(p.plausible[0] - nulls[p.name]), abs(p.plausible[1] - nulls[p.name]))
            if mde[p.name] > span:
                return (
                    f"too little information: the smallest detectable {p.name} is {mde[p.name]:.3g} "
                    f"{p.unit}, beyond its plausible range {p.plausible}"
                )
    return None
