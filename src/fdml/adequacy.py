"""Every fit checks its own adequacy: score tests of the effect library and residual checks.

After a fit, from the base fit alone (no refits):

* every applicable deterministic effect of the library
  (:mod:`fdml.models.effect_library`) is screened with the diagnosis's score
  (Lagrange-multiplier) screen, :func:`fdml.score.screen`, on the
  fit's own grid and white-noise likelihood (one residual covariance R,
  docs/theory.md Eq. 24).  The screen's linearised estimate eta_lin is one
  Gauss-Newton step from the base fit along the effect and the base
  parameters together; the statistic tested is the likelihood ratio at that
  one-step estimate,

      LR_1 = 2 N_ind (ln det R_0 - ln det R_1),

  with R_1 the residual covariance after the step and N_ind the independent
  frequencies (a grid finer than 2 pi/T counts each one K = 2 pi/(T dw) times,
  see :mod:`fdml.diagnose.data`).  Under the null LR_1 and the score statistic
  agree to first order (both chi2); under the alternative the score statistic,
  which weights the residual with R_0 (inflated by the very misfit it tests),
  is far weaker: on the Twin Otter 018 record the alpha delay has LM 7.0,
  LR_1 14.8 and a refitted LR of 29.6 (``fdml diagnose``).  Both are kept;
* the null distribution is the diagnosis's (chi2, chi-bar-square for a
  parameter whose null is on a bound, Davies' bound for a parameter not
  identified under the null: :func:`fdml.score.p_value`);
* two residual checks on the independent frequencies (grid spacing >= 2 pi/T):
  *coherence*, the squared multiple coherence of each output's residual with
  the inputs in each band (F test, ``F = (n - q)/q c/(1 - c) ~ F(2q, 2(n - q))``
  for complex Gaussian residuals independent of the inputs), and *whiteness*,
  Bartlett's test that each output's residual power (divided by the transform's
  noise gain) is the same in every band (``|v|^2`` is sigma^2 chi2_2 / 2, so
  each band's mean power is a variance estimate on 2 n_b degrees of freedom).
  Each is Bonferroni-combined over its cells (valid under any dependence);
* Holm's step-down correction (:func:`fdml.score.holm`) over the
  whole family (the identifiable effects and the two residual checks); a test
  whose Holm p-value is below ``alpha`` (default :data:`ALPHA`) is flagged.

The false-alarm rate over simulated records (time-domain simulator) is
measured by ``benchmarks/adequacy_false_alarms.py``; the cost relative to the
fit by ``benchmarks/bench_adequacy.py``.  The candidate sensitivities are
array operations on the fit's own problem (:class:`_Context`), and nothing
here imports the diagnosis package (:mod:`fdml.score` holds the statistics
both use).
"""

from __future__ import annotations

import functools
import math
import shlex
import time
import warnings
import weakref
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .errors import AdequacyWarning, FdmlError
from .jsoncodec import Codec, Spec, integer, mapping, nested, nested_list, number_map, text, texts
from .kinematics import input_resolution, kinematic_evidence, known_terms
from .models.base import OUTPUTS, ModelResponse, model_airspeed
from .models.effects import (
    AugmentedModel,
    OutputEffect,
    applied_effects,
    get_effect,
    registered_effects,
    root_model,
    with_effects,
)
from .score import ScreenContext, attempt, grid_variation, holm, null_kind, p_value, screen_all
from .tails import chi2_sf, f_sf
from .verdict import LEVEL, choose_among, judge

__all__ = [
    "ALPHA",
    "Adequacy",
    "EffectTest",
    "ResidualCheck",
    "Verdict",
    "advice",
    "check",
    "rank",
    "reworded",
]

#: Family-wise level of the adequacy check (every fit runs it: 1 in 100 adequate fits warns); the
#: diagnosis's too (:data:`fdml.verdict.LEVEL`).
ALPHA = LEVEL
#: Bands of the residual checks: at most this many, each with at least MIN_BAND independent frequencies.
MAX_BANDS = 4
MIN_BAND = 6

#: What a refit or a check that cannot run raises: reported, never fatal.
_FAILURES = (FdmlError, np.linalg.LinAlgError, ValueError, ArithmeticError)

#: Output effects whose function evaluates a nuisance grid at once (checked once each, see _Context._agrees).
_VECTORISES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class EffectTest(Codec):
    """The score screen of one library effect at the base fit.

    Parameters
    ----------
    key, effect, channel : str
        ``time_delay@alpha``, ``time_delay``, ``alpha``.
    statistic : float
        Likelihood ratio at the one-step estimate (LR_1, see module doc).
    lm : float
        The score (LM) statistic of the diagnosis's screen.
    df : int
        Degrees of freedom: the number of tested parameters.
    null : str
        ``chi2``, ``chibar`` or ``davies``.
    p_value, p_holm : float
        Unadjusted and Holm-adjusted (whole family) p-values.
    expected : dict
        One-step estimate of every tested parameter, ``{name: value}`` (its unit in ``units``).
    units : dict
        Unit of every tested parameter, ``{name: unit}`` (``""`` when dimensionless).
    """

    key: str
    effect: str
    channel: str
    statistic: float
    lm: float
    df: int
    null: str
    p_value: float
    p_holm: float
    expected: dict
    units: dict

    json_fields = {
        "df": integer(0),
        "null": text(("chi2", "chibar", "davies")),
        "expected": number_map(),
        "units": Spec(lambda f, k, done: {n: str(v) for n, v in f.mapping(k, default={}).items()}),
    }
    json_source = "effect test"

    @property
    def option(self) -> str:
        """The ``--effect`` value that adds it: ``time_delay:alpha``."""
        return f"{self.effect}:{self.channel}"

    def describe(self) -> str:
        """One line: the effect, its expected parameter values, LR, p and Holm-corrected p.

        Returns
        -------
        str
            The line.
        """
        vals = ", ".join(f"{k} = {_fmt(v, self.units.get(k, ''))}" for k, v in self.expected.items())
        return f"{self.key} ({vals}; LR {self.statistic:.3g}, p {self.p_value:.2g}, Holm p {self.p_holm:.2g})"


@dataclass(frozen=True)
class ResidualCheck(Codec):
    """A residual check (``coherence`` or ``whiteness``), Bonferroni over its cells.

    ``worst`` names the cell with the smallest p-value (``record/channel band lo-hi rad/s``);
    ``cells`` is the number of cells (0: not testable, p = 1).

    Parameters
    ----------
    name : {"coherence", "whiteness"}
        Which check.
    statistic : float
        Statistic of the worst cell: the multiple coherence of the residual
        with the inputs (coherence), or Bartlett's statistic of equal power
        across bands (whiteness).
    p_value : float
        Bonferroni-adjusted p-value over the cells.
    p_holm : float
        Holm-adjusted p-value over the whole family (effects and both checks).
    cells : int
        Number of cells tested.
    worst : str
        The cell with the smallest p-value.
    """

    name: str
    statistic: float
    p_value: float
    p_holm: float
    cells: int
    worst: str

    json_fields = {"name": text(("whiteness", "coherence")), "cells": integer(0)}
    json_source = "residual check"


@dataclass(frozen=True)
class Verdict(Codec):
    """What the diagnosis would accept first, by its rules (:mod:`fdml.verdict`), from the fit alone.

    Parameters
    ----------
    key : str or None
        The effect (None: every candidate was set aside).
    params : dict
        Its parameters, ``{name: [value, stderr]}``, each in ``units``.
    units : dict
        Unit of every parameter.
    source : str
        ``"kinematics"`` (settled by the short-period identity, :mod:`fdml.kinematics`), ``"refit"``
        (the flagged candidates, or the kinematics' alias set, refitted and ranked) or ``"steps"``
        (the timing of the elevator's steps between samples explains the residuals better than any
        of them, by BIC: docs/theory.md section 7a; ``key`` is then ``"input_edges"``).
    aliases : tuple of str
        Every effect these data cannot tell apart from it (itself included).
    set_aside : tuple of (str, str)
        Significant candidates that were set aside, with the reason.
    lr : float
        Its likelihood ratio against the fit.
    with_steps : bool
        The timing of the elevator's steps between samples belongs beside it (docs/theory.md section
        7a): the advice refits with ``--input-edges estimated`` too.
    """

    key: str | None
    params: dict
    units: dict
    source: str
    aliases: tuple = ()
    set_aside: tuple = ()
    lr: float = 0.0
    with_steps: bool = False

    json_fields = {
        "params": Spec(lambda f, k, done: {n: tuple(float(x) for x in v) for n, v in f.mapping(k).items()}),
        "units": mapping(),
        "source": text(("kinematics", "refit", "steps")),
        "aliases": texts(),
        "set_aside": Spec(lambda f, k, done: tuple(tuple(str(y) for y in x) for x in f.raw(k))),
    }
    json_source = "adequacy verdict"

    @property
    def ambiguous(self) -> bool:
        """More than one effect explains the data equally."""
        return len(self.aliases) > 1

    def describe(self) -> str:
        """One line: the effect and its parameters.

        Returns
        -------
        str
            The line.
        """
        vals = ", ".join(
            f"{k} = {_fmt(v, self.units.get(k, ''))} +- {_fmt(se, self.units.get(k, ''))}"
            for k, (v, se) in self.params.items()
        )
        how = "settled by the kinematics" if self.source == "kinematics" else f"LR {self.lr:.3g}"
        if self.source == "steps":
            return f"the timing of the elevator's steps between samples ({how})"
        return f"{self.key} ({vals}; {how})"


@dataclass(frozen=True)
class Adequacy(Codec):
    """The adequacy check of one fit (:func:`check`).

    Parameters
    ----------
    alpha : float
        Family-wise level.
    effects : tuple of EffectTest
        Every tested (identifiable) effect, most significant first.
    skipped : tuple of (key, reason)
        Effects that do not apply or that these data cannot test.
    whiteness, coherence : ResidualCheck
        The two residual checks.
    elapsed : float
        Seconds spent.
    verdict : Verdict or None
        When anything is flagged: the effect the diagnosis would accept first, by its rules.
    """

    alpha: float
    effects: tuple
    skipped: tuple
    whiteness: ResidualCheck
    coherence: ResidualCheck
    elapsed: float = 0.0
    verdict: Verdict | None = None

    json_fields = {
        "effects": nested_list(EffectTest),
        "skipped": Spec(
            lambda f, k, done: tuple((x.string("key"), x.string("reason")) for x in f.items(k, default=[])),
            write=lambda skipped: [{"key": k, "reason": r} for k, r in skipped],
        ),
        "whiteness": nested(ResidualCheck),
        "coherence": nested(ResidualCheck),
        "verdict": nested(Verdict, none=True),
    }
    json_source = "adequacy check"

    @property
    def flagged(self) -> tuple:
        """The effects whose Holm p-value is below ``alpha``."""
        return tuple(e for e in self.effects if e.p_holm < self.alpha)

    @property
    def residual_flags(self) -> tuple:
        """The residual checks (coherence, whiteness) that failed at the family level, after Holm."""
        return tuple(c for c in (self.coherence, self.whiteness) if c.p_holm < self.alpha)

    @property
    def adequate(self) -> bool:
        """Nothing flagged."""
        return not self.flagged and not self.residual_flags

    def brief(self) -> dict:
        """The short form of ``fdml fit --json``: flagged effects and residual checks.

        Returns
        -------
        dict
            ``adequate``, ``alpha``, ``flagged`` (effect dicts), ``whiteness``, ``coherence``.
        """
        return {
            "adequate": self.adequate,
            "alpha": self.alpha,
            "flagged": [e.to_dict() for e in self.flagged],
            "verdict": None if self.verdict is None else self.verdict.to_dict(),
            "whiteness": self.whiteness.to_dict(),
            "coherence": self.coherence.to_dict(),
        }

    def lines(self) -> list:
        """Text lines of the summary's adequacy section.

        Returns
        -------
        list of str
            Flagged effects and residual checks, or one line saying nothing is flagged.
        """
        out = []
        v = self.verdict
        if v is not None and v.key is not None:
            amb = f" (or equally: {', '.join(k for k in v.aliases if k != v.key)})" if v.ambiguous else ""
            out.append(f"FIRST {v.describe()}{amb}")
        out += [f"FLAGGED {e.describe()}" for e in self.flagged]
        for c in self.residual_flags:
            out.append(f"FLAGGED residual {c.name}: p {c.p_value:.2g}, Holm p {c.p_holm:.2g} (worst: {c.worst})")
        if self.adequate:
            top = self.effects[0] if self.effects else None
            more = f"; smallest Holm p {top.p_holm:.2g} ({top.key})" if top is not None else ""
            out.append(
                f"nothing flagged at family level {self.alpha:g} ({len(self.effects)} effects, "
                f"coherence and whiteness of the residuals tested{more})"
            )
        else:
            out.append(f"family level {self.alpha:g}, {len(self.effects) + 2} tests, Holm-corrected")
        return out


def _fmt(v: float, unit: str) -> str:
    if unit == "s" and abs(v) < 1.0:
        return f"{v * 1e3:.3g} ms"
    return f"{v:.3g} {unit if unit != '-' else ''}".rstrip()  # "-": dimensionless


# --- the check ------------------------------------------------------------------------------------


def _per_independent(d) -> float:
    """Grid points per independent frequency 2 pi/T of a record's spectra (1 for a single frequency)."""
    return 2 * math.pi / (d.T * float(np.median(np.diff(d.omega)))) if d.m > 1 else 1.0


def _oversampling(prob) -> np.ndarray:
    """K per record: grid points per independent frequency 2 pi/T (at least 1)."""
    return np.array([max(1.0, _per_independent(d)) for d in prob.data])


@dataclass(frozen=True)
class _BaseFit:
    """The fit as the diagnosis's score screen reads it (model, theta, residual V, band covariances Rs)."""

    model: object
    theta: np.ndarray
    V: np.ndarray
    Rs: list
    prob: object
    params: dict  # estimates by name (read once per candidate parameter by the screen)


class _Context(ScreenContext):
    """The score screen's context on the fit's own problem, with the candidate sensitivities as array operations.

    The screen's own :meth:`fdml.score.ScreenContext.candidate_sensitivities`
    prepares a problem for every candidate model and predicts it twice per
    parameter.  Here the change of the prediction is measured directly:
    without output biases the measurement (Eqs. 18-19) is linear in the
    response (G, H, P), so the central difference of the predictions is the
    measurement of the central difference of the responses
    (:meth:`fdml.estimate.Problem.linear_predict`, the fit's own boundary
    terms), all parameters at once.  The responses: an output-level effect on
    top of the base model acts on the base model's response, computed once
    (as :meth:`fdml.models.effects.AugmentedModel.evaluate` does); any other
    candidate evaluates its own model.  Over a nuisance grid (a structural
    mode's frequency) an output-level effect is evaluated at every grid value
    in one call, the grid value an array along the frequency rows; an effect
    function that does not take that is evaluated value by value.
    """

    def candidate_sensitivities(self, model, names, steps, one_sided):
        (A,) = self.candidate_sensitivities_many([(model, names, steps, one_sided)])
        if isinstance(A, Exception):
            raise A
        return A

    def candidate_sensitivities_many(self, cands) -> list:
        """Every candidate's dy/d eta from one measurement of all their response changes."""
        tried = [attempt(self._changes, *c) for c in cands]
        changes = [t for t in tried if not isinstance(t, Exception)]
        if not changes:
            return tried
        base = self._base
        A = self._measure(
            [
                [_stack_grid([e for c in changes for e in c[r][i]], base[r][i]) for i in range(3)]
                for r in range(len(base))
            ]
        )
        q = [len(c[1]) for t, c in zip(tried, cands) if not isinstance(t, Exception)]  # columns per candidate
        blocks = iter(np.split(A, np.cumsum(q)[:-1], axis=-1))
        return [t if isinstance(t, Exception) else next(blocks) for t in tried]

    def _changes(self, model, names, steps, one_sided) -> list:
        """Per record and part (G, H, P), the response change per tested parameter (None: unchanged)."""
        eff = _output_effect_on(model, self.fit.model)
        vals = model.parameters.values
        cols = [
            self._column(
                eff, model, {**vals, n: vals[n] + h}, vals if os_ else {**vals, n: vals[n] - h}, h if os_ else 2 * h
            )
            for n, h, os_ in zip(names, steps, one_sided)
        ]
        return [[[c[r][i] for c in cols] for i in range(3)] for r in range(len(self.fit.prob.data))]

    def grid_sensitivities(self, model, names, steps, one_sided, gname, grid):
        eff = _output_effect_on(model, self.fit.model)
        if eff is not None:
            try:
                A = self._grid_sensitivities(eff, model, names, steps, one_sided, gname, grid)
            except (TypeError, ValueError, IndexError, ArithmeticError):
                A = None  # the effect function takes scalar parameters only
            if A is not None and self._agrees(eff, A, model, names, steps, one_sided, gname, grid):
                return A
        return super().grid_sensitivities(model, names, steps, one_sided, gname, grid)

    def _agrees(self, eff, A, model, names, steps, one_sided, gname, grid) -> bool:
        """The grid evaluation equals the value-by-value one at the grid's ends (a guard on the effect function).

        Checked once per effect object and process (:data:`_VECTORISES`): whether a function takes
        an array-valued parameter is a property of its code.
        """
        if _VECTORISES.get(eff) is not None:
            return _VECTORISES[eff]
        ok = True
        for k in (0, grid.size - 1):
            ref = self.candidate_sensitivities(model.with_values({gname: float(grid[k])}), names, steps, one_sided)
            ok = ok and bool(np.allclose(A[:, :, k, :], ref, rtol=1e-9, atol=1e-12 * max(np.max(np.abs(ref)), 1e-300)))
        _VECTORISES[eff] = ok
        return ok

    @functools.cached_property
    def _base(self) -> list:
        """(G, H, P) per record of the fit's model (computed once)."""
        return [_ghp(self.fit.model.evaluate(d.omega)) for d in self.fit.prob.data]

    def _response(self, eff, model, p) -> list:
        """(G, H, P) per record of ``model`` at the values ``p``."""
        if eff is None:
            return [_ghp(model.evaluate(d.omega, p)) for d in self.fit.prob.data]
        root = root_model(self.fit.model)
        return [eff.output(1j * d.omega, p, *r, root) for d, r in zip(self.fit.prob.data, self._base)]

    def _column(self, eff, model, up, down, step) -> list:
        """Per record, the central (or forward) difference of the responses, (dG, dH, dP); None: unchanged."""
        return [
            tuple(None if a is b else (a - b) / step for a, b in zip(ru, rd))
            for ru, rd in zip(self._response(eff, model, up), self._response(eff, model, down))
        ]

    def _measure(self, changes: list) -> np.ndarray:
        """dy/d eta, shape (N, n_out, q), from per-record response changes with a leading parameter axis."""
        prob = self.fit.prob
        dy = [
            prob.linear_predict(self.fit.theta, r, ModelResponse(d.omega, *ch))[..., prob.out_idx]
            for r, (d, ch) in enumerate(zip(prob.data, changes))
        ]
        return np.moveaxis(np.concatenate(dy, axis=-2), 0, -1)

    def _grid_sensitivities(self, eff, model, names, steps, one_sided, gname, grid):
        """dy/d eta of shape (N, n_out, g, q): every grid value in one call of the effect per step."""
        g, q = grid.size, len(names)
        vals = dict(model.parameters.values)
        root = root_model(self.fit.model)
        changes = []
        for d, r in zip(self.fit.prob.data, self._base):
            m = d.m
            s = np.tile(1j * d.omega, g)
            base = tuple(np.tile(x, (g, 1, 1)) for x in r)
            at = {**vals, gname: np.repeat(grid, m)}
            cols = [[None] * 3 for _ in range(q)]
            for j, (n, h, os_) in enumerate(zip(names, steps, one_sided)):
                up = _grid_call(eff, s, {**at, n: vals[n] + h}, base, root)
                down = _grid_call(eff, s, at if os_ else {**at, n: vals[n] - h}, base, root)
                step = h if os_ else 2 * h
                cols[j] = [
                    None if a is b and c is b else (a - c).reshape((g, m) + b.shape[1:]) / step
                    for a, c, b in zip(up, down, base)
                ]
            changes.append([_stack_grid([c[i] for c in cols], r[i], g) for i in range(3)])
        A = self._measure(changes)
        return A.reshape(A.shape[:2] + (g, q))


def _grid_call(eff, s: np.ndarray, p: dict, base: tuple, root) -> tuple:
    """The effect on the tiled base response, with the grid parameter an array along the rows."""
    res = eff.output(s, p, *base, root)
    if any(np.shape(x) != np.shape(b) for x, b in zip(res, base)):
        raise ValueError("the effect does not evaluate a grid at once")
    return res


def _stack_grid(cols: list, like: np.ndarray, g: int = 1) -> np.ndarray:
    """Response changes of one part (G, H or P) of q parameters stacked on a leading axis.

    Each change is (g, m, ...) over a grid of g values (``like``'s shape alone without one); stacked as
    (g q, m, ...), grid value first.  Unchanged ones (None) are zero; a part no parameter changes is a
    zero of leading size 1 (it broadcasts in the measurement).
    """
    if all(c is None for c in cols):
        return np.zeros((1,) + like.shape, complex)
    out = np.zeros((g, len(cols)) + like.shape, complex)
    for j, c in enumerate(cols):
        if c is not None:
            out[:, j] = c
    return out.reshape((-1,) + like.shape)


def _ghp(r) -> tuple:
    """(G, H, P) of a :class:`fdml.models.base.ModelResponse`."""
    return r.G, r.H, r.P


def _output_effect_on(model, base):
    """The output-level effect ``model`` adds on top of ``base`` (None when it is not just that)."""
    if not isinstance(model, AugmentedModel) or not model.effects:
        return None
    eff = model.effects[-1]
    if isinstance(eff, OutputEffect) and tuple(model.effects[:-1]) == tuple(applied_effects(base)):
        return eff
    return None


def _context(prob, model, theta, V, R, A=None, prepare=None):
    """The screen's context on the fit's own grid: one R, each record's rows counted 1/K times.

    ``A``: the fit's sensitivities at ``theta`` (``prob.sensitivities(theta)``) when the caller has them;
    ``prepare``: :func:`fdml.estimate.prepare` for the screen's generic path (its own never needs it).
    """
    K = _oversampling(prob)
    rows = np.concatenate([np.full(d.m, i) for i, d in enumerate(prob.data)])
    # the whitener of R K_i divides record i's rows by sqrt(K_i): the LM sum then counts independent frequencies
    theta = np.asarray(theta, float)
    base = _BaseFit(model, theta, V, [R * k for k in K], prob, dict(zip(prob.names, theta.tolist())))
    floor = 1.0 / np.sqrt(np.maximum(np.real(np.diag(R)), 1e-300))
    fw = floor[None, :] / np.sqrt(K[rows])[:, None]  # diagonal white-noise floors for aliasing and the MDE
    options = {
        "outputs": list(prob.outputs),
        "boundary": prob.boundary,
        "biases": False,
        "state_biases": bool(prob.state_biases),
        "input_bias": bool(prob.input_bias),
        "input_edges": prob.input_edges,
    }
    return _Context(base, rows, 1, prob.data, options, fw, sensitivities=A, prepare=prepare), K[rows]


def _logdet_weighted(r: np.ndarray, Kr: np.ndarray) -> tuple[np.ndarray, float]:
    """ln det of the K-weighted covariance of each whitened residual (columns of r), and the independent frequencies.

    ``r`` of shape (2 N n_out, E): E real-stacked residuals; returns (E,) log-determinants.
    """
    M = r.shape[0] // 2
    c = (r[:M] + 1j * r[M:]).T.reshape(r.shape[1], Kr.size, -1) * np.sqrt(Kr)[None, :, None]  # (E, N, n_out)
    w = 1.0 / Kr
    S = np.einsum("enj,n,enk->ejk", c, w, c.conj()) / w.sum()
    return np.linalg.slogdet(S)[1], float(w.sum())


def _one_step_lrs(ctx, screens: list, Kr: np.ndarray) -> np.ndarray:
    """LR at the one-step estimate of each (effect, screen): base parameters re-projected, the effect at
    eta_lin (module doc), all at once.

    Each step is along the screen's own candidate sensitivities (``scr.jacobian``, at the best
    grid value of a nuisance-grid effect).
    """
    if not screens:
        return np.zeros(0)
    steps = []
    for eff, scr in screens:
        nulls = eff.nulls(ctx.fit.model)
        steps.append(scr.jacobian[0] @ np.array([v - nulls[n] for n, v in scr.eta_lin.items()]))
    l0, n_ind = _logdet_weighted(ctx.r[:, None], Kr)
    l1, _ = _logdet_weighted(ctx.r[:, None] - ctx.perp(np.stack(steps, axis=1)), Kr)
    return np.maximum(2.0 * n_ind * (l0[0] - l1), 0.0)


def _test_effects(prob, model, theta, V, R, alpha: float, library=None, A=None):
    """(tests as dicts, skipped) for every applicable deterministic effect."""
    ctx, Kr = _context(prob, model, theta, V, R, A)
    usable, skipped = [], []
    for eff in library if library is not None else registered_effects():
        if eff.kind != "deterministic":
            continue
        why = eff.applicable(model, inputs=tuple(prob.data[0].inputs), outputs=tuple(ctx.options["outputs"]))
        (skipped.append((eff.key, why)) if why else usable.append(eff))
    ctx.family_size = max(len(usable), 1)
    band = (float(min(d.omega[0] for d in prob.data)), float(max(d.omega[-1] for d in prob.data)))
    screened = []
    for eff, scr in zip(usable, screen_all(ctx, usable, level=alpha, band=band)):
        if isinstance(scr, Exception):  # an effect the check cannot evaluate is reported, never fatal
            skipped.append((eff.key, f"cannot be evaluated: {scr}"))
        elif not scr.identifiable:
            skipped.append((eff.key, scr.reason))
        else:
            screened.append((eff, scr))
    moved = [(eff, scr) for eff, scr in screened if scr.lm > 0]
    lr1 = dict(zip((eff.key for eff, _ in moved), _one_step_lrs(ctx, moved, Kr)))
    tests = []
    for eff, scr in screened:
        lr = lr1.get(eff.key, 0.0)
        null, q = null_kind(eff, model, scr)
        Vg, ng = grid_variation(scr)
        p, _ = p_value(lr, q, null, V=Vg, n_grid=ng)
        units = {p_.name: p_.unit for p_ in eff.param_list(model)}
        tests.append(
            {
                "key": eff.key,
                "effect": eff.name,
                "channel": eff.channel,
                "statistic": float(lr),
                "lm": float(scr.lm),
                "df": int(q),
                "null": null,
                "p_value": float(p),
                "expected": dict(scr.eta_lin),
                "units": {k: units.get(k, "") for k in scr.eta_lin},
            }
        )
    return tests, skipped


def _independent(d) -> np.ndarray:
    """Grid indices at spacing >= 2 pi/T (the residuals there are independent, docs/theory.md section 7)."""
    return np.arange(0, d.m, max(math.ceil(_per_independent(d) - 1e-9), 1))


def _bands(n: int) -> list:
    return np.array_split(np.arange(n), max(min(MAX_BANDS, n // MIN_BAND), 1))


def _residual_checks(prob, V) -> tuple[tuple, tuple]:
    """(coherence, whiteness) as (statistic, p, cells, worst) each, Bonferroni over cells."""
    coh, white = [], []
    for d, v in zip(prob.data, np.split(V, np.cumsum([d.m for d in prob.data])[:-1])):
        idx = _independent(d)
        u, vi = d.u[idx], v[idx]
        gain = d.noise_gain(include_trim=False)[idx]
        bands = _bands(idx.size)
        cells = [_coherence_cells(u[b], vi[b]) for b in bands]  # every output of a band at once
        for j, ch in enumerate(prob.outputs):
            for b, (c, p) in zip(bands, cells):
                coh.append((c[j], p[j], (f"{d.name}/{ch}", d.omega[idx[b[0]]], d.omega[idx[b[-1]]])))
            if len(bands) >= 2:
                white.append(_bartlett_cell(np.abs(vi[:, j]) ** 2 / gain, bands, f"{d.name}/{ch}"))
    return _bonferroni(coh), _bonferroni(white)


def _coherence_cells(u: np.ndarray, v: np.ndarray) -> tuple:
    """Multiple coherence of each column of v with the inputs u and its F-test p-value (module doc)."""
    n, q = u.shape
    if n <= q + 1:
        return np.zeros(v.shape[1]), np.ones(v.shape[1])
    coef, *_ = np.linalg.lstsq(u, v, rcond=None)
    fitted = np.sum(np.abs(u @ coef) ** 2, axis=0)
    total = np.sum(np.abs(v) ** 2, axis=0)
    c = np.where(total > 0, np.minimum(fitted / np.where(total > 0, total, 1.0), 1.0 - 1e-15), 0.0)
    F = (n - q) / q * c / (1.0 - c)
    return c, np.array([f_sf(x, 2 * q, 2 * (n - q)) for x in F])


def _bartlett_cell(power: np.ndarray, bands: list, where: str):
    """Bartlett's test of equal mean power across bands, each band a variance on 2 n_b degrees of freedom."""
    nu = np.array([2.0 * b.size for b in bands])
    s2 = np.array([power[b].mean() for b in bands])
    pooled = float(np.sum(nu * s2) / nu.sum())
    k = len(bands)
    M = nu.sum() * math.log(pooled) - float(np.sum(nu * np.log(s2)))
    C = 1.0 + (np.sum(1.0 / nu) - 1.0 / nu.sum()) / (3.0 * (k - 1))
    return M / C, chi2_sf(M / C, k - 1), where


def _bonferroni(cells: list) -> tuple:
    """(statistic, Bonferroni p, cells, where) of the cell with the smallest p.

    ``where`` of a cell: a label, or (label, lo, hi) of a band in rad/s (formatted for the worst only).
    """
    if not cells:
        return 0.0, 1.0, 0, "not testable (too few independent frequencies)"
    stat, p, where = min(cells, key=lambda c: c[1])
    if not isinstance(where, str):
        where = f"{where[0]} {where[1]:.3g}-{where[2]:.3g} rad/s"
    return float(stat), min(1.0, float(p) * len(cells)), len(cells), where


def check(prob, theta, V, R, *, alpha: float = ALPHA, library=None, sensitivities=None) -> Adequacy:
    """The adequacy check of a fit, from its problem and estimate (no refits).

    Parameters
    ----------
    prob : fdml.estimate.Problem
        The fitted problem (data, configured model, nuisance terms).
    theta : ndarray
        The estimate (``prob.names`` order).
    V : ndarray, complex, shape (N, n_out)
        Residuals at the estimate.
    R : ndarray, complex, shape (n_out, n_out)
        Residual covariance (Eq. 24).
    alpha : float, optional
        Family-wise level (default :data:`ALPHA`).
    library : sequence of Effect, optional
        Effects to screen (default: every registered one).
    sensitivities : ndarray, complex, shape (N, n_out, p), optional
        ``prob.sensitivities(theta)`` when the caller has them (the fit's last ones).

    Returns
    -------
    Adequacy
        The score screen of every applicable library effect and the two residual checks.
    """
    if not 0 < alpha < 1:
        raise FdmlError(f"adequacy level alpha must lie in (0, 1), got {alpha}")
    t0 = time.perf_counter()
    model = prob.model.with_values(prob.model_values(np.asarray(theta, float)))
    tests, skipped = _test_effects(prob, model, theta, V, R, alpha, library, sensitivities)
    coh, white = _residual_checks(prob, V)
    ph = holm(np.array([t["p_value"] for t in tests] + [coh[1], white[1]]))
    effects = sorted(
        (EffectTest(**t, p_holm=float(h)) for t, h in zip(tests, ph)), key=lambda e: (e.p_holm, e.p_value, -e.statistic)
    )
    return Adequacy(
        alpha=float(alpha),
        effects=tuple(effects),
        skipped=tuple(skipped),
        coherence=ResidualCheck("coherence", coh[0], coh[1], float(ph[-2]), coh[2], coh[3]),
        whiteness=ResidualCheck("whiteness", white[0], white[1], float(ph[-1]), white[2], white[3]),
        elapsed=time.perf_counter() - t0,
    )


# --- one ranking: what the diagnosis would accept first -----------------------------------------------

#: Flagged candidates refitted to rank them, at most (the most significant first).
MAX_REFITS = 5


@dataclass
class _Refit:
    """A candidate refitted on the fit's own spectra (the fields :func:`fdml.verdict.choose_among` reads)."""

    effect: Any
    result: Any
    lr: float
    p: float
    q_eff: int
    params: dict
    demoted: str | None


def _kinematics(prob, model):
    """The short-period identity on the fit's spectra (None without alpha, q and a_z or an airspeed)."""
    U = model_airspeed(model)
    if U is None or not set(OUTPUTS) <= set(prob.outputs):  # alpha, q and a_z fitted (theta may be too)
        return None
    try:
        return kinematic_evidence(prob.data, U, known=known_terms(model))
    except (FdmlError, np.linalg.LinAlgError, ValueError):
        return None


def _refitted(refit, model, **options):
    """``refit(model, **options)``, None when it fails."""
    try:
        return refit(model, **options)
    except _FAILURES:
        return None


def _lr(R0: np.ndarray, R1: np.ndarray, n_ind: float) -> float:
    """The likelihood ratio of a refit with residual covariance R1 against R0 (module doc), at least 0."""
    return max(2.0 * n_ind * (np.linalg.slogdet(R0)[1] - np.linalg.slogdet(R1)[1]), 0.0)


def _refit_one(eff, start: dict, prob, result, refit, kin, n_ind: float) -> _Refit | None:
    model = with_effects(result.model, eff)
    model = model.with_values({k: v for k, v in start.items() if k in model.parameters and math.isfinite(v)})
    r = _refitted(refit, model)
    if r is None:
        return None
    lr = _lr(result.R, r.R, n_ind)
    null, q = null_kind(eff, result.model)
    p, _ = p_value(lr, q, null)
    plist = eff.param_list(result.model)
    params = {x.name: (r.params.get(x.name, math.nan), r.errors.get(x.name, math.nan)) for x in plist}
    base = [x.name for x in root_model(result.model).parameters if x.free and x.name in r.params]
    derivs = {n: (r.params[n], r.errors[n]) for n in base}
    dt = max(float(d.dt) for d in prob.data)
    floor = input_resolution([d.record for d in prob.data], dt)
    why = judge(eff, params, result.model, derivs, kin, dt=dt, U=model_airspeed(result.model), input_floor=floor)
    return _Refit(eff, r, lr, p, q + len([x for x in plist if x.nuisance]), params, why)


def _candidates(adequacy: Adequacy, kin) -> list:
    """(effect, start values) to refit: the kinematics' alias set, else the flagged effects."""
    if kin is not None and kin.aliases:
        # a lag starts at its kinematic value (its cost has other minima); an offset or a scale at its
        # null, where the fit's own estimate is the optimum (Twin Otter 017: 6 and 8 passes, not 8 and 12)
        return [(get_effect(m.key), {m.param: m.value} if m.unit == "s" else {}) for m in kin.aliases[0]]
    return [(get_effect(e.key), dict(e.expected)) for e in adequacy.flagged[:MAX_REFITS]]


def rank(adequacy: Adequacy, prob, result, refit) -> Verdict | None:
    """The effect the diagnosis would accept first, by its rules (:mod:`fdml.verdict`); None when nothing is flagged.

    Sensors first: what the short-period identity settles is the answer.  Otherwise the candidates --
    the identity's alias set when it shows a sensor error it cannot attribute, else the flagged
    effects -- are refitted on the fit's own spectra with its options, and chosen as the diagnosis
    chooses.

    Parameters
    ----------
    adequacy : Adequacy
        The check of the fit.
    prob : fdml.estimate.Problem
        The fit's problem.
    result : FitResult
        The fit.
    refit : callable
        ``refit(model) -> FitResult``: the fit's own options on its own spectra, no adequacy check.

    Returns
    -------
    Verdict or None
        The verdict.
    """
    if adequacy.adequate:
        return None
    kin = _kinematics(prob, result.model)
    n_ind = float(sum(_independent(d).size for d in prob.data))
    if kin is not None and kin.settled:
        m = kin.settled[0]
        beside = _steps_beside(prob, result, refit, n_ind, m)
        return Verdict(
            m.key, {m.param: (m.value, m.stderr)}, {m.param: m.unit}, "kinematics", (m.key,), (), m.finding.lr, beside
        )
    raw = [_refit_one(eff, st, prob, result, refit, kin, n_ind) for eff, st in _candidates(adequacy, kin)]
    fits: list[_Refit] = [f for f in raw if f is not None]
    level = adequacy.alpha / max(len(fits), 1)
    eligible = [f for f in fits if f.p < level and f.demoted is None]
    best, aliases = choose_among(eligible, 2.0 * n_ind * len(prob.out_idx))
    aside = tuple((f.effect.key, f.demoted) for f in fits if f.demoted is not None and f.p < level)
    steps, steps_lr = _steps_verdict(prob, result, refit, n_ind, best, level)
    if steps == "steps":
        return Verdict("input_edges", {}, {}, "steps", (), aside, steps_lr)
    if best is None:
        return Verdict(None, {}, {}, "refit", (), aside, 0.0) if aside else None
    units = {x.name: x.unit for x in best.effect.param_list(result.model)}
    keys = tuple(f.effect.key for f in aliases)
    return Verdict(best.effect.key, dict(best.params), units, "refit", keys, aside, best.lr, steps == "beside")


def _steps(prob, n_ind: float) -> tuple[int, float]:
    """(k, ln n): the records' elevator steps between samples (0 when the fit estimated their timing or there
    are none, docs/theory.md section 7a) and the log of the real independent observations of BIC."""
    k = 0 if prob.input_edges != "none" else sum(d.edges.size for d in prob.data)
    return k, math.log(max(2.0 * n_ind * len(prob.out_idx), 2.0))


def _lr_of_steps(refit, model, R0: np.ndarray, n_ind: float) -> float | None:
    """LR of ``model`` refitted with every step's timing against residual covariance ``R0`` (None: no fit).

    Only its R counts, so the refit's covariance is the information matrix's (``naive``), not the white
    noise's: with a timing per step that one is the costly part (Gram columns per step and output).
    """
    r = _refitted(refit, model, input_edges="estimated", cov_type="naive")
    return _lr(R0, r.R, n_ind) if r is not None and r.converged else None


def _steps_verdict(prob, result, refit, n_ind: float, best, level: float):
    """Where the timing of the elevator's steps between samples (docs/theory.md section 7a) enters the verdict.

    The fit's model and, with a ``best`` candidate, its refit are refitted with every step's timing and
    compared by BIC (``q ln n - LR``, as :func:`fdml.verdict.choose_among` compares candidates).  Returns
    (``"steps"``, LR) when the timing alone explains the residuals best (or, with no best, significantly),
    (``"beside"``, LR) when it lowers the BIC beside the best candidate, else (None, 0) (also for records
    without such steps and for a fit that estimated them).
    """
    k, logn = _steps(prob, n_ind)
    if not k:
        return None, 0.0
    alone = _lr_of_steps(refit, result.model, result.R, n_ind)
    if best is None:
        return ("steps", alone) if alone is not None and chi2_sf(alone, k) < level else (None, 0.0)
    beside = _lr_of_steps(refit, best.result.model, result.R, n_ind)
    bic = {"best": (best.q_eff * logn - best.lr, best.lr)}
    if alone is not None:
        bic["steps"] = (k * logn - alone, alone)
    if beside is not None:
        bic["beside"] = ((best.q_eff + k) * logn - beside, beside)
    choice = min(bic, key=lambda n: bic[n][0])
    return (None, 0.0) if choice == "best" else (choice, bic[choice][1])


def _steps_beside(prob, result, refit, n_ind: float, m) -> bool:
    """Whether the steps' timing lowers the BIC beside the sensor effect ``m`` the kinematics settled (held at
    its kinematic value, as the advice refits it): :func:`_steps_verdict` for the kinematics' verdict."""
    k, logn = _steps(prob, n_ind)
    if not k:
        return False
    model = with_effects(result.model, get_effect(m.key)).fix({m.param: m.value})
    r0 = _refitted(refit, model, cov_type="naive")  # only its R counts
    lr = None if r0 is None else _lr_of_steps(refit, model, r0.R, n_ind)
    return lr is not None and lr > k * logn


# --- the warning ----------------------------------------------------------------------------------


def advice(
    adequacy: Adequacy,
    cov_type: str | None = None,
    *,
    fit_argv: list[str] | None = None,
    diagnose_argv: list[str] | None = None,
    in_diagnosis: bool = False,
) -> str | None:
    """The warning text for a flagged fit (None when nothing is flagged).

    It names the most significant flagged effect and the command that refits
    with it, or runs the diagnosis. Every suggestion is spelled as it is run:
    command-line options on the command line, keywords in Python. The text
    depends on its arguments alone: the command layer passes the running
    command (:func:`reworded`).

    Parameters
    ----------
    adequacy : Adequacy
        The check of a fit.
    cov_type : str, optional
        The fit's covariance type; ``"colored"`` is not suggested again.
    fit_argv : list of str, optional
        The running ``fdml fit`` command line; the advice quotes it with
        ``--effect NAME:CHANNEL`` added. Without it the advice gives the
        generic command and the Python call.
    diagnose_argv : list of str, optional
        The matching ``fdml diagnose`` command line.
    in_diagnosis : bool
        The fit is the diagnosis's own: the advice does not send the user to
        the diagnosis.

    Returns
    -------
    str or None
        The warning text.
    """
    if adequacy.adequate:
        return None
    diag = _command(diagnose_argv, [], "fdml diagnose RECORD ... (or fdml.diagnose.diagnose(records, model))")
    diagnosis = "" if in_diagnosis else f"run the full diagnosis: {diag}"
    v = adequacy.verdict
    if v is not None:
        return _verdict_advice(adequacy, v, fit_argv, diagnosis)
    if adequacy.flagged:
        top = adequacy.flagged[0]
        refit = _command(
            fit_argv,
            ["--effect", top.option],
            f"fdml fit RECORD ... --effect {top.option} (Python: fdml.with_effects(model, {top.option!r}))",
        )
        also = _also([e.key for e in adequacy.flagged[1:]])
        return f"the fit's residuals carry {top.describe()}{also}. Refit with it: {refit}" + _or(diagnosis)
    c = adequacy.residual_flags[0]
    bounds = "the bounds assume white noise"
    if cov_type == "colored":
        bounds = "the colored bounds allow for non-white noise"
    elif adequacy.whiteness in adequacy.residual_flags:  # not for coherence: a model error, not coloured noise
        bounds += " (try --cov-type colored)" if fit_argv else ' (try --cov-type colored; cov_type="colored" in Python)'
    return (
        f"the fit's residuals fail the {c.name} check (Holm p {c.p_holm:.2g}, worst {c.worst}) but no "
        f"library effect explains them: {bounds}" + (f"; {diagnosis}" if diagnosis else "")
    )


def _command(argv, args: list, generic: str) -> str:
    """The running command line ``argv`` with ``args`` added, else the ``generic`` spelling."""
    return shlex.join([*argv, *args]) if argv else generic


def _also(keys: list) -> str:
    return f"; also flagged: {', '.join(keys)}" if keys else ""


def _or(diagnosis: str) -> str:
    return f"; or {diagnosis}" if diagnosis else ""


def _airspeed_alias(v: Verdict) -> str:
    """A scale of a_z relative to q is what a wrong airspeed gives (fdml.kinematics, Eq. 5): say so."""
    if v.key != "sensor_scale@az":
        return ""
    k = v.params["k_az"][0]
    return f" (or the airspeed given is {1 + k:.4g} times too small: the identity scales a_z by g/U)"


def _verdict_advice(adequacy: Adequacy, v: Verdict, fit_argv, diagnosis: str) -> str:
    """The warning when the check ranked the flagged effects as the diagnosis would (:func:`rank`).

    ``diagnosis``: "run the full diagnosis: COMMAND", or "" within the diagnosis itself.
    """
    tail = f"; {diagnosis}" if diagnosis else ""
    if v.key is None:
        why = "; ".join(f"{k}: {r}" for k, r in v.set_aside)
        return f"the fit's residuals flag effects that were all set aside ({why}){tail}"
    if v.source == "steps":
        refit = _command(
            fit_argv,
            ["--input-edges", "estimated"],
            'fdml fit RECORD ... --input-edges estimated (Python: input_edges="estimated")',
        )
        return (
            f"the elevator steps between samples, and their timing (LR {v.lr:.3g}) explains the fit's residuals better "
            f"than any flagged effect ({', '.join(e.key for e in adequacy.flagged) or 'none'}): the record "
            f"does not keep when each step happened. Refit with it: {refit}{tail}"
        )
    extra = [f"{k}={val:.6g}" for k, (val, _) in v.params.items()] if v.source == "kinematics" else []
    args = ["--effect", v.key.replace("@", ":", 1)] + [a for x in extra for a in ("--fix", x)]  # NAME:CHANNEL
    args += ["--input-edges", "estimated"] if v.with_steps else []
    refit = _command(fit_argv, args, "fdml fit RECORD ... " + shlex.join(args))
    also = _also([e.key for e in adequacy.flagged if e.key not in v.aliases])
    if v.source == "kinematics":
        what = (
            f"the kinematics (alpha, q and a_z against the short-period identity, whatever the aerodynamics) "
            f"settle {v.describe()}{_airspeed_alias(v)}{also}; the refit holds it at that value. Refit with it: {refit}"
        )
    elif v.ambiguous:
        what = (
            f"the fit's residuals carry one of {', '.join(v.aliases)}, which these data cannot tell apart "
            f"(the best: {v.describe()}){also}; the diagnosis says what would separate them"
        )
    else:
        steps = ", with the timing of the elevator's steps between samples" if v.with_steps else ""
        what = f"the fit's residuals carry {v.describe()}{steps}{also}. Refit with it: {refit}"
    return what + _or(diagnosis)


def reworded(
    result: Any,
    *,
    fit_argv: list[str] | None = None,
    diagnose_argv: list[str] | None = None,
    in_diagnosis: bool = False,
) -> Any:
    """``result`` with its adequacy warning worded for where the fit ran (:func:`advice`).

    A fit warns with the generic advice (the library knows no command line); the
    command line re-words it to quote the running command, and the diagnosis
    to leave out the advice to run the diagnosis. Only the warning that
    :func:`advice` gave is replaced; other warnings are kept as they are.

    Parameters
    ----------
    result : FitResult
        A fit with its adequacy check (``result.adequacy``).
    fit_argv : list of str, optional
        The running ``fdml fit`` command line (:func:`advice`).
    diagnose_argv : list of str, optional
        The matching ``fdml diagnose`` command line.
    in_diagnosis : bool
        The fit is the diagnosis's own.

    Returns
    -------
    FitResult
        ``result`` with the re-worded warning (itself when there is none).
    """
    found = getattr(result, "adequacy", None)
    if found is None or found.adequate:
        return result
    cov_type = getattr(result, "cov_type", None)
    generic = advice(found, cov_type)
    text = advice(found, cov_type, fit_argv=fit_argv, diagnose_argv=diagnose_argv, in_diagnosis=in_diagnosis)
    kept = tuple(
        replace(w, message=text) if w.category == "AdequacyWarning" and w.message == generic else w
        for w in result.warnings
    )
    return replace(result, warnings=kept)


def attach(prob, result, V, sensitivities=None, refit=None):
    """``result`` with its adequacy check (``FitResult.adequacy``) and, when it flags, the warning.

    Called by :func:`fdml.estimate.fit` after a converged fit (``sensitivities``: the fit's
    ``prob.sensitivities`` at the estimate, when it has them).  The warning
    (:class:`~fdml.errors.AdequacyWarning`) is kept in ``result.warnings`` by
    :func:`fdml.estimate.fit`, which records every warning of a fit.  A check that cannot run says so in a warning;
    it never fails the fit.

    Parameters
    ----------
    prob : fdml.estimate.Problem
        The fit's problem.
    result : FitResult
        The converged fit.
    V : numpy.ndarray
        Residuals at the estimate, shape (N, n_out), complex.
    sensitivities : numpy.ndarray, optional
        The fit's sensitivities at the estimate.
    refit : callable, optional
        ``refit(model) -> FitResult`` with the fit's own options (:func:`rank`); without it the
        flagged effects are not ranked.

    Returns
    -------
    FitResult
        ``result`` with ``adequacy`` set (unchanged when the check could not run).
    """
    try:
        found = check(prob, result.values, V, result.R, sensitivities=sensitivities)
        if refit is not None and not found.adequate:
            found = replace(found, verdict=rank(found, prob, result, refit))
    except _FAILURES as exc:
        warnings.warn(f"the adequacy check could not run: {exc}", AdequacyWarning, stacklevel=4)
        return result
    msg = advice(found, cov_type=getattr(result, "cov_type", None))
    if msg is not None:
        warnings.warn(msg, AdequacyWarning, stacklevel=4)
    return replace(result, adequacy=found)
