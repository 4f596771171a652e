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
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from .constants import G0

__all__ = [
    "Output",
    "OUTPUT_TABLE",
    "ALL_OUTPUTS",
    "OUTPUTS",
    "STATES",
    "STATIONS",
    "row_space",
    "boundary_channels",
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

#: The states of every model's short-period equations: angle of attack (rad) and pitch rate (rad/s).
STATES = ("alpha", "q")
#: The sensor station of an output, m ahead of the c.g. (zero unless an aircraft file or a
#: ``sensor_offset`` effect gives it): the parameter its row of :data:`OUTPUT_TABLE` reads.
STATIONS = {"alpha": "x_alpha", "az": "x_az"}


def _none(U: float, p: Mapping[str, float]) -> tuple[float, float]:
    """No term: zero coefficients on alpha and q.

    Parameters
    ----------
    U : float
        Airspeed, m/s.
    p : mapping of str to float
        Parameter values.

    Returns
    -------
    tuple of float
        ``(0.0, 0.0)``.
    """
    return (0.0, 0.0)


@dataclass(frozen=True)
class Output:
    """How one measured output is formed from the states x = (alpha, q): its row of G, H and P.

    ``y = v . x + r . x' + i . int_0^t x dt``; each coefficient pair (on alpha, q) is a
    function of the airspeed U (m/s) and the parameter values p (a sensor station of
    :data:`STATIONS`).  Over a record of length T the transform of ``x'`` is ``s x~ - d``
    with ``d = x(0) - x(T) exp(-sT)`` the states' boundary vector, and an integral output
    carries its own boundary term: ``y~ = (i . x~ + y(0) - y(T) exp(-sT)) / s``
    (docs/theory.md section 7).  Adding an output is one entry of :data:`OUTPUT_TABLE`
    (its unit in :data:`SIGNALS`) plus the column its record readers map to it.

    Parameters
    ----------
    name : str
        The channel (a key of :data:`SIGNALS`).
    value, rate, integral : callable
        ``f(U, p) -> (c_alpha, c_q)``: the coefficients on the states, on their rates and
        on their integrals since the start of the record.
    """

    name: str
    value: Callable[[float, Mapping[str, float]], tuple[float, float]] = _none
    rate: Callable[[float, Mapping[str, float]], tuple[float, float]] = _none
    integral: Callable[[float, Mapping[str, float]], tuple[float, float]] = _none

    @property
    def integrates(self) -> bool:
        """Whether the output integrates a state (and so has its own boundary term)."""
        return self.integral is not _none


#: Every output a model predicts, in the row order of G, H, P and of the spectra.
OUTPUT_TABLE = (
    # alpha at a vane x_alpha ahead of the c.g.: alpha - x q/U
    Output("alpha", value=lambda U, p: (1.0, -p.get(STATIONS["alpha"], 0.0) / U)),
    Output("q", value=lambda U, p: (0.0, 1.0)),
    # Eq. 5, a_z = (U/g)(alpha_dot - q), in g, at an accelerometer x_az ahead of the c.g.: a_z - x q_dot/g
    Output("az", value=lambda U, p: (0.0, -U / G0), rate=lambda U, p: (U / G0, -p.get(STATIONS["az"], 0.0) / G0)),
    Output("theta", integral=lambda U, p: (0.0, 1.0)),  # pitch attitude: theta_dot = q (wings level)
    Output("qdot", rate=lambda U, p: (0.0, 1.0)),  # pitch acceleration
)
#: The names of :data:`OUTPUT_TABLE`, in row order.
ALL_OUTPUTS = tuple(o.name for o in OUTPUT_TABLE)
#: The outputs every record carries and every model predicts, in the row order of G, H
#: and P: alpha (rad), q (rad/s), a_z (g, body z positive down).  A model asked for more
#: (:func:`row_space`) has them first, then the others in :data:`ALL_OUTPUTS` order.
OUTPUTS = ALL_OUTPUTS[:3]
#: Input channels a model may have, in column order of G: the elevator and, for a
#: model with a gust input, the measured vertical gust angle.
INPUTS = ("de", "alpha_w")
#: The control input (elevator deflection, rad, trailing edge down positive) and the
#: gust channel (measured vertical gust angle, rad).
INPUT, GUST = INPUTS
#: Channels every record must have: the elevator and the outputs of :data:`OUTPUTS`.
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
DISPLAY_UNITS = {u: (180.0 / math.pi, u.replace("rad", "deg")) for u in ("rad", "rad/s", "rad/s^2")}

#: Record formats accepted by :func:`fdml.io.load_record` (``auto`` inspects the file).
FORMATS = ("auto", "sidpac", "dlr-asc", "dlr-mat", "csv", "csv-map")


def row_space(outputs=None) -> tuple[str, ...]:
    """The rows a model predicts for ``outputs``: :data:`OUTPUTS`, then the others asked for, in table order.

    Parameters
    ----------
    outputs : iterable of str or str, optional
        Output names of :data:`ALL_OUTPUTS`, or ``"theta,qdot"`` (None: :data:`OUTPUTS`).

    Returns
    -------
    tuple of str
        The row names.

    Raises
    ------
    ValueError
        An unknown name (callers turn it into their own error class).
    """
    if isinstance(outputs, str):
        outputs = [o.strip() for o in outputs.split(",") if o.strip()]
    wanted = set(outputs or ())
    bad = sorted(wanted - set(ALL_OUTPUTS))
    if bad:
        raise ValueError(f"unknown output(s) {bad}; choose from {', '.join(ALL_OUTPUTS)}")
    return OUTPUTS + tuple(o for o in ALL_OUTPUTS[len(OUTPUTS) :] if o in wanted)


def boundary_channels(rows) -> tuple[str, ...]:
    """The channels whose values at a record's ends enter the transform of ``rows``.

    The states, then each integral output among the rows (its own boundary term,
    docs/theory.md section 7).

    Parameters
    ----------
    rows : iterable of str
        Output names of :data:`ALL_OUTPUTS`.

    Returns
    -------
    tuple of str
        ``("alpha", "q")`` plus, e.g., ``"theta"``.
    """
    return STATES + tuple(o.name for o in OUTPUT_TABLE if o.integrates and o.name in rows)


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
