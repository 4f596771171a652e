"""CSV records in any column layout: a user-given column map, units and signs."""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Mapping

import numpy as np

from ..channels import REQUIRED, SIGNALS
from ..errors import RecordError
from ._common import check_path, check_trim, finish, wrap_read_error
from .units import QUANTITY, normalise_unit, unit_factor

__all__ = ["read_csv_mapped", "split_header_unit"]

_HEADER_UNIT = re.compile(r"^\s*(?P<name>.*?)\s*[\[(](?P<unit>[^\])]*)[\])]\s*$")


def split_header_unit(cell: str) -> tuple[str, str | None]:
    """``"alpha (deg)"`` or ``"alpha [deg]"`` -> ``("alpha", "deg")``; ``"alpha"`` -> ``("alpha", None)``.

    Parameters
    ----------
    cell : str
        A header cell.

    Returns
    -------
    name : str
        The column name, stripped.
    unit : str or None
        The unit in brackets or parentheses, or None.
    """
    m = _HEADER_UNIT.match(cell)
    if m and m.group("name"):
        return m.group("name").strip(), m.group("unit").strip() or None
    return cell.strip(), None


def read_csv_mapped(
    path,
    columns: Mapping[str, str],
    units: Mapping[str, str] | None = None,
    sign: Mapping[str, float] | None = None,
    t0: float | None = None,
    t1: float | None = None,
    *,
    delimiter: str | None = None,
    trim: str | None = None,
    name: str | None = None,
    meta: Mapping | None = None,
    check_units: bool = True,
):
    """Read a CSV record with a user-given column map, units and signs.

    Parameters
    ----------
    path : str or Path
        Text file with one header row naming the columns, then one sample
        per row.  Header cells may carry a unit, ``"AOA (deg)"`` or
        ``"AOA [deg]"``; the column is then matched by ``AOA`` or the full cell.
    columns : mapping
        A mapping fdml signal -> column name, e.g. ``{"t": "time", "de": "elev",
        "alpha": "AOA", "q": "pitch_rate", "az": "nz"}``.  ``t``, ``de``,
        ``alpha``, ``q`` and ``az`` are required; any other fdml signal
        (``theta``, ``V``, ``h``, ``qdot``, ``ax``, ``qbar``, ``alpha_w``,
        ``hdot``) may be mapped too.
    units : mapping, optional
        A mapping fdml signal -> unit of its column, e.g. ``{"alpha": "deg", "q":
        "deg/s", "az": "m/s^2"}``.  Needed for every mapped signal whose
        header carries no unit (``t`` defaults to s).  Accepted units (see
        :data:`fdml.io.units.UNITS`): angles rad, deg, mrad; rates rad/s, deg/s;
        specific force g, m/s^2, ft/s^2; speed m/s, ft/s, kt, km/h; length
        m, ft; time s, ms; pressure Pa, hPa, kPa, lbf/ft^2.
    sign : mapping, optional
        A mapping fdml signal -> +1 or -1, applied after unit conversion.  fdml wants
        ``az`` positive **down** (body-z specific force, about -1 g in level
        flight, docs/theory.md Eq. 5): a normal load factor n_z (+1 g in level
        flight, positive up) needs ``units={"az": "g"}, sign={"az": -1}``.
        Elevator: trailing edge down positive; alpha, q: nose up positive.
    t0, t1 : float, optional
        Time window, s (the file's time, after unit conversion).
    delimiter : str, optional
        Field separator; default: sniffed among ``,`` ``;`` tab and spaces.
    trim : {None, "none", "first", "mean"}, optional
        Trim is kept by default (the estimator removes it).
    name : str, optional
        Record name (default: file stem).
    meta : mapping, optional
        Flight condition to attach (``U`` m/s, ``rho``, ``mass``, ...);
        ``U`` defaults to the window mean of a mapped ``V``.
    check_units : bool, optional
        Passed to :class:`~fdml.record.Record` (rejects angles that look like
        degrees after conversion).

    Returns
    -------
    Record
        The record in fdml's units and signs (SI, ``az`` in g positive down).

    Raises
    ------
    RecordError
        Naming the file and the problem: a mapped column the header lacks, an
        unknown unit, a unit of the wrong kind (``deg`` for ``az``), a unit
        given both in the header and in ``units`` that disagree ("mixed
        units"), a sign other than +-1, a row with a missing or non-numeric
        value, or a window outside the record.
    """
    p = check_path(path)
    check_trim(trim)
    units, sign = _check_maps(p, columns, units, sign)
    header, col_index, header_units, data = _read_columns(p, columns, delimiter)
    t, signals, conv, chans = _convert(p, header, col_index, header_units, data, units, sign)
    m = {
        "source": str(p),
        "format": "csv-map",
        "channels": chans,
        "conversion": conv,
        "sign": {k: int(sign.get(k, 1)) for k in signals},
    }
    user_meta = dict(meta or {})
    if "V" in signals and "U" not in user_meta:
        m["_per_sample"] = {"U": signals["V"]}
    m.update(user_meta)
    return finish(p, t, signals, m, name=name, t0=t0, t1=t1, trim=trim, check_units=check_units)


def _check_maps(p, columns, units, sign) -> tuple[dict, dict]:
    """Check the column, unit and sign maps against fdml's signals; the unit and sign maps as dicts."""
    if not isinstance(columns, Mapping) or not columns:
        raise RecordError(
            f"{p}: columns must map fdml signals to CSV column names, e.g. "
            "{'t': 'time', 'de': 'elev', 'alpha': 'AOA', 'q': 'q', 'az': 'nz'}"
        )
    units = dict(units or {})
    sign = dict(sign or {})
    known = ("t", *SIGNALS)
    for label, mp in (("columns", columns), ("units", units), ("sign", sign)):
        bad = [k for k in mp if k not in known]
        if bad:
            raise RecordError(
                f"{p}: {label} names unknown fdml signal(s) {', '.join(map(repr, bad))}; known: {', '.join(known)}"
            )
    missing_req = [k for k in ("t", *REQUIRED) if k not in columns]
    if missing_req:
        raise RecordError(f"{p}: the column map lacks {', '.join(missing_req)} (t, de, alpha, q and az are required)")
    for label, mp in (("units", units), ("sign", sign)):
        extra = [k for k in mp if k not in columns]
        if extra:
            raise RecordError(f"{p}: {label} given for signal(s) not in the column map: {', '.join(extra)}")
    for k, v in sign.items():
        if isinstance(v, bool) or v not in (1, -1):  # exactly +-1: a scale factor belongs in units=
            raise RecordError(f"{p}: sign of {k} must be +1 or -1, got {v!r}")
    return units, sign


def _read_columns(p, columns, delimiter):
    """Header cells, column index and header unit per mapped signal, and the numeric data (unmapped: nan)."""
    try:
        text = p.read_text(encoding="utf-8-sig")  # UTF-8; a leading BOM (spreadsheet export) is dropped
    except (OSError, UnicodeDecodeError) as exc:
        raise wrap_read_error(p, "a CSV text file", exc) from None
    lines = [
        (i, ln) for i, ln in enumerate(text.splitlines(), start=1) if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not lines:
        raise RecordError(f"{p}: no header row and no data")
    split = _splitter(p, lines[0][1], delimiter)
    header = [c.strip() for c in split(lines[0][1])]
    names = [split_header_unit(c) for c in header]

    col_index, header_units = {}, {}
    for sig, col in columns.items():
        if not isinstance(col, str):
            raise RecordError(f"{p}: column for {sig} must be a header name (string), got {col!r}")
        hits = [i for i, (h, (nm, _u)) in enumerate(zip(header, names)) if col.strip() in (h, nm)]
        if not hits:
            raise RecordError(f"{p}: no column {col!r} (mapped to {sig}); the header has: {', '.join(header)}")
        if len(hits) > 1:
            raise RecordError(f"{p}: column name {col!r} (mapped to {sig}) appears {len(hits)} times in the header")
        col_index[sig] = hits[0]
        header_units[sig] = names[hits[0]][1]

    data = np.full((len(lines) - 1, len(header)), np.nan)  # unmapped columns stay nan
    for r, (lineno, ln) in enumerate(lines[1:]):
        cells = split(ln)
        if len(cells) != len(header):
            raise RecordError(
                f"{p}: line {lineno} has {len(cells)} fields but the header has {len(header)} "
                "(truncated or corrupt file?)"
            )
        for c in sorted(set(col_index.values())):
            s = cells[c].strip()
            if not s:
                raise RecordError(f"{p}: line {lineno}, column {header[c]!r}: missing value")
            try:
                data[r, c] = float(s)
            except ValueError:
                raise RecordError(f"{p}: line {lineno}, column {header[c]!r}: {s!r} is not a number") from None
    if data.shape[0] < 4:
        raise RecordError(f"{p}: only {data.shape[0]} data row(s); at least 4 are needed")
    return header, col_index, header_units, data


def _convert(p, header, col_index, header_units, data, units, sign):
    """Time and signals in fdml's units and signs, with the conversion and source column of each."""
    signals, conv, chans = {}, {}, {}
    for sig, i in col_index.items():
        hu, uu = header_units[sig], units.get(sig)
        if hu is not None and uu is not None and normalise_unit(hu) != normalise_unit(uu):
            raise RecordError(
                f"{p}: mixed units for {sig}: the header of column {header[i]!r} says {hu!r} but --units "
                f"(Python: units=) says {uu!r}"
            )
        unit = uu or hu or ("s" if sig == "t" else None)
        if unit is None:
            raise RecordError(
                f"{p}: no unit for {sig} (column {header[i]!r}); give --units {sig}=UNIT (Python: "
                f"units={{{sig!r}: ...}}) or write it in the header, e.g. 'AOA (deg)'"
            )
        f = unit_factor(unit, QUANTITY[sig], what=f"{p}: {sig} (column {header[i]!r})")
        signals[sig] = data[:, i] * f * float(sign.get(sig, 1))
        chans[sig] = header[i]
        conv[sig] = {"unit": unit, "factor": f}
    return signals.pop("t"), signals, conv, chans


def _splitter(p, head: str, delimiter: str | None):
    """A function splitting a line into cells: by ``delimiter``, else by the first of , ; tab or spaces in ``head``."""
    if delimiter is None:
        delimiter = next((d for d in (",", ";", "\t") if d in head), None)
    if delimiter is None:
        if len(head.split()) < 2:
            raise RecordError(
                f"{p}: cannot tell the field separator from the header {head[:60]!r}; give --delimiter CHAR "
                "(Python: delimiter=)"
            )
        delimiter = "whitespace"
    if delimiter in (" ", "whitespace"):
        return str.split
    return lambda ln: next(csv.reader(io.StringIO(ln), delimiter=delimiter))
