"""Flight records: time histories in SI units, checked on the way in.

A :class:`Record` holds a uniformly sampled time vector and named signals:
``de`` (elevator, rad, trailing edge down positive), ``alpha`` (rad), ``q``
(rad/s), ``az`` (body-z specific force in g, positive down, docs/theory.md Eq. 5)
and optionally ``alpha_w`` (vertical gust angle, rad).  Construction checks
everything a fit relies on and raises :class:`~fdml.errors.RecordError` with
a message that names the problem.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .channels import ALL_OUTPUTS, SIGNALS, display_unit
from .channels import REQUIRED as REQUIRED_SIGNALS
from .errors import ParameterError, RecordError
from .jsoncodec import SKIP, Codec, Spec, floats
from .outputs import atomic_write_text

__all__ = [
    "Record",
    "read_csv",
    "add_noise",
    "noise_stds",
    "check_noise",
    "uniform_interval",
    "SIGNALS",
    "REQUIRED_SIGNALS",
]


#: Largest plausible perturbation magnitudes in SI units.  A larger value in a
#: channel almost always means degrees (or deg/s) where radians are due:
#: 1 rad is 57 deg of angle of attack or elevator, 3 rad/s is 170 deg/s.
_DEGREE_LIMITS = {"de": 1.0, "alpha": 1.0, "alpha_w": 1.0, "q": 3.0, "theta": 1.6}
#: Sample-interval jitter tolerated, as a fraction of the mean interval.  The
#: Fourier front end assumes exact uniform sampling; 1e-3 of dt shifts phase
#: at 10 rad/s by at most 1e-3 * 10 * dt rad, far below measurement noise.
_JITTER_TOL = 1e-3
#: Sample rates of flight records, Hz.  Below 1 Hz (Nyquist pi rad/s) no record
#: resolves a short-period mode (1.5-10 rad/s); data systems sample at most a
#: few kHz.  A record whose sample interval in seconds is slower than 1 Hz, but
#: a plausible rate if read as milliseconds or microseconds, has its time in
#: that unit: t = 0, 20, 40, ... is 50 Hz in ms, not one sample per 20 s.
_RATE_RANGE_HZ = (1.0, 2000.0)
#: Longest plausible record at 1-2 Hz, s.  Time in ms at 1-2 kHz gives an
#: interval of 0.5-1 "s", inside the rate range, so the length decides: a
#: record of 1-2 Hz samples lasting more than an hour holds no short-period
#: manoeuvre (those last seconds to minutes), while a 10 s record at 2 kHz in
#: ms is 10,000 "s" long.
_SLOW_RECORD_MAX_S = 3600.0
#: Time-unit candidates for :func:`_time_unit_problem`: name and factor to seconds.
_TIME_UNITS = (("milliseconds", 1e-3), ("microseconds", 1e-6))


#: How trim is removed (:meth:`Record.remove_trim`): the first sample, a leading mean, or not at all.
TRIM_MODES = ("first", "mean", "none")


def _signals_field(f, key: str, done: dict) -> dict:
    """The signals of a record in JSON, each as long as its time."""
    sub = f.sub(key)
    return {k: sub.floats(k, (len(done["t"]),)) for k in sub.doc}


@dataclass(frozen=True)
class Record(Codec):
    """A uniformly sampled flight record in SI units.

    Parameters
    ----------
    t : array_like, shape (n,)
        Time, s, strictly increasing and evenly spaced.
    signals : mapping of str to array_like
        Signals by name (see :data:`SIGNALS`), each of shape (n,).
    name : str, optional
        Label used in reports and errors.
    meta : mapping, optional
        Flight condition and provenance (``U`` m/s, ``rho``, ``source``,
        ``trim``, ...).
    check_units : bool, optional
        Reject channels whose magnitude suggests degrees (default True).
    require : tuple of str, optional
        Signals that must be present (default de, alpha, q, az).
    """

    t: np.ndarray
    signals: Mapping[str, np.ndarray]
    name: str = "record"
    meta: Mapping = field(default_factory=dict)
    check_units: bool = True
    require: tuple = REQUIRED_SIGNALS

    json_fields = {"t": floats(None), "signals": Spec(_signals_field), "check_units": SKIP, "require": SKIP}
    json_source = "record"

    @classmethod
    def from_fields(cls, f, **given) -> "Record":
        """A record from the fields of its JSON object (:meth:`to_dict`), every key checked.

        Its units were checked when it was made, so they are not checked again.

        Parameters
        ----------
        f : fdml.jsoncodec.Fields
            The fields of ``{"t", "signals", "name", "meta"}``.
        **given
            Other field values.

        Returns
        -------
        Record
            The record.
        """
        return super().from_fields(f, **{"check_units": False, **given})

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        where = f"record {self.name!r}"
        if t.ndim != 1:
            raise RecordError(f"{where}: time must be one-dimensional, got shape {t.shape}")
        if t.size < 4:
            raise RecordError(f"{where}: only {t.size} samples; at least 4 are needed")
        _check_finite(t, "t", where)
        mean_dt = uniform_interval(t, _JITTER_TOL, where, "resample the record onto a uniform grid first")
        unit_problem = _time_unit_problem(mean_dt, float(t[-1] - t[0]))
        if unit_problem:
            raise RecordError(f"{where}: {unit_problem}")
        missing = [k for k in self.require if k not in self.signals]
        if missing:
            raise RecordError(
                f"{where}: missing signal(s) {', '.join(missing)}; it has {', '.join(self.signals) or 'none'}"
            )
        sig = {}
        for k, v in self.signals.items():
            if k not in SIGNALS:
                raise RecordError(f"{where}: unknown signal {k!r}; known: {', '.join(SIGNALS)}")
            a = np.asarray(v, dtype=float)
            if a.shape != t.shape:
                raise RecordError(f"{where}: signal {k} has {a.size} samples but time has {t.size}")
            _check_finite(a, k, where)
            sig[k] = a
        if self.check_units:
            for k, lim in _DEGREE_LIMITS.items():
                size = max(np.max(np.abs(sig[k] - sig[k][0])), np.max(np.abs(sig[k]))) if k in sig else 0.0
                if size > lim:  # the span about the first sample, or the peak
                    raise RecordError(
                        f"{where}: {k} reaches {size:.3g} {SIGNALS[k]}, which looks like "
                        f"{display_unit(SIGNALS[k])[1]} where {SIGNALS[k]} is due; convert to radians "
                        "(or, if this is real, --no-unit-check; Python: check_units=False)"
                    )
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "signals", sig)
        object.__setattr__(self, "meta", dict(self.meta))

    def __repr__(self) -> str:
        return (
            f"<Record {self.name!r}: {self.n} samples at {self.dt:g} s ({self.duration:g} s), "
            f"signals {', '.join(self.signals)}>"
        )

    # --- accessors ---------------------------------------------------------------
    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.signals[name]
        except KeyError:
            raise RecordError(f"record {self.name!r} has no signal {name!r}") from None

    def __getattr__(self, name: str) -> np.ndarray:
        """A channel as an attribute (``rec.de``, ``rec.alpha``), the same array as ``rec["de"]``.

        Called only when ordinary lookup fails, so the fields and methods win.
        A name that is no channel of this record raises AttributeError naming
        the channels it has (``hasattr`` and ``getattr(rec, name, default)`` work).
        """
        signals = self.__dict__.get("signals")
        if name.startswith("__") or signals is None:  # copy/pickle probe before __init__ ran
            raise AttributeError(name)
        if name in signals:
            return signals[name]
        what = "no channel" if name in SIGNALS else "no attribute or channel"
        raise AttributeError(f"record {self.name!r} has {what} {name!r}; its channels: {', '.join(signals)}")

    def has(self, name: str) -> bool:
        """True if the record carries signal ``name``.

        Parameters
        ----------
        name : str
            An fdml signal name (``"alpha_w"``, ``"theta"``, ...).

        Returns
        -------
        bool
            Whether the signal is present.
        """
        return name in self.signals

    @property
    def n(self) -> int:
        """Number of samples."""
        return self.t.size

    @property
    def dt(self) -> float:
        """Mean sample interval, s."""
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1))

    @property
    def duration(self) -> float:
        """Record length T = (n - 1) dt, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def nyquist(self) -> float:
        """Nyquist frequency pi/dt, rad/s."""
        return math.pi / self.dt

    # --- transformations -------------------------------------------------------------
    def window(self, t0: float | None = None, t1: float | None = None) -> "Record":
        """The samples with ``t0 <= t <= t1`` (s), time kept as recorded.

        Parameters
        ----------
        t0, t1 : float, optional
            Window start and end, s (default: the record's first and last sample).

        Returns
        -------
        Record
            A copy holding the samples in the window.
        """
        lo = self.t[0] if t0 is None else float(t0)
        hi = self.t[-1] if t1 is None else float(t1)
        if not lo < hi:
            raise RecordError(f"record {self.name!r}: window start {lo} s is not before its end {hi} s")
        if lo < self.t[0] - 1e-9 or hi > self.t[-1] + 1e-9:
            raise RecordError(
                f"record {self.name!r}: window [{lo:g}, {hi:g}] s lies outside the record "
                f"[{self.t[0]:g}, {self.t[-1]:g}] s"
            )
        keep = (self.t >= lo - 1e-9 * self.dt) & (self.t <= hi + 1e-9 * self.dt)
        return replace(
            self,
            t=self.t[keep],
            signals={k: v[keep] for k, v in self.signals.items()},
            meta={**self.meta, "window": [lo, hi]},
        )

    def remove_trim(self, mode: str = "first", window: float = 0.5) -> "Record":
        """Subtract the trim value from every signal.

        Parameters
        ----------
        mode : {"first", "mean", "none"}
            ``first``: the first sample; ``mean``: the mean over the leading
            ``window`` seconds; ``none``: leave the record as it is.
        window : float
            Leading window for ``mean``, s.

        Returns
        -------
        Record
            The perturbation record; ``meta["trim"]`` holds the removed values
            and ``meta["trim_mode"]`` the mode, so the change can be undone.
        """
        if mode not in TRIM_MODES:
            raise RecordError(f"unknown trim mode {mode!r}; use 'first', 'mean' or 'none'")
        if mode == "none":
            return self
        n_lead = 1 if mode == "first" else int(round(window / self.dt)) + 1  # the first sample is its own mean
        if mode == "mean" and (window <= 0 or n_lead > self.n):
            raise RecordError(
                f"record {self.name!r}: trim window {window} s must be positive and within the "
                f"{self.duration:.3g} s record"
            )
        trim = {k: float(np.mean(v[:n_lead])) for k, v in self.signals.items()}
        prev = self.meta.get("trim", {})
        total = {k: prev.get(k, 0.0) + trim[k] for k in trim}
        return replace(
            self,
            signals={k: v - trim[k] for k, v in self.signals.items()},
            meta={**self.meta, "trim": total, "trim_mode": mode, "trim_samples": n_lead},
        )

    def with_signals(self, **signals: np.ndarray) -> "Record":
        """Return a copy with signals added or replaced.

        Parameters
        ----------
        **signals : numpy.ndarray
            Signals by name, each shape ``(n,)``, in fdml's units.

        Returns
        -------
        Record
            The copy.
        """
        return replace(self, signals={**self.signals, **signals})

    # --- CSV ---------------------------------------------------------------------
    def to_csv_text(self) -> str:
        """CSV text with a header row ``t,de,alpha,q,az[,alpha_w]``.

        Returns
        -------
        str
            The header and one row per sample (full float precision).
        """
        cols = ["t"] + [k for k in SIGNALS if k in self.signals]
        data = np.column_stack([self.t] + [self.signals[k] for k in cols[1:]])
        buf = io.StringIO()
        np.savetxt(buf, data, delimiter=",", fmt="%.17g", header=",".join(cols), comments="")
        return buf.getvalue()

    def to_csv(self, path: str | Path) -> Path:
        """Write the record as CSV (atomically: never a half-written file).

        Parameters
        ----------
        path : str or Path
            The file to write.

        Returns
        -------
        pathlib.Path
            The file written.
        """
        atomic_write_text(path, self.to_csv_text())
        return Path(path)


def uniform_interval(t: np.ndarray, tol: float, where: str, advice: str) -> float:
    """Mean sample interval, s, of a time vector that must rise strictly and evenly.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Time, s, finite, n >= 2.
    tol : float
        Largest deviation of an interval from the mean interval, as a fraction of it.
    where : str
        What the time vector belongs to, for messages (``"record 'x'"``, ``"simulate"``).
    advice : str
        What to do about uneven sampling, appended to its message.

    Returns
    -------
    float
        The mean sample interval, s.

    Raises
    ------
    RecordError
        Naming the first sample where time does not increase, or the interval
        farthest from the mean when it is farther than ``tol``.
    """
    d = np.diff(t)
    if np.any(d <= 0):
        i = int(np.argmax(d <= 0))
        raise RecordError(
            f"{where}: time is not strictly increasing at sample {i + 1} (t = {t[i]:.9g} then {t[i + 1]:.9g} s)"
        )
    mean_dt = float((t[-1] - t[0]) / (t.size - 1))
    dev = np.abs(d - mean_dt) / mean_dt
    i = int(np.argmax(dev))
    if dev[i] > tol:
        raise RecordError(
            f"{where}: time is not uniformly spaced (uneven sampling): interval {d[i]:.9g} s at sample {i + 1} "
            f"differs from the mean {mean_dt:.9g} s by {dev[i]:.3g} of it (limit {tol:.3g}); {advice}"
        )
    return mean_dt


def add_noise(record: Record, noise, rng: np.random.Generator, *, relative: bool = False) -> Record:
    """Add white Gaussian noise to the outputs of a record.

    Parameters
    ----------
    record : Record
        The noise-free record.
    noise : float or mapping
        Standard deviation per output (``{"alpha": rad, "q": rad/s, "az": g}``),
        or one number for all outputs.
    rng : numpy.random.Generator
        Source of the noise (never the global generator).
    relative : bool, optional
        If True, ``noise`` is a fraction of each output's RMS about its mean.

    Returns
    -------
    Record
        A copy with noisy ``alpha``, ``q``, ``az`` (and ``theta``, ``qdot`` where
        it has them); ``meta["noise_std"]`` holds the standard deviations used.
    """
    if not isinstance(rng, np.random.Generator):
        raise RecordError("add_noise needs a numpy Generator (np.random.default_rng(seed))")
    std = noise_stds(record, noise, relative=relative)
    noisy = {k: record[k] + std[k] * rng.standard_normal(record.n) for k in std}
    return replace(record, signals={**record.signals, **noisy}, meta={**record.meta, "noise_std": std})


def noise_stds(record: Record, noise, *, relative: bool = False) -> dict[str, float]:
    """Noise standard deviation per output, from one number or a mapping.

    The one reading of a noise level, shared by :func:`add_noise` (the
    simulator, Monte Carlo) and :mod:`fdml.design` (the predicted bounds).

    Parameters
    ----------
    record : Record
        The noise-free record (its outputs' RMS scales a relative level).
    noise : float or mapping
        Standard deviation per output (``{"alpha": rad, "q": rad/s, "az": g}``,
        missing outputs 0), or one number for all outputs.
    relative : bool, optional
        If True, ``noise`` is a fraction of each output's RMS about its mean.

    Returns
    -------
    dict of str to float
        Standard deviation per output the record has: alpha rad, q rad/s, az g[, theta rad, qdot rad/s^2].
    """
    outputs = [k for k in ALL_OUTPUTS if record.has(k)]
    level = check_noise(noise)
    std = {k: level.get(k, 0.0) for k in outputs} if isinstance(level, dict) else dict.fromkeys(outputs, level)
    if relative:
        std = {k: v * float(np.std(record[k])) for k, v in std.items()}
    return std


def check_noise(noise) -> float | dict[str, float]:
    """A measurement-noise level, checked: one number, or standard deviations by output.

    The one check of a noise level for every command and library call (the
    simulator, :func:`add_noise`, Monte Carlo, the experiment design, the
    diagnosis' truths); what one number means (a fraction of each output's
    RMS, or one standard deviation) is the caller's.

    Parameters
    ----------
    noise : float or mapping
        One number, or ``{"alpha": rad, "q": rad/s, "az": g}``.

    Returns
    -------
    float or dict of str to float
        The number, or the standard deviation of each output given.

    Raises
    ------
    ParameterError
        An unknown output, a value that is not a number, or one that is
        negative or not finite.
    """
    if isinstance(noise, Mapping):
        bad = [k for k in noise if k not in ALL_OUTPUTS]
        if bad:
            raise ParameterError(
                f"unknown noise channel(s) {', '.join(map(str, bad))}; channels: {', '.join(ALL_OUTPUTS)}"
            )
        return {k: _noise_level(v, f"noise std for {k}", f" ({SIGNALS[k]})") for k, v in noise.items()}
    if isinstance(noise, bool) or not isinstance(noise, (int, float, np.integer, np.floating)):
        raise ParameterError(
            f"noise must be a fraction of each output's RMS (a number such as 0.02) or a "
            f"mapping {{'alpha': rad, 'q': rad/s, 'az': g}} of standard deviations, got {noise!r}"
        )
    return _noise_level(noise, "noise", "")


def _noise_level(value, what: str, unit: str) -> float:
    """``value`` as a finite, non-negative float, or a ParameterError naming ``what`` (and its unit)."""
    try:
        level = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{what} must be a number{unit}, got {value!r}") from None
    if not (math.isfinite(level) and level >= 0):
        raise ParameterError(f"{what} must be finite and >= 0{unit}, got {value!r}")
    return level


def _time_unit_problem(dt: float, duration: float) -> str | None:
    """A message if time is evidently not in seconds (see :data:`_RATE_RANGE_HZ`), else None.

    Parameters
    ----------
    dt : float
        Mean sample interval in the record's time unit.
    duration : float
        Record length in the same unit.
    """
    lo_hz, hi_hz = _RATE_RANGE_HZ
    slow_and_long = dt >= 1.0 / (2 * lo_hz) and duration > _SLOW_RECORD_MAX_S
    if dt <= 1.0 / lo_hz and not slow_and_long:
        return None
    fits = [(unit, f) for unit, f in _TIME_UNITS if 1.0 / hi_hz <= dt * f <= 1.0 / lo_hz]
    if not fits:
        return (
            f"sample interval {dt:g} s ({1 / dt:.3g} Hz) is slower than any flight record "
            f"({lo_hz:g}-{hi_hz:g} Hz); give time in seconds"
        )
    unit, f = fits[0]
    also = f" (or {fits[1][0]})" if len(fits) > 1 else ""
    return (
        f"time looks like {unit}{also}: sample interval {dt:g} and record length {duration:g} are "
        f"{dt * f:g} s ({1 / (dt * f):.4g} Hz) and {duration * f:g} s in {unit}; give time in seconds"
    )


def _check_finite(a: np.ndarray, label: str, where: str) -> None:
    bad = ~np.isfinite(a)
    if np.any(bad):
        i = int(np.argmax(bad))
        kind = "NaN" if np.isnan(a[i]) else "inf"
        raise RecordError(f"{where}: {label} has {int(bad.sum())} non-finite value(s) (first: {kind} at sample {i})")


def read_csv(
    path: str | Path, *, name: str | None = None, check_units: bool = True, require: tuple = REQUIRED_SIGNALS
) -> Record:
    """Read fdml's own CSV layout.

    A header row naming ``t`` (s), ``de`` (rad), ``alpha`` (rad), ``q``
    (rad/s), ``az`` (g, positive down) and optionally ``alpha_w`` (rad); other
    columns are ignored.  The record is returned as recorded (trim not removed).
    The file is UTF-8 (a byte-order mark, as spreadsheet programs write, is
    accepted); a column fdml reads that appears twice in the header is an error.
    ``require`` names the signals that must be present (an input history: ``("de",)``).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    name : str, optional
        Record name (default: the file stem).
    check_units : bool, optional
        Passed to :class:`Record` (rejects angles that look like degrees).
    require : tuple of str, optional
        Signals that must be present besides ``t`` (default: the channel
        registry's required signals).

    Returns
    -------
    Record
        The record as recorded (trim not removed).
    """
    path = Path(path)
    if not path.exists():
        raise RecordError(f"record file {path} does not exist")
    try:
        text = path.read_text(encoding="utf-8-sig")  # utf-8-sig: drops a leading BOM
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordError(f"cannot read record file {path}: {exc}") from None
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    if not rows:
        raise RecordError(f"record file {path} is empty")
    header = [h.strip() for h in rows[0]]
    if "t" not in header:
        raise RecordError(f"record file {path}: no 't' column in the header {header}; expected t,de,alpha,q,az")
    for h in ("t", *SIGNALS):  # columns fdml ignores may repeat; one it reads must be unambiguous
        if header.count(h) > 1:
            raise RecordError(
                f"record file {path}: column {h!r} appears {header.count(h)} times in the header; keep one"
            )
    for i, r in enumerate(rows[1:], start=2):
        if len(r) != len(header):
            raise RecordError(
                f"record file {path}: line {i} has {len(r)} values but the header has {len(header)} "
                "(truncated or corrupt file?)"
            )
    try:
        data = np.array([[float(c) for c in r] for r in rows[1:]], dtype=float)
    except ValueError as exc:
        raise RecordError(f"record file {path}: a non-numeric value in the data ({exc})") from None
    if data.ndim != 2 or data.shape[0] == 0:
        raise RecordError(f"record file {path} has a header but no data rows")
    cols = dict(zip(header, data.T))
    signals = {k: cols[k] for k in SIGNALS if k in cols}
    try:
        return Record(
            cols["t"],
            signals,
            name=name or path.stem,
            meta={"source": str(path)},
            check_units=check_units,
            require=require,
        )
    except RecordError as exc:
        raise RecordError(f"record file {path}: {exc}") from None
