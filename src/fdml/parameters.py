"""Named model parameters: value, free or fixed, bounds, unit.

A :class:`Parameters` set is immutable: every change returns a new set, so a fit
never mutates the caller's parameters and no stale standard error survives a
refit (the lmfit #189 trap: a refit that kept the previous fit's errors).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from .errors import ParameterError
from .jsoncodec import SKIP, Codec, Spec, choice

__all__ = ["NUISANCE_ROLES", "Parameter", "Parameters", "Role", "Slot", "as_names", "check_fix_free", "fixed_values"]


class Role(str, Enum):
    """What an estimated or fixed quantity is, typed rather than read from its name.

    ``AERO``: a derivative or coefficient of the model's equations of motion;
    ``DELAY``: a pure input time delay (``tau_de``), s; ``EFFECT``: a parameter
    an effect adds (:mod:`fdml.models.effects`); ``OUTPUT_BIAS``: a constant on
    a measured output (``bias_q``); ``STATE_BIAS``: a constant in a state
    equation (``bias_q_dot``); ``INPUT_BIAS``: an elevator offset
    (``bias_de``); ``INPUT_EDGE``: the timing of an elevator step between two
    samples (``edge_de_1``, s; docs/theory.md section 7a); ``BOUNDARY``: a boundary value x(0) or x(T) of the finite
    transform (``x0_alpha``, docs/theory.md section 7).  The value is the JSON
    form: ``Role("delay")`` is :attr:`Role.DELAY`.
    """

    AERO = "aero"
    DELAY = "delay"
    EFFECT = "effect"
    OUTPUT_BIAS = "output_bias"
    STATE_BIAS = "state_bias"
    INPUT_BIAS = "input_bias"
    INPUT_EDGE = "input_edge"
    BOUNDARY = "boundary"

    @property
    def nuisance(self) -> bool:
        """True for the measurement's nuisance terms (biases, boundary values), False for the model's own."""
        return self in NUISANCE_ROLES


#: Roles of the nuisance terms: not part of the model's dynamics, not reported as its parameters.
NUISANCE_ROLES = frozenset({Role.OUTPUT_BIAS, Role.STATE_BIAS, Role.INPUT_BIAS, Role.INPUT_EDGE, Role.BOUNDARY})


@dataclass(frozen=True)
class Slot(Codec):
    """One estimated quantity of a fit, typed: what it is and which record it belongs to.

    Parameters
    ----------
    name : str
        The estimate's name in the result (``"bias_q[rec]"`` for a record's
        nuisance term in a fit of several records, else the base name).
    base : str
        The quantity's own name (``"bias_q"``, ``"Cm_a"``).
    role : Role
        What the quantity is.
    record : str or None
        The record a nuisance term belongs to; None for the model's
        parameters, which every record shares.
    """

    name: str
    base: str
    role: Role
    record: str | None = None

    json_fields = {"name": SKIP, "role": choice(Role)}  # the name is the result's (its container's)
    json_source = "slot"

    @classmethod
    def from_fields(cls, f, name: str | None = None, **given) -> "Slot":
        """Inverse of :meth:`to_dict` from the fields of ``{"base", "role", "record"}``, every key checked.

        Parameters
        ----------
        f : fdml.jsoncodec.Fields
            The fields of the JSON object.
        name : str, optional
            The estimate's name in its result (default: the base name, as in a fit of one record).
        **given
            Other field values (none: every other one is in the JSON).

        Returns
        -------
        Slot
            The slot.
        """
        return super().from_fields(f, name=f.string("base") if name is None else name, **given)


def _bound(sign: float) -> Spec:
    """A bound written as a number, an infinite one as null (read back as ``sign`` * inf)."""
    return Spec(
        lambda f, k, done: sign * math.inf if (v := f.number(k, allow_none=True)) is None else v,
        write=lambda v: None if math.isinf(v) else v,
    )


@dataclass(frozen=True)
class Parameter(Codec):
    """One model parameter.

    ``to_dict``/``from_dict`` (:class:`~fdml.jsoncodec.Codec`) write every field, infinite
    bounds as null and the role as its JSON string; a missing optional key takes its default.

    Parameters
    ----------
    name : str
        Identifier, e.g. ``"CLa_w"`` or ``"M_a"``.
    value : float
        Current (or starting) value, in ``unit``.
    free : bool, optional
        True if the estimator adjusts it, False if it is held fixed.
    lower, upper : float, optional
        Bounds applied by the estimator (default unbounded).
    unit : str, optional
        Unit string for reports (``"1/rad"``, ``"s"``, ``"-"``).
    description : str, optional
        One line for summaries.
    role : Role, optional
        What the parameter is (default :attr:`Role.AERO`).
    """

    name: str
    value: float
    free: bool = True
    lower: float = -math.inf
    upper: float = math.inf
    unit: str = ""
    description: str = ""
    role: Role = Role.AERO

    json_fields = {"lower": _bound(-1.0), "upper": _bound(1.0), "role": choice(Role)}
    json_source = "parameter"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError("a parameter needs a non-empty name")
        v = float(self.value)
        if not math.isfinite(v):
            raise ParameterError(f"parameter {self.name!r} has a non-finite value {self.value!r}")
        if not self.lower <= self.upper:
            raise ParameterError(f"parameter {self.name!r}: lower bound {self.lower} exceeds upper bound {self.upper}")
        if not self.lower <= v <= self.upper:
            raise ParameterError(
                f"parameter {self.name!r}: value {v} lies outside its bounds [{self.lower}, {self.upper}]"
            )
        object.__setattr__(self, "value", v)
        object.__setattr__(self, "role", _role(self.role, self.name))


def _role(value, name: str) -> Role:
    """``value`` as a :class:`Role` (its JSON string accepted); an unknown one is a one-line error."""
    try:
        return Role(value)
    except ValueError:
        raise ParameterError(
            f"parameter {name!r}: unknown role {value!r}; one of {', '.join(r.value for r in Role)}"
        ) from None


@dataclass(frozen=True)
class Parameters:
    """An ordered, immutable set of :class:`Parameter`.

    Indexing by name returns the :class:`Parameter`; :attr:`values` is a plain
    ``{name: value}`` dict.  Methods that change something return a new set.

    Parameters
    ----------
    items : tuple of Parameter, optional
        The parameters, in order; their names must be unique.
    """

    items: tuple[Parameter, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        names = [p.name for p in self.items]
        if len(set(names)) != len(names):
            dup = {n for n in names if names.count(n) > 1}
            raise ParameterError(f"duplicate parameter names: {sorted(dup)}")

    def __repr__(self) -> str:
        rows = [
            f"  {p.name:14s} {p.value:12.6g} {'free' if p.free else 'fixed':5s} {p.unit}".rstrip() for p in self.items
        ]
        return "Parameters(\n" + "\n".join(rows) + "\n)"

    # --- mapping-like access -------------------------------------------------
    def __getitem__(self, name: str) -> Parameter:
        for p in self.items:
            if p.name == name:
                return p
        raise ParameterError(self._unknown_message(name))

    def __contains__(self, name: object) -> bool:
        return any(p.name == name for p in self.items)

    def __iter__(self) -> Iterator[Parameter]:
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)

    def _unknown_message(self, name: str) -> str:
        return f"unknown parameter {name!r}; known parameters: {', '.join(self.names)}"

    def check_names(self, names: Iterable[str]) -> None:
        """Raise :class:`ParameterError` naming any name not in this set.

        Parameters
        ----------
        names : iterable of str
            Names to check.
        """
        known = set(self.names)
        for n in names:
            if not isinstance(n, str) or n not in known:
                raise ParameterError(self._unknown_message(n))

    @property
    def names(self) -> tuple[str, ...]:
        """All parameter names, in order."""
        return tuple(p.name for p in self.items)

    @property
    def free_names(self) -> tuple[str, ...]:
        """Names of the free parameters, in order."""
        return tuple(p.name for p in self.items if p.free)

    @property
    def free_model_names(self) -> tuple[str, ...]:
        """Names of the free parameters that belong to the model itself (no nuisance :class:`Role`), in order."""
        return tuple(p.name for p in self.items if p.free and not p.role.nuisance)

    @property
    def values(self) -> dict[str, float]:
        """``{name: value}`` for every parameter."""
        return {p.name: p.value for p in self.items}

    def array(self, names: Iterable[str] | None = None) -> np.ndarray:
        """Values of ``names`` (default: the free ones) as a float array.

        Parameters
        ----------
        names : iterable of str, optional
            Parameters, in the order wanted; default the free ones.

        Returns
        -------
        numpy.ndarray
            The values, each in its parameter's unit.
        """
        names = self.free_names if names is None else tuple(names)
        return np.array([self[n].value for n in names], dtype=float)

    # --- functional updates --------------------------------------------------
    def _update(self, changes: Mapping[str, dict]) -> "Parameters":
        self.check_names(changes)
        return Parameters(tuple(replace(p, **changes[p.name]) if p.name in changes else p for p in self.items))

    def with_values(self, values: Mapping[str, float] | None = None, **kw: float) -> "Parameters":
        """Return a copy with new values (free/fixed status unchanged).

        Parameters
        ----------
        values : mapping of str to float, optional
            New values by name.
        **kw : float
            More new values by name.

        Returns
        -------
        Parameters
            The copy.
        """
        vals = dict(values or {}, **kw)
        return self._update({k: {"value": float(v)} for k, v in vals.items()})

    def fix(self, names: Iterable[str] | Mapping[str, float]) -> "Parameters":
        """Return a copy with ``names`` fixed (a mapping also sets their values).

        Parameters
        ----------
        names : iterable of str or mapping of str to float
            Parameters to fix (with their values for a mapping).

        Returns
        -------
        Parameters
            The copy.
        """
        if isinstance(names, Mapping):
            return self._update({k: {"value": float(v), "free": False} for k, v in names.items()})
        return self._update({k: {"free": False} for k in names})

    def free(self, names: Iterable[str]) -> "Parameters":
        """Return a copy with ``names`` freed.

        Parameters
        ----------
        names : iterable of str
            Parameters to free.

        Returns
        -------
        Parameters
            The copy.
        """
        return self._update({k: {"free": True} for k in names})

    def bound(self, name: str, lower: float = -math.inf, upper: float = math.inf) -> "Parameters":
        """Return a copy with bounds on ``name`` (its value is moved inside them).

        Parameters
        ----------
        name : str
            The parameter.
        lower, upper : float, optional
            The bounds, in the parameter's unit (default unbounded).

        Returns
        -------
        Parameters
            The copy.
        """
        if not lower <= upper:
            raise ParameterError(f"parameter {name!r}: lower bound {lower} exceeds upper bound {upper}")
        v = min(max(self[name].value, float(lower)), float(upper))
        return self._update({name: {"lower": float(lower), "upper": float(upper), "value": v}})

    def only_free(self, names: Iterable[str]) -> "Parameters":
        """Return a copy in which exactly ``names`` are free.

        Parameters
        ----------
        names : iterable of str
            The parameters to free; all others are fixed.

        Returns
        -------
        Parameters
            The copy.
        """
        names = set(names)
        self.check_names(names)
        return Parameters(tuple(replace(p, free=p.name in names) for p in self.items))

    def extended(self, extra: Iterable[Parameter]) -> "Parameters":
        """Return a copy with ``extra`` parameters appended.

        Parameters
        ----------
        extra : iterable of Parameter
            Parameters to append (names not yet in the set).

        Returns
        -------
        Parameters
            The copy.
        """
        return Parameters(self.items + tuple(extra))

    def to_list(self) -> list[dict]:
        """JSON-ready list of dicts.

        Returns
        -------
        list of dict
            :meth:`Parameter.to_dict` of each parameter, in order.
        """
        return [p.to_dict() for p in self.items]

    @classmethod
    def from_list(cls, items: Iterable[Mapping]) -> "Parameters":
        """Inverse of :meth:`to_list`.

        Parameters
        ----------
        items : iterable of mapping
            Dicts as written by :meth:`Parameter.to_dict`.

        Returns
        -------
        Parameters
            The set.
        """
        return cls(tuple(Parameter.from_dict(d) for d in items))


def as_names(value, what: str) -> list[str]:
    """Parameter names given as ``fix``/``free``: a str is one name (or several, comma-separated).

    A str is not iterated character by character (``"Cm_de"`` is one name,
    not ``C``, ``m``, ...); commas separate names as they do for ``outputs``.

    Parameters
    ----------
    value : None, str or iterable of str
        The names; a mapping gives its keys.
    what : str
        The argument's name, for messages (``"fix"``, ``"free"``).

    Returns
    -------
    list of str
        The names, in order (empty for None).
    """
    if value is None:
        return []
    if isinstance(value, str):
        return [n.strip() for n in value.split(",") if n.strip()]
    try:
        names = list(value)  # a mapping gives its keys
    except TypeError:
        raise ParameterError(f"{what} must be parameter names (a str or a list of str), got {value!r}") from None
    bad = [n for n in names if not isinstance(n, str)]
    if bad:
        raise ParameterError(f"{what} must be parameter names (str), got {bad[0]!r}")
    return names


def fixed_values(value) -> dict[str, float] | list[str]:
    """``fix`` normalised: a ``{name: value}`` mapping as a dict of floats, else the names (:func:`as_names`).

    Parameters
    ----------
    value : None, str, iterable of str or mapping
        The parameters to fix (a mapping also sets their values).

    Returns
    -------
    dict of str to float, or list of str
        The values by name, or the names.
    """
    if not isinstance(value, Mapping):
        return as_names(value, "fix")
    out = {}
    for k, v in value.items():
        if not isinstance(k, str):
            raise ParameterError(f"fix must map parameter names (str) to values, got the key {k!r}")
        try:
            out[k] = float(v)
        except (TypeError, ValueError):
            raise ParameterError(f"fix: the value of {k} must be a number, got {v!r}") from None
    return out


def check_fix_free(fix, free) -> None:
    """Refuse a parameter named both in ``fix`` and in ``free`` (``--fix`` and ``--free``).

    Which one should win is not knowable, so neither does: the user decides.

    Parameters
    ----------
    fix, free : None, str or iterable of str
        The names to fix and to free (see :func:`as_names`).
    """
    both = [n for n in as_names(fix, "fix") if n in set(as_names(free, "free"))]
    if both:
        raise ParameterError(
            f"parameter(s) {', '.join(both)} named in both fix and free (--fix and --free): "
            "a parameter is either fixed or free; drop it from one of them"
        )
