"""Candidate effects: nested augmentations of any fdml model, and their registry.

An :class:`Effect` adds one to a few parameters to a base model; at the
parameters' *null* values the augmented model reproduces the base model
exactly (the nesting the likelihood-ratio test needs; tested to machine
precision in ``tests/test_diagnose_effects.py``).  Effects act at one of two
levels:

``"output"``
    on the frequency response ``ModelResponse(omega, G, H, P)`` of the base
    model: sensor effects (delay, scale, position), input filters (actuator
    lag, which scales the elevator column of G), additive paths (a structural
    mode).  They work on every fdml model.
``"matrix"``
    on the matrices ``(M, B, E)`` of the short-period solve
    (:func:`fdml.models.base.solve_short_period`), e.g. a lag on the lift
    derivative or an alpha-dot moment; they need a base model that exposes
    ``_matrices`` (all of fdml's models do).

Effects that already exist as fixed parameters of the base model (the
elevator delay ``tau_de``, Wells-Keskar ``y_w``, ``G``, Kussner ``b1``, the
derivatives model's ``Cm_adot``) are augmentations by *freeing* that
parameter; the quasi-steady Wells-Keskar model is first rewritten as the
unsteady model with every lag switched off, which is the same model
(THEORY.md section 6).

A user adds an effect in a few lines::

    from fdml.diagnose import OutputEffect, Param, register_effect

    def gyro_lag(s, p, G, H, P, model):
        f = 1.0 / (1.0 + s * p["T_gyro"])
        return scale_rows(G, H, P, 1, f)          # row 1 is q

    register_effect(OutputEffect("gyro_lag", "q", (Param("T_gyro", 0.0, lower=0.0,
                    plausible=(0.0, 0.1), unit="s"),), gyro_lag))

Everything here is a pure function of ``s = j omega`` (rad/s) vectorised over
frequency.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from ..errors import FdmlError, ParameterError
from ..parameters import Parameter, Parameters
from .base import Model, ModelResponse

__all__ = [
    "Param",
    "Effect",
    "OutputEffect",
    "MatrixEffect",
    "FreeParameterEffect",
    "AugmentedModel",
    "register_effect",
    "unregister_effect",
    "get_effect",
    "registered_effects",
    "default_library",
    "root_model",
    "applied_effects",
    "with_gust",
    "scale_rows",
    "CHANNELS",
    "resolve_effect",
    "with_effects",
    "assemble",
    "check_effects",
    "confounded_effect_parameters",
    "catalogue",
]

#: Output channels, in the row order of G, H and P.
CHANNELS = ("alpha", "q", "az")


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
    start : float, optional
        A typical non-null size (used for start values and finite-difference
        steps); default 1 % of the plausible range, else 1e-3.
    nuisance : bool, optional
        A parameter that is not identified when the effect is absent (a
        structural mode's frequency and damping): held fixed on a grid for the
        test, then refined continuously (DIAGNOSIS.md 2.6 rule 5).
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
        """A small, typical non-null size (for finite differences and MDE units)."""
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

    Attributes
    ----------
    name : str
        Library name, shared by the variants of one effect.
    channel : str
        Where it applies.
    params : tuple of Param
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

    @property
    def key(self) -> str:
        """Unique id of this variant: ``name@channel``."""
        return f"{self.name}@{self.channel}" if self.channel else self.name

    def applicable(
        self, model: Model, inputs: Sequence[str] = ("de",), outputs: Sequence[str] = CHANNELS
    ) -> str | None:
        """None if the effect can be tested on ``model`` with these channels, else the reason."""
        for need in self.needs:
            if need not in inputs and need not in outputs:
                return f"needs the {need} channel, which the record(s) lack"
        for ch in self.channel.split(","):
            if ch in CHANNELS and ch not in outputs:
                return f"acts on {ch}, which is not among the fitted outputs"
        return None

    def param_list(self, model: Model) -> tuple:
        """The :class:`Param` list for this base model (most effects: :attr:`params`)."""
        return tuple(self.params)

    def augment(self, model: Model) -> Model:  # pragma: no cover - abstract
        """The augmented model, with the new parameters free and at their null."""
        raise NotImplementedError

    def nulls(self, model: Model) -> dict[str, float]:
        """Null values of the effect's parameters on ``model``."""
        out = {}
        vals = model.parameters.values
        for p in self.param_list(model):
            out[p.name] = vals.get(p.name, 0.0) if p.null is None else float(p.null)
        return out

    def simulate(self, t, signals: dict, values: Mapping[str, float], model: Model) -> dict:
        """Apply the effect to noise-free time histories (for truth generation).

        Built-in effects implement it in :mod:`fdml.diagnose.truth`; a user
        effect without a time-domain form cannot be used as a validation truth.
        """
        raise FdmlError(f"effect {self.key} has no time-domain form for validation truths")

    def realize(self, target, p: Mapping[str, float], root: Model):
        """The effect on a time-domain realisation (see :func:`fdml.simulate.realize`).

        Output-level effects act on the state space of the base model
        (``fdml.simulate`` helpers ``delay_output``, ``scale_output``,
        ``mix_output``, ``add_output_rate``, ``filter_input``, ``add_mode``);
        matrix-level effects on its descriptor form
        (:class:`fdml.simulate.Descriptor`) or, on a Wells-Keskar base, on the
        options of its realisation.  An effect without one cannot be simulated.
        """
        raise ParameterError(
            f"effect {self.key} has no time-domain realisation: it can be fitted, "
            "not simulated or exported as a state space"
        )

    def describe(self) -> str:
        """A short description of the effect: its signature, else its key."""
        return self.signature or self.key

    def label(self) -> str:
        """Short name for a model's description: ``alpha time delay (tau_alpha, s)``."""
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
    """

    root: Model = field(default=None)  # type: ignore[assignment]
    effects: tuple = ()
    #: The effects as requested (:meth:`Model.with_effects`), free-parameter ones included; these
    #: describe and serialise the model.  Empty for the diagnosis' internal augmentations.
    requested: tuple = ()

    def __post_init__(self) -> None:
        if not isinstance(self.root, Model) or isinstance(self.root, AugmentedModel):
            raise ParameterError("AugmentedModel needs a plain fdml model as root")
        object.__setattr__(self, "gust", self.root.gust)
        object.__setattr__(self, "output_bias", self.root.output_bias)
        if self.parameters is None:
            items = list(self.root.parameters.items)
            for eff in self.effects:
                for par in eff.param_list(self.root):
                    items.append(
                        Parameter(
                            par.name,
                            0.0 if par.null is None else par.null,
                            free=False,
                            lower=par.lower,
                            upper=par.upper,
                            unit=par.unit,
                            description=par.description or eff.key,
                        )
                    )
            object.__setattr__(self, "parameters", Parameters(tuple(items)))

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
        return super().sensitivity(omega, values, names, parts)

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

    def _matrices(self, s, p):
        M, B, E = self.root._matrices(s, self._root_values(p))
        for eff in self.effects:
            if isinstance(eff, MatrixEffect):
                M, B, E = eff.matrices(s, p, M, B, E, self.root)
        return M, B, E

    def evaluate(self, omega, values: Mapping[str, float] | None = None) -> ModelResponse:
        """:meth:`Model.evaluate` (its ``_matrices`` apply the matrix-level effects), then the output-level ones."""
        r = Model.evaluate(self, omega, values)  # input delays and the solve: written once, in Model
        p = self.values(values)
        s = 1j * r.omega
        G, H, P = r.G, r.H, r.P
        for eff in self.effects:
            if isinstance(eff, OutputEffect):
                G, H, P = eff.output(s, p, G, H, P, self.root)
        return ModelResponse(omega, G, H, P)

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        return self.root.derived(self._root_values(self.values(values)))

    def describe(self) -> str:
        """The model by its parts: ``dimensional model (...) + alpha time delay (tau_alpha, s) + ...``."""
        return " + ".join([self.root.describe()] + [e.label() for e in self.parts])

    def __repr__(self) -> str:
        return f"<fdml model: {self.describe()}>"


def root_model(model: Model) -> Model:
    """The plain fdml model under any augmentation."""
    return model.root if isinstance(model, AugmentedModel) else model


def applied_effects(model: Model) -> tuple:
    """Output/matrix effects applied to ``model`` (empty for a plain model)."""
    return model.effects if isinstance(model, AugmentedModel) else ()


def _rebuild(model: Model, root: Model, effects: tuple) -> Model:
    """A model with a new root and effect list, keeping every common parameter's value and status."""
    if not effects:
        new = root
    else:
        new = AugmentedModel(root=root, effects=effects)
    old = {p.name: p for p in model.parameters}
    items = []
    for p in new.parameters:
        q = old.get(p.name)
        if q is None or (q.value, q.free, q.lower, q.upper) == (p.value, p.free, p.lower, p.upper):
            items.append(p)
        else:
            items.append(replace(p, value=q.value, free=q.free, lower=q.lower, upper=q.upper))
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
    """
    if model.gust:
        return model
    root, effs = root_model(model), applied_effects(model)
    groot = replace(root, gust=True, parameters=cast(Parameters, None))  # None: the default set (Model.__post_init__)
    vals = root.parameters.values
    common = {k: v for k, v in vals.items() if k in groot.parameters}
    groot = groot.with_values(common)
    if not effs:
        return groot
    aug = AugmentedModel(root=groot, effects=effs)
    ev = model.parameters.values
    return aug.with_values({k: v for k, v in ev.items() if k in aug.parameters})


# --- effect kinds ----------------------------------------------------------------------


class OutputEffect(Effect):
    """An effect on the model's frequency response (G, H, P), for any fdml model.

    Parameters
    ----------
    name, channel : str
    params : tuple of Param
    fn : callable
        ``fn(s, p, G, H, P, root) -> (G, H, P)``: ``s`` = j omega (n,), ``p``
        all parameter values by name, ``G`` (n, 3, n_in), ``H`` and ``P``
        (n, 3, 2), ``root`` the plain base model (for U, the aircraft).
        Must return the inputs unchanged when the effect's parameters are at
        their nulls.
    needs : tuple of str, optional
    signature : str, optional
    nuisance_grid : dict, optional
    applies : callable, optional
        ``applies(model) -> str | None``: a reason the effect cannot be tested
        on this base model (e.g. no chord for a lift lag), or None.
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
        simulate: Callable | None = None,
        realize: Callable | None = None,
    ):
        self._realize = realize
        self.name = name
        self.channel = channel
        self.params = tuple(params)
        self._fn = fn
        self.needs = tuple(needs)
        self.signature = signature
        self.nuisance_grid = nuisance_grid
        self._applies = applies
        self._simulate = simulate

    def output(self, s, p, G, H, P, root):
        """Apply the effect to the output matrices at ``s = j omega``; returns ``(G, H, P)``."""
        return self._fn(s, p, G, H, P, root)

    def applicable(self, model, inputs=("de",), outputs=CHANNELS):
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

    def simulate(self, t, signals, values, model):
        if self._simulate is None:
            return super().simulate(t, signals, values, model)
        return self._simulate(t, signals, values, model)


class MatrixEffect(OutputEffect):
    """An effect on the short-period matrices (M, B, E) before the solve.

    ``fn(s, p, M, B, E, root) -> (M, B, E)`` with ``M`` (n, 2, 2) = sE - A(s),
    ``B`` (n, 2, n_in) without input delays, ``E`` (2, 2) or (n, 2, 2).
    """

    def matrices(self, s, p, M, B, E, root):
        """Apply the effect to the short-period matrices; returns ``(M, B, E)``."""
        return self._fn(s, p, M, B, E, root)

    def output(self, s, p, G, H, P, root):  # pragma: no cover - never called for matrix effects
        """Leave the outputs unchanged: a matrix effect acts through :meth:`matrices`."""
        return G, H, P

    def applicable(self, model, inputs=("de",), outputs=CHANNELS):
        why = super().applicable(model, inputs, outputs)
        if why is None and not hasattr(root_model(model), "_matrices"):
            why = "the base model does not expose its state-space matrices"
        return why


class FreeParameterEffect(Effect):
    """An effect that exists in the base model as a fixed parameter: testing it frees it.

    Parameters
    ----------
    name, channel : str
    param : Param
        ``null=None`` takes the null from the base model's value; a number
        sets the parameter to it first (e.g. y_w = 0 on a steady model).
    models : tuple of str
        Base model kinds this applies to.
    convert : callable, optional
        ``convert(root) -> root'``: rewrite the base model first (e.g. steady
        to the unsteady model with every lag off); must be the same model.
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
        simulate: Callable | None = None,
        bounds: tuple | None = None,
    ):
        self.name = name
        self.channel = channel
        self.params = (param,)
        self.models = tuple(models)
        self._convert = convert
        self.needs = tuple(needs)
        self.signature = signature
        self._simulate = simulate
        self._bounds = bounds

    def _target_root(self, model: Model) -> Model:
        root = root_model(model)
        if self._convert is not None:
            root = self._convert(root)
        return root

    def applicable(self, model, inputs=("de",), outputs=CHANNELS):
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

    def simulate(self, t, signals, values, model):
        if self._simulate is None:
            return super().simulate(t, signals, values, model)
        return self._simulate(t, signals, values, model)


def scale_rows(G, H, P, row: int, factor):
    """Multiply output row ``row`` of G, H and P by ``factor`` (scalar or (n,) array)."""
    f = np.asarray(factor)
    f = f[:, None] if f.ndim == 1 else f
    G = G.copy()
    H = H.copy()
    P = P.copy()
    G[:, row] = G[:, row] * f
    H[:, row] = H[:, row] * f
    P[:, row] = P[:, row] * f
    return G, H, P


# --- effects as parts of a model ----------------------------------------------------------

#: Channel spellings accepted in effect keys, and the channel they mean.
_CHANNEL_ALIASES = {"a_z": "az", "alpha_g": "alpha_w", "elevator": "de"}


def resolve_effect(spec, model: Model | None = None) -> Effect:
    """The registered effect named by ``spec``: an :class:`Effect`, ``NAME``, ``NAME:CHANNEL`` or ``NAME@CHANNEL``.

    ``NAME`` alone is enough when the effect has one variant (``actuator_lag``)
    or, given ``model``, one variant defined for it.

    Raises
    ------
    ParameterError
        An unknown name (the known ones are listed) or channel, or an
        ambiguous name.
    """
    if isinstance(spec, Effect):
        return spec
    if not isinstance(spec, str) or not spec.strip():
        raise ParameterError(f"an effect is NAME, NAME:CHANNEL or an Effect, got {spec!r}")
    text = spec.strip().replace(":", "@", 1)
    name, _, channel = text.partition("@")
    channel = ",".join(_CHANNEL_ALIASES.get(c.strip(), c.strip()) for c in channel.split(",")) if channel else ""
    variants = [e for e in registered_effects() if e.name == name]
    if not variants:
        names = sorted(dict.fromkeys(e.name for e in registered_effects()))
        raise ParameterError(f"unknown effect {spec!r}; known effects: {', '.join(names)}")
    if channel:
        for e in variants:
            if e.channel == channel or set(e.channel.split(",")) == set(channel.split(",")):
                return e
        raise ParameterError(
            f"effect {name} has no channel {channel!r}; its channels: {', '.join(e.channel for e in variants)}"
        )
    if len(variants) > 1 and model is not None:
        usable = [e for e in variants if e.applicable(model, model.inputs, CHANNELS) is None]
        variants = usable if len(usable) == 1 else variants
    if len(variants) > 1:
        raise ParameterError(
            f"effect {name} acts on one of {', '.join(e.channel for e in variants)}: give {name}:CHANNEL"
        )
    return variants[0]


def with_effects(model: Model, effects) -> Model:
    """``model`` plus ``effects`` (keys or :class:`Effect` objects), each free at its null value.

    The result describes itself by its parts and serialises as its base kind
    plus its effects (:func:`fdml.models.model_to_dict`).

    Raises
    ------
    ParameterError
        An unknown or ambiguous effect, one not defined for this model (the
        reason from :meth:`Effect.applicable`), a noise-kind effect (it is
        not a part of the response) or an effect given twice.
    """
    specs = [effects] if isinstance(effects, (str, Effect)) else list(effects or ())
    parts = list(model.parts) if isinstance(model, AugmentedModel) else []
    for spec in specs:
        eff = resolve_effect(spec, model)
        if eff.kind != "deterministic":
            raise ParameterError(
                f"effect {eff.key} is a noise model tested by fdml diagnose, not a part of the model's response"
            )
        if any(e.key == eff.key for e in parts):
            raise ParameterError(f"effect {eff.key} is already in the model")
        why = eff.applicable(model, model.inputs, CHANNELS)
        if why is not None:
            raise ParameterError(f"effect {eff.key} on the {root_model(model).kind} model: {why}")
        impl = eff.impl(model) if hasattr(eff, "impl") else eff  # a Dispatch: the variant for this model
        model = eff.augment(model)
        parts.append(impl)
    if not parts:
        return model
    return AugmentedModel(
        root=root_model(model), effects=applied_effects(model), requested=tuple(parts), parameters=model.parameters
    )


def assemble(root: Model, keys: Sequence[str]) -> Model:
    """The model ``root`` + the effects ``keys`` as saved (parameters set by the caller).

    The inverse of the ``kind``/``effects`` pair of :func:`fdml.models.model_to_dict`:
    ``root`` is the saved base model (already converted, e.g. steady to
    unsteady, by any free-parameter effect), so free-parameter effects are
    only recorded here and output/matrix effects are applied in order.
    """
    parts, applied = [], []
    for key in keys:
        eff = resolve_effect(key, root)
        impl = eff.impl(root) if hasattr(eff, "impl") else eff
        if impl is None:
            raise ParameterError(f"effect {eff.key} is not defined for the {root.kind} model")
        parts.append(impl)
        if isinstance(impl, OutputEffect):
            applied.append(impl)
    if not parts:
        return root
    return AugmentedModel(root=root, effects=tuple(applied), requested=tuple(parts))


def check_effects(model: Model, outputs: Sequence[str], inputs: Sequence[str] | None = None) -> None:
    """Refuse a model whose requested effects act on channels the fit does not have.

    Raises
    ------
    ParameterError
        One line naming the effect and the missing channel.
    """
    inputs = model.inputs if inputs is None else inputs
    for eff in getattr(model, "requested", ()):
        why = Effect.applicable(eff, model, inputs, outputs)  # channels and needs only
        if why is not None:
            raise ParameterError(
                f"effect {eff.key} {why} (outputs: {','.join(outputs)}); "
                "add the channel to the outputs or drop the effect"
            )


def confounded_effect_parameters(model: Model, omega, outputs: Sequence[str], tol: float = 1e-5) -> list:
    """Free effect parameters whose sensitivity lies in the span of the other free parameters'.

    Such a parameter is not identifiable with these outputs: any value of it is
    matched by a change of the others (e.g. an alpha-vane offset with alpha and
    q alone is a change of state coordinates that the derivatives absorb).  At
    exact confounding the normalised residual is the finite-difference error of
    the sensitivities (about 1e-9); an identifiable effect leaves O(0.1).

    Returns
    -------
    list of (str, str, float)
        (effect key, parameter, residual norm / column norm).
    """
    if not isinstance(model, AugmentedModel) or not model.requested:
        return []
    rows = [CHANNELS.index(o) for o in outputs]
    free = [n for n in model.parameters.free_names if not n.startswith("bias_")]
    if not free:  # every parameter fixed (a prediction): nothing to confound
        return []
    _, dG, _, _ = model.sensitivity(omega, None, free, parts=("G",))
    J = dG[:, :, rows, :].reshape(len(free), -1)
    J = np.concatenate([J.real, J.imag], axis=1).T  # (data, parameters)
    J = J / np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    out = []
    for eff in model.requested:
        for par in eff.param_list(model.root):
            if par.name not in free:
                continue
            k = free.index(par.name)
            others = np.delete(J, k, axis=1)
            coef = np.linalg.lstsq(others, J[:, k], rcond=None)[0] if others.size else np.zeros(0)
            res = float(np.linalg.norm(J[:, k] - others @ coef))
            if res < tol:
                out.append((eff.key, par.name, res))
    return out


def catalogue() -> list[dict]:
    """Every registered effect: key, channel(s), kind, signature and, per base model, its parameters."""
    from . import MODEL_KINDS

    out = []
    for eff in registered_effects():
        impls = getattr(eff, "impls", None)
        per = (
            impls
            if impls is not None
            else {k: eff for k in MODEL_KINDS if not hasattr(eff, "models") or k in eff.models}
        )
        params = {}
        for kind, imp in per.items():
            params[kind] = [
                {
                    "name": p.name,
                    "unit": p.unit,
                    "null": p.null,
                    "lower": p.lower,
                    "upper": p.upper,
                    "plausible": list(p.plausible) if p.plausible else None,
                    "nuisance": p.nuisance,
                    "description": p.description,
                }
                for p in imp.params
            ]
        out.append(
            {
                "key": eff.key,
                "name": eff.name,
                "channel": eff.channel,
                "kind": eff.kind,
                "needs": list(eff.needs),
                "signature": eff.signature,
                "models": list(per),
                "parameters": params,
            }
        )
    return out


# --- registry ---------------------------------------------------------------------------

_REGISTRY: dict[str, Effect] = {}


def register_effect(effect: Effect, *, replace_existing: bool = False) -> Effect:
    """Add an effect to the library used by :func:`fdml.diagnose.diagnose`.

    Parameters
    ----------
    effect : Effect
        An :class:`OutputEffect`, :class:`MatrixEffect`,
        :class:`FreeParameterEffect` or your own subclass.
    replace_existing : bool, optional
        Allow replacing an effect with the same ``name@channel`` key.

    Returns
    -------
    Effect
        ``effect`` (so the call can be used as an expression).
    """
    if not isinstance(effect, Effect):
        raise ParameterError(f"register_effect needs an Effect, got {type(effect).__name__}")
    if effect.kind not in ("deterministic", "noise"):
        raise ParameterError(f"effect kind must be 'deterministic' or 'noise', got {effect.kind!r}")
    if effect.key in _REGISTRY and not replace_existing:
        raise ParameterError(f"an effect {effect.key} is already registered (replace_existing=True to swap)")
    names = [p.name for p in effect.params]
    if len(set(names)) != len(names) or not names and effect.kind == "deterministic":
        raise ParameterError(f"effect {effect.key} needs distinct parameter names")
    _REGISTRY[effect.key] = effect
    return effect


def unregister_effect(key: str) -> None:
    """Remove a registered effect by its ``name@channel`` key."""
    _REGISTRY.pop(key, None)


def get_effect(key: str) -> Effect:
    """A registered effect by ``name@channel`` key."""
    _ensure_builtins()
    try:
        return _REGISTRY[key]
    except KeyError:
        raise ParameterError(f"unknown effect {key!r}; registered: {', '.join(_REGISTRY)}") from None


def registered_effects() -> tuple:
    """Every registered effect, in registration order."""
    _ensure_builtins()
    return tuple(_REGISTRY.values())


def default_library(names: Sequence[str] | None = None) -> tuple:
    """The registered effects, optionally only those whose name or key is in ``names``."""
    effs = registered_effects()
    if names is None:
        return effs
    wanted = set(names)
    out = tuple(e for e in effs if e.name in wanted or e.key in wanted)
    unknown = wanted - {e.name for e in out} - {e.key for e in out}
    if unknown:
        raise ParameterError(f"unknown effect(s) {sorted(unknown)}; known: {', '.join(sorted({e.name for e in effs}))}")
    return out


def _ensure_builtins() -> None:
    from . import effect_library  # noqa: F401  (registers the built-in effects on import)
