"""Reading real flight records into fdml :class:`~fdml.record.Record` objects.

Every loader returns a record in fdml's units and signs (SI, radians; ``az``
and ``ax`` in g, body z positive **down**, docs/theory.md Eq. 5; alpha, q and the
elevator as in :mod:`fdml.record`), with the flight condition and the
conversion applied in ``record.meta``.  Trim is kept unless ``trim=`` asks
for its removal (the estimator removes it itself); the trim values are
reported in ``meta["trim_values"]`` either way.

========================  ==========================================================
:func:`read_sidpac`       SIDPAC ``fdata`` .mat (NASA; Twin Otter records)
:func:`read_dlr_asc`      DLR/Jategaonkar .asc (HFB-320 layout, or ATTAS)
:func:`read_dlr_mat`      DLR/Jategaonkar .mat (ATTAS layout, or HFB-320)
:func:`read_csv_mapped`   CSV with a user-given column map, units and signs
:func:`read_fdml_csv`     fdml's own CSV (``t,de,alpha,q,az[,...]``) with a window
:func:`load_record`       any of the above by format name or by inspection
:func:`load_records`      several records, checked to share one sample rate
:func:`data_dir`          the shared data folder (``$FDML_DATA``; fdml never searches for one)
:func:`data_path`         a file in it, or an error naming the file and where it looked
========================  ==========================================================
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..channels import FORMATS
from ..errors import RecordError
from ..record import Record, read_csv
from ._common import check_path, check_trim, finish
from .csvmap import read_csv_mapped
from .dlr import LAYOUTS, read_dlr_asc, read_dlr_mat
from .paths import DATA_ENV, data_dir, data_path
from .sidpac import read_sidpac
from .sniff import check_format_fits, first_numeric_width, mat_format
from .units import UNITS, to_si

__all__ = [
    "read_sidpac",
    "read_dlr_asc",
    "read_dlr_mat",
    "read_csv_mapped",
    "read_fdml_csv",
    "load_record",
    "load_records",
    "detect_format",
    "check_same_rate",
    "data_dir",
    "data_path",
    "DATA_ENV",
    "FORMATS",
    "LAYOUTS",
    "UNITS",
    "to_si",
]

#: Relative difference of sample intervals tolerated between records fitted together.
_RATE_TOL = 1e-6


def read_fdml_csv(
    path,
    t0: float | None = None,
    t1: float | None = None,
    *,
    trim: str | None = None,
    name: str | None = None,
    check_units: bool = True,
) -> Record:
    """Read fdml's own CSV (:func:`fdml.record.read_csv`) with a window and trim options.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    t0, t1 : float, optional
        Time window, s.
    trim : {None, "none", "first", "mean"}, optional
        Trim is kept by default; see :func:`fdml.io.read_sidpac`.
    name : str, optional
        Record name (default: file stem).
    check_units : bool, optional
        Passed to :class:`~fdml.record.Record` (rejects angles that look like degrees).

    Returns
    -------
    Record
        The record, with ``meta["format"] == "csv"`` and its trim values.
    """
    p = check_path(path)
    check_trim(trim)
    rec = read_csv(p, name=name, check_units=check_units)
    meta = {**rec.meta, "format": "csv"}
    return finish(p, rec.t, dict(rec.signals), meta, name=rec.name, t0=t0, t1=t1, trim=trim, check_units=check_units)


_LOADERS: dict[str, Callable[..., Record]] = {
    "sidpac": read_sidpac,
    "dlr-asc": read_dlr_asc,
    "dlr-mat": read_dlr_mat,
    "csv": read_fdml_csv,
    "csv-map": read_csv_mapped,
}


def detect_format(path, **kw) -> tuple[str, dict]:
    """Format name (and implied options such as ``layout``) of a record file.

    ``.mat``: ``sidpac`` when the file holds ``fdata``, else ``dlr-mat`` with
    the layout whose column count matches.  ``.asc``/``.dat``/``.txt``:
    ``dlr-asc`` by column count.  ``.csv``: ``csv-map`` when ``columns`` is
    given, else fdml's own ``csv``.

    Parameters
    ----------
    path : str or Path
        The record file.
    **kw
        Loader options given so far: ``layout`` (the DLR layout is then not
        guessed) and ``columns`` (a ``.csv`` is then ``csv-map``).

    Returns
    -------
    format : str
        One of ``"sidpac"``, ``"dlr-asc"``, ``"dlr-mat"``, ``"csv"``, ``"csv-map"``.
    options : dict
        Options the file implies, e.g. ``{"layout": "attas"}``.
    """
    p = check_path(path)
    suffix = p.suffix.lower()
    if suffix == ".mat":
        return mat_format(p, **kw)
    if suffix in (".asc", ".dat", ".txt"):
        if "layout" in kw:
            return "dlr-asc", {}
        n_cols = first_numeric_width(p)
        for lay, spec in LAYOUTS.items():
            if spec["n_columns"] == n_cols:
                return "dlr-asc", {"layout": lay}
        known = ", ".join(f"{k}: {v['n_columns']}" for k, v in LAYOUTS.items())
        raise RecordError(f"{p}: {n_cols} columns match no known DLR layout ({known}); give --layout (Python: layout=)")
    if suffix == ".csv":
        return ("csv-map" if kw.get("columns") else "csv"), {}
    raise RecordError(
        f"{p}: cannot tell the record format from the suffix {suffix or '(none)'}; give --format "
        f"(Python: format=): {', '.join(FORMATS[1:])}"
    )


def load_record(path, format: str = "auto", t0: float | None = None, t1: float | None = None, **kw) -> Record:
    """Read a flight record in any supported format.

    Parameters
    ----------
    path : str or Path
        The record file.
    format : {"auto", "sidpac", "dlr-asc", "dlr-mat", "csv", "csv-map"}
        ``auto`` inspects the file (:func:`detect_format`).
    t0, t1 : float, optional
        Time window, s.
    **kw
        Options of the chosen loader (``trim``, ``name``, ``layout``,
        ``columns``, ``units``, ``sign``, ``original``, ...); an option the
        loader does not take is an error naming it.

    Returns
    -------
    Record
        The record in fdml's units and signs.
    """
    if format not in FORMATS:
        raise RecordError(f"unknown record format {format!r}; use one of {', '.join(FORMATS)}")
    if format == "auto":
        format, implied = detect_format(path, **kw)
    else:  # a format given: one that does not fit the file is named with the one it looks like
        implied = check_format_fits(path, format, **kw)
    loader = _LOADERS[format]
    params = inspect.signature(loader).parameters
    unknown = [k for k in kw if k not in params]
    if unknown:
        raise RecordError(
            f"{path}: option(s) {', '.join(unknown)} do not apply to format {format!r} "
            f"(it takes: {', '.join(k for k in params if k not in ('path', 't0', 't1'))})"
        )
    return loader(path, t0=t0, t1=t1, **{**implied, **kw})


def load_records(paths, format: str = "auto", t0: float | None = None, t1: float | None = None, **kw) -> list[Record]:
    """Read several records that are to be used together (e.g. a joint fit).

    Parameters
    ----------
    paths : str, Path or sequence of them
        The record files.
    format : str
        As :func:`load_record`, for every file.
    t0, t1 : float, optional
        Time window, s, for every file.
    **kw
        Loader options, as :func:`load_record`, for every file.

    Returns
    -------
    list of Record
        The records, in the order of ``paths``.

    Raises
    ------
    RecordError
        If the records have different sample intervals, naming each file and
        its rate: fdml stacks their spectra on one grid with one noise model,
        and a silent mix of rates usually means a mix of processing chains.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    recs = [load_record(p, format=format, t0=t0, t1=t1, **kw) for p in paths]
    check_same_rate(recs, paths)
    return recs


def check_same_rate(records, paths=None) -> None:
    """Raise a RecordError naming the files if the records' sample intervals differ.

    Parameters
    ----------
    records : sequence of Record
        The records to be used together.
    paths : sequence of str or Path, optional
        Their files, named in the error (default: each record's source or name).
    """
    if len(records) < 2:
        return
    dts = np.array([r.dt for r in records])
    if np.max(np.abs(dts - dts[0])) > _RATE_TOL * dts[0]:
        names = [str(p) for p in paths] if paths is not None else [r.meta.get("source", r.name) for r in records]
        listing = "; ".join(f"{n}: {1 / d:.6g} Hz (dt {d:.6g} s)" for n, d in zip(names, dts))
        raise RecordError(
            f"records at different sample rates cannot be used together: {listing}; resample them to one rate first"
        )
