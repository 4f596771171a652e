"""Aircraft geometry, mass, flight condition and unsteady constants.

Presets (``navion``, ``sundowner``, ``do128``) are JSON files in
``fdml/presets``; every value carries its source and the assumed ones are
flagged (docs/theory.md sections 10 and 11).  A user's own aircraft is a JSON file
with the keys ``name, S_w, c_w, S_t, c_t, l_t, mass, Iy, U, rho`` (SI) and,
optionally, the span ``b``, any of the model constants by parameter name,
``lag_constants``, ``description``, ``sources`` and ``assumed``
(:data:`KEY_MEANINGS` says what each one is).  :func:`aircraft_template` starts
such a file from what a flight record carries (``fdml aircraft init``).
"""

from __future__ import annotations

import json
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from .channels import STATIONS
from .errors import AircraftError

__all__ = [
    "Aircraft",
    "REQUIRED_KEYS",
    "MAX_AIRSPEED",
    "CONSTANT_KEYS",
    "GENERIC_CONSTANTS",
    "LAG_KEYS",
    "LAG_SOURCES",
    "get_aircraft",
    "jones_lag_constants",
    "lag_provenance",
    "aircraft_for_lags",
    "missing_lag_message",
    "list_aircraft",
    "load_aircraft",
    "KEY_MEANINGS",
    "AircraftTemplate",
    "aircraft_template",
]

#: Keys every aircraft description must have (SI units).
REQUIRED_KEYS = ("name", "S_w", "c_w", "S_t", "c_t", "l_t", "mass", "Iy", "U", "rho")
#: The same with the optional span after the wing chord: the order a description and a new
#: aircraft file list them in.
_FILE_ORDER = (*REQUIRED_KEYS[:3], "b", *REQUIRED_KEYS[3:])
#: The optional fields a description may give as they are.
_OPTIONAL_FIELDS = ("sources", "description", "lag_constants", "b", "sensors")

_UNITS = {
    "b": "m",
    "S_w": "m^2",
    "c_w": "m",
    "S_t": "m^2",
    "c_t": "m",
    "l_t": "m",
    "mass": "kg",
    "Iy": "kg m^2",
    "U": "m/s",
    "rho": "kg/m^3",
}

#: What each key of an aircraft file holds (the geometry, mass and flight condition, SI), for
#: messages, templates and the docs.
KEY_MEANINGS = {
    "name": "short identifier",
    "S_w": "wing reference area, m^2",
    "c_w": "wing reference chord, m (the Wells-Keskar model's chord; a record's mean aerodynamic chord serves)",
    "b": "wing span, m (optional; the aspect ratio b^2/S_w of the jones lag source, else S_w/c_w^2)",
    "S_t": "horizontal-tail area, m^2",
    "c_t": "horizontal-tail chord, m (tail area over tail span)",
    "l_t": "tail length, m: centre of gravity to the tail's aerodynamic centre (quarter chord)",
    "mass": "mass, kg",
    "Iy": "pitch moment of inertia, kg m^2",
    "U": "true airspeed of the flight condition, m/s",
    "rho": "air density, kg/m^3",
    "lag_constants": "a documented source of the lag constants the file does not give: jones or none",
    "description": "one line on the aircraft and the flight condition",
    "sources": "where each value comes from, by key",
    "assumed": "the keys whose values are assumptions rather than data",
    "sensors": 'known sensor positions, m ahead of the c.g.: {"alpha": {"x": m}, "az": {"x": m}} (optional)',
}

#: Largest airspeed fdml accepts, m/s.  No aircraft has flown faster in the
#: atmosphere than the X-15 (2021 m/s, Mach 6.7); 3000 m/s leaves room for that
#: and still refuses what is certainly a unit slip (mm/s, or a speed in km/h
#: typed with a factor 1000) before it reaches the models, where U enters
#: squared and cubed: U = 1e50 m/s overflowed to OverflowError, 1e154 to a
#: response table of NaN.  (The unsteady Wagner/Kussner lag terms are
#: incompressible theory: validity is the user's call, not this limit's.)
MAX_AIRSPEED = 3000.0

#: Start values used for constants an aircraft file does not give.  They are
#: generic light-aircraft numbers, not data: a fit frees the first five, and
#: the lag constants default to "no lag" so that nothing unsteady is assumed.
GENERIC_CONSTANTS = {
    "CLa_w": 4.5,
    "CLa_t": 3.5,
    "deps_da": 0.4,
    "Cm_de": -1.0,
    "Cz_de": -0.4,
    "y_w": 0.0,
    "z_w": 0.381,
    "y_t": 0.0,
    "z_t": 0.381,
    "F": 0.0,
    "G": 0.0,
    "H": 0.065,
    "b1": 7.5,
}

#: Optional model constants an aircraft may carry, by parameter name.
CONSTANT_KEYS = tuple(GENERIC_CONSTANTS)


#: The lag constants of the unsteady model (docs/theory.md Eqs. 1-2): lift lag of wing
#: and tail, downwash lag.  An aircraft that gives none of them and names no
#: source for them cannot make the unsteady model (it would be the steady one).
LAG_KEYS = ("y_w", "z_w", "y_t", "z_t", "F", "G", "H")

#: Documented sources an aircraft file may name for its lag constants
#: (``"lag_constants": NAME``), with what each one means.
LAG_SOURCES = {
    "jones": "lift lags from R. T. Jones's one-term finite-wing indicial approximation (NACA Rep. 681) "
    "for the aspect ratio S/c^2 of wing and tail (docs/theory.md section 2); downwash lag F, G, H borrowed "
    "from the Sundowner, WK Table 2",
    "none": "no lag chosen by the user: the unsteady model is then the quasi-steady model",
}

#: R. T. Jones's one-term approximation 1 - y exp(-z s) (docs/theory.md section 2) at two aspect ratios.
_JONES_TABLE = {3.0: (0.283, 0.540), 6.0: (0.361, 0.381)}
#: WK Table 2 (Sundowner) downwash-lag constants, borrowed by the "jones" source.
_WK_TABLE2_DOWNWASH = {"F": 1.358, "G": 0.513, "H": 0.065}


def jones_lag_constants(aspect_ratio: float) -> tuple[float, float, float, float]:
    """(y, z, sigma_y, sigma_z) of R. T. Jones's one-term lift lag for an aspect ratio.

    Linear in 1/AR between Jones's AR 3 and AR 6 elliptic-wing values
    (docs/theory.md section 2), held at the nearer end outside [3, 6].  The
    uncertainty is half the AR 3-6 spread (0.039 in y, 0.080 in z), doubled
    outside [3, 6]: the one-term form and the [MEM] table do not support more.

    Parameters
    ----------
    aspect_ratio : float
        Wing aspect ratio S/c^2 (or b^2/S), dimensionless.

    Returns
    -------
    tuple of float
        ``(y, z, sigma_y, sigma_z)``: lift-lag amplitude and rate (dimensionless,
        per semichord travelled) and their standard uncertainties.
    """
    (a3, (y3, z3)), (a6, (y6, z6)) = sorted(_JONES_TABLE.items())
    ar = min(max(float(aspect_ratio), a3), a6)
    w = (1.0 / ar - 1.0 / a6) / (1.0 / a3 - 1.0 / a6)  # 0 at AR 6, 1 at AR 3
    grow = 1.0 if a3 <= aspect_ratio <= a6 else 2.0
    return y6 + w * (y3 - y6), z6 + w * (z3 - z6), grow * abs(y3 - y6) / 2, grow * abs(z3 - z6) / 2


def _jones_fill(S_w, c_w, S_t, c_t, b=None) -> tuple[dict, dict, dict]:
    """(constants, sources, uncertainty) of the "jones" lag source; the wing's AR is b^2/S_w when the span is given."""
    consts, sources, sigma = {}, {}, {}
    for part, S, c in (("w", S_w, c_w), ("t", S_t, c_t)):
        span = part == "w" and b is not None
        ar = b**2 / S if span else S / c**2
        y, z, sy, sz = jones_lag_constants(ar)
        for key, v, sv in ((f"y_{part}", y, sy), (f"z_{part}", z, sz)):
            consts[key], sigma[key] = v, sv
            sources[key] = (
                f"R. T. Jones one-term lift lag for AR = {'b^2/S' if span else 'S/c^2'} = {ar:.3g} "
                f"(docs/theory.md 2), +/- {sv:.2g}"
            )
    for key, v in _WK_TABLE2_DOWNWASH.items():
        consts[key], sigma[key] = v, abs(v)  # another aircraft's value: of the order of itself
        sources[key] = "borrowed from the Sundowner, WK Table 2 (docs/theory.md 11.2), +/- 100 %"
    return consts, sources, sigma


@dataclass(frozen=True)
class Aircraft:
    """Geometry, mass properties and flight condition of one aircraft (SI).

    Parameters
    ----------
    name : str
        Short identifier.
    S_w, c_w : float
        Wing area (m^2) and wing root chord (m), the reference chord of the
        Wells-Keskar model (docs/theory.md section 1).
    S_t, c_t : float
        Horizontal-tail area (m^2) and chord (m).
    l_t : float
        Tail length, c.g. to tail aerodynamic centre (m).
    mass : float
        Mass, kg.
    Iy : float
        Pitch moment of inertia, kg m^2.
    U : float
        True airspeed, m/s.
    rho : float
        Air density, kg/m^3.
    constants : mapping, optional
        Model constants by parameter name (see :data:`CONSTANT_KEYS`); missing
        ones take :data:`GENERIC_CONSTANTS`.
    sources : mapping, optional
        Where each value comes from (free text, per key).
    assumed : frozenset of str, optional
        Keys whose values are assumptions rather than data.
    description : str, optional
        One line on the aircraft and the flight condition.
    lag_constants : str, optional
        A documented source for the lag constants the aircraft does not give
        (a key of :data:`LAG_SOURCES`: ``"jones"`` or ``"none"``); "" for none named.
    b : float or None, optional
        Wing span, m: the wing's aspect ratio b^2/S_w for the ``"jones"``
        lag source (without it, S_w/c_w^2).  No model uses it otherwise.
    sensors : mapping, optional
        Known sensor positions, ``{"alpha": {"x": m}, "az": {"x": m}}``: the alpha vane's and the
        normal accelerometer's distance ahead of the c.g. (aft negative), m.  Every model of the
        aircraft applies them as known (fixed ``sensor_offset`` effects, :func:`fdml.models.make_model`),
        and the diagnosis does not test them.

    Attributes
    ----------
    given : frozenset of str
        The constants the description gave (the rest are :data:`GENERIC_CONSTANTS`).
    lag_uncertainty : dict
        Standard uncertainty of each lag constant filled in from ``lag_constants``.
    """

    name: str
    S_w: float
    c_w: float
    S_t: float
    c_t: float
    l_t: float
    mass: float
    Iy: float
    U: float
    rho: float
    constants: Mapping[str, float] = field(default_factory=dict)
    sources: Mapping[str, str] = field(default_factory=dict)
    assumed: frozenset = frozenset()
    description: str = ""
    lag_constants: str = ""
    b: float | None = None
    sensors: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    given: frozenset = field(default=frozenset(), init=False, compare=False)
    lag_uncertainty: Mapping[str, float] = field(default_factory=dict, init=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise AircraftError(f"aircraft name must be a non-empty string, got {self.name!r}")
        for key in (*REQUIRED_KEYS[1:], *(("b",) if self.b is not None else ())):
            # every field is a size, a mass, an inertia, a speed or a density: positive
            v = _real(getattr(self, key), f"aircraft {self.name!r}: {key} ({_UNITS[key]})")
            if v <= 0:
                raise AircraftError(
                    f"aircraft {self.name!r}: {key} must be positive and finite ({_UNITS[key]}), got {v!r}"
                )
            object.__setattr__(self, key, v)
        if self.U > MAX_AIRSPEED:
            raise AircraftError(
                f"aircraft {self.name!r}: airspeed U = {self.U:g} m/s is not physical "
                f"(limit {MAX_AIRSPEED:g} m/s); give U in m/s"
            )
        if not isinstance(self.sources, Mapping) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in self.sources.items()
        ):
            raise AircraftError(
                f"aircraft {self.name!r}: sources must map keys to text, "
                f'e.g. {{"mass": "POH p. 6"}}, got {self.sources!r}'
            )
        if isinstance(self.assumed, str) or not all(isinstance(k, str) for k in self.assumed):
            raise AircraftError(f"aircraft {self.name!r}: assumed must be a list of key names, got {self.assumed!r}")
        if not isinstance(self.description, str):
            raise AircraftError(f"aircraft {self.name!r}: description must be text, got {self.description!r}")
        object.__setattr__(self, "sensors", _checked_sensors(self.sensors, f"aircraft {self.name!r}"))
        unknown = set(self.constants) - set(CONSTANT_KEYS)
        if unknown:
            raise AircraftError(
                f"aircraft {self.name!r}: unknown constants {sorted(unknown)}; known: {', '.join(CONSTANT_KEYS)}"
            )
        consts = dict(GENERIC_CONSTANTS)
        consts.update({k: _real(v, f"aircraft {self.name!r}: constant {k}") for k, v in self.constants.items()})
        given, sources, assumed = frozenset(self.constants), dict(self.sources), set(self.assumed)
        if self.lag_constants not in ("", *LAG_SOURCES):
            raise AircraftError(
                f"aircraft {self.name!r}: lag_constants must be one of {', '.join(LAG_SOURCES)}, "
                f"got {self.lag_constants!r}"
            )
        sigma: dict[str, float] = {}
        if self.lag_constants == "jones":
            filled, why, sigma = _jones_fill(self.S_w, self.c_w, self.S_t, self.c_t, self.b)
            sigma = {k: v for k, v in sigma.items() if k not in given}
            consts.update({k: filled[k] for k in sigma})
            sources.update({k: why[k] for k in sigma})
            assumed |= set(sigma)
        object.__setattr__(self, "constants", consts)
        object.__setattr__(self, "sources", sources)
        object.__setattr__(self, "assumed", frozenset(assumed))
        object.__setattr__(self, "given", given)
        object.__setattr__(self, "lag_uncertainty", sigma)

    @property
    def lag_status(self) -> str | None:
        """Where the lag constants come from: "aircraft file", a :data:`LAG_SOURCES` name, or None (nowhere)."""
        if self.lag_constants:
            return self.lag_constants
        return "aircraft file" if self.given & set(LAG_KEYS) else None

    @property
    def placeholders(self) -> dict[str, str]:
        """Constants at a generic start value (:data:`GENERIC_CONSTANTS`) that nothing gave: name -> "generic NAME = V".

        A constant the description gives, one filled from a named lag source, and
        the lag constants of ``"lag_constants": "none"`` (no lag, chosen) are not
        placeholders.
        """
        chosen = set(LAG_KEYS) if self.lag_constants == "none" else set()  # no lag, by choice
        given = chosen | self.given | set(self.lag_uncertainty)
        return {k: f"generic {k} = {GENERIC_CONSTANTS[k]:g}" for k in CONSTANT_KEYS if k not in given}

    # --- derived quantities --------------------------------------------------
    @property
    def k_z(self) -> float:
        """The factor of C_z in docs/theory.md Eq. 3, rho U S_w / (2 m), 1/s."""
        return self.rho * self.U * self.S_w / (2.0 * self.mass)

    @property
    def k_m(self) -> float:
        """The factor of C_m in Eq. 4, rho U^2 S_w c_w / (2 I_y), 1/s^2."""
        return self.rho * self.U**2 * self.S_w * self.c_w / (2.0 * self.Iy)

    @property
    def qbar(self) -> float:
        """Dynamic pressure rho U^2 / 2, Pa."""
        return 0.5 * self.rho * self.U**2

    def with_changes(self, **changes) -> "Aircraft":
        """Return a copy with fields (or constants, by name) changed.

        Parameters
        ----------
        **changes
            New values by field name (SI) or by constant name (:data:`CONSTANT_KEYS`).

        Returns
        -------
        Aircraft
            The changed copy.
        """
        consts = {k: self.constants[k] for k in self.given}
        fields_ = {}
        for k, v in changes.items():
            if k in CONSTANT_KEYS:
                consts[k] = v
            elif k in REQUIRED_KEYS or k in ("lag_constants", "b"):
                fields_[k] = v
            else:
                raise AircraftError(f"unknown aircraft field or constant {k!r}")
        return replace(self, constants=consts, **fields_)

    # --- serialisation --------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict in the aircraft-file layout.

        Returns
        -------
        dict
            The required keys, the constants, ``description``, ``sources`` and ``assumed``.
        """
        d = {k: getattr(self, k) for k in REQUIRED_KEYS}
        if self.b is not None:
            d["b"] = self.b
        d.update({k: v for k, v in self.constants.items() if k in self.given})  # generic defaults stay implicit
        if self.lag_constants:
            d["lag_constants"] = self.lag_constants
        if self.sensors:
            d["sensors"] = {k: dict(v) for k, v in self.sensors.items()}
        d["description"] = self.description
        d["sources"] = dict(self.sources)
        d["assumed"] = sorted(self.assumed)
        return d

    @classmethod
    def from_dict(cls, d: Mapping, origin: str = "aircraft description") -> "Aircraft":
        """Build from a mapping with the aircraft-file keys.

        Parameters
        ----------
        d : Mapping
            The aircraft-file keys (SI values).
        origin : str, optional
            What the mapping came from, named in errors.

        Returns
        -------
        Aircraft
            The aircraft.
        """
        if not isinstance(d, Mapping):
            raise AircraftError(f"{origin}: expected a JSON object, got {type(d).__name__}")
        missing = [k for k in REQUIRED_KEYS if k not in d]
        if missing:
            raise AircraftError(f"{origin}: missing key(s) {', '.join(missing)} (all SI units)")
        empty = [k for k in REQUIRED_KEYS if d[k] is None]
        if empty:  # what fdml aircraft init leaves for the user
            raise AircraftError(
                f"{origin}: not filled in (null): "
                + "; ".join(f"{k}: {KEY_MEANINGS[k]}" for k in empty)
                + "; give their values"
            )
        extra = set(d) - set(REQUIRED_KEYS) - set(CONSTANT_KEYS) - set(KEY_MEANINGS)
        if extra:
            raise AircraftError(f"{origin}: unknown key(s) {', '.join(sorted(extra))}")
        assumed = d.get("assumed", ())
        known = (*REQUIRED_KEYS, *CONSTANT_KEYS, "b")  # a str or a mapping is not a list of them
        if not isinstance(assumed, (list, tuple)) or any(k not in known for k in assumed):
            raise AircraftError(f'{origin}: assumed must be a list of key names (e.g. ["S_t", "b1"]), got {assumed!r}')
        try:
            return cls(
                name=str(d["name"]),
                **{k: d[k] for k in REQUIRED_KEYS[1:]},
                constants={k: d[k] for k in CONSTANT_KEYS if k in d},
                assumed=frozenset(assumed),
                **{k: d[k] for k in _OPTIONAL_FIELDS if k in d},  # the others keep their defaults
            )
        except AircraftError as exc:
            raise AircraftError(f"{origin}: {exc}") from None  # name the user's file

    def describe(self) -> str:
        """Multi-line text: every value with its unit, source and assumed flag.

        Returns
        -------
        str
            One line per value.
        """
        lines = [f"{self.name}: {self.description}".rstrip(": ")]
        for k in _FILE_ORDER[1:]:
            if getattr(self, k) is not None:
                lines.append(self._line(k, getattr(self, k), _UNITS[k]))
        for k in CONSTANT_KEYS:
            lines.append(self._line(k, self.constants[k], ""))
        return "\n".join(lines)

    def _line(self, key: str, value: float, unit: str) -> str:
        flag = " [assumed]" if key in self.assumed else ""
        src = self.sources.get(key, "generic default" if key in CONSTANT_KEYS else "")
        return f"  {key:8s} = {value:12.6g} {unit:8s}{flag}  {src}"


def lag_provenance(ac: Aircraft) -> dict:
    """Where the unsteady model's lag constants come from, for a result's provenance.

    ``{"source", "meaning", "constants": {name: {"value", "uncertainty", "source"}}}``;
    ``uncertainty`` is None where the aircraft file gave the value.

    Parameters
    ----------
    ac : Aircraft
        The aircraft whose lag constants are described.

    Returns
    -------
    dict
        ``{"source", "meaning", "constants": {name: {"value", "uncertainty", "source"}}}``.
    """
    status = ac.lag_status
    return {
        "source": status,
        "meaning": LAG_SOURCES.get(status or "", "values given in the aircraft description"),
        "constants": {
            k: {
                "value": ac.constants[k],
                "uncertainty": ac.lag_uncertainty.get(k),
                "source": ac.sources.get(k, "aircraft description" if k in ac.given else "generic default"),
            }
            for k in LAG_KEYS
        },
    }


def aircraft_for_lags(spec, free=(), given=None, source: str = "given as a parameter value") -> "Aircraft":
    """The aircraft ``spec`` with the lag constants supplied beside it: given values, or freed ones.

    A lag constant supplied with the model counts as given by the aircraft
    (``fdml response --set y_w=...``, ``fdml fit --fix y_w=...``): the aircraft
    carries it, with ``source`` as its source, so the unsteady model accepts an
    aircraft file without lag constants when they come this way.  Freeing an
    identifiable lag constant is the other way out of the missing-constants
    refusal: the fit estimates it, from the "jones" start values (the rest stay at those).

    Parameters
    ----------
    spec : str, Aircraft or mapping
        A preset name, an aircraft file or an :class:`Aircraft`.
    free : sequence of str, optional
        Parameters the fit frees (lag constants among them start at Jones's values).
    given : mapping of str to float, optional
        Parameter values supplied with the model; the lag constants among them
        (:data:`LAG_KEYS`, dimensionless) are put into the aircraft.
    source : str, optional
        Where those values come from, recorded as their source (``"--set"``).

    Returns
    -------
    Aircraft
        The aircraft with the given lag constants, and Jones's lag constants filled
        in where a freed one needs a start.
    """
    ac = load_aircraft(spec)
    supplied = {k: float(v) for k, v in (given or {}).items() if k in LAG_KEYS}
    if supplied:
        ac = replace(
            ac,
            constants={**{k: ac.constants[k] for k in ac.given}, **supplied},
            sources={**ac.sources, **dict.fromkeys(supplied, source)},
            assumed=ac.assumed - set(supplied),
        )
    if ac.lag_status is None and set(free or ()) & set(LAG_KEYS):
        return ac.with_changes(lag_constants="jones")
    return ac


def missing_lag_message(ac: Aircraft, kind: str = "unsteady") -> str:
    """The one-line refusal of the unsteady model for an aircraft without lag constants, with the ways out.

    Parameters
    ----------
    ac : Aircraft
        The aircraft that gives none of the lag constants.
    kind : str, optional
        The model kind asked for (``"unsteady"``).

    Returns
    -------
    str
        The message, naming the missing constants and the ways out.
    """
    return (
        f"the {kind} model needs the lag constants {', '.join(LAG_KEYS)} and aircraft {ac.name!r} gives none of "
        "them (without them it is the steady model); give them in the aircraft file, or name a documented "
        'source there, "lag_constants": "jones" (R. T. Jones\'s finite-wing lift lag for the aspect ratio, '
        'docs/theory.md section 2; downwash lag from WK Table 2; uncertainty recorded in the result) or "none" '
        "(no lag, by choice), or give them on the command line (--set y_w=... or fdml fit --fix y_w=...), "
        "or free the identifiable ones (fdml fit --free y_w z_w ...)"
    )


#: Largest |x| of a sensor position, m: outside it no airframe has a sensor.
MAX_SENSOR_X = 50.0


def _checked_sensors(sensors, where: str) -> Mapping:
    """The ``sensors`` entry checked: known channels, one number ``x`` each, inside any airframe."""
    example = '{"alpha": {"x": 13.0}, "az": {"x": 0.4}}'
    if not isinstance(sensors, Mapping):
        raise AircraftError(f"{where}: sensors must map channels to positions, e.g. {example}, got {sensors!r}")
    out = {}
    for ch, pos in sensors.items():
        if ch not in STATIONS:  # channels whose position a file can give (fdml.channels)
            raise AircraftError(
                f"{where}: sensors: unknown channel {ch!r}; positions can be given for {', '.join(STATIONS)}"
            )
        if not isinstance(pos, Mapping) or set(pos) != {"x"}:
            raise AircraftError(
                f'{where}: sensors: {ch} must be {{"x": metres ahead of the c.g.}}, e.g. {example}, got {pos!r}'
            )
        x = _real(pos["x"], f"{where}: sensors: {ch} x (m ahead of the c.g.)")
        if abs(x) > MAX_SENSOR_X:
            raise AircraftError(
                f"{where}: sensors: {ch} x = {x:g} m lies outside any airframe (|x| <= {MAX_SENSOR_X:g} m); "
                "give metres ahead of the c.g."
            )
        out[ch] = {"x": x}
    return out


def _real(value, what: str) -> float:
    """``value`` as a finite float; a bool, a string (even ``"12"``), NaN or inf is an AircraftError."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise AircraftError(f"{what} must be a number, got {value!r} ({type(value).__name__})")
    v = float(value)
    if not math.isfinite(v):
        raise AircraftError(f"{what} must be finite, got {value!r}")
    return v


def list_aircraft() -> list[str]:
    """Names of the bundled presets.

    Returns
    -------
    list of str
        The names, sorted.
    """
    folder = resources.files("fdml") / "presets"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".json"))


def get_aircraft(name: str) -> Aircraft:
    """Return a bundled preset by name (``navion``, ``sundowner``, ``do128``).

    Parameters
    ----------
    name : str
        A name of :func:`list_aircraft` (an :class:`Aircraft` is returned as is).

    Returns
    -------
    Aircraft
        The preset.
    """
    if isinstance(name, Aircraft):
        return name
    names = list_aircraft()
    if name not in names:
        raise AircraftError(f"unknown aircraft {name!r}; presets: {', '.join(names)}")
    text = (resources.files("fdml") / "presets" / f"{name}.json").read_text()
    return Aircraft.from_dict(json.loads(text), origin=f"preset {name}")


def load_aircraft(spec: str | Path | Aircraft) -> Aircraft:
    """Resolve a preset name or a JSON file path to an :class:`Aircraft`.

    Parameters
    ----------
    spec : str, Path or Aircraft
        A preset name, the path of an aircraft JSON file, or an aircraft.

    Returns
    -------
    Aircraft
        The aircraft.
    """
    if isinstance(spec, Aircraft):
        return spec
    spec_s = str(spec)
    if spec_s in list_aircraft():
        return get_aircraft(spec_s)
    path = Path(spec_s)
    if path.suffix.lower() != ".json" and not path.exists():
        raise AircraftError(f"unknown aircraft {spec_s!r}: not a preset ({', '.join(list_aircraft())}) nor a JSON file")
    if not path.exists():
        raise AircraftError(f"aircraft file {spec_s} does not exist")
    if path.is_dir():
        raise AircraftError(f"aircraft file {spec_s} is a folder, not a JSON file")
    try:
        text = path.read_text(encoding="utf-8-sig")  # JSON is UTF-8 (RFC 8259); a BOM is tolerated
    except UnicodeDecodeError as exc:
        raise AircraftError(
            f"aircraft file {spec_s} is not UTF-8 text (byte {exc.start}: "
            f"{exc.object[exc.start : exc.start + 1]!r}); save it as UTF-8"
        ) from None
    except OSError as exc:
        raise AircraftError(f"cannot read aircraft file {spec_s}: {exc.strerror or exc}") from None
    try:
        d = json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise AircraftError(f"aircraft file {spec_s} is not valid JSON: {exc}") from None
    except ValueError as exc:  # NaN / Infinity, which JSON does not have
        raise AircraftError(f"aircraft file {spec_s}: {exc}") from None
    return Aircraft.from_dict(d, origin=f"aircraft file {spec_s}")


def _no_constant(name: str):
    """json ``parse_constant`` hook: Python's json reads NaN and Infinity, JSON has neither."""
    raise ValueError(f"{name} is not a JSON number")


# --- an aircraft file started from a record -------------------------------------------------
#: Keys a record's ``meta`` may fill (the readers put them there in SI: fdml.io), in file order.
_FROM_RECORD = ("S_w", "c_w", "b", "mass", "Iy", "U", "rho")


@dataclass(frozen=True)
class AircraftTemplate:
    """The start of an aircraft file: what a record carries, and what it does not.

    Parameters
    ----------
    values : dict
        The aircraft-file layout (:data:`KEY_MEANINGS`): the keys the record
        fills, ``None`` (JSON null) for each required key it does not, and
        ``sources`` naming where every filled value comes from.
    missing : dict
        Required key -> what it is and where to find it, for the keys left null.
    """

    values: dict
    missing: dict

    def as_file(self) -> dict:
        """The aircraft file, JSON-ready (missing values as None).

        Returns
        -------
        dict
            A copy of :attr:`values`; more keys may be added to it before writing.
        """
        return json.loads(json.dumps(self.values))

    def describe(self) -> str:
        """What was filled (value, unit, source) and what is left to fill, one line each.

        Returns
        -------
        str
            The text ``fdml aircraft init`` prints.
        """
        v = self.values
        lines = [f"aircraft {v['name']!r} from {v['sources'].get('name', 'the record')}:"]
        origin = v["sources"].get("name", "")
        for k in _FROM_RECORD:
            if v.get(k) is not None:
                lines.append(f"  {k:5s} = {v[k]:12.6g} {_UNITS[k]:8s} {v['sources'][k].removeprefix(origin + ': ')}")
        lines.append("left to fill (null in the file):" if self.missing else "nothing left to fill")
        lines += [f"  {k:5s}  {why}" for k, why in self.missing.items()]
        lines.append(
            "optional: the model constants (" + ", ".join(CONSTANT_KEYS[:5]) + "; generic placeholders where not "
            'given) and the lag constants (give them, or "lag_constants": "jones" or "none")'
        )
        return "\n".join(lines)


def aircraft_template(record, name: str | None = None) -> AircraftTemplate:
    """Start an aircraft file from what a flight record carries (``fdml aircraft init``).

    The readers put the flight condition and any reference geometry a file
    holds into ``record.meta`` in SI (fdml.io): SIDPAC files carry S, the mean
    chord, the span, the mass, Iy and the density; the DLR layouts the book's
    constants.  Every value taken gets a source; each required key the record
    does not give is left null, with what it is.

    Parameters
    ----------
    record : fdml.Record
        A record as read (its ``meta`` and ``name`` are used).
    name : str, optional
        The aircraft's name (default: the aircraft the record names, else the record's name).

    Returns
    -------
    AircraftTemplate
        The file's values, and the keys left to fill.
    """
    meta = record.meta
    origin = f"record {record.name} ({meta.get('format', 'record')} file {meta.get('source', record.name)})"
    values: dict = {"name": name or meta.get("aircraft") or record.name}
    sources: dict = {"name": origin}
    for k in _FROM_RECORD:
        x = meta.get(k)
        if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0:
            values[k] = float(x)
            sources[k] = f"{origin}: " + _record_source(k, meta)
    missing = {k: KEY_MEANINGS[k] + _hint(k, meta) for k in REQUIRED_KEYS[1:] if k not in values}
    ordered = {k: values.get(k) for k in _FILE_ORDER if k != "b" or "b" in values}
    ordered["description"] = f"started by fdml aircraft init from {origin}; fill the null values"
    return AircraftTemplate({**ordered, "sources": sources, "assumed": []}, missing)


def _record_source(key: str, meta: Mapping) -> str:
    """Where a reader found ``key``: a channel's mean over the record, a file's constant, or its reference geometry."""
    if key in meta.get("window_means", ()):
        noun = {"U": "true airspeed", "rho": "density", "mass": "mass", "Iy": "pitch inertia"}.get(key, key)
        return f"mean over the record of its {noun} channel"
    note = f"; 2 qbar/V^2 over the record gives {meta['rho_from_data']:.4g} kg/m^3" if key == "rho" else ""
    if meta.get("constants_source"):
        return meta["constants_source"] + (note if "rho_from_data" in meta else "")
    return {"S_w": "sarea", "c_w": "cbar (mean aerodynamic chord)", "b": "bspan"}.get(key, f"meta[{key!r}]")


def _hint(key: str, meta: Mapping) -> str:
    """Where to find a missing value, when the record gives a clue."""
    k = meta.get("Sc_over_Iy")
    if key in ("c_w", "Iy") and k:
        return f"; the record gives S c/Iy = {k:.5g} m/kg only: Iy = S_w c_w / {k:.5g}"
    if key in ("S_t", "c_t", "l_t"):
        return "; tail geometry is in no record: the type's data or a three-view"
    return ""
