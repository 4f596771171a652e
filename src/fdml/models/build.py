"""A model by kind, with its aircraft's known sensors and any effects: :func:`make_model`.

Above :mod:`fdml.models.effects` (a model is built with effects) and :mod:`fdml.models.kinds`
(the kinds by name).
"""

from __future__ import annotations

from ..aircraft import Aircraft, load_aircraft
from ..channels import STATIONS
from ..errors import ParameterError
from .base import Model
from .effects import with_effects
from .kinds import MODEL_KINDS

__all__ = ["make_model", "known_sensors"]


def make_model(kind: str, aircraft: Aircraft | str | None = None, *, effects=(), **options) -> Model:
    """Build a model by name.

    Parameters
    ----------
    kind : {"unsteady", "steady", "derivatives", "dimensional"}
        The model: Wells-Keskar unsteady or steady, non-dimensional
        derivatives, or dimensional derivatives.
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
        The model, with its default parameter set and the effects free at their nulls; the
        aircraft's known sensor positions (its ``sensors`` entry) come first, as fixed
        ``sensor_offset`` effects.
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
    model = known_sensors(model)
    return with_effects(model, effects) if effects else model


def known_sensors(model: Model) -> Model:
    """``model`` with its aircraft's known sensor positions applied: fixed ``sensor_offset`` effects.

    Parameters
    ----------
    model : Model
        A model whose aircraft may give ``sensors`` (:class:`~fdml.aircraft.Aircraft`).

    Returns
    -------
    Model
        The model, unchanged without known positions.
    """
    sensors = getattr(getattr(model, "aircraft", None), "sensors", None) or {}
    if not sensors:
        return model
    m = with_effects(model, [f"sensor_offset:{ch}" for ch in sensors])
    return m.fix({STATIONS[ch]: float(pos["x"]) for ch, pos in sensors.items()})
