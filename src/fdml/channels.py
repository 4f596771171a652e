"""The one registry of fdml's channels, their units and the record formats.

Every module that names a channel, a channel's unit or a record format takes it
from here, so that the output order (the row order of G, H and P, docs/theory.md
Eq. 5), the units a record is held in and the formats the readers accept are
written once.  Units are fdml's SI units (radians, rad/s, and standard gravity
``g`` for the specific forces, docs/theory.md Eq. 5); :data:`DISPLAY_UNITS` gives the
unit a person reads a channel in (degrees for angles and rates) and the factor
from the SI value to it.
"""

from __future__ import annotations

import math

__all__ = [
    "OUTPUTS",
    "INPUT",
    "GUST",
    "INPUTS",
    "REQUIRED",
    "SIGNALS",
    "CONDITION_UNITS",
    "DISPLAY_UNITS",
    "display_unit",
    "FORMATS",
]

#: Output channels of every model, in the row order of G, H and P: alpha (rad),
#: q (rad/s), a_z (g, body z positive down).
OUTPUTS = ("alpha", "q", "az")
#: Input channels a model may have, in column order of G: the elevator and, for a
#: model with a gust input, the measured vertical gust angle.
INPUTS = ("de", "alpha_w")
#: The control input (elevator deflection, rad, trailing edge down positive) and the
#: gust channel (measured vertical gust angle, rad).
INPUT, GUST = INPUTS
#: Channels every record must have: the elevator and the three outputs.
REQUIRED = (INPUT, *OUTPUTS)

#: Every signal fdml knows, with its SI unit.  The first five enter fits; the
#: others (pitch attitude, airspeed, pitch acceleration, longitudinal specific
#: force, altitude, dynamic pressure, inertial vertical speed ``hdot`` positive
#: up) serve data-compatibility checks and gust estimation.
SIGNALS = {
    "de": "rad",
    "alpha": "rad",
    "q": "rad/s",
    "az": "g",
    "alpha_w": "rad",
    "theta": "rad",
    "V": "m/s",
    "qdot": "rad/s^2",
    "ax": "g",
    "h": "m",
    "qbar": "Pa",
    "hdot": "m/s",
}

#: Units of the flight condition a reader puts in ``record.meta`` (``meta["units"]``).
CONDITION_UNITS = {
    "U": "m/s",
    "rho": "kg/m^3",
    "rho_from_data": "kg/m^3",
    "mass": "kg",
    "Iy": "kg m^2",
    "S_w": "m^2",
    "c_w": "m",
    "b": "m",
}

#: SI unit -> (factor from the SI value, unit it is read in): angles in degrees.
DISPLAY_UNITS = {
    "rad": (180.0 / math.pi, "deg"),
    "rad/s": (180.0 / math.pi, "deg/s"),
    "rad/s^2": (180.0 / math.pi, "deg/s^2"),
}

#: Record formats accepted by :func:`fdml.io.load_record` (``auto`` inspects the file).
FORMATS = ("auto", "sidpac", "dlr-asc", "dlr-mat", "csv", "csv-map")


def display_unit(unit: str) -> tuple[float, str]:
    """Factor and unit a value in SI ``unit`` is shown in (degrees for angles; others unchanged).

    Parameters
    ----------
    unit : str
        An SI unit of :data:`SIGNALS` (``"rad"``, ``"rad/s"``, ``"g"`` ...).

    Returns
    -------
    tuple of (float, str)
        Multiply the SI value by the factor to read it in the returned unit.
    """
    return DISPLAY_UNITS.get(unit, (1.0, unit))
