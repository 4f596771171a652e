"""Nested augmentations of any fdml model: what an effect is, and a model with effects applied.

The kinds of effect (:class:`OutputEffect` on the frequency response, :class:`MatrixEffect`
on the short-period matrices, :class:`FreeParameterEffect` that frees a fixed parameter), their
parameters (:class:`Param`) and :class:`AugmentedModel`.  The registry of named effects, and the
built-in ones, live above this module (:mod:`fdml.models.effects`,
:mod:`fdml.models.effect_library`), so that the library can be built from these classes and the
registry filled from the library in one place, without an import circle.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from ..channels import INPUT, OUTPUTS
from ..errors import FdmlError, ParameterError
from ..parameters import Parameter, Parameters, Role
from .base import Model, ModelResponse, _responded

__all__ = [
    "Param",
    "Effect",
    "OutputEffect",
    "MatrixEffect",
    "FreeParameterEffect",
    "AugmentedModel",
    "root_model",
    "applied_effects",
    "with_gust",
    "scale_rows",
]


@dataclass(frozen=True)
class Param:
    """A parameter an effect adds (or frees).

    Parameters
    ----------
    name : str
        Parameter name inside the augmented model (unique across effects).
    null : float or None
        Value at which the effect vanishes.  ``None`` for an effect that frees
        an existing parameter: the null is then that parameter's value in the
        base model.
    lower, upper : float
        Bounds for the estimator.  A null on a bound makes the test one-sided
        (chi-bar-square null distribution).
    plausible : (float, float), optional
        Physical range; a fitted value outside it means the effect is
        absorbing something else, and the MDE screen compares against it.
    unit, description : str
        The parameter's unit and a one-line description.
    start : float, optional
        A typical non-null size (used for start values and finite-difference
        steps); default 1 % of the plausible range, else 1e-3.
    nuisance : bool, optional
        A parameter that is not identified when the effect is absent (a
        structural mode's frequency and damping): held fixed on a grid for the
        test, then refined continuously (docs/diagnosis_method.md 2.6 rule 5).
    """

    name: str
    null: float | None = 0.0
    lower: float = -math.inf
    upper: float = math.inf
    plausible: tuple | None = None
    unit: str = ""
    description: str = ""
    start: float | None = None
    nuisance: bool = False

    def typical(self) -> float:
        """A small, typical non-null size (for finite differences and MDE units).

        Returns
        -------
        float
            The size, in the parameter's unit (positive).
        """
        if self.start is not None:
            return abs(float(self.start))
        if self.plausible is not None:
            lo, hi = self.plausible
            return 0.01 * max(abs(hi - lo), 1e-12)
        return 1e-3


class Effect:
    """An unmodelled effect, testable as a nested augmentation of a model.

    Subclasses set :attr:`name` (the library name, e.g. ``"time_delay"``),
    :attr:`channel` (``alpha``, ``q``, ``az``, ``de``, ``alpha_w`` or a comma
    list), :attr:`params` and implement :meth:`augment`.

    The diagnosis is validated on records simulated with one withheld effect.
    Those truths are written independently of the effects' code, on purpose (a
    truth that shared the candidate's code would confirm its mistakes): an
    effect that frees a model parameter is simulated as the plain model, the
    others by their entry in :data:`fdml.diagnose.truth.TRUTHS`.  An effect
    without one (a new effect; the lags of the dimensional and derivatives
    models) can be fitted and diagnosed, but it cannot be a validation truth.

    Attributes
    ----------
    name : str
        Library name, shared by the variants of one effect.
    channel : str
        Where it applies.
    params : tuple of Param
        The parameters the effect adds or frees.
    kind : {"deterministic", "noise"}
        Noise-kind effects change the residual's covariance, not the
        model's response; they are tested separately (after the
        deterministic ones) on the part of the residual that is incoherent
        with the inputs.
    needs : tuple of str
        Record channels required (e.g. ``("alpha_w",)``).
    nuisance_grid : dict, optional
        ``{param name: grid}`` for parameters that are not identified under
        the null (Davies problem; e.g. a structural mode's frequency).
    signature : str
        One line on where the effect shows, for reports.
    """

    name: str = "effect"
    channel: str = ""
    params: tuple = ()
    kind: str = "deterministic"
    needs: tuple = ()
    nuisance_grid: dict | None = None
    signature: str = ""

    def _describe(self, name: str, channel: str, params: Sequence[Param], needs: Sequence[str], signature: str) -> None:
        """Set the attributes every effect has, for an effect made by its constructor's arguments."""
        self.name = name
        self.channel = channel
        self.params = tuple(params)
        self.needs = tuple(needs)
        self.signature = signature

    @property
    def key(self) -> str:
        """Unique id of this variant: ``name@channel``."""
        return f"{self.name}@{self.channel}" if self.channel else self.name

    def applicable(
        self, model: Model, inputs: Sequence[str] = (INPUT,), outputs: Sequence[str] = OUTPUTS
    ) -> str | None:
        """None if the effect can be tested on ``model`` with these channels, else the reason.

        Parameters
        ----------
        model : Model
            The base model.
        inputs : sequence of str, optional
            Input channels of the record(s).
        outputs : sequence of str, optional
            Fitted output channels.

        Returns
        -------
        str or None
            Why the effect cannot be tested, or None.
        """
        for need in self.needs:
            if need not in inputs and need not in outputs:
                return f"needs the {need} channel, which the record(s) lack"
        for ch in self.channel.split(","):
            if ch in OUTPUTS and ch not in outputs:
                return f"acts on {ch}, which is not among the fitted outputs"
        return None

    def param_list(self, model: Model) -> tuple:
        """The :class:`Param` list for this base model (most effects: :attr:`params`).

        Parameters
        ----------
        model : Model
            The base model.

        Returns
        -------
        tuple of Param
            The effect's parameters on ``model``.
        """
        return tuple(self.params)

    def augment(self, model: Model) -> Model:  # pragma: no cover - abstract
        """The augmented model, with the new parameters free and at their null.

        Parameters
        ----------
        model : Model
            The base model.

        Returns
        -------
        Model
            The augmented model.
        """
        raise NotImplementedError

    def nulls(self, model: Model) -> dict[str, float]:
        """Null values of the effect's parameters on ``model``.

        Parameters
        ----------
        model : Model
            The base model.

        Returns
        -------
        dict of str to float
            Parameter name -> null value, in its unit.
        """
        vals = model.parameters.values
        return {p.name: vals.get(p.name, 0.0) if p.null is None else float(p.null) for p in self.param_list(model)}

    def realize(self, target, p: Mapping[str, float], root: Model):
        """The effect on a time-domain realisation (see :func:`fdml.models.realization.realize`).

        Output-level effects act on the state space of the base model
        (:mod:`fdml.models.realization` helpers ``delay_output``, ``scale_output``,
        ``filter_input``, ``add_mode``);
        matrix-level effects on its descriptor form
        (:class:`fdml.models.realization.Descriptor`) or, on a Wells-Keskar base, on the
        options of its realisation.  An effect without one cannot be simulated.

        Parameters
        ----------
        target : object
            The realisation being built: a state space, a
            :class:`fdml.simulate.Descriptor` or realisation options.
        p : mapping of str to float
            All parameter values by name.
        root : Model
            The plain base model.

        Returns
        -------
        object
            ``target`` (or a new one of its kind) with the effect applied.
        """
        raise ParameterError(
            f"effect {self.key} has no time-domain realisation: it can be fitted, "
            "not simulated or exported as a state space"
        )

    def describe(self) -> str:
        """A short description of the effect: its signature, else its key.

        Returns
        -------
        str
            The description.
        """
        return self.signature or self.key

    def label(self) -> str:
        """Short name for a model's description: ``alpha time delay (tau_alpha, s)``.

        Returns
        -------
        str
            The name, with the parameters and their units.
        """
        where = "" if not self.channel else f"{self.channel} "
        pars = ", ".join(f"{p.name}, {p.unit}" if p.unit else p.name for p in self.params if not p.nuisance)
        return f"{where}{self.name.replace('_', ' ')}" + (f" ({pars})" if pars else "")


# --- the augmented model ---------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class AugmentedModel(Model):
    """A base fdml model plus a sequence of output- or matrix-level effects.

    Its parameter set is the root model's followed by every effect's new
    parameters; ``evaluate`` applies the matrix-level effects before the
    short-period solve and the output-level effects after it, in order.  The
    estimator sees an ordinary :class:`~fdml.models.base.Model`.

    Parameters
    ----------
    gust, output_bias : bool, optional
        Taken from ``root`` (the values given are replaced).
    parameters : Parameters, optional
        The parameter set; default the root's followed by the effects' (fixed at their nulls).
    outputs : tuple of str, optional
        Taken from ``root`` (the value given is replaced).
    root : Model
        The plain base model.
    effects : tuple of Effect, optional
        The output- and matrix-level effects, in the order they apply.
    requested : tuple of Effect, optional
        The effects as requested, free-parameter ones included (they describe and serialise the model).
    """

    root: Model = field(default=None)  # type: ignore[assignment]
    effects: tuple = ()
    #: The effects as requested (:func:`fdml.models.with_effects`), free-parameter ones included; these
    #: describe and serialise the model.  Empty for the diagnosis' internal augmentations.
    requested: tuple = ()

    def __post_init__(self) -> None:
        if not isinstance(self.root, Model) or isinstance(self.root, AugmentedModel):
            raise ParameterError("AugmentedModel needs a plain fdml model as root")
        for name in ("gust", "output_bias", "outputs"):
            object.__setattr__(self, name, getattr(self.root, name))
        if self.parameters is None:
            own = [
                Parameter(
                    par.name,
                    0.0 if par.null is None else par.null,
                    free=False,
                    lower=par.lower,
                    upper=par.upper,
                    unit=par.unit,
                    description=par.description or eff.key,
                    role=Role.EFFECT,
                )
                for eff in self.effects
                for par in eff.param_list(self.root)
            ]
            object.__setattr__(self, "parameters", Parameters((*self.root.parameters.items, *own)))

    def _placeholder_sources(self) -> dict[str, tuple[float, str]]:
        return self.root._placeholder_sources()  # the effects start at their nulls: no placeholders

    def with_outputs(self, outputs) -> Model:
        root = self.root.with_outputs(outputs)
        if root is self.root:
            return self
        # the root's new biases, and this model's own values of everything it keeps
        keep = {p.name for p in self.parameters if p.role is not Role.OUTPUT_BIAS or p.name in root.parameters}
        params = Parameters(tuple(p for p in self.parameters if p.name in keep)).extended(
            p for p in root.parameters if p.name not in keep
        )
        return replace(self, root=root, parameters=params)

    @property
    def parts(self) -> tuple:
        """The effects that make this model (as requested, else the applied ones)."""
        return self.requested or self.effects

    @property
    def kind(self) -> str:  # type: ignore[override]
        return "+".join([self.root.kind] + [e.key for e in self.parts])

    def sensitivity(self, omega, values=None, names=(), parts=("G", "H", "P")):
        if not self.effects:  # only freed parameters of the root: its analytic sensitivities
            return self.root.sensitivity(omega, self._root_values(self.values(values)), names, parts)
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        p = self.values(values)
        names = list(names)
        own = self._output_names()
        inner = [n for n in names if n not in own]  # through the solve: root, matrix-level and station parameters
        outer = [n for n in names if n in own]  # output-level effects' own: differences of the effects alone
        r, dG, dH, dP = self._matrix_sensitivity(omega, p, inner, ("G", "H", "P"))
        s = 1j * r.omega
        base = (r.G, r.H, r.P)
        G, H, P, dG, dH, dP = self._through_outputs(s, p, base, (dG, dH, dP))
        extra = [self._output_difference(s, p, base, n) for n in outer]
        order = [inner.index(n) if n in inner else len(inner) + outer.index(n) for n in names]

        def joined(a, i):
            return np.concatenate([a] + [x[i][None] for x in extra])[order] if extra else a[order]

        return ModelResponse(omega, G, H, P, self.outputs), joined(dG, 0), joined(dH, 1), joined(dP, 2)

    def forced_sensitivity(self, omega, values, names, u, boundary=None, forcing=None):
        """:meth:`Model.forced_sensitivity`, through output-level effects given by their factors.

        When each output-level effect gives its :attr:`OutputEffect.factors`, their linear part scales
        the outputs and the inputs: a base or matrix-level parameter's derivative is then the solve's,
        with the inputs scaled and the outputs scaled, and an output-level effect's own parameter's is
        its central difference (:meth:`_output_difference`) applied to the forcing.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s, shape (n,).
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.
        names : sequence of str
            Parameters to differentiate with respect to.
        u : numpy.ndarray
            Input spectra (de rad s[, alpha_w rad s]), complex, shape (n, n_in).
        boundary : numpy.ndarray, optional
            Boundary vector d, complex, shape (n, n_b); None for none.
        forcing : numpy.ndarray, optional
            State forcing f, shape (n, 2); None for none.

        Returns
        -------
        resp : ModelResponse
            The response at ``omega``, the effects applied.
        dy : numpy.ndarray
            Derivatives of the outputs per name, complex, shape (len(names), n, n_y).
        """
        factored = [e.factors for e in self.effects if isinstance(e, OutputEffect)]
        if not factored or None in factored or not self.root._solves_matrices():
            return super().forced_sensitivity(omega, values, names, u, boundary, forcing)
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        p, s, names, own = self.values(values), 1j * omega, list(names), self._output_names()
        rows, cols = 1.0, 1.0  # the products of the effects' factors: diagonal scalings commute
        for f in factored:
            r, c, _ = f(s, p, self.root)
            rows, cols = rows if r is None else rows * r, cols if c is None else cols * c
        inner, outer = [n for n in names if n not in own], [n for n in names if n in own]
        base, dy = self._forced_solve(omega, p, inner, u * cols, boundary, forcing)
        resp = (base.G, base.H, base.P)
        extra = [
            _responded(ModelResponse(omega, *self._output_difference(s, p, resp, n)), u, boundary, forcing)[None]
            for n in outer
        ]
        dy = np.concatenate([dy * rows] + extra)
        order = [inner.index(n) if n in inner else len(inner) + outer.index(n) for n in names]
        return ModelResponse(omega, *self._outputs(s, p, *resp), self.outputs), dy[order]

    def _solves_matrices(self) -> bool:
        return self.root._solves_matrices() and not any(isinstance(e, OutputEffect) for e in self.effects)

    def _output_names(self) -> set:
        """The output-level effects' own parameters."""
        return {q.name for e in self.effects if isinstance(e, OutputEffect) for q in e.param_list(self.root)}

    def _outputs(self, s, p, G, H, P) -> tuple:
        """(G, H, P) through the output-level effects, in order."""
        for eff in self.effects:
            if isinstance(eff, OutputEffect):
                G, H, P = eff.output(s, p, G, H, P, self.root)
        return G, H, P

    def _output_difference(self, s, p, base: tuple, name: str) -> tuple:
        """d(G, H, P)/d(name) of an output-level effect's parameter: central differences of the effects alone."""
        v = p[name]
        h = 1e-5 * max(abs(v), 1e-2)
        up, dn = self._outputs(s, {**p, name: v + h}, *base), self._outputs(s, {**p, name: v - h}, *base)
        return tuple((a - b) / (2 * h) for a, b in zip(up, dn))

    def _through_outputs(self, s, p, resp: tuple, derivs: tuple) -> tuple:
        """The output-level effects applied to a response and pushed along its derivatives.

        The root parameters' derivatives come through the solve (:meth:`Model._matrix_sensitivity`);
        an output effect maps (G, H, P) to an affine function of them, so its derivative along dG is
        ``(T(G + e dG) - T(G - e dG)) / 2e``, exact for an affine T, all parameters in one call.
        Returns (G, H, P, dG, dH, dP) after the effects.
        """
        k = derivs[0].shape[0]
        if k == 0 or not any(isinstance(e, OutputEffect) for e in self.effects):
            return (*self._outputs(s, p, *resp), *derivs)
        scale = max(float(np.max(np.abs(resp[0]))), 1e-300)
        eps = 1e-6 * scale / np.maximum(np.max(np.abs(derivs[0]), axis=(1, 2, 3)), 1e-300)  # one step per parameter
        e = eps.reshape(k, 1, 1, 1)
        stacks = [
            np.concatenate([x[None], x[None] + e * d, x[None] - e * d]).reshape((-1,) + x.shape[1:])
            for x, d in zip(resp, derivs)
        ]
        out = [x.reshape((2 * k + 1, s.size) + x.shape[1:]) for x in self._outputs(np.tile(s, 2 * k + 1), p, *stacks)]
        return (*(x[0] for x in out), *((x[1 : k + 1] - x[k + 1 :]) / (2 * e) for x in out))

    @property
    def U(self) -> float:
        return self.root.U

    @property
    def aircraft(self):
        """The base model's aircraft (None for a model without one)."""
        return getattr(self.root, "aircraft", None)

    def _root_values(self, p: Mapping[str, float]) -> dict[str, float]:
        names = self.root.parameters.names
        return {k: p[k] for k in names}

    def _matrix_derivatives(self, s, p, names):
        """The root's own (closed-form where it has them) when no effect acts on the matrices; the
        central differences of :meth:`Model._matrix_derivatives` for the rest (a matrix-level effect
        maps the root's matrices, and its own parameters enter only through it)."""
        if any(isinstance(e, MatrixEffect) and e.acts_on_matrices for e in self.effects):
            return super()._matrix_derivatives(s, p, names)
        root = [n for n in names if n in self.root.parameters]
        out = self.root._matrix_derivatives(s, self._root_values(p), root) if root else {}
        rest = [n for n in names if n not in out]
        return {**out, **(super()._matrix_derivatives(s, p, rest) if rest else {})}

    def _matrices(self, s, p):
        M, B, E = self.root._matrices(s, self._root_values(p))
        for eff in self.effects:
            if isinstance(eff, MatrixEffect):
                M, B, E = eff.matrices(s, p, M, B, E, self.root)
        return M, B, E

    def evaluate(self, omega, values: Mapping[str, float] | None = None) -> ModelResponse:
        """:meth:`Model.evaluate` (its ``_matrices`` apply the matrix-level effects), then the output-level ones.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        ModelResponse
            The response at ``omega``.
        """
        r = Model.evaluate(self, omega, values)  # input delays and the solve: written once, in Model
        G, H, P = self._outputs(1j * r.omega, self.values(values), r.G, r.H, r.P)
        return ModelResponse(omega, G, H, P, self.outputs)

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        return self.root.derived(self._root_values(self.values(values)))

    def describe(self) -> str:
        """The model by its parts: ``dimensional model (...) + alpha time delay (tau_alpha, s) + ...``.

        Returns
        -------
        str
            One line.
        """
        return " + ".join([self.root.describe()] + [e.label() for e in self.parts])

    def __repr__(self) -> str:
        return f"<fdml model: {self.describe()}>"


def root_model(model: Model) -> Model:
    """The plain fdml model under any augmentation.

    Parameters
    ----------
    model : Model
        A plain or augmented model.

    Returns
    -------
    Model
        ``model.root`` for an augmented model, else ``model``.
    """
    return model.root if isinstance(model, AugmentedModel) else model


def applied_effects(model: Model) -> tuple:
    """Output/matrix effects applied to ``model`` (empty for a plain model).

    Parameters
    ----------
    model : Model
        A plain or augmented model.

    Returns
    -------
    tuple of Effect
        The applied effects, in order.
    """
    return model.effects if isinstance(model, AugmentedModel) else ()


def _rebuild(model: Model, root: Model, effects: tuple) -> Model:
    """A model with a new root and effect list, keeping every common parameter's value and status."""
    new = AugmentedModel(root=root, effects=effects) if effects else root
    old = {p.name: p for p in model.parameters}
    items = [
        p
        if (q := old.get(p.name)) is None or (q.value, q.free, q.lower, q.upper) == (p.value, p.free, p.lower, p.upper)
        else replace(p, value=q.value, free=q.free, lower=q.lower, upper=q.upper)
        for p in new.parameters
    ]
    if all(a is b for a, b in zip(items, new.parameters.items)):  # nothing to carry over
        return new
    return new.with_parameters(Parameters(tuple(items)))


def _append(model: Model, effect: "Effect") -> Model:
    """``model`` with an output/matrix effect appended; its parameters free at the null."""
    root, effs = root_model(model), applied_effects(model)
    if any(e.key == effect.key for e in effs):
        raise ParameterError(f"effect {effect.key} is already in the model")
    new = _rebuild(model, root, effs + (effect,))
    names = [p.name for p in effect.param_list(root) if not p.nuisance]
    return new.with_parameters(new.parameters.free(names))


def with_gust(model: Model) -> Model:
    """The same model (same parameter values) with a gust input alpha_w added.

    Used for the direction of unmeasured turbulence in output space; returns
    ``model`` itself when it already has a gust input.

    Parameters
    ----------
    model : Model
        A plain or augmented model.

    Returns
    -------
    Model
        The model with the inputs de and alpha_w.
    """
    if model.gust:
        return model
    root, effs = root_model(model), applied_effects(model)
    groot = replace(root, gust=True, parameters=cast(Parameters, None))  # None: the default set (Model.__post_init__)
    groot = groot.with_values({k: v for k, v in root.parameters.values.items() if k in groot.parameters})
    if not effs:
        return groot
    aug = AugmentedModel(root=groot, effects=effs)
    return aug.with_values({k: v for k, v in model.parameters.values.items() if k in aug.parameters})


# --- effect kinds ----------------------------------------------------------------------


class _AppliedEffect(Effect):
    """What output- and matrix-level effects share: a function ``fn`` a model applies to its response.

    The two kinds differ only in where ``fn`` acts (:class:`OutputEffect`: the
    frequency response; :class:`MatrixEffect`: the matrices before the solve);
    both are appended to the model's effects by :meth:`augment`.
    """

    def __init__(
        self,
        name: str,
        channel: str,
        params: Sequence[Param],
        fn: Callable,
        *,
        needs: Sequence[str] = (),
        signature: str = "",
        nuisance_grid: dict | None = None,
        applies: Callable | None = None,
        realize: Callable | None = None,
    ):
        self._describe(name, channel, params, needs, signature)
        self._fn = fn
        self.nuisance_grid = nuisance_grid
        self._applies = applies
        self._realize = realize

    def applicable(self, model, inputs=(INPUT,), outputs=OUTPUTS):
        why = super().applicable(model, inputs, outputs)
        if why is None and self._applies is not None:
            why = self._applies(root_model(model))
        return why

    def augment(self, model: Model) -> Model:
        return _append(model, self)

    def realize(self, target, p, root):
        if self._realize is None:
            return super().realize(target, p, root)
        return self._realize(target, p, root)


class OutputEffect(_AppliedEffect):
    """An effect on the model's frequency response (G, H, P), for any fdml model.

    Parameters
    ----------
    name, channel : str
        Library name and the channel it applies to.
    params : tuple of Param
        The parameters the effect adds.
    fn : callable
        ``fn(s, p, G, H, P, root) -> (G, H, P)``: ``s`` = j omega (n,), ``p``
        all parameter values by name, ``G`` (n, n_y, n_in), ``H`` (n, n_y, n_b) and
        ``P`` (n, n_y, 2), rows in ``root.outputs`` order (alpha, q, a_z first),
        ``root`` the plain base model (for U, the aircraft).
        Must return the inputs unchanged when the effect's parameters are at
        their nulls.
    needs : tuple of str, optional
        Record channels required.
    signature : str, optional
        One line on where the effect shows, for reports.
    nuisance_grid : dict, optional
        ``{param name: grid function}`` for parameters not identified under the null.
    applies : callable, optional
        ``applies(model) -> str | None``: a reason the effect cannot be tested
        on this base model (e.g. no chord for a lift lag), or None.
    realize : callable, optional
        The effect on a realisation, with the signature of :meth:`Effect.realize` (without ``self``).
    factors : callable, optional
        Instead of ``fn``, for an effect that scales outputs and inputs:
        ``factors(s, p, root) -> (rows, columns, added)``, the effect being
        ``G' = rows G columns + added``, ``H' = rows H``, ``P' = rows P``, with
        ``rows`` (n, n_y) per output, ``columns`` (n, n_in) per input and
        ``added`` (n, n_y, n_in) independent of the base model's parameters
        (each None for none).  A model then forms its outputs' derivatives
        without its response's (:meth:`AugmentedModel.forced_sensitivity`).
    """

    def __init__(
        self,
        name: str,
        channel: str,
        params: Sequence[Param],
        fn: Callable | None = None,
        *,
        needs: Sequence[str] = (),
        signature: str = "",
        nuisance_grid: dict | None = None,
        applies: Callable | None = None,
        realize: Callable | None = None,
        factors: Callable | None = None,
    ):
        if (fn is None) == (factors is None):
            raise ParameterError(f"OutputEffect {name!r} needs either fn or factors")
        fn = fn or (lambda *a: _factored(self.factors, *a))
        super().__init__(
            name,
            channel,
            params,
            fn,
            needs=needs,
            signature=signature,
            nuisance_grid=nuisance_grid,
            applies=applies,
            realize=realize,
        )
        self._factors = cast(Callable, factors)  # read only when given (self.factors is not None)
        #: ``factors(s, p, root) -> (rows, columns, added)`` with their shapes checked, or None (``fn`` given).
        self.factors = None if factors is None else self._checked_factors

    def _checked_factors(self, s, p, root) -> tuple:
        """The effect's factors at ``s``, each None or of its shape (else a ParameterError naming the effect)."""
        out = self._factors(s, p, root)
        n, ny, nin = s.size, len(root.outputs), len(root.inputs)
        for what, x, shape in zip(("rows", "columns", "added"), out, ((n, ny), (n, nin), (n, ny, nin))):
            if x is not None and np.shape(x) != shape:
                raise ParameterError(f"effect {self.key}: its factors give {what} of shape {np.shape(x)}, not {shape}")
        return out

    def output(self, s, p, G, H, P, root):
        """Apply the effect to the output matrices at ``s = j omega``; returns ``(G, H, P)``.

        Parameters
        ----------
        s : numpy.ndarray
            The Laplace variable j omega, rad/s, shape (n,).
        p : mapping of str to float
            All parameter values by name.
        G : numpy.ndarray
            Outputs per input, shape (n, n_y, n_in).
        H, P : numpy.ndarray
            Outputs per boundary term and per state-equation forcing, shapes (n, n_y, n_b) and (n, n_y, 2).
        root : Model
            The plain base model.

        Returns
        -------
        G : numpy.ndarray
            Outputs per input with the effect applied, same shape.
        H : numpy.ndarray
            Outputs per boundary term with the effect applied, same shape.
        P : numpy.ndarray
            Outputs per state-equation forcing with the effect applied, same shape.
        """
        return self._fn(s, p, G, H, P, root)


def _factored(factors, s, p, G, H, P, root) -> tuple:
    """(G, H, P) through an effect given by its :attr:`OutputEffect.factors`."""
    rows, cols, added = factors(s, p, root)
    G = G if cols is None else G * cols[:, None, :]
    if rows is not None:
        G, H, P = (x * rows[:, :, None] for x in (G, H, P))
    return (G, H, P) if added is None else (G + added, H, P)


class MatrixEffect(_AppliedEffect):
    """An effect on the short-period matrices (M, B, E) before the solve.

    ``fn(s, p, M, B, E, root) -> (M, B, E)`` with ``M`` (n, 2, 2) = sE - A(s),
    ``B`` (n, 2, n_in) without input delays, ``E`` (2, 2) or (n, 2, 2).

    Parameters
    ----------
    name, channel : str
        Library name and the channel it applies to.
    params : tuple of Param
        The parameters the effect adds.
    fn : callable
        ``fn(s, p, M, B, E, root) -> (M, B, E)``; must return the inputs
        unchanged when the effect's parameters are at their nulls.
    needs : tuple of str, optional
        Record channels required.
    signature : str, optional
        One line on where the effect shows, for reports.
    nuisance_grid : dict, optional
        ``{param name: grid function}`` for parameters not identified under the null.
    applies : callable, optional
        ``applies(model) -> str | None``: a reason the effect cannot be tested, or None.
    realize : callable, optional
        The effect on a realisation, with the signature of :meth:`Effect.realize` (without ``self``).
    """

    #: False for an effect that enters elsewhere (a sensor's station: the output rows) and leaves the matrices
    #: as they are; the root's closed-form matrix derivatives then still hold.
    acts_on_matrices = True

    def matrices(self, s, p, M, B, E, root):
        """Apply the effect to the short-period matrices; returns ``(M, B, E)``.

        Parameters
        ----------
        s : numpy.ndarray
            The Laplace variable j omega, rad/s, shape (n,).
        p : mapping of str to float
            All parameter values by name.
        M : numpy.ndarray
            ``s E - A(s)``, shape (n, 2, 2).
        B : numpy.ndarray
            Input matrix without input delays, shape (n, 2, n_in).
        E : numpy.ndarray
            Matrix multiplying the state derivative, shape (2, 2) or (n, 2, 2).
        root : Model
            The plain base model.

        Returns
        -------
        M : numpy.ndarray
            ``s E - A(s)`` with the effect applied.
        B : numpy.ndarray
            The input matrix with the effect applied.
        E : numpy.ndarray
            The derivative matrix with the effect applied.
        """
        return self._fn(s, p, M, B, E, root)

    def applicable(self, model, inputs=(INPUT,), outputs=OUTPUTS):
        why = super().applicable(model, inputs, outputs)
        if why is None and not hasattr(root_model(model), "_matrices"):
            why = "the base model does not expose its state-space matrices"
        return why


class FreeParameterEffect(Effect):
    """An effect that exists in the base model as a fixed parameter: testing it frees it.

    Parameters
    ----------
    name, channel : str
        Library name and the channel it applies to.
    param : Param
        ``null=None`` takes the null from the base model's value; a number
        sets the parameter to it first (e.g. y_w = 0 on a steady model).
    models : tuple of str
        Base model kinds this applies to.
    convert : callable, optional
        ``convert(root) -> root'``: rewrite the base model first (e.g. steady
        to the unsteady model with every lag off); must be the same model.
    needs : tuple of str, optional
        Record channels required.
    signature : str, optional
        One line on where the effect shows, for reports.
    bounds : tuple of float, optional
        (lower, upper) bounds of the freed parameter, widened to include its null; default the Param's.
    """

    def __init__(
        self,
        name: str,
        channel: str,
        param: Param,
        models: Sequence[str],
        *,
        convert: Callable | None = None,
        needs: Sequence[str] = (),
        signature: str = "",
        bounds: tuple | None = None,
    ):
        self._describe(name, channel, (param,), needs, signature)
        self.models = tuple(models)
        self._convert = convert
        self._bounds = bounds

    def _target_root(self, model: Model) -> Model:
        root = root_model(model)
        return root if self._convert is None else self._convert(root)

    def applicable(self, model, inputs=(INPUT,), outputs=OUTPUTS):
        why = super().applicable(model, inputs, outputs)
        if why is not None:
            return why
        root = root_model(model)
        if root.kind not in self.models:
            return f"not defined for the {root.kind} model"
        name = self.params[0].name
        try:
            troot = self._target_root(model)
        except FdmlError as exc:
            return str(exc)
        if name not in troot.parameters:
            return f"the {root.kind} model has no parameter {name}"
        if name in model.parameters and model.parameters[name].free:
            return f"{name} is already free in the base model"
        return None

    def nulls(self, model: Model) -> dict[str, float]:
        par = self.params[0]
        if par.null is not None:
            return {par.name: float(par.null)}
        vals = model.parameters.values
        if par.name in vals:
            return {par.name: vals[par.name]}
        return {par.name: self._target_root(model).parameters.values[par.name]}

    def augment(self, model: Model) -> Model:
        par = self.params[0]
        troot = self._target_root(model)
        new = _rebuild(model, troot, applied_effects(model))
        null = self.nulls(model)[par.name]
        params = new.parameters.with_values({par.name: null}).free([par.name])
        lo, hi = self._bounds if self._bounds is not None else (par.lower, par.upper)
        if lo != -math.inf or hi != math.inf:
            cur = params[par.name]
            params = params.bound(par.name, min(lo, cur.value), max(hi, cur.value))
        return new.with_parameters(params)


def scale_rows(G, H, P, row: int, factor):
    """Multiply output row ``row`` of G, H and P by ``factor`` (scalar or (n,) array).

    Parameters
    ----------
    G : numpy.ndarray
        Outputs per input, shape (n, n_y, n_in).
    H, P : numpy.ndarray
        Outputs per boundary term and per state-equation forcing, shapes (n, n_y, n_b) and (n, n_y, 2).
    row : int
        The output's row: 0 alpha, 1 q, 2 a_z (then those of ``model.outputs``).
    factor : float or numpy.ndarray
        The factor, a scalar or one per frequency (n,).

    Returns
    -------
    G : numpy.ndarray
        A copy of ``G`` with the row scaled.
    H : numpy.ndarray
        A copy of ``H`` with the row scaled.
    P : numpy.ndarray
        A copy of ``P`` with the row scaled.
    """
    f = np.asarray(factor)
    f = f[:, None] if f.ndim == 1 else f
    out = tuple(x.copy() for x in (G, H, P))
    for x in out:
        x[:, row] = x[:, row] * f
    return out
