"""DLR / Jategaonkar flight records: HFB-320 (.asc) and ATTAS (.mat) layouts.

The data supplement of R. V. Jategaonkar, *Flight Vehicle System
Identification* (2nd ed., AIAA), stores each record as a plain matrix, one
channel per column, whose order and units depend on the aircraft.  A
*layout* (:data:`LAYOUTS`) names the columns fdml uses; the same layout
serves the .asc and the .mat form of a file.
"""

from __future__ import annotations

import numpy as np

from ..channels import CONDITION_UNITS
from ..errors import RecordError
from ._common import check_path, check_trim, columns_to_si, finish, read_mat, wrap_read_error
from .units import to_si, unit_factor

__all__ = ["read_dlr_asc", "read_dlr_mat", "LAYOUTS"]

#: Column layouts (1-based column, unit in the file).  Sources: the data
#: README and the channel list of the book's ``flt_data`` folder.
LAYOUTS = {
    "hfb320": {
        "n_columns": 20,
        "signals": {
            "t": (1, "s"),
            "de": (2, "rad"),
            "qbar": (3, "Pa"),
            "V": (5, "m/s"),
            "alpha": (6, "rad"),
            "theta": (7, "rad"),
            "q": (8, "rad/s"),
            "qdot": (9, "rad/s^2"),
            "ax": (10, "m/s^2"),
            "az": (11, "m/s^2"),
        },
        "condition": {},
        # constants used with this record in Jategaonkar's book (data README)
        "constants": {
            "mass": 7472.0,
            "S_w": 4.028e-3 * 7472.0,
            "Sc_over_Iy": 8.0027e-4,
            "rho": 0.792,
            "V0": 104.67,
            "thrust_inclination": 0.0524,
        },
        "constants_units": {
            "mass": "kg",
            "S_w": "m^2",
            "Sc_over_Iy": "m/kg",
            "rho": "kg/m^3",
            "V0": "m/s",
            "thrust_inclination": "rad",
        },
        "constants_source": "data README: Jategaonkar, Flight Vehicle System Identification (2nd ed.), HFB-320 "
        "model constants (S = S/m * m = 4.028e-3 * 7472 m^2); c_w and Iy are not given "
        "separately, only S c / Iy",
        "aircraft": "HFB-320 Hansa Jet",
    },
    "attas": {
        "n_columns": 45,
        "signals": {
            "t": (1, "s"),
            "ax": (2, "m/s^2"),
            "az": (4, "m/s^2"),
            "q": (8, "deg/s"),
            "theta": (11, "deg"),
            "alpha": (13, "deg"),
            "V": (15, "m/s"),
            "h": (16, "ft"),
            "qdot": (18, "deg/s^2"),
            "de": (22, "deg"),
        },
        "condition": {"rho": (34, "kg/m^3", "density")},
        # ATTAS mass and geometry as used with these records by the book's own
        # pre-processing (umr_reg_attas.m); the data README gives none.
        "constants": {"mass": 17631.0, "Iy": 2.52687e5, "S_w": 64.0, "c_w": 3.159, "b": 21.5},
        "constants_units": {k: CONDITION_UNITS[k] for k in ("mass", "Iy", "S_w", "c_w", "b")},
        "constants_source": "Jategaonkar, Flight Vehicle System Identification (2nd ed.), umr_reg_attas.m "
        "(mass, iY, sRef, lRef, 2 bRef); not in the data README",
        "aircraft": "DLR ATTAS (VFW-614)",
    },
}


def _layout(layout: str) -> dict:
    key = str(layout).lower().replace("-", "").replace("_", "")
    if key not in LAYOUTS:
        raise RecordError(f"unknown DLR layout {layout!r}; known: {', '.join(LAYOUTS)}")
    return LAYOUTS[key]


def read_dlr_asc(
    path,
    layout: str = "hfb320",
    t0: float | None = None,
    t1: float | None = None,
    *,
    trim: str | None = None,
    name: str | None = None,
    check_units: bool = True,
):
    """Read a whitespace-separated DLR/Jategaonkar .asc record.

    Parameters
    ----------
    path : str or Path
        Plain text, one sample per line, one channel per column.  Leading
        header lines (text) are skipped; any later non-numeric line, or a line
        with another number of columns, is an error naming the line.
    layout : {"hfb320", "attas"}
        Column layout (:data:`LAYOUTS`).
    t0, t1 : float, optional
        Time window, s (the file's time column).
    trim : {None, "none", "first", "mean"}, optional
        Trim is kept by default; see :func:`fdml.io.read_sidpac`.
    name, check_units : optional
        Record name (default: file stem); passed to :class:`~fdml.record.Record`.

    Returns
    -------
    Record
        The record in fdml's units and signs (SI, ``az`` in g positive down).

    Notes
    -----
    HFB-320 (``hfb320_1_10.asc``, 20 columns, SI): 1 time s, 2 elevator rad,
    3 dynamic pressure Pa, 5 true airspeed m/s, 6 alpha rad, 7 theta rad, 8 q
    rad/s, 9 qdot rad/s^2, 10 ax m/s^2, 11 az m/s^2.  (The book's channel list
    swaps the *descriptions* of columns 11 and 12, "AZCG lateral" and "AYCG
    vertical"; the names and the data agree with the README: column 11 reads
    -9.87 m/s^2 in trim, column 12 about 0.)

    Signs need no change.  a_z reads -9.87 m/s^2 = -1.006 g at the first
    sample (-0.995 g over the leading 0.5 s), i.e. body z positive down; q
    against d theta/dt has slope +0.99 (correlation 0.97);
    an equation-error fit of dq/dt gives M_de = -5.1 1/s^2 (trailing edge
    down positive).  Accelerations are divided by g0 = 9.80665 m/s^2.

    ``meta`` holds ``U`` (mean airspeed over the window), the book's
    constants (mass 7472 kg, S_w = 30.1 m^2, S c/Iy, rho 0.792 kg/m^3,
    V0 104.67 m/s, thrust inclination) and ``rho_from_data``
    (2 qbar / V^2 averaged over the window).
    """
    p = check_path(path)
    check_trim(trim)
    lay = _layout(layout)
    data = _read_ascii(p, lay["n_columns"])
    return _build(p, data, lay, "dlr-asc", t0, t1, trim, name, check_units)


def read_dlr_mat(
    path,
    layout: str = "attas",
    t0: float | None = None,
    t1: float | None = None,
    *,
    variable: str | None = None,
    trim: str | None = None,
    name: str | None = None,
    check_units: bool = True,
):
    """Read a DLR/Jategaonkar .mat record (one matrix, one channel per column).

    Parameters
    ----------
    path : str or Path
        MATLAB v5 file holding the record matrix.
    layout : {"attas", "hfb320"}
        Column layout (:data:`LAYOUTS`).
    t0, t1 : float, optional
        Time window, s.
    variable : str, optional
        Name of the matrix; default the file's only matrix (``fAttasElv1``).
    trim, name, check_units : optional
        As :func:`read_dlr_asc`.

    Returns
    -------
    Record
        The record in fdml's units and signs (SI, ``az`` in g positive down).

    Notes
    -----
    ATTAS (``fAttasElv1.mat``, 45 columns, 25 Hz; the book's ``flt_data``
    channel list): 1 time s, 2 ax m/s^2, 4 az m/s^2 (AZCG), 8 q deg/s,
    11 theta deg, 13 alpha deg (ALCG), 15 true airspeed m/s, 16 pressure
    altitude ft, 18 qdot deg/s^2, 22 elevator deg, 34 density kg/m^3.

    Signs need no change: a_z reads -9.61 m/s^2 = -0.98 g over the leading
    0.5 s (body z positive down); q against d theta/dt has slope +0.98
    (correlation 0.997); an equation-error fit of dq/dt gives
    M_de = -6.8 1/s^2 (trailing edge down positive).

    ``meta`` holds ``U``, ``rho`` (window means of columns 15 and 34) and the
    mass, pitch inertia and geometry that the book's own pre-processing uses
    for ATTAS (mass 17631 kg, Iy 2.527e5 kg m^2, S_w 64 m^2, c_w 3.159 m,
    b 21.5 m), marked with their source in ``constants_source``.
    """
    p = check_path(path)
    check_trim(trim)
    lay = _layout(layout)
    mat = read_mat(p)
    names = [k for k in mat if not k.startswith("__")]
    if variable is None:
        arrays = {k: np.asarray(mat[k]) for k in names}
        mats = [k for k, a in arrays.items() if a.ndim == 2 and a.shape[0] > 1 and np.issubdtype(a.dtype, np.number)]
        if len(mats) != 1:
            raise RecordError(
                f"{p}: expected one record matrix, found {len(mats)} ({', '.join(mats) or 'none'}); "
                "give --variable NAME (Python: variable=NAME)"
            )
        variable = mats[0]
    if variable not in mat:
        raise RecordError(f"{p}: no variable {variable!r} (variables: {', '.join(names) or 'none'})")
    data = np.asarray(mat[variable])
    if data.ndim != 2 or not np.issubdtype(data.dtype, np.number):
        raise RecordError(f"{p}: {variable} is not a numeric matrix (shape {data.shape})")
    if data.shape[1] != lay["n_columns"]:
        raise RecordError(
            f"{p}: {variable} has {data.shape[1]} columns; the {layout} layout has "
            f"{lay['n_columns']} (truncated file or another layout?)"
        )
    return _build(p, np.asarray(data, dtype=float), lay, "dlr-mat", t0, t1, trim, name, check_units, variable=variable)


def _read_ascii(p, n_columns: int) -> np.ndarray:
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise wrap_read_error(p, "a text (.asc) record", exc) from None
    rows: list[list[float]] = []
    for i, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s[0] in "%#":
            continue
        try:
            vals = [float(x) for x in s.replace(",", " ").split()]
        except ValueError:
            if not rows:
                continue  # header line
            raise RecordError(f"{p}: line {i} is not numeric ({s[:40]!r}...); corrupt file?") from None
        if len(vals) != n_columns:
            raise RecordError(
                f"{p}: line {i} has {len(vals)} values, the layout has {n_columns} columns (truncated or corrupt file?)"
            )
        rows.append(vals)
    if len(rows) < 4:
        raise RecordError(f"{p}: only {len(rows)} data line(s); not a record (empty or truncated file?)")
    return np.array(rows, dtype=float)


def _build(p, data, lay, fmt, t0, t1, trim, name, check_units, variable=None):
    sig_cols = lay["signals"]
    tcol, tunit = sig_cols["t"]
    t = to_si(data[:, tcol - 1], tunit, "t", what=f"{p} column {tcol}")
    signals, channels, conv, _ = columns_to_si(
        p, data, {k: v for k, v in sig_cols.items() if k != "t"}, lambda col, unit: f"column {col} ({unit})"
    )
    meta = {
        "source": str(p),
        "format": fmt,
        "aircraft": lay["aircraft"],
        "channels": channels,
        "conversion": conv,
        "sign": {k: 1 for k in signals},
    }
    if variable is not None:
        meta["variable"] = variable
    per = {}
    if "V" in signals:
        per["U"] = signals["V"]
        if "qbar" in signals:
            per["rho_from_data"] = 2.0 * signals["qbar"] / signals["V"] ** 2
    for k, (col, unit, quantity) in lay["condition"].items():
        per[k] = data[:, col - 1] * unit_factor(unit, quantity)
    meta["_per_sample"] = per
    meta.update(lay["constants"])
    meta["constants_source"] = lay["constants_source"]
    meta["units"] = {k: CONDITION_UNITS[k] for k in ("U", "rho", "rho_from_data")} | lay["constants_units"]
    return finish(p, t, signals, meta, name=name, t0=t0, t1=t1, trim=trim, check_units=check_units)
