"""Planned input histories: classic manoeuvres and multisines with their limits checked.

Every generator returns a :class:`DesignInput`, a Record-compatible input
history (``t``, ``de`` and optionally a second input) that writes as fdml's
record CSV for a flight-test card.  The signals themselves come from
:mod:`fdml.maneuvers` (doublet, 3-2-1-1, multisine, sweep); this module adds
the planning limits: a peak amplitude, a surface rate limit and the record
length, each respected (step edges get the ramp the rate limit allows, a
multisine or sweep is scaled down to meet it) and reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import maneuvers as mv
from ..channels import INPUTS
from ..errors import BandError, FdmlError, ParameterError
from ..record import Record, read_csv
from ..spectral import parse_band

__all__ = ["DesignInput", "Limits", "CLASSIC_KINDS", "classic_input", "multisine_input", "read_input", "spectrum"]

#: Input kinds :func:`classic_input` builds.
CLASSIC_KINDS = ("doublet", "3211", "sweep", "log-sweep", "schroeder", "min-crest")
#: First edge of the step manoeuvres, s (the aircraft starts at trim).
_START = 1.0


@dataclass(frozen=True)
class Limits:
    """Planning limits of an input.

    Parameters
    ----------
    amplitude : float
        Largest ``|de|``, rad.
    duration : float
        Record length, s.
    dt : float
        Sample interval, s.
    rate : float
        Largest ``|d de/dt|``, rad/s (inf: none).
    """

    amplitude: float
    duration: float
    dt: float = 0.02
    rate: float = math.inf

    def __post_init__(self):
        for k in ("amplitude", "duration", "dt"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ParameterError(f"{k} limit must be a positive number, got {v!r}")
        if not (self.rate > 0):
            raise ParameterError(f"rate limit must be positive (rad/s), got {self.rate!r}")
        if self.duration < 8 * self.dt:
            raise ParameterError(f"duration {self.duration} s holds fewer than 8 samples of dt = {self.dt} s")

    @property
    def nyquist(self) -> float:
        """Nyquist frequency pi / dt, rad/s."""
        return math.pi / self.dt


@dataclass(frozen=True)
class DesignInput:
    """An input history for a manoeuvre.

    Parameters
    ----------
    name : str
        What it is (``3211``, ``min-crest multisine``, ...).
    t : ndarray, shape (n,)
        Time, s, from 0.
    signals : dict
        ``de`` (rad) and optionally ``alpha_w`` (rad).
    options : dict
        The generator's options (band rad/s, unit s, harmonics ...).
    limits : Limits
        The limits it was built for.
    """

    name: str
    t: np.ndarray = field(repr=False)
    signals: dict = field(repr=False)
    options: dict = field(default_factory=dict)
    limits: Limits | None = None

    @property
    def de(self) -> np.ndarray:
        """Elevator history, rad, shape (n,)."""
        return self.signals["de"]

    def report(self) -> dict:
        """Peak (rad), largest rate (rad/s), RMS (rad), crest factor, relative peak factor, duration (s).

        Returns
        -------
        dict
            ``peak``, ``rate``, ``rms``, ``crest_factor``, ``relative_peak_factor``,
            ``duration`` and, with limits, ``within_limits``.
        """
        u = self.de
        rate = np.max(np.abs(np.diff(u))) / (self.t[1] - self.t[0])
        out = {
            "peak": float(np.max(np.abs(u))),
            "rate": float(rate),
            "rms": float(np.sqrt(np.mean(u**2))),
            "crest_factor": mv.crest_factor(u),
            "relative_peak_factor": mv.relative_peak_factor(u),
            "duration": float(self.t[-1] - self.t[0]),
        }
        if self.limits is not None:
            lim = self.limits
            out["within_limits"] = bool(
                out["peak"] <= lim.amplitude * (1 + 1e-9) and out["rate"] <= lim.rate * (1 + 1e-6)
            )
        return out

    def to_record(self) -> Record:
        """A Record holding the input history only (``t``, ``de``[, ``alpha_w``]).

        Returns
        -------
        Record
            The input history, named after the input.
        """
        return Record(self.t, self.signals, name=self.name, require=("de",), check_units=False)

    def to_csv(self, path) -> None:
        """Write fdml's record CSV (``t,de``[,``alpha_w``]) atomically, for a flight-test card.

        Parameters
        ----------
        path : str or Path
            The file to write.
        """
        self.to_record().to_csv(path)


def _check_band(band, lim: Limits) -> tuple[float, float]:
    """The band's edges, rad/s (:func:`fdml.spectral.parse_band`), holding two harmonics of the record."""
    lo, hi, _ = parse_band(band, dt=lim.dt)  # an input's band has no grid
    if hi - lo < 2 * math.pi / lim.duration:
        raise BandError(
            f"band {lo:g}:{hi:g} rad/s holds no two harmonics of 2 pi/T = {2 * math.pi / lim.duration:.3g} rad/s "
            "for a record of this length; widen the band or lengthen the record"
        )
    return lo, hi


def _steps(kind: str, lim: Limits, unit: float | None) -> DesignInput:
    """Doublet or 3-2-1-1 whose edges take the ramp the rate limit allows."""
    units = 2 if kind == "doublet" else 7
    if unit is None:  # the manoeuvre fills the record but for the start and a settling tail
        unit = min((lim.duration - _START) / (units + 2.5), 1.0)
    if _START + units * unit > lim.duration:
        raise ParameterError(
            f"a {kind} of unit {unit:g} s lasts {units * unit:g} s from t = {_START:g} s: longer than the "
            f"{lim.duration:g} s record"
        )
    # a raised-cosine ramp across a jump of 2A has a peak slope pi A / rise (maneuvers._smooth_step)
    rise = 0.0 if math.isinf(lim.rate) else math.pi * lim.amplitude / lim.rate
    rise = max(rise, lim.dt)  # at least one sample: a sampled step has rate 2A/dt otherwise
    if rise > unit:
        raise ParameterError(
            f"no {kind} of unit {unit:g} s reaches {lim.amplitude:.4g} rad within the rate limit "
            f"{lim.rate:.4g} rad/s (each edge needs {rise:.3g} s); raise the unit or the rate limit, "
            "or lower the amplitude"
        )
    t = mv.time_vector(lim.duration, lim.dt)
    if kind == "doublet":
        de = mv.doublet(t, lim.amplitude, start=_START, width=unit, rise=rise)
    else:
        de = mv.three_two_one_one(t, lim.amplitude, start=_START, unit=unit, rise=rise)
    return DesignInput(kind, t, {"de": de}, {"unit": unit, "rise": rise, "start": _START}, lim)


def _rate_scaled(u: np.ndarray, lim: Limits) -> tuple[np.ndarray, float]:
    """Scale a peak-normalised signal to the amplitude limit, or lower to meet the rate limit."""
    rate = float(np.max(np.abs(np.diff(u)))) / lim.dt  # per unit peak
    scale = min(lim.amplitude, lim.rate / rate) if rate > 0 else lim.amplitude
    return u * scale, scale / lim.amplitude


def classic_input(kind: str, lim: Limits, band=(0.5, 10.0), *, unit: float | None = None) -> DesignInput:
    """A classic input within the limits.

    Parameters
    ----------
    kind : {"doublet", "3211", "sweep", "log-sweep", "schroeder", "min-crest"}
        Doublet and 3-2-1-1 (``unit`` s, default: the longest up to 1 s that
        fits the record), linear and logarithmic sweeps over the band, and flat
        multisines over the band with Schroeder or minimum-crest-factor phases.
    lim : Limits
        Amplitude, rate, duration and sample interval.
    band : (lo, hi), optional
        Band of the sweeps and multisines, rad/s.
    unit : float, optional
        Time unit of the doublet (pulse width) and 3-2-1-1, s.

    Returns
    -------
    DesignInput
        Its ``options`` say when the rate limit lowered the amplitude
        (``amplitude_fraction`` < 1).
    """
    if kind in ("doublet", "3211"):
        return _steps(kind, lim, unit)
    lo, hi = _check_band(band, lim)
    if kind in ("schroeder", "min-crest"):
        return multisine_input(lim, (lo, hi), phases=kind, name=f"{kind} multisine")
    if kind not in ("sweep", "log-sweep"):
        raise ParameterError(f"unknown input kind {kind!r}; kinds: {', '.join(CLASSIC_KINDS)}")
    t = mv.time_vector(lim.duration, lim.dt)
    shape = "log" if kind == "log-sweep" else "linear"
    u = mv.sweep(t, 1.0, lo, hi, kind=shape)
    de, frac = _rate_scaled(u / np.max(np.abs(u)), lim)
    return DesignInput(kind, t, {"de": de}, {"band": [lo, hi], "kind": shape, "amplitude_fraction": frac}, lim)


def multisine_input(
    lim: Limits,
    band,
    amplitudes=None,
    *,
    phases: str = "min-crest",
    stride: int = 1,
    offset: int = 0,
    second: str | None = None,
    name: str = "multisine",
) -> DesignInput:
    """A multisine over the band's harmonics of 2 pi / T, peak-scaled to the limits.

    ``amplitudes`` (relative, one per harmonic) shape the spectrum; with
    ``second`` (``"alpha_w"``) a second input gets the interleaved harmonics
    (stride 2, offsets 0 and 1), mutually orthogonal over the record.

    Parameters
    ----------
    lim : Limits
        Amplitude, rate, duration and sample interval.
    band : (lo, hi)
        Band, rad/s, below the Nyquist frequency.
    amplitudes : array_like, optional
        Relative amplitude of each harmonic (default flat).
    phases : {"min-crest", "schroeder", "random"} or array_like, optional
        Phases, as for :func:`fdml.maneuvers.multisine`.
    stride, offset : int, optional
        Keep the harmonics whose index in the band is ``offset`` modulo ``stride``.
    second : {"alpha_w"}, optional
        A second input on the interleaved harmonics (a gust-like input for simulation).
    name : str, optional
        Name of the input.

    Returns
    -------
    DesignInput
        The multisine; its ``options`` hold the band, the harmonics (rad/s)
        and ``amplitude_fraction`` (< 1 when the rate limit lowered the amplitude).
    """
    lo, hi = _check_band(band, lim)
    t = mv.time_vector(lim.duration, lim.dt)
    if second is not None:
        stride = 2
    u = mv.multisine(t, 1.0, lo, hi, phases=phases, amplitudes=amplitudes, stride=stride, offset=offset)
    de, frac = _rate_scaled(u, lim)
    omega = mv.multisine_frequencies(t, lo, hi, stride=stride, offset=offset)
    signals = {"de": de}
    opts = {"band": [lo, hi], "phases": phases, "harmonics": omega.tolist(), "amplitude_fraction": frac}
    if second is not None:
        if second != "alpha_w":
            raise ParameterError(f"second input {second!r}: only 'alpha_w' (a gust-like input for simulation)")
        signals[second] = mv.multisine(t, lim.amplitude, lo, hi, phases=phases, stride=2, offset=1 - offset)
        opts["second_harmonics"] = mv.multisine_frequencies(t, lo, hi, stride=2, offset=1 - offset).tolist()
    return DesignInput(name, t, signals, opts, lim)


def read_input(path) -> DesignInput:
    """An input history from fdml's record CSV (``t``, ``de``[, ``alpha_w``]; other columns ignored).

    Parameters
    ----------
    path : str or Path
        The CSV file.

    Returns
    -------
    DesignInput
        The history, time from 0, with limits taken from it (peak ``|de|``, length, dt).
    """
    rec = read_csv(path, require=("de",), check_units=True)
    t = rec.t - rec.t[0]
    signals = {k: rec[k] for k in INPUTS if rec.has(k)}
    if not np.any(signals["de"]):
        raise FdmlError(f"input file {path}: de is zero throughout: nothing excites the aircraft")
    lim = Limits(amplitude=float(np.max(np.abs(signals["de"]))), duration=float(t[-1]), dt=rec.dt)
    return DesignInput(rec.name, t, signals, {"source": str(path)}, lim)


def spectrum(inp: DesignInput, omega) -> np.ndarray:
    """|finite Fourier transform| of de at omega (rad/s), rad s (fdml.fourier's end-corrected quadrature).

    Parameters
    ----------
    inp : DesignInput
        The input history.
    omega : array_like
        Frequencies, rad/s.

    Returns
    -------
    numpy.ndarray
        The magnitude, rad s, shaped like ``omega``.
    """
    from ..fourier import finite_fourier_transform

    return np.abs(finite_fourier_transform(inp.de, float(inp.t[1] - inp.t[0]), np.asarray(omega, float)))
