"""fdml models: each gives G(j omega, theta) for outputs (alpha, q, a_z).

=============  =========================================================
kind           model
=============  =========================================================
unsteady       Wells-Keskar, docs/theory.md Eqs. 13-17 (+ Kussner gust lag)
steady         its quasi-steady limit (N = a, E = deps_da, K = 1)
derivatives    six non-dimensional derivatives (+ optional alpha-dot)
dimensional    Z_a, Z_q, Z_de, M_a, M_q, M_de (records without geometry)
=============  =========================================================
"""

from __future__ import annotations

from ..aircraft import Aircraft, load_aircraft
from ..errors import ParameterError
from .base import OUTPUTS, Model, ModelResponse, solve_short_period
from .conventional import DerivativesModel, DimensionalModel, to_dimensional
from .wells_keskar import SteadyModel, UnsteadyModel, alternate_set

MODEL_KINDS = {
    "unsteady": UnsteadyModel,
    "steady": SteadyModel,
    "derivatives": DerivativesModel,
    "dimensional": DimensionalModel,
}


def make_model(kind: str, aircraft: Aircraft | str | None = None, *, effects=(), **options) -> Model:
    """Build a model by name.

    Parameters
    ----------
    kind : {"unsteady", "steady", "derivatives", "dimensional"}
    aircraft : Aircraft or str, optional
        An :class:`~fdml.aircraft.Aircraft`, a preset name or a JSON file path.
        Required except for ``dimensional`` given ``airspeed=``.
    effects : sequence, optional
        Effects made part of the model (``"time_delay:alpha"``,
        ``"sensor_offset@az"``, ``"actuator_lag"`` or Effect objects), each
        free at its null value; ``fdml effects`` lists them.
    **options
        Model options (``gust``, ``output_bias``, ``adot``, ``airspeed``,
        ``tail_lag_chord``, ``gust_lag``, ``tail_gust_delay``).

    Returns
    -------
    Model
    """
    try:
        cls = MODEL_KINDS[kind]
    except KeyError:
        raise ParameterError(f"unknown model {kind!r}; models: {', '.join(MODEL_KINDS)}") from None
    if aircraft is not None:
        aircraft = load_aircraft(aircraft)
    try:
        model = cls(aircraft=aircraft, **options)
    except TypeError as exc:
        raise ParameterError(f"bad option for the {kind} model: {exc}") from None
    return model.with_effects(effects) if effects else model


__all__ = [
    "OUTPUTS",
    "Model",
    "ModelResponse",
    "MODEL_KINDS",
    "make_model",
    "solve_short_period",
    "UnsteadyModel",
    "SteadyModel",
    "DerivativesModel",
    "DimensionalModel",
    "alternate_set",
    "to_dimensional",
]


def model_to_dict(model: Model) -> dict:
    """JSON-ready description of a model: base kind, options, aircraft, effects, parameters.

    A model with effects is saved as its base model's kind and options plus
    the effect keys (``"time_delay@alpha"``) in order; the parameters are the
    whole set, the effects' included.
    """
    import dataclasses

    from .effects import AugmentedModel

    base = model.root if isinstance(model, AugmentedModel) else model
    if isinstance(model, AugmentedModel) and not model.requested:
        raise ParameterError(
            f"{model.describe()}: built by the diagnosis, not with_effects; "
            "rebuild it with model.with_effects(...) to save it"
        )
    opts = {}
    for f in dataclasses.fields(base):
        if f.name in ("aircraft", "parameters"):
            continue
        opts[f.name] = getattr(base, f.name)
    ac = getattr(base, "aircraft", None)
    out = {
        "kind": base.kind,
        "options": opts,
        "aircraft": None if ac is None else ac.to_dict(),
        "parameters": model.parameters.to_list(),
    }
    if model.parts:
        out["effects"] = [e.key for e in model.parts]
    return out


def model_from_dict(d: dict) -> Model:
    """Inverse of :func:`model_to_dict`."""
    from ..parameters import Parameters
    from .effects import assemble

    ac = None if d.get("aircraft") is None else Aircraft.from_dict(d["aircraft"], origin="saved model")
    model = assemble(make_model(d["kind"], ac, **d.get("options", {})), d.get("effects") or ())
    roles = {p.name: p.role.value for p in model.parameters}  # the model knows its parameters' roles
    return model.with_parameters(
        Parameters.from_list({**p, "role": roles.get(p["name"]) or p.get("role", "aero")} for p in d["parameters"])
    )


__all__ += ["model_to_dict", "model_from_dict"]
