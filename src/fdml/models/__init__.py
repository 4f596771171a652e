"""fdml models: each gives G(j omega, theta) for outputs (alpha, q, a_z[, theta, q_dot]).

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

from ..aircraft import Aircraft
from ..errors import ParameterError
from .base import OUTPUTS, DescriptorModel, Model, ModelResponse, solve_short_period
from .build import make_model
from .conventional import DerivativesModel, DimensionalModel, to_dimensional
from .effects import AugmentedModel, assemble, with_effects
from .kinds import MODEL_KINDS
from .realization import realize
from .wells_keskar import SteadyModel, UnsteadyModel, alternate_set

__all__ = [
    "OUTPUTS",
    "Model",
    "DescriptorModel",
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
    "with_effects",
    "realize",
]


def model_to_dict(model: Model) -> dict:
    """JSON-ready description of a model: base kind, options, aircraft, effects, parameters.

    A model with effects is saved as its base model's kind and options plus
    the effect keys (``"time_delay@alpha"``) in order; the parameters are the
    whole set, the effects' included.

    Parameters
    ----------
    model : Model
        The model.

    Returns
    -------
    dict
        JSON-ready.
    """
    import dataclasses

    base = model.root if isinstance(model, AugmentedModel) else model
    if isinstance(model, AugmentedModel) and not model.requested:
        raise ParameterError(
            f"{model.describe()}: built by the diagnosis, not with_effects; "
            "rebuild it with fdml.with_effects(model, ...) to save it"
        )
    opts = {}
    for f in dataclasses.fields(base):
        if f.name in ("aircraft", "parameters") or (f.name == "outputs" and base.outputs == OUTPUTS):
            continue  # the default outputs are not written: the files of three-output models stay as they were
        opts[f.name] = list(base.outputs) if f.name == "outputs" else getattr(base, f.name)
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
    """Inverse of :func:`model_to_dict`.

    Parameters
    ----------
    d : dict
        A dict as written by :func:`model_to_dict`.

    Returns
    -------
    Model
        The model, its parameters and effects as saved.
    """
    from ..parameters import Parameters

    ac = None if d.get("aircraft") is None else Aircraft.from_dict(d["aircraft"], origin="saved model")
    model = assemble(make_model(d["kind"], ac, **d.get("options", {})), d.get("effects") or ())
    roles = {p.name: p.role.value for p in model.parameters}  # the model knows its parameters' roles
    return model.with_parameters(
        Parameters.from_list({**p, "role": roles.get(p["name"]) or p.get("role", "aero")} for p in d["parameters"])
    )


__all__ += ["model_to_dict", "model_from_dict"]
