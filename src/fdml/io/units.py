"""Units of recorded channels and their conversion to fdml's SI units.

Every fdml signal has a physical quantity (angle, angular rate, ...) and one
target unit, :data:`fdml.record.SIGNALS`: radians for angles, rad/s, rad/s^2,
m/s, m, Pa, and standard gravity (g) for the specific forces ``az`` and
``ax`` (docs/theory.md Eq. 5).  :func:`to_si` multiplies a recorded channel by the
exact factor of its unit (NIST SP 811 factors from :mod:`fdml.constants`) and
refuses a unit that is unknown or belongs to another quantity, so a
conversion can never be silently wrong.
"""

from __future__ import annotations

import re

import numpy as np

from ..constants import DEG, FT, G0, KNOT, LBF, SLUG
from ..errors import RecordError

__all__ = ["QUANTITY", "UNITS", "normalise_unit", "unit_factor", "to_si", "units_text"]

#: Physical quantity of each fdml signal (and of the time column ``t``).
QUANTITY = {
    signal: quantity
    for quantity, signals in {
        "time": "t",
        "angle": "de alpha alpha_w theta",
        "angular rate": "q",
        "angular acceleration": "qdot",
        "specific force": "az ax",
        "speed": "V hdot",
        "length": "h",
        "pressure": "qbar",
    }.items()
    for signal in signals.split()
}

#: Known units per quantity: factor that turns a value in that unit into fdml's unit.
#: Keys are the canonical spellings produced by :func:`normalise_unit`.
UNITS = {
    "time": {"s": 1.0, "ms": 1e-3, "min": 60.0},
    "angle": {"rad": 1.0, "deg": DEG, "mrad": 1e-3},
    "angular rate": {"rad/s": 1.0, "deg/s": DEG},
    "angular acceleration": {"rad/s^2": 1.0, "deg/s^2": DEG},
    # specific forces are kept in units of standard gravity
    "specific force": {"g": 1.0, "m/s^2": 1.0 / G0, "ft/s^2": FT / G0},
    "speed": {"m/s": 1.0, "ft/s": FT, "kt": KNOT, "km/h": 1.0 / 3.6, "ft/min": FT / 60.0},
    "length": {"m": 1.0, "ft": FT, "km": 1000.0},
    "pressure": {"pa": 1.0, "hpa": 100.0, "kpa": 1000.0, "mbar": 100.0, "lbf/ft^2": LBF / FT**2},
    "density": {"kg/m^3": 1.0, "slug/ft^3": SLUG / FT**3},
    "mass": {"kg": 1.0, "slug": SLUG, "lb": 0.45359237},
    "inertia": {"kg m^2": 1.0, "slug ft^2": SLUG * FT**2},
    "area": {"m^2": 1.0, "ft^2": FT**2},
}

#: Other spellings of the units (lower case, as :func:`normalise_unit` leaves them) -> the spelling of :data:`UNITS`,
#: written as ``canonical: "spelling spelling ..."``.
_ALIASES = {
    alias: unit
    for unit, aliases in {
        "s": "sec second seconds",
        "ms": "msec",
        "deg": "degree degrees",
        "rad": "radian radians",
        "deg/s": "deg/sec dps",
        "rad/s": "rad/sec rps",
        "deg/s^2": "deg/s/s",
        "rad/s^2": "rad/s/s",
        "g": "gs g0 gee",
        "m/s^2": "m/s/s mps2",
        "ft/s^2": "ft/s/s fps2",
        "m/s": "mps",
        "ft/s": "fps ft/sec",
        "kt": "kts knot knots kn",
        "km/h": "kmh kph",
        "ft/min": "fpm",
        "ft": "feet foot",
        "m": "meter meters metre metres",
        "lbf/ft^2": "psf lb/ft^2",
        "pa": "n/m^2",
        "slug": "slugs",
        "lb": "lbm",
        "kg m^2": "kgm^2 kg*m^2",
        "slug ft^2": "slug-ft^2 slugft^2 slug*ft^2",
    }.items()
    for alias in aliases.split()
}


def normalise_unit(unit: str) -> str:
    """Canonical spelling of a unit string (``"deg/sec"`` -> ``"deg/s"``, ``"m/s2"`` -> ``"m/s^2"``).

    Parameters
    ----------
    unit : str
        A unit as written in a file or on the command line.

    Returns
    -------
    str
        The spelling used as key of :data:`UNITS` (lower case).
    """
    if not isinstance(unit, str):
        raise RecordError(f"a unit must be a string such as 'deg' or 'm/s^2', got {unit!r}")
    u = unit.strip().lower().replace("**", "^").replace("²", "^2").replace("³", "^3")
    u = re.sub(r"\s+", " ", u)
    u = u.replace(" / ", "/").replace("/ ", "/").replace(" /", "/")
    u = re.sub(r"\bsec\b", "s", u)
    u = re.sub(r"(?<=[a-z])([23])$", r"^\1", u)  # m/s2 -> m/s^2, ft2 -> ft^2, slug/ft3 -> slug/ft^3
    u = re.sub(r"(?<=[a-z])([23])(?=[/ ])", r"^\1", u)
    return _ALIASES.get(u, u)


def unit_factor(unit: str, quantity: str, *, what: str = "") -> float:
    """Factor turning a value in ``unit`` into fdml's unit of ``quantity``.

    Raises :class:`RecordError` naming ``what`` when the unit is unknown or
    measures another quantity (e.g. ``deg`` for an acceleration).

    Parameters
    ----------
    unit : str
        The unit, in any spelling :func:`normalise_unit` accepts.
    quantity : str
        A quantity of :data:`UNITS` (``"angle"``, ``"angular rate"``, ...).
    what : str, optional
        What carries the unit (a channel or option), for the error message.

    Returns
    -------
    float
        The factor: value in fdml's unit = value in ``unit`` * factor.
    """
    u = normalise_unit(unit)
    table = UNITS[quantity]
    if u in table:
        return float(table[u])
    label = f"{what}: " if what else ""
    for other, tab in UNITS.items():
        if u in tab:
            raise RecordError(
                f"{label}unit {unit!r} measures {other}, but this channel is {_article(quantity)} {quantity} "
                f"(units: {', '.join(_display(k) for k in table)})"
            )
    raise RecordError(
        f"{label}unknown unit {unit!r} for {_article(quantity)} {quantity}; "
        f"known: {', '.join(_display(k) for k in table)}"
    )


def to_si(values, unit: str, signal: str, *, what: str = "") -> np.ndarray:
    """Convert a recorded channel of fdml signal ``signal`` from ``unit`` to fdml's unit.

    Parameters
    ----------
    values : array_like
        The recorded samples, in ``unit``.
    unit : str
        Their unit.
    signal : str
        The fdml signal (a key of :data:`QUANTITY`, e.g. ``"alpha"``).
    what : str, optional
        What to name in an error (default: ``signal``).

    Returns
    -------
    numpy.ndarray
        The samples in fdml's unit of the signal, float.
    """
    if signal not in QUANTITY:
        raise RecordError(f"{what + ': ' if what else ''}unknown signal {signal!r}; known: {', '.join(QUANTITY)}")
    return np.asarray(values, dtype=float) * unit_factor(unit, QUANTITY[signal], what=what or signal)


def units_text() -> str:
    """One line per quantity listing the accepted units (for help texts).

    Returns
    -------
    str
        Lines ``"quantity: unit, unit, ..."``.
    """
    return "\n".join(f"{q}: {', '.join(_display(k) for k in tab)}" for q, tab in UNITS.items())


def _display(u: str) -> str:
    return {"pa": "Pa", "hpa": "hPa", "kpa": "kPa"}.get(u, u)


def _article(word: str) -> str:
    return "an" if word[0] in "aeiou" else "a"
