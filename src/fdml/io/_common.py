"""Shared steps of the loaders: build a Record, window it, report trim, wrap errors."""

from __future__ import annotations

import faulthandler
import math
import os
import pickle
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..channels import REQUIRED
from ..errors import RecordError
from ..record import Record
from .units import QUANTITY, unit_factor

#: Leading window over which ``meta["trim_values"]`` are averaged, s.  Half a
#: second is many samples at any flight-test rate (5 at 10 Hz, 25 at 50 Hz) and
#: short against the short-period time scale, so the mean is the trim state
#: before the input starts on records that begin in trim.
TRIM_WINDOW = 0.5

_TRIM_MODES = (None, "none", "first", "mean")
#: A window edge this many sample intervals beyond a sample still includes it.
WINDOW_TOL = 0.01


def check_path(path) -> Path:
    """A readable file, or a RecordError that names it."""
    p = Path(path)
    if not p.exists():
        raise RecordError(f"record file {p} does not exist")
    if p.is_dir():
        raise RecordError(f"record file {p} is a directory, not a file")
    if p.stat().st_size == 0:
        raise RecordError(f"record file {p} is empty")
    return p


def check_trim(trim) -> None:
    if trim not in _TRIM_MODES:
        raise RecordError(f"unknown trim mode {trim!r}; use None/'none' (keep trim), 'first' or 'mean'")


def trim_values(t: np.ndarray, signals: Mapping[str, np.ndarray], window: float = TRIM_WINDOW) -> dict:
    """Mean of every signal over the leading ``window`` seconds (SI)."""
    dt = (t[-1] - t[0]) / (t.size - 1)
    k = min(t.size, int(round(window / dt)) + 1)
    return {name: float(np.mean(v[:k])) for name, v in signals.items()}


def columns_to_si(p: Path, data: np.ndarray, columns: Mapping[str, tuple], label) -> tuple[dict, dict, dict, list]:
    """The signals of a record matrix in fdml's units, from a layout ``{signal: (1-based column, unit)}``.

    A column of zeros was not recorded: an error for a required signal, else
    the signal is left out (listed in ``absent``).  ``label(column, unit)`` is
    the channel's description in ``meta["channels"]``.

    Parameters
    ----------
    p : Path
        The file, named in errors.
    data : numpy.ndarray
        The record matrix, one channel per column, in the file's units.
    columns : mapping
        fdml signal -> (1-based column, unit in the file).
    label : callable
        ``label(column, unit)``: the channel's description.

    Returns
    -------
    signals, channels, conversion : dict
        The SI signals, their channel descriptions and ``{"unit", "factor"}``.
    absent : list of str
        The signals whose column holds only zeros.
    """
    signals, channels, conv, absent = {}, {}, {}, []
    for sig, (col, unit) in columns.items():
        x = np.asarray(data[:, col - 1], dtype=float)
        if not np.any(x != 0.0):
            if sig in REQUIRED:
                raise RecordError(f"{p}: column {col} ({sig}) holds only zeros: the channel was not recorded")
            absent.append(sig)
            continue
        factor = unit_factor(unit, QUANTITY[sig], what=f"{p} column {col}")
        signals[sig] = x * factor
        channels[sig] = label(col, unit)
        conv[sig] = {"unit": unit, "factor": factor}
    return signals, channels, conv, absent


def finish(
    path: Path, t, signals: dict, meta: dict, *, name: str | None, t0, t1, trim, check_units: bool = True
) -> Record:
    """Build the Record, cut the window, record trim values, optionally remove trim.

    Flight-condition entries that depend on the window (``U``, mean ``rho``)
    are computed by the caller from the windowed arrays through
    ``meta["_per_sample"]``: a dict of SI arrays averaged here after windowing.
    """
    per_sample = meta.pop("_per_sample", {})
    try:
        rec = Record(t, signals, name=name or path.stem, meta=meta, check_units=check_units)
    except RecordError as exc:
        raise RecordError(f"{path}: {exc}") from None
    keep = np.ones(rec.n, dtype=bool)
    if t0 is not None or t1 is not None:
        for label, v in (("t0", t0), ("t1", t1)):
            if v is not None and not (isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v)):
                raise RecordError(f"{path}: window {label} must be a finite number of seconds, got {v!r}")
        # Time stamps in files carry rounding (HFB-320: 30.00001 s for 30 s), so a
        # window edge within WINDOW_TOL sample intervals of a sample includes it.
        tol = WINDOW_TOL * rec.dt
        a = rec.t[0] if t0 is None else float(t0)
        b = rec.t[-1] if t1 is None else float(t1)
        if not a < b:
            raise RecordError(f"{path}: window start {a:g} s is not before its end {b:g} s")
        if a < rec.t[0] - tol or b > rec.t[-1] + tol:
            raise RecordError(
                f"{path}: window [{a:g}, {b:g}] s lies outside the record [{rec.t[0]:g}, {rec.t[-1]:g}] s"
            )
        keep = (rec.t >= max(a - tol, rec.t[0])) & (rec.t <= min(b + tol, rec.t[-1]))
        if int(keep.sum()) < 4:
            raise RecordError(
                f"{path}: window [{a:g}, {b:g}] s holds only {int(keep.sum())} samples; at least 4 are needed"
            )
        rec = rec.window(rec.t[keep][0], rec.t[keep][-1])
        rec = replace(rec, meta={**rec.meta, "window": [a, b]})
    extra = {key: float(np.mean(np.asarray(arr, dtype=float)[keep])) for key, arr in per_sample.items()}
    # window_means: which meta values are means of per-sample channels over the record (their provenance)
    tv = trim_values(rec.t, rec.signals)
    meta2 = {**rec.meta, **extra, "window_means": sorted(extra), "trim_values": tv, "trim_values_window": TRIM_WINDOW}
    rec = replace(rec, meta=meta2)
    if trim not in (None, "none"):
        try:
            rec = rec.remove_trim(trim, window=TRIM_WINDOW)
        except RecordError as exc:  # e.g. a record shorter than the trim window
            raise RecordError(f"{path}: {exc}") from None
    return rec


def read_mat(path: Path, *, names_only: bool = False):
    """``scipy.io.loadmat`` (or ``whosmat`` with ``names_only``), isolated in a forked child.

    scipy's MAT reader is partly C: some damaged files crash the interpreter
    instead of raising (scipy 1.17: a corrupted data-element tag gives a
    segmentation fault, found by tests/test_properties.py).  On POSIX the file
    is parsed in a child process and its variables are passed back pickled,
    so a crash becomes a :class:`RecordError` naming the file.  Where there
    is no ``fork`` the file is read directly.

    Raises
    ------
    RecordError
        The file is not a readable MAT file, or parsing it crashed the reader.
    """
    from scipy.io import loadmat, whosmat

    def parse():
        try:
            return "ok", (whosmat(str(path)) if names_only else loadmat(str(path)))
        except Exception as exc:  # scipy raises many types on corrupt input
            return "error", wrap_read_error(path, "a MATLAB .mat file", exc)

    kind, value = _in_child(parse, path) if hasattr(os, "fork") else parse()
    if kind == "error":
        raise value
    return value


def _in_child(func, path: Path):
    """``func()`` run in a forked child; its (picklable) value, or a RecordError if the child died."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: never returns into the caller's code
        code = 1
        try:
            faulthandler.disable()  # a crash here is expected and reported by the parent, without a dump
            os.close(r)
            with os.fdopen(w, "wb") as fh:
                pickle.dump(func(), fh, protocol=pickle.HIGHEST_PROTOCOL)
            code = 0
        finally:
            os._exit(code)
    os.close(w)
    with os.fdopen(r, "rb") as fh:
        data = fh.read()
    _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if not data or code != 0:
        how = f"signal {-code}" if code < 0 else f"exit code {code}"
        return "error", RecordError(
            f"{path}: cannot read it as a MATLAB .mat file (corrupt or truncated file?): the MAT reader crashed ({how})"
        )
    return pickle.loads(data)


def wrap_read_error(path: Path, what: str, exc: BaseException) -> RecordError:
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return RecordError(f"{path}: cannot read it as {what} (corrupt or truncated file?): {msg}")
