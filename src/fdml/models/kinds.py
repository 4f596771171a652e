"""The model kinds by name (:data:`MODEL_KINDS`).

Below :mod:`fdml.models.effects` and the effect library, which build models
by kind; :func:`fdml.models.build.make_model` builds one with its effects.
"""

from __future__ import annotations

from .conventional import DerivativesModel, DimensionalModel
from .wells_keskar import SteadyModel, UnsteadyModel

__all__ = ["MODEL_KINDS"]

MODEL_KINDS = {
    "unsteady": UnsteadyModel,
    "steady": SteadyModel,
    "derivatives": DerivativesModel,
    "dimensional": DimensionalModel,
}
