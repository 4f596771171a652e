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
(docs/theory.md section 6).

A user adds an effect in a few lines::

    from fdml.models.effects import OutputEffect, Param, register_effect, scale_rows

    def gyro_lag(s, p, G, H, P, model):
        f = 1.0 / (1.0 + s * p["T_gyro"])
        return scale_rows(G, H, P, 1, f)          # row 1 is q

    register_effect(OutputEffect("gyro_lag", "q", (Param("T_gyro", 0.0, lower=0.0,
                    plausible=(0.0, 0.1), unit="s"),), gyro_lag))

An effect that scales outputs or inputs (or adds a response of its own parameters) can say so
with ``factors`` instead of ``fn``; a fit then forms its sensitivities without the response's
derivatives (for the built-in delays and lags, about a third of the time: 0.26 ms, not 0.84)::

    def gyro_factors(s, p, model):
        rows = np.ones((s.size, len(model.outputs)), complex)
        rows[:, 1] = 1.0 / (1.0 + s * p["T_gyro"])  # q's row scaled
        return rows, None, None                       # no input scaled, nothing added

    OutputEffect("gyro_lag", "q", (Param("T_gyro", ...),), factors=gyro_factors)

Everything here is a pure function of ``s = j omega`` (rad/s) vectorised over
frequency.  This module is the effects' one public home: the classes, defined in
:mod:`fdml.models.augment` below the library, are published here beside the registry, which it
fills from the built-in effects of :mod:`fdml.models.effect_library` once, at import.  Each
built-in effect's validation truth is simulated independently of its code, on purpose, in
:mod:`fdml.diagnose.truth` (see :class:`Effect`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..channels import OUTPUTS
from ..errors import ParameterError
from .augment import (
    AugmentedModel,
    Effect,
    FreeParameterEffect,
    MatrixEffect,
    OutputEffect,
    Param,
    applied_effects,
    root_model,
    scale_rows,
    with_gust,
)
from .base import Model
from .effect_library import BUILTINS
from .kinds import MODEL_KINDS

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
    "register_effect",
    "unregister_effect",
    "get_effect",
    "registered_effects",
    "default_library",
    "resolve_effect",
    "with_effects",
    "assemble",
    "check_effects",
    "confounded_effect_parameters",
    "catalogue",
]


# --- effects as parts of a model ----------------------------------------------------------

#: Channel spellings accepted in effect keys, and the channel they mean.
_CHANNEL_ALIASES = {"a_z": "az", "alpha_g": "alpha_w", "elevator": "de"}


def resolve_effect(spec, model: Model | None = None) -> Effect:
    """The registered effect named by ``spec``: an :class:`Effect`, ``NAME``, ``NAME:CHANNEL`` or ``NAME@CHANNEL``.

    ``NAME`` alone is enough when the effect has one variant (``actuator_lag``)
    or, given ``model``, one variant defined for it.

    Parameters
    ----------
    spec : Effect or str
        The effect or its name/key.
    model : Model, optional
        The model, to choose among the variants of a bare ``NAME``.

    Returns
    -------
    Effect
        The registered effect (``spec`` itself when it is one).

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
        usable = [e for e in variants if e.applicable(model, model.inputs, OUTPUTS) is None]
        variants = usable if len(usable) == 1 else variants
    if len(variants) > 1:
        raise ParameterError(
            f"effect {name} acts on one of {', '.join(e.channel for e in variants)}: give {name}:CHANNEL"
        )
    return variants[0]


def with_effects(model: Model, *effects) -> Model:
    """``model`` plus ``effects`` (keys or :class:`Effect` objects), each free at its null value.

    ``with_effects(model, "time_delay:alpha", "sensor_offset:az")``; sequences of them are
    flattened, so ``with_effects(model, ["time_delay:alpha"])`` is the same.  The result
    describes itself by its parts and serialises as its base kind plus its effects
    (:func:`fdml.models.model_to_dict`).

    Parameters
    ----------
    model : Model
        The base model (plain or already augmented).
    *effects : str or Effect, or sequences of them
        Effect keys (``NAME``, ``NAME:CHANNEL``, ``NAME@CHANNEL``) or objects, in order.

    Returns
    -------
    Model
        The augmented model (``model`` itself when no effect is given).

    Raises
    ------
    ParameterError
        An unknown or ambiguous effect, one not defined for this model (the
        reason from :meth:`Effect.applicable`), a noise-kind effect (it is
        not a part of the response) or an effect given twice.
    """
    specs = [
        e for item in effects for e in ([item] if isinstance(item, str) or not hasattr(item, "__iter__") else item)
    ]
    parts = list(model.parts) if isinstance(model, AugmentedModel) else []
    for spec in specs:
        eff = resolve_effect(spec, model)
        if eff.kind != "deterministic":
            raise ParameterError(
                f"effect {eff.key} is a noise model tested by fdml diagnose, not a part of the model's response"
            )
        if any(e.key == eff.key for e in parts):
            raise ParameterError(f"effect {eff.key} is already in the model")
        why = eff.applicable(model, model.inputs, OUTPUTS)
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

    Parameters
    ----------
    root : Model
        The saved base model.
    keys : sequence of str
        The saved effect keys, in order.

    Returns
    -------
    Model
        The model with the effects (``root`` itself without any).
    """
    parts, applied = [], []
    for key in keys:
        eff = resolve_effect(key, root)
        impl = eff.impl(root) if hasattr(eff, "impl") else eff
        if impl is None:
            raise ParameterError(f"effect {eff.key} is not defined for the {root.kind} model")
        parts.append(impl)
        if isinstance(impl, (OutputEffect, MatrixEffect)):  # applied; a freed parameter is in root
            applied.append(impl)
    if not parts:
        return root
    return AugmentedModel(root=root, effects=tuple(applied), requested=tuple(parts))


def check_effects(model: Model, outputs: Sequence[str], inputs: Sequence[str] | None = None) -> None:
    """Refuse a model whose requested effects act on channels the fit does not have.

    Parameters
    ----------
    model : Model
        The model to fit.
    outputs : sequence of str
        The fitted outputs.
    inputs : sequence of str, optional
        The records' inputs (default the model's).

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

    Parameters
    ----------
    model : Model
        The model (a plain one has no effect parameters: ``[]``).
    omega : array_like
        Frequencies, rad/s.
    outputs : sequence of str
        The fitted outputs.
    tol : float, optional
        Normalised residual below which a parameter counts as confounded.

    Returns
    -------
    list of (str, str, float)
        (effect key, parameter, residual norm / column norm).
    """
    if not isinstance(model, AugmentedModel) or not model.requested:
        return []
    rows = [model.outputs.index(o) for o in outputs]
    free = list(model.parameters.free_model_names)
    if not free:  # every parameter fixed (a prediction): nothing to confound
        return []
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    unit = np.eye(len(model.inputs), dtype=complex)  # dG column by column: the outputs' derivatives per input
    dG = np.stack([model.forced_sensitivity(omega, None, free, np.tile(e, (omega.size, 1)))[1] for e in unit], -1)
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
    """Every registered effect: key, channel(s), kind, signature and, per base model, its parameters.

    Returns
    -------
    list of dict
        One dict per registered effect, in registration order.
    """
    out = []
    for eff in registered_effects():
        per = getattr(eff, "impls", None)
        if per is None:
            per = {k: eff for k in MODEL_KINDS if not hasattr(eff, "models") or k in eff.models}
        params = {
            kind: [
                {
                    **{f: getattr(p, f) for f in _CATALOGUE_FIELDS},
                    "plausible": list(p.plausible) if p.plausible else None,
                }
                for p in imp.params
            ]
            for kind, imp in per.items()
        }
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


#: The fields of a :class:`Param` in :func:`catalogue`, in order.
_CATALOGUE_FIELDS = ("name", "unit", "null", "lower", "upper", "plausible", "nuisance", "description")


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
    """Remove a registered effect by its ``name@channel`` key.

    Parameters
    ----------
    key : str
        The effect's key.
    """
    _REGISTRY.pop(key, None)


def get_effect(key: str) -> Effect:
    """A registered effect by ``name@channel`` key.

    Parameters
    ----------
    key : str
        The effect's key.

    Returns
    -------
    Effect
        The effect.
    """
    try:
        return _REGISTRY[key]
    except KeyError:
        raise ParameterError(f"unknown effect {key!r}; registered: {', '.join(_REGISTRY)}") from None


def registered_effects() -> tuple:
    """Every registered effect, in registration order.

    Returns
    -------
    tuple of Effect
        The effects.
    """
    return tuple(_REGISTRY.values())


def default_library(names: Sequence[str] | None = None) -> tuple:
    """The registered effects, optionally only those whose name or key is in ``names``.

    Parameters
    ----------
    names : sequence of str, optional
        Effect names or keys; default all.

    Returns
    -------
    tuple of Effect
        The effects, in registration order.
    """
    effs = registered_effects()
    if names is None:
        return effs
    wanted = set(names)
    out = tuple(e for e in effs if e.name in wanted or e.key in wanted)
    unknown = wanted - {e.name for e in out} - {e.key for e in out}
    if unknown:
        raise ParameterError(f"unknown effect(s) {sorted(unknown)}; known: {', '.join(sorted({e.name for e in effs}))}")
    return out


# The registry's one filling: the built-in library, checked like any user's effect.
for _effect in BUILTINS:
    register_effect(_effect)
