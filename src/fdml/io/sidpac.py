"""SIDPAC ``fdata`` .mat files (NASA System IDentification Programs for AirCraft).

SIDPAC stores a flight record as one matrix ``fdata`` with a fixed channel per
column (labels in ``varlab``) in US customary units and degrees, plus the
reference geometry as scalars ``sarea`` (ft^2), ``bspan`` (ft), ``cbar`` (ft).
"""

from __future__ import annotations

import numpy as np

from ..channels import CONDITION_UNITS
from ..errors import RecordError
from ._common import check_path, check_trim, columns_to_si, finish, read_mat
from .units import unit_factor

__all__ = ["read_sidpac", "SIDPAC_COLUMNS"]

#: fdml signal -> (1-based fdata column, unit in the file, label keyword).
SIDPAC_COLUMNS = {
    "V": (2, "ft/s", "airspeed"),
    "alpha": (4, "deg", "alpha"),
    "q": (6, "deg/s", "q "),
    "theta": (9, "deg", "theta"),
    "ax": (11, "g", "ax"),
    "az": (13, "g", "az"),
    "de": (14, "deg", "elevator"),
    "qbar": (27, "lbf/ft^2", "qbar"),
    "h": (30, "ft", "altitude"),
    "qdot": (43, "deg/s^2", "qdot"),
}
#: Per-sample flight-condition columns averaged over the window into meta.
_CONDITION_COLUMNS = {
    "rho": (29, "slug/ft^3", "rho", "density"),
    "mass": (48, "slug", "mass", "mass"),
    "Iy": (50, "slug ft^2", "iyy", "inertia"),
}

#: Reference geometry: meta key -> (scalar variable of the file, unit, quantity).
_GEOMETRY = {"S_w": ("sarea", "ft^2", "area"), "c_w": ("cbar", "ft", "length"), "b": ("bspan", "ft", "length")}


def read_sidpac(
    path,
    t0: float | None = None,
    t1: float | None = None,
    *,
    trim: str | None = None,
    original: bool = False,
    name: str | None = None,
    check_units: bool = True,
):
    """Read a SIDPAC ``fdata`` .mat file into an fdml :class:`~fdml.record.Record`.

    Parameters
    ----------
    path : str or Path
        MATLAB v5 file with ``fdata`` (n x 90 in SIDPAC's standard layout).
    t0, t1 : float, optional
        Time window, s, in the record's time (the file's ``t``, zero at the
        first sample).
    trim : {None, "none", "first", "mean"}, optional
        Trim is **kept** by default (the estimator removes it,
        :func:`fdml.spectral.spectra`); ``"first"`` or ``"mean"`` subtract the
        first sample or the mean over the leading 0.5 s from every signal.
    original : bool, optional
        Read ``fdatao`` (the measurements as recorded) instead of ``fdata``.
        In the Twin Otter files ``fdata`` is SIDPAC's *compatibility-corrected*
        copy: ``fdata - fdatao`` is a constant for q, a_z and a_x (bias
        corrections) and a linear function of alpha and theta (scale-factor
        corrections, ``pclab`` names the parameters).
    name : str, optional
        Record name (default: the file stem).
    check_units : bool, optional
        Passed to :class:`~fdml.record.Record`.

    Returns
    -------
    Record
        Signals ``de, alpha, q, az`` and, where the column holds data,
        ``theta, V, qdot, ax, h, qbar``; SI units, radians, a_z and a_x in g.

    Notes
    -----
    Columns (1-based) and units, from the data README and the file's own
    ``varlab`` labels, which are checked: 2 airspeed ft/s, 4 alpha deg, 6 q
    deg/s, 9 theta deg, 11 ax g, 13 az g, 14 elevator deg, 27 dynamic
    pressure lbf/ft^2, 29 density slug/ft^3, 30 altitude ft, 43 qdot deg/s^2,
    48 mass slug, 50 Iyy slug ft^2.

    Signs need no change; the evidence, on both Twin Otter maneuvers:

    * a_z reads -1.01 and -0.99 g in the leading trim: body-z specific force,
      positive **down**, already fdml's a_z (docs/theory.md Eq. 5); a regression of
      a_z on (V/g)(d alpha/dt - q) has slope +0.97 and +1.06 (a sign error
      would give -1);
    * q against d theta/dt: slope +0.89, correlation 0.99 (nose up positive);
    * elevator: an equation-error fit of dq/dt on alpha, q, de gives
      M_de = -12.6 and -12.2 1/s^2, i.e. trailing edge down positive with a
      nose-down moment, as fdml expects (C_m_de < 0).

    ``meta`` holds ``U`` (mean airspeed over the window, m/s), ``rho``
    (kg/m^3), ``mass`` (kg), ``Iy`` (kg m^2), ``S_w`` (m^2), ``c_w`` (m; the
    file's mean chord ``cbar``), ``b`` (m), the column and unit of every
    channel (``channels``), the factors applied (``conversion``), the trim
    values (``trim_values``: means over the leading 0.5 s, SI) and
    ``time_of_day_start`` (fdata column 1 at the first sample, s).
    """
    p = check_path(path)
    check_trim(trim)
    mat = read_mat(p)
    key = "fdatao" if original else "fdata"
    if key not in mat:
        names = sorted(k for k in mat if not k.startswith("__"))
        raise RecordError(f"{p}: no {key!r} matrix, so not a SIDPAC file (variables: {', '.join(names) or 'none'})")
    fd = np.asarray(mat[key])
    if fd.ndim != 2 or not np.issubdtype(fd.dtype, np.number):
        raise RecordError(f"{p}: {key} is not a numeric matrix (shape {fd.shape}, type {fd.dtype})")
    need = max(c for c, *_ in [*SIDPAC_COLUMNS.values(), *_CONDITION_COLUMNS.values()])
    if fd.shape[1] < need:
        raise RecordError(
            f"{p}: {key} has {fd.shape[1]} columns; SIDPAC's layout needs at least {need} "
            "(truncated file or another layout?)"
        )
    if fd.shape[0] < 4:
        raise RecordError(f"{p}: {key} has only {fd.shape[0]} rows")
    labels = _labels(mat)
    for sig, (col, unit, word) in SIDPAC_COLUMNS.items():
        _check_label(p, labels, col, word, sig)

    if "t" in mat and np.size(mat["t"]) == fd.shape[0]:
        t = np.asarray(mat["t"], dtype=float).ravel()
        t_src = "variable t (s)"
    else:
        t = fd[:, 0] - fd[0, 0]
        t_src = "fdata column 1 minus its first value (s)"
    signals, channels, conv, absent = columns_to_si(
        p,
        fd,
        {sig: (col, unit) for sig, (col, unit, _word) in SIDPAC_COLUMNS.items()},
        lambda col, unit: f"{key} column {col} ({labels.get(col, '').strip() or unit})",
    )
    meta = {
        "source": str(p),
        "format": "sidpac",
        "matrix": key,
        "time": t_src,
        "channels": channels,
        "conversion": conv,
        "sign": {k: 1 for k in signals},
        "time_of_day_start": float(fd[0, 0]),
    }
    if absent:
        meta["absent_channels"] = absent
    per = {}
    if "V" in signals:
        per["U"] = signals["V"]
    for k, (col, unit, _w, quantity) in _CONDITION_COLUMNS.items():
        x = np.asarray(fd[:, col - 1], dtype=float)
        if np.all(np.isfinite(x)) and np.any(x != 0.0):
            per[k] = x * unit_factor(unit, quantity)
    meta["_per_sample"] = per
    for k, (var, unit, quantity) in _GEOMETRY.items():
        if var in mat and np.size(mat[var]) == 1:
            meta[k] = float(np.asarray(mat[var], dtype=float).ravel()[0]) * unit_factor(unit, quantity)
    meta["units"] = {k: CONDITION_UNITS[k] for k in ("U", "rho", "mass", "Iy", "S_w", "c_w", "b")}
    return finish(p, t, signals, meta, name=name, t0=t0, t1=t1, trim=trim, check_units=check_units)


def _labels(mat) -> dict[int, str]:
    """1-based column -> varlab text, when the file has labels."""
    lab = mat.get("varlab")
    if lab is None:
        return {}
    try:
        arr = np.asarray(lab).ravel()
        return {i + 1: str(np.asarray(s).ravel()[0]) if np.asarray(s).size else "" for i, s in enumerate(arr)}
    except Exception:  # pragma: no cover - odd label encodings are not fatal
        return {}


def _check_label(p, labels: dict, col: int, word: str, sig: str) -> None:
    if not labels:
        return
    text = labels.get(col, "")
    if word.strip() and word.lower() not in text.lower() + " ":
        raise RecordError(
            f"{p}: column {col} is labelled {text.strip()!r} but SIDPAC's layout has {sig} ({word.strip()}) "
            "there; this is not the standard fdata layout"
        )
