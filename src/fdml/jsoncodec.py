"""The one JSON codec of fdml: results, studies, reports, batch tables and ``--json`` output.

Writing
    :func:`to_jsonable` turns what fdml holds into plain JSON data: numpy
    scalars (``bool_``, integers, floats) into Python ones, arrays into nested
    lists, complex numbers and arrays into ``{"re": [...], "im": [...]}``,
    non-finite floats into the strings ``"nan"``, ``"inf"`` and ``"-inf"``
    (JSON has neither; ``nonfinite="null"`` writes ``null`` instead), tuples
    and sets into lists, paths into strings, mapping keys into strings and
    objects with a ``to_dict()`` method into its dict.  :func:`dumps`,
    :func:`json_text` (the text, also written to a file when given: the body of
    every ``to_json``) and :func:`write_json` (atomic, through
    :func:`fdml.outputs.atomic_write_text`) use it, so no writer ever meets a
    type it cannot encode.

Reading
    :func:`loads` parses text (a UTF-8 byte-order mark is ignored);
    :func:`read_json` reads a user's file and turns every way it can be
    unreadable (missing, a folder, not UTF-8, not JSON) into one
    :class:`~fdml.errors.FdmlError` line that names the file.
    :class:`Fields` gives typed access to the keys of a decoded object, so
    that a hand-edited file with a key missing or of the wrong type or shape
    is refused with one line naming the file and the key.  The decoders
    accept what :func:`to_jsonable` writes and also the ``NaN``/``Infinity``
    tokens and ``null`` that earlier fdml versions wrote.

Objects
    A result or state object (a fit, a record, its spectra, a parameter, a
    comparison, a verdict, ...) derives ``to_dict`` and ``from_dict`` from its
    dataclass fields (:class:`Codec`, one :class:`Spec` per field that needs
    more than its annotation says).  The fit's options are read field by field
    into :class:`~fdml.fit_options.FitOptions`, whose constructor validates each
    one.  Six objects write a layout of their own
    with :class:`Fields` instead, because their JSON is not their fields: the
    aircraft file (a user's file, keys in SI units, with its own messages), and
    the reports read by people and scripts, whose keys are figures derived from
    the fields (a gap-map cell's coherent fraction, the kinematic evidence's
    flattened findings, the diagnosis report's sections, a design plan's gains
    and a prediction's ``{name: {value, stderr}}``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path, PurePath
from typing import Any, ClassVar, Literal, cast, overload

import numpy as np

from .errors import FdmlError

__all__ = [
    "to_jsonable",
    "dumps",
    "loads",
    "read_json",
    "write_json",
    "json_text",
    "float_value",
    "float_array",
    "complex_array",
    "Fields",
    "Codec",
    "Spec",
    "SKIP",
    "boolean",
    "choice",
    "complexes",
    "floats",
    "integer",
    "mapping",
    "nested",
    "nested_list",
    "number",
    "number_map",
    "numbers",
    "pairs",
    "path",
    "renamed",
    "specs",
    "text",
    "texts",
]

#: Strings that stand for non-finite floats (lower case; ``str(float)`` and JavaScript spellings).
_NONFINITE = {
    "nan": math.nan,
    **dict.fromkeys(("inf", "+inf", "infinity", "+infinity"), math.inf),
    **dict.fromkeys(("-inf", "-infinity"), -math.inf),
}


# --- writing ------------------------------------------------------------------------------------
def _float(x: float, nonfinite: str):
    if math.isfinite(x):
        return x
    if nonfinite == "null":
        return None
    return str(x)  # "nan", "inf", "-inf"


def _complex(a, nonfinite: str) -> dict:
    a = np.asarray(a)
    return {"re": _array(a.real.astype(float), nonfinite), "im": _array(a.imag.astype(float), nonfinite)}


def _array(a: np.ndarray, nonfinite: str):
    if a.dtype.kind == "f":
        if a.ndim == 0:
            return _float(float(a), nonfinite)
        if np.all(np.isfinite(a)):
            return a.tolist()  # fast path: nothing to replace
        return [_array(x, nonfinite) for x in a]
    return a.tolist()  # bool, integer, string arrays


def to_jsonable(obj, *, default=str, nonfinite: str = "string"):
    """A copy of ``obj`` made of JSON types only (dict, list, str, int, float, bool, None).

    Parameters
    ----------
    obj : object
        Plain data, numpy scalars and arrays (complex ones as ``{"re", "im"}``),
        tuples, sets, paths, mappings, and objects with a ``to_dict()`` method,
        nested in any way.
    default : callable or None, optional
        Applied to any other object (default ``str``); None raises
        :class:`TypeError` instead.
    nonfinite : {"string", "null"}, optional
        How NaN and infinities are written: as ``"nan"``, ``"inf"``, ``"-inf"``
        (default; :func:`float_value` reads them back) or as ``null``.

    Returns
    -------
    object
        Encodable by :func:`json.dumps` with ``allow_nan=False``.
    """
    if nonfinite not in ("string", "null"):
        raise ValueError(f"nonfinite must be 'string' or 'null', got {nonfinite!r}")

    def conv(o):
        if o is None or isinstance(o, str):
            return o
        if isinstance(o, (bool, np.bool_)):
            return bool(o)
        if isinstance(o, (int, np.integer)):
            return int(o)
        if isinstance(o, (float, np.floating)):
            return _float(float(o), nonfinite)
        if isinstance(o, (complex, np.complexfloating)) or (isinstance(o, np.ndarray) and o.dtype.kind == "c"):
            return _complex(o, nonfinite)
        if isinstance(o, np.ndarray):
            if o.dtype.kind in "biuf":
                return _array(o, nonfinite)
            return [conv(x) for x in o.tolist()]
        if isinstance(o, Mapping):
            return {k if isinstance(k, str) else str(conv(k)): conv(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [conv(x) for x in o]
        if isinstance(o, (set, frozenset)):
            items = [conv(x) for x in o]
            try:
                return sorted(items)
            except TypeError:  # mixed types: any stable order will do
                return sorted(items, key=repr)
        if isinstance(o, PurePath):
            return str(o)
        to_dict = getattr(o, "to_dict", None)
        if callable(to_dict) and not isinstance(o, type):
            return conv(to_dict())
        if default is None:
            raise TypeError(f"cannot write an object of type {type(o).__name__} as JSON: {o!r}")
        return conv(default(o))

    return conv(obj)


def dumps(
    obj,
    *,
    indent: int | None = 1,
    compact: bool = False,
    sort_keys: bool = False,
    default=str,
    nonfinite: str = "string",
) -> str:
    """JSON text of ``obj`` (see :func:`to_jsonable` for the types and ``default``).

    ``compact=True`` writes one line without spaces (``indent`` ignored);
    ``indent=None`` one line with the usual spaces.

    Parameters
    ----------
    obj : object
        What to encode (see :func:`to_jsonable`).
    indent : int or None, optional
        Spaces per nesting level (default 1); None writes one line.
    compact : bool, optional
        One line without spaces after separators.
    sort_keys : bool, optional
        Sort the keys of every object.
    default : callable or None, optional
        Applied to objects of no JSON type (see :func:`to_jsonable`).
    nonfinite : {"string", "null"}, optional
        How NaN and infinities are written.

    Returns
    -------
    str
        The JSON text.
    """
    data = to_jsonable(obj, default=default, nonfinite=nonfinite)
    if compact:
        return json.dumps(data, separators=(",", ":"), sort_keys=sort_keys, allow_nan=False)
    return json.dumps(data, indent=indent, sort_keys=sort_keys, allow_nan=False)


def write_json(path, obj, *, inputs=(), indent: int | None = 1, what: str = "output file") -> Path:
    """Write ``obj`` as JSON to ``path`` atomically; return the path.

    Goes through :func:`fdml.outputs.atomic_write_text`, which refuses to
    replace any of ``inputs`` or anything that is not a regular file
    (``what`` names the file in its messages).

    Parameters
    ----------
    path : str or Path
        The file to write.
    obj : object
        What to encode (see :func:`to_jsonable`).
    inputs : iterable of str or Path, optional
        Files the output must not replace.
    indent : int or None, optional
        Spaces per nesting level (default 1); None writes one line.
    what : str, optional
        What the file is, for the messages.

    Returns
    -------
    Path
        The path written.
    """
    json_text(obj, path, inputs=inputs, indent=indent, what=what)
    return Path(path)


def json_text(obj, path=None, *, inputs=(), indent: int | None = 1, what: str = "output file") -> str:
    """JSON text of ``obj``; written atomically to ``path`` as well when given.

    The body of every ``to_json`` method and of :func:`write_json`: goes through
    :func:`fdml.outputs.atomic_write_text`, which refuses to replace any of
    ``inputs`` or anything that is not a regular file (``what`` names the file
    in its messages).

    Parameters
    ----------
    obj : object
        What to encode (see :func:`to_jsonable`).
    path : str or Path, optional
        The file to write; None only returns the text.
    inputs : iterable of str or Path, optional
        Files the output must not replace.
    indent : int or None, optional
        Spaces per nesting level (default 1); None writes one line.
    what : str, optional
        What the file is, for the messages.

    Returns
    -------
    str
        The JSON text (the file holds it and a newline).
    """
    from .outputs import atomic_write_text

    text = dumps(obj, indent=indent)
    if path is not None:
        atomic_write_text(path, text + "\n", inputs=inputs, what=what)
    return text


# --- reading ------------------------------------------------------------------------------------
def loads(text: str | bytes):
    """Parse JSON text (bytes are read as UTF-8); a leading byte-order mark is ignored.

    Raises :class:`json.JSONDecodeError` (a ``ValueError``) on invalid JSON and
    :class:`UnicodeDecodeError` on bytes that are not UTF-8.

    Parameters
    ----------
    text : str or bytes
        The JSON text.

    Returns
    -------
    object
        The decoded value (dict, list, str, int, float, bool or None).
    """
    if isinstance(text, (bytes, bytearray)):
        text = bytes(text).decode("utf-8-sig")
    elif text.startswith("\ufeff"):
        text = text[1:]
    return json.loads(text)


def read_json(path, *, what: str = "result file"):
    """Read and parse the JSON file ``path``; every failure is one :class:`FdmlError` line.

    Parameters
    ----------
    path : str or Path
        The JSON file to read.
    what : str, optional
        What the file is, for the messages (``"result file"``,
        ``"Monte Carlo file"``, ``"aircraft file"``).

    Returns
    -------
    object
        The decoded value (dict, list, str, int, float, bool or None).

    Raises
    ------
    FdmlError
        The file does not exist, is a folder or not a regular file, cannot be
        read, is empty, is not UTF-8 (Latin-1 bytes, for example) or is not
        valid JSON (with the line and column).
    """
    p = Path(path)
    where = f"{what} {p}"
    try:
        st = os.stat(p)
        if stat.S_ISDIR(st.st_mode):
            raise FdmlError(f"{where} is a folder, not a JSON file")
        if not stat.S_ISREG(st.st_mode):
            raise FdmlError(f"{where} is not a regular file (a device, FIFO or socket)")
        raw = p.read_bytes()
    except FileNotFoundError:
        raise FdmlError(f"{where} does not exist") from None
    except OSError as exc:
        raise FdmlError(f"{where} cannot be read: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FdmlError(
            f"{where} is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}; "
            f"saved as Latin-1 or another code page?)"
        ) from None
    if not text.strip():
        raise FdmlError(f"{where} is empty")
    try:
        return loads(text)
    except json.JSONDecodeError as exc:
        raise FdmlError(f"{where} is not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    except RecursionError:
        raise FdmlError(f"{where} is not usable JSON: nested too deeply") from None


def _kind(v) -> str:
    """The JSON type of a decoded value, for messages."""
    return "null" if v is None else "object" if isinstance(v, Mapping) else type(v).__name__


def _checked(v, types, what: str):
    """``v`` if it is of ``types``, else a TypeError "must be <what>, got <its JSON type>"."""
    if not isinstance(v, types):
        raise TypeError(f"must be {what}, got {_kind(v)}")
    return v


def float_value(x) -> float:
    """A number as written by :func:`to_jsonable`: a JSON number or ``"nan"``, ``"inf"``, ``"-inf"``.

    Raises :class:`TypeError` or :class:`ValueError` for anything else
    (booleans and other strings included).

    Parameters
    ----------
    x : object
        The decoded JSON value.

    Returns
    -------
    float
        The number (NaN or an infinity for the strings).
    """
    if isinstance(x, bool):
        raise TypeError("must be a number, got bool")
    if isinstance(x, (int, float)):
        try:
            return float(x)
        except OverflowError:
            raise ValueError(
                f"must be a number within the float range, got an integer of {len(str(x))} digits"
            ) from None
    if isinstance(x, str):
        v = _NONFINITE.get(x.strip().lower())
        if v is not None:
            return v
        raise ValueError(f"must be a number, got the string {x[:40]!r}")
    raise TypeError(f"must be a number, got {_kind(x)}")


class _BadElement(ValueError):
    """An array element that is not a number (its description in ``args[0]``)."""


def _nested(v, depth=0, nulls=False):
    if isinstance(v, list):
        if depth > 32:
            raise _BadElement("lists nested more than 32 deep")
        return [_nested(x, depth + 1, nulls) for x in v]
    if v is None and nulls:
        return math.nan
    try:
        return float_value(v)
    except (TypeError, ValueError):
        desc = (
            f"the string {v[:40]!r}"
            if isinstance(v, str)
            else ("an object" if isinstance(v, Mapping) else f"a value of type {_kind(v)}")
        )
        if isinstance(v, int) and not isinstance(v, bool):
            desc = f"an integer of {len(str(v))} digits (beyond the float range)"
        raise _BadElement(desc) from None


def _shape_text(shape) -> str:
    return " x ".join("any" if s is None else str(s) for s in shape)


def _check_shape(a: np.ndarray, shape) -> np.ndarray:
    if shape is None:
        return a
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        got = f"shape {_shape_text(a.shape)}" if a.ndim else "a single number"
        if len(shape) == 1:
            want = "a list of numbers" if shape[0] is None else f"a list of {shape[0]} numbers"
            if a.ndim == 1:
                got = f"{a.size}"
        else:
            want = f"an array of shape {_shape_text(shape)}"
        raise ValueError(f"must be {want}, got {got}")
    return a


def float_array(v, shape=None, *, nulls: bool = False) -> np.ndarray:
    """A float array from nested lists of numbers (non-finite ones as strings).

    ``shape`` (a tuple, None for any length of that axis) is checked when
    given; ``nulls=True`` reads ``null`` as NaN.  Raises :class:`TypeError` or :class:`ValueError` with a message that
    completes "key 'x' ...".

    Parameters
    ----------
    v : object
        The decoded JSON value: a number or nested lists of numbers.
    shape : tuple of (int or None), optional
        The expected shape; None for any shape.
    nulls : bool, optional
        Read ``null`` as NaN instead of refusing it.

    Returns
    -------
    numpy.ndarray
        The float array.
    """
    if shape is not None and len(shape) > 0 and not isinstance(v, list):
        raise TypeError(f"must be a list of numbers, got {_kind(v)}")
    try:
        nested = _nested(v, 0, nulls)
    except _BadElement as exc:
        if not isinstance(v, list):
            raise TypeError(f"must be a number, got {exc.args[0]}") from None
        raise TypeError(f"must be a list of numbers, holds {exc.args[0]}") from None
    try:
        a = np.array(nested, dtype=float)
    except ValueError:
        raise ValueError("must be a rectangular array of numbers, got rows of different lengths") from None
    return _check_shape(a, shape)


def complex_array(v, shape=None) -> np.ndarray:
    """A complex array from ``{"re": ..., "im": ...}`` (see :func:`float_array`).

    Parameters
    ----------
    v : object
        The decoded JSON value, an object with the keys ``"re"`` and ``"im"``.
    shape : tuple of (int or None), optional
        The expected shape; None for any shape.

    Returns
    -------
    numpy.ndarray
        The complex array.
    """
    _checked(v, Mapping, "an object with keys 're' and 'im'")
    missing = [k for k in ("re", "im") if k not in v]
    if missing:
        raise ValueError(f"must be an object with keys 're' and 'im'; '{missing[0]}' is missing")
    re, im = float_array(v["re"]), float_array(v["im"])
    if re.shape != im.shape:
        raise ValueError(f"has 're' of shape {_shape_text(re.shape)} but 'im' of shape {_shape_text(im.shape)}")
    out = np.empty(re.shape, complex)
    out.real, out.imag = re, im  # not re + 1j * im: 1j * inf is nan + inf j
    return _check_shape(out, shape)


_MISSING = object()


def _typed_list(v, typ, what: str, length: int | None) -> list:
    _checked(v, list, f"a list of {what}")
    for x in v:
        if not isinstance(x, typ) or (typ is int and isinstance(x, bool)):
            raise TypeError(f"must be a list of {what}, holds {_kind(x)}")
        if typ is int and abs(x) >= 2**63:
            raise ValueError(f"must be a list of {what} below 2**63, holds one of {len(str(x))} digits")
    if length is not None and len(v) != length:
        raise ValueError(f"must have {length} entries, got {len(v)}")
    return v


class Fields:
    """Typed access to the keys of a decoded JSON object, with one-line errors.

    Every accessor raises :class:`FdmlError` ``"<source>: key '<key>' ..."``
    when the key is missing (and has no default) or holds the wrong type or
    shape; nested objects are named ``outer.inner`` or ``outer[i].inner``.

    Parameters
    ----------
    doc : object
        The decoded JSON value that should be an object.
    source : str
        What and where, e.g. ``"result file run.json"``.
    prefix : str, optional
        Key path of ``doc`` inside the file (for nested objects).
    """

    def __init__(self, doc, source: str, prefix: str = ""):
        self.source = source
        self.prefix = prefix
        if not isinstance(doc, Mapping):
            where = f"key '{prefix.rstrip('.')}' must be an object" if prefix else "expected a JSON object"
            raise FdmlError(f"{source}: {where}, got {_kind(doc)}")
        self.doc = doc

    def name(self, key: str) -> str:
        """The key's full path in the file (prefix and key).

        Parameters
        ----------
        key : str
            The key in this object.

        Returns
        -------
        str
            The prefix followed by the key.
        """
        return f"{self.prefix}{key}"

    def error(self, key: str, text: str) -> FdmlError:
        """The error for ``key``: ``"<source>: key '<key>' <text>"``.

        Parameters
        ----------
        key : str
            The key in this object.
        text : str
            What is wrong with the key's value.

        Returns
        -------
        FdmlError
            The error (not raised).
        """
        return FdmlError(f"{self.source}: key '{self.name(key)}' {text}")

    def __contains__(self, key) -> bool:
        return key in self.doc

    def raw(self, key: str, default=_MISSING):
        """The value of ``key`` as decoded, or ``default``; a missing key without default is an error.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        object
            The decoded value, unchecked.
        """
        if key not in self.doc and default is _MISSING:
            raise self.error(key, "is missing")
        return self.doc.get(key, default)

    def _get(self, key, default, convert):
        if key not in self.doc and default is not _MISSING:
            return default
        v = self.raw(key)
        try:
            return convert(v)
        except (TypeError, ValueError) as exc:
            raise self.error(key, str(exc)) from None

    def version(self, key: str, expected: int, older: tuple = ()) -> int:
        """An integer version equal to ``expected`` or one of ``older``; a string '1' is named as such.

        Parameters
        ----------
        key : str
            The key in this object.
        expected : int
            The version this code writes.
        older : tuple of int, optional
            Older versions it still reads.

        Returns
        -------
        int
            The version.
        """
        v = self.raw(key)
        known = (*older, expected)
        if isinstance(v, str):
            if v.strip() in map(str, known):
                raise self.error(key, f"is the string {v!r} where the integer {v.strip()} is expected")
            raise self.error(key, f"must be the integer {expected}, got the string {v[:40]!r}")
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.error(key, f"must be the integer {expected}, got {_kind(v)}")
        if v not in known:
            which = f"version {expected} only" if not older else f"versions {', '.join(map(str, known))}"
            raise self.error(key, f"is {v}: this fdml reads {which}")
        return v

    def integer(self, key: str, default=_MISSING, minimum: int | None = None) -> int:
        """The integer at ``key`` (not a bool), at least ``minimum`` when given.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        minimum : int, optional
            The smallest value allowed.

        Returns
        -------
        int
            The integer (or ``default``).
        """

        def conv(v):
            if isinstance(v, bool) or not isinstance(v, int):
                raise TypeError(f"must be an integer, got {_kind(v)}")
            if minimum is not None and v < minimum:
                raise ValueError(f"must be at least {minimum}, got {v}")
            return v

        return self._get(key, default, conv)

    @overload
    def number(self, key: str, default: float = ..., allow_none: Literal[False] = False) -> float: ...
    @overload
    def number(self, key: str, default: float | None = ..., allow_none: bool = False) -> float | None: ...

    def number(self, key: str, default: Any = _MISSING, allow_none: bool = False) -> float | None:
        """The finite number at ``key`` as a float (None allowed with ``allow_none``).

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        allow_none : bool, optional
            Accept ``null``, returned as None.

        Returns
        -------
        float or None
            The number (or ``default``).
        """
        return self._get(key, default, lambda v: None if v is None and allow_none else float_value(v))

    def boolean(self, key: str, default=_MISSING) -> bool:
        """The boolean at ``key``.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        bool
            The value (or ``default``).
        """
        return self._get(key, default, lambda v: _checked(v, bool, "true or false"))

    @overload
    def string(self, key: str, default: str = ..., choices: Any = None, allow_none: Literal[False] = False) -> str: ...
    @overload
    def string(
        self, key: str, default: str | None = ..., choices: Any = None, allow_none: bool = False
    ) -> str | None: ...

    def string(self, key: str, default: Any = _MISSING, choices: Any = None, allow_none: bool = False) -> str | None:
        """The string at ``key``, one of ``choices`` when given (None allowed with ``allow_none``).

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        choices : collection of str, optional
            The allowed values.
        allow_none : bool, optional
            Accept ``null``, returned as None.

        Returns
        -------
        str or None
            The string (or ``default``).
        """

        def conv(v):
            if v is None and allow_none:
                return None
            _checked(v, str, "a string")
            if choices is not None and v not in choices:
                raise ValueError(f"must be one of {', '.join(map(repr, choices))}, got {v[:40]!r}")
            return v

        return self._get(key, default, conv)

    def strings(self, key: str, default=_MISSING, length: int | None = None, choices=None) -> tuple:
        """The list of strings at ``key`` as a tuple, of ``length`` and from ``choices`` when given.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        length : int, optional
            The required number of entries.
        choices : collection of str, optional
            The allowed values.

        Returns
        -------
        tuple of str
            The strings (or ``default``).
        """

        def conv(v):
            _typed_list(v, str, "strings", length)
            if choices is not None:
                odd = [x for x in v if x not in choices]
                if odd:
                    raise ValueError(f"holds {odd[0][:40]!r}; allowed: {', '.join(choices)}")
            return tuple(v)

        return self._get(key, default, conv)

    def numbers(self, key: str, default=_MISSING, length: int | None = None, min_length: int = 0) -> tuple:
        """The list of finite numbers at ``key`` as a tuple of floats.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        length : int, optional
            The required number of entries.
        min_length : int, optional
            The smallest number of entries allowed.

        Returns
        -------
        tuple of float
            The numbers (or ``default``).
        """

        def conv(v):
            a = float_array(v, (length,))
            if a.size < min_length:
                raise ValueError(f"must hold at least {min_length} number(s), got {a.size}")
            return tuple(a.tolist())

        return self._get(key, default, conv)

    def floats(self, key: str, shape=None, default=_MISSING, nulls: bool = False) -> np.ndarray:
        """The float array at ``key``, of ``shape`` when given (NaN for null with ``nulls``).

        Parameters
        ----------
        key : str
            The key in this object.
        shape : tuple of (int or None), optional
            The expected shape (None for any length of an axis).
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        nulls : bool, optional
            Read ``null`` as NaN.

        Returns
        -------
        numpy.ndarray
            The float array (or ``default``).
        """
        return self._get(key, default, lambda v: float_array(v, shape, nulls=nulls))

    def flags(self, key: str, length: int | None = None, default=_MISSING) -> np.ndarray:
        """A list of true/false as a bool array.

        Parameters
        ----------
        key : str
            The key in this object.
        length : int, optional
            The required number of entries.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        numpy.ndarray
            The bool array (or ``default``).
        """
        return self._get(key, default, lambda v: np.array(_typed_list(v, bool, "true or false", length), bool))

    def integers(self, key: str, length: int | None = None, default=_MISSING) -> np.ndarray:
        """A list of integers as an int array.

        Parameters
        ----------
        key : str
            The key in this object.
        length : int, optional
            The required number of entries.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        numpy.ndarray
            The int array (or ``default``).
        """
        return self._get(key, default, lambda v: np.array(_typed_list(v, int, "integers", length), int))

    def complexes(self, key: str, shape=None, default=_MISSING) -> np.ndarray:
        """The complex array at ``key`` (stored as real and imaginary parts), of ``shape`` when given.

        Parameters
        ----------
        key : str
            The key in this object.
        shape : tuple of (int or None), optional
            The expected shape (None for any length of an axis).
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        numpy.ndarray
            The complex array (or ``default``).
        """
        return self._get(key, default, lambda v: complex_array(v, shape))

    def mapping(self, key: str, default=_MISSING) -> dict:
        """The JSON object at ``key`` as a dict.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        dict
            A copy of the object (or ``default``).
        """
        return self._get(key, default, lambda v: dict(_checked(v, Mapping, "an object")))

    def number_map(self, key: str, default=_MISSING) -> dict:
        """The JSON object of finite numbers at ``key`` as ``{name: float}``.

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        dict of str to float
            The numbers by name, in the file's order (or ``default``).
        """
        sub = self.sub(key, default)
        return sub if sub is default else {name: sub.number(name) for name in sub.doc}

    @overload
    def sub(self, key: str) -> Fields: ...
    @overload
    def sub(self, key: str, default: Any) -> Any: ...

    def sub(self, key: str, default: Any = _MISSING) -> Any:
        """The nested object at ``key`` as :class:`Fields` (``default`` when absent).

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.

        Returns
        -------
        Fields
            Access to the nested object (or ``default``).
        """
        return self._get(key, default, lambda v: Fields(v, self.source, f"{self.name(key)}."))

    def items(self, key: str, default=_MISSING, allow_none: bool = False) -> list:
        """A list of objects at ``key``, each as :class:`Fields` (None entries kept with ``allow_none``).

        Parameters
        ----------
        key : str
            The key in this object.
        default : object, optional
            Returned when the key is absent; without it a missing key is an error.
        allow_none : bool, optional
            Keep ``null`` entries as None.

        Returns
        -------
        list of Fields
            One entry per object (or ``default``).
        """

        def conv(v):
            return [
                None if (x is None and allow_none) else Fields(x, self.source, f"{self.name(key)}[{i}].")
                for i, x in enumerate(_checked(v, list, "a list"))
            ]

        return self._get(key, default, conv)


# --- the declarative codec ----------------------------------------------------------------------
@dataclass(frozen=True)
class Spec:
    """How one dataclass field is written to JSON and read back (see :class:`Codec`).

    Parameters
    ----------
    read : callable
        ``read(f, key, done) -> value``: the value at ``key`` of the :class:`Fields` ``f``;
        ``done`` holds the fields read so far (for shapes that follow another field).
    write : callable, optional
        ``write(value) -> JSON data`` (None: the value as it is, for :func:`to_jsonable`).
    key : str, optional
        The JSON key, when it is not the field's name (a key kept for old files).
    """

    read: Callable
    write: Callable | None = None
    key: str | None = None


#: A field that is not written (a cache, a back reference); it gets its default when read.
SKIP = Spec(read=lambda f, key, done: None)


def _dims(shape, done) -> tuple | None:
    """A shape whose entries may name an earlier field (its length)."""
    return None if shape is None else tuple(len(done[s]) if isinstance(s, str) else s for s in shape)


def text(choices=None, none: bool = False) -> Spec:
    """A string, one of ``choices`` when given (null allowed with ``none``).

    Parameters
    ----------
    choices : collection of str, optional
        The allowed values.
    none : bool, optional
        Accept null (None).

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.string(k, choices=choices, allow_none=none))


def number(none: bool = False) -> Spec:
    """A number (non-finite ones as the strings ``"nan"``, ``"inf"``), null allowed with ``none``.

    Parameters
    ----------
    none : bool, optional
        Accept null (None).

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.number(k, allow_none=none))


def integer(minimum: int | None = None) -> Spec:
    """An integer, at least ``minimum`` when given.

    Parameters
    ----------
    minimum : int, optional
        The smallest value allowed.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.integer(k, minimum=minimum))


def boolean() -> Spec:
    """True or false.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.boolean(k))


def choice(enum) -> Spec:
    """A member of the enumeration ``enum``, written as its value (a string).

    Parameters
    ----------
    enum : type
        An :class:`enum.Enum` of string values.

    Returns
    -------
    Spec
        The field's spec.
    """
    values = tuple(m.value for m in enum)
    return Spec(lambda f, k, done: enum(f.string(k, choices=values)), write=lambda m: m.value)


def texts(choices=None, length: int | None = None) -> Spec:
    """A list of strings, read as a tuple.

    Parameters
    ----------
    choices : collection of str, optional
        The allowed values.
    length : int, optional
        The required number of entries.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.strings(k, choices=choices, length=length))


def numbers(length: int | None = None, none: bool = False, min_length: int = 0) -> Spec:
    """A list of numbers, read as a tuple of floats (null for the whole list with ``none``).

    Parameters
    ----------
    length : int, optional
        The required number of entries.
    none : bool, optional
        Accept null (None).
    min_length : int, optional
        The smallest number of entries allowed.

    Returns
    -------
    Spec
        The field's spec.
    """

    def read(f, k, done):
        return None if none and f.raw(k) is None else f.numbers(k, length=length, min_length=min_length)

    return Spec(read)


def floats(*shape, nulls: bool = False) -> Spec:
    """A float array; ``shape`` entries are lengths, None (any) or the name of an earlier field (its length).

    Parameters
    ----------
    *shape : int, None or str
        The expected shape; none given: any shape.
    nulls : bool, optional
        Read null entries as NaN.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.floats(k, _dims(shape or None, done), nulls=nulls))


def complexes(*shape) -> Spec:
    """A complex array written as ``{"re", "im"}`` (``shape`` as for :func:`floats`).

    Parameters
    ----------
    *shape : int, None or str
        The expected shape; none given: any shape.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.complexes(k, _dims(shape or None, done)))


def pairs() -> Spec:
    """A list of number pairs, read as a tuple of float tuples.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: () if f.raw(k) == [] else tuple(map(tuple, f.floats(k, (None, 2)).tolist())))


def path() -> Spec:
    """A file system path, written as its string.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: Path(f.string(k)))


def mapping() -> Spec:
    """A JSON object, read as a dict as it is.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.mapping(k))


def number_map() -> Spec:
    """A JSON object of numbers, read as ``{name: float}``.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: f.number_map(k))


def nested(kind, none: bool = False) -> Spec:
    """An object of a class with ``from_fields`` (a :class:`Codec`), null allowed with ``none``.

    Parameters
    ----------
    kind : type
        The class.
    none : bool, optional
        Accept null (None).

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: None if none and f.raw(k) is None else kind.from_fields(f.sub(k)))


def nested_list(kind) -> Spec:
    """A list of objects of a class with ``from_fields``, read as a tuple.

    Parameters
    ----------
    kind : type
        The class.

    Returns
    -------
    Spec
        The field's spec.
    """
    return Spec(lambda f, k, done: tuple(kind.from_fields(x) for x in f.items(k)))


def renamed(spec: Spec, key: str) -> Spec:
    """``spec`` under another JSON key (kept for files written before a field was renamed).

    Parameters
    ----------
    spec : Spec
        The field's spec.
    key : str
        The key in the file.

    Returns
    -------
    Spec
        The spec, renamed.
    """
    return replace(spec, key=key)


#: Field annotations (as written, ``from __future__ import annotations``) and the spec each gets.
_BY_ANNOTATION = {
    "str": text,
    "str | None": lambda: text(none=True),
    "float": number,
    "float | None": lambda: number(none=True),
    "int": integer,
    "bool": boolean,
    "tuple[str, ...]": texts,
    "np.ndarray": floats,
    "dict": mapping,
    "Mapping": mapping,
    "Path": path,
}


def specs(kind: Any) -> dict[str, Spec]:
    """The spec of every field of the dataclass ``kind``: its ``json_fields`` entry, else by its annotation.

    Parameters
    ----------
    kind : type
        A dataclass deriving from :class:`Codec`.

    Returns
    -------
    dict of str to Spec
        Field name -> spec, in field order.

    Raises
    ------
    TypeError
        A field with neither an entry nor a known annotation (the class must say how to read it).
    """
    out = {}
    for fld in dataclasses.fields(kind):
        if fld.name in kind.json_fields:
            out[fld.name] = kind.json_fields[fld.name]
        elif (make := _BY_ANNOTATION.get(str(fld.type))) is not None:
            out[fld.name] = make()
        else:
            raise TypeError(
                f"{kind.__name__}.{fld.name}: annotation {fld.type!r} has no JSON spec; add it to json_fields"
            )
    return out


def _has_default(fld) -> bool:
    return fld.default is not dataclasses.MISSING or fld.default_factory is not dataclasses.MISSING


class Codec:
    """``to_dict``, ``from_dict`` and ``from_fields`` derived from a frozen dataclass's fields.

    A field is written under its name (or its spec's ``key``) as :func:`to_jsonable` writes its
    value, and read back with the reader its annotation calls for (``str``, ``float | None``,
    ``tuple[str, ...]``, ``np.ndarray``, ...) or the class's ``json_fields`` entry (a
    :class:`Spec`: shapes, choices, complex arrays, nested objects, renamed keys; :data:`SKIP`
    for a field not written).  A key that is absent gets the field's default, if it has one;
    every other problem is one :class:`~fdml.errors.FdmlError` line naming the source and the key.
    A class sets ``json_source`` (how its JSON is named in messages by default), may list
    derived properties in ``json_extra`` (written, not read) and may set ``json_format``, the
    ``(format, version)`` written first as the keys ``"format"`` and ``"version"`` (the class's
    reader checks them, with its own messages).
    """

    json_fields: ClassVar[Mapping[str, Spec]] = {}
    json_extra: ClassVar[tuple[str, ...]] = ()
    json_source: ClassVar[str] = "JSON object"
    json_format: ClassVar[tuple[str, int] | None] = None

    def to_dict(self) -> dict:
        """The object as plain JSON data: the format keys, if any, then every field (but the skipped ones) by name.

        Returns
        -------
        dict
            JSON-ready (:func:`to_jsonable`).
        """
        out: dict[str, Any] = {}
        if self.json_format is not None:
            out.update(format=self.json_format[0], version=self.json_format[1])
        for name, spec in specs(type(self)).items():
            if spec is not SKIP:
                value = getattr(self, name)
                out[spec.key or name] = value if spec.write is None else spec.write(value)
        out.update({name: getattr(self, name) for name in self.json_extra})
        return to_jsonable(out)

    @classmethod
    def from_fields(cls, f: Fields, **given):
        """Inverse of :meth:`to_dict` from the fields of a JSON object, every key checked.

        Parameters
        ----------
        f : Fields
            The object's fields.
        **given
            Field values the JSON does not hold (the container's: a name, an input).

        Returns
        -------
        object
            An instance of the class.
        """
        done = dict(given)
        fields_ = {fld.name: fld for fld in dataclasses.fields(cast(Any, cls))}
        for name, spec in specs(cls).items():
            key = spec.key or name
            if name in given or spec is SKIP or (key not in f and _has_default(fields_[name])):
                continue
            done[name] = spec.read(f, key, done)
        try:
            return cls(**done)
        except (TypeError, ValueError) as exc:
            where = f"key '{f.prefix.rstrip('.')}'" if f.prefix else "the object"
            raise FdmlError(f"{f.source}: {where} does not describe a {cls.__name__}: {exc}") from None

    @classmethod
    def from_dict(cls, d, *, source: str | None = None, **given):
        """Inverse of :meth:`to_dict`; a missing or mistyped key raises a one-line FdmlError naming ``source``.

        Parameters
        ----------
        d : dict
            As written by :meth:`to_dict`.
        source : str, optional
            What ``d`` came from, for the message (default the class's ``json_source``).
        **given
            Field values the JSON does not hold.

        Returns
        -------
        object
            An instance of the class.
        """
        return cls.from_fields(Fields(d, cls.json_source if source is None else source), **given)
