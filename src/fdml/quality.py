"""Data quality of a flight record, checked before any fit.

:func:`check_quality` looks at what a frequency-domain fit silently relies
on and states plainly what it finds:

* **sampling**: rate and jitter of the time vector;
* **per channel**: resolution (smallest step), number of distinct levels,
  how often the value changes, held values (dropouts) and flat tops at the
  extreme values (saturation);
* **excitation in the band**: the input's energy spectrum over the band, the
  fraction of the input energy inside it, the band frequencies where the
  input is more than 40 dB below its peak, the ordinary coherence
  between the elevator and each output, and a verdict on whether the band
  carries enough input to identify the model's parameters.

Every threshold is stated where it is defined, with its reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .channels import OUTPUTS, SIGNALS
from .errors import BandError, RecordError
from .jsoncodec import Codec, Spec, floats, integer, nested_list, numbers, pairs, texts
from .record import Record

__all__ = ["check_quality", "QualityReport", "ChannelQuality", "LOW_INPUT_DB", "GOOD_COHERENCE"]

#: Input level below its peak (over all frequencies) at which a frequency counts as
#: unexcited, dB.  Information about parameters at a frequency grows with
#: |u(w)|^2 (docs/theory.md Eq. 23: A_i is proportional to the input), so -40 dB
#: (1 % of the peak amplitude) carries 1e-4 of the peak's information: with a
#: signal-to-noise ratio of 40 dB or less at the peak -- typical of flight
#: data -- the output there is at or below the noise.
LOW_INPUT_DB = 40.0
#: Coherence regarded as good for identification, the flight-test rule of
#: thumb (CIFER and Tischler & Remple use 0.6): above it, the linear part of
#: the response dominates noise and nonlinearity by at least 1.5 : 1 in power
#: (gamma^2/(1 - gamma^2) = 1.5).
GOOD_COHERENCE = 0.6
#: Significance level of the zero-coherence test (coherence threshold
#: 1 - alpha**(1/(n_d - 1)) for n_d averages; Carter 1987).
COHERENCE_ALPHA = 0.05
#: Welch segments aimed at (50 % overlap): 7 segments give ~7 averages, so
#: random coherence of unrelated signals stays below 1 - 0.05**(1/6) = 0.39.
WELCH_SEGMENTS = 7
#: Daniell smoothing width (bins) when the record is too short for Welch.
DANIELL_BINS = 5
#: Welch is used only if its segments resolve at least half of the band and
#: give at least this many estimates inside it; fewer cannot show how
#: coherence varies over the band.
MIN_COHERENCE_ESTIMATES = 5
#: Default number of estimated quantities for the excitation verdict: a
#: dimensional short-period model (6) plus 3 output biases and 4 boundary
#: values (fdml.fit's defaults).
DEFAULT_N_PARAMS = 13


@dataclass(frozen=True)
class ChannelQuality(Codec):
    """Findings for one channel.

    Parameters
    ----------
    name, unit : str
        Channel name and its SI unit.
    resolution : float
        Smallest non-zero step between samples (the quantisation, at most), SI.
    n_levels : int
        Distinct values.
    change_rate : float
        Value changes per second, 1/s.  A channel cannot carry information
        above half this rate (it is held, or coarser than the motion).
    repeat_fraction : float
        Fraction of samples equal to the previous one.
    holds : tuple of (start s, duration s)
        Runs of >= 3 identical samples across which the signal moved by more
        than 2 (L+1)/(L-1) resolution steps: impossible for a continuous
        signal read through a quantiser (it would cross a level), so the value
        was held -- a dropout, or for an input, a held stick.
    flat_max, flat_min : float
        Longest run at the record's maximum / minimum, s.
    clipped : tuple of str
        ``"max"``/``"min"`` where the run at the extreme is >= 3 samples and a
        parabola through the samples on both sides peaks beyond the flat level
        by more than 3 resolution steps and 3 times its fit residual: the
        signal was heading further and was cut off (saturation).
    flags : tuple of str
        Plain-language findings.
    """

    name: str
    unit: str
    resolution: float
    n_levels: int
    change_rate: float
    repeat_fraction: float
    holds: tuple = ()
    flat_max: float = 0.0
    flat_min: float = 0.0
    clipped: tuple = ()
    flags: tuple = ()

    json_fields = {"n_levels": integer(0), "holds": pairs(), "clipped": texts(("max", "min")), "flags": texts()}
    json_source = "channel quality"


def _coherence_field(f, key: str, done: dict) -> dict:
    """The coherence estimates by output, each on the report's ``coherence_omega``."""
    m = f.floats("coherence_omega", (None,)).size
    sub = f.sub(key)
    return {k: sub.floats(k, (m,)) for k in sub.doc}


@dataclass(frozen=True)
class QualityReport(Codec):
    """What :func:`check_quality` found.  Frozen; print :meth:`summary`.

    Parameters
    ----------
    name : str
        Record name.
    n, dt, duration : int, float, float
        Samples, mean interval (s), length (s).
    jitter : float
        Largest deviation of a sample interval from the mean, as a fraction of it.
    channels : tuple of ChannelQuality
        One report per channel.
    band : tuple
        (lo, hi, step) rad/s.
    omega : ndarray
        Band frequencies, rad/s.
    input_db : ndarray
        Input energy spectrum ``|de(w)|^2`` on ``omega``, dB relative to its peak
        over all frequencies (0 to Nyquist).
    input_energy_fraction : float
        Fraction of the input's energy (mean removed) at frequencies inside the band.
    low_input : tuple of (lo, hi)
        Band intervals, rad/s, where the input is more than LOW_INPUT_DB below its peak.
    coherence : dict
        Output name -> ordinary coherence on ``coherence_omega``.
    coherence_omega : ndarray
        Frequencies of the coherence estimates (inside the band), rad/s.
    coherence_method : str
        How coherence was estimated, and why.
    coherence_threshold : float
        Coherence below which input and output are indistinguishable from
        unrelated at the 5 % level.
    independent_frequencies : float
        Band width times T / (2 pi): frequencies whose transforms are uncorrelated.
    useful_frequencies : float
        Independent frequencies where the input is within LOW_INPUT_DB of its
        peak and at least one output is coherent (above both the significance
        threshold and GOOD_COHERENCE).
    required_frequencies : int
        The number ceil(n_params / (2 n_outputs)): each independent frequency
        gives 2 real equations per output.
    n_params : int
        Number of quantities the fit will estimate.
    sufficient : bool
        ``useful_frequencies >= required_frequencies``.
    findings : tuple of str
        Plain statements, most important first.
    """

    name: str
    n: int
    dt: float
    duration: float
    jitter: float
    channels: tuple
    band: tuple
    omega: np.ndarray
    input_db: np.ndarray
    input_energy_fraction: float
    low_input: tuple
    coherence: dict
    coherence_omega: np.ndarray
    coherence_method: str
    coherence_threshold: float
    independent_frequencies: float
    useful_frequencies: float
    required_frequencies: int
    n_params: int
    sufficient: bool
    findings: tuple = field(default=())

    json_fields = {
        "n": integer(0),
        "channels": nested_list(ChannelQuality),
        "band": numbers(3),
        "omega": floats(None),
        "input_db": floats("omega"),
        "low_input": pairs(),
        "coherence": Spec(_coherence_field),
        "coherence_omega": floats(None),
        "required_frequencies": integer(0),
        "n_params": integer(0),
        "findings": texts(),
    }
    json_source = "quality report"

    def channel(self, name: str) -> ChannelQuality:
        """The report of channel ``name`` (KeyError if there is none).

        Parameters
        ----------
        name : str
            A channel of the record.

        Returns
        -------
        ChannelQuality
            Its report.
        """
        return {c.name: c for c in self.channels}[name]

    def summary(self) -> str:
        """Plain-text report.

        Returns
        -------
        str
            Sampling, channel table, excitation, coherence and findings.
        """
        lo, hi, step = self.band
        out = [
            f"Data quality: {self.name}",
            f"  {self.n} samples, dt {self.dt:.6g} s ({1 / self.dt:.4g} Hz), {self.duration:.4g} s, "
            f"jitter {self.jitter:.2g} of dt",
            f"  band {lo:g}-{hi:g} rad/s ({lo / (2 * math.pi):.3g}-{hi / (2 * math.pi):.3g} Hz), "
            f"{self.independent_frequencies:.1f} independent frequencies (spacing 2 pi/T = "
            f"{2 * math.pi / self.duration:.3g} rad/s)",
            "",
            "  channel   resolution     levels  changes/s  repeats  holds  flat max/min (s)",
        ]
        for c in self.channels:
            out.append(
                f"  {c.name:8s} {c.resolution:11.4g} {c.unit:7s}{c.n_levels:5d} {c.change_rate:9.3g}"
                f" {100 * c.repeat_fraction:7.1f}% {len(c.holds):5d}  {c.flat_max:.3g}/{c.flat_min:.3g}"
            )
        out += ["", f"  input energy inside the band: {100 * self.input_energy_fraction:.1f} %"]
        if self.low_input:
            out.append(f"  input more than {LOW_INPUT_DB:g} dB below its peak at: {_spans(self.low_input)} rad/s")
        out.append(f"  coherence: {self.coherence_method}")
        for k, g in self.coherence.items():
            if g.size:
                good = float(np.mean(_coherent(g, self.coherence_threshold)))
                out.append(
                    f"    de -> {k:6s}: median {np.median(g):.2f}, min {np.min(g):.2f}, "
                    f">= {GOOD_COHERENCE:g} at {100 * good:.0f} % of {g.size} estimates"
                )
        out += ["", "Findings:", *(f"  - {f}" for f in self.findings)]
        return "\n".join(out)


def check_quality(record: Record, band=None, *, n_params: int = DEFAULT_N_PARAMS, outputs=OUTPUTS) -> QualityReport:
    """Check a record's sampling, channels and excitation before a fit.

    Parameters
    ----------
    record : Record
        The record to check.
    band : tuple or str, optional
        ``(lo, hi, step)`` rad/s or ``"LO:HI:STEP"``; default 0.1:10:0.1 as
        :func:`fdml.fit`.  Must lie below the Nyquist frequency.
    n_params : int, optional
        Number of quantities the fit will estimate (default 13: a dimensional
        model with output biases and boundary terms); sets how many
        independent, excited frequencies the band must hold.
    outputs : sequence of str, optional
        Outputs whose coherence with the elevator is estimated.

    Returns
    -------
    QualityReport
        The findings on sampling, channels and excitation.

    Notes
    -----
    Coherence is estimated with :func:`scipy.signal.coherence` (Welch, Hann
    windows, 50 % overlap, about 7 segments) when those segments resolve at
    least half of the band; segments shorter than the record cannot resolve
    frequencies below 2 pi / (segment length).  Otherwise (short records: a
    6 s record cannot resolve 0.1 Hz with any segment shorter than itself)
    it is estimated from the whole-record FFT smoothed over 5 adjacent bins
    (Daniell), which resolves 5 x 2 pi/T and has 5 averages; the report says
    which, and the significance threshold follows the number of averages.
    """
    from . import fourier
    from .spectral import parse_band

    if not isinstance(record, Record):
        raise RecordError(f"expected an fdml Record, got {type(record).__name__}")
    if isinstance(n_params, bool) or not isinstance(n_params, (int, np.integer)) or n_params < 1:
        raise RecordError(f"n_params (the number of estimated quantities) must be an integer >= 1, got {n_params!r}")
    band = parse_band(band)
    lo, hi, step = band
    if hi > record.nyquist:
        raise BandError(
            f"band reaches {hi:g} rad/s, above the Nyquist frequency {record.nyquist:.4g} rad/s "
            f"of record {record.name!r}"
        )
    omega = fourier.omega_band(lo, hi, step)
    n, dt, T = record.n, record.dt, record.duration
    jitter = float(np.max(np.abs(np.diff(record.t) - dt)) / dt)

    # --- channels --------------------------------------------------------------------------
    chans, findings, findings_low = _channel_findings(record, outputs, hi)
    if jitter > 1e-6:
        findings_low.append(f"sample intervals vary by up to {100 * jitter:.2g} % of dt")

    # --- input energy ----------------------------------------------------------------------
    # The input as the estimator sees it (trim = first sample removed).  Its energy
    # spectrum on a dense grid (8x zero-padded FFT, dt X_k ~ the Fourier integral)
    # gives the global peak and the share of energy inside the band; the band values
    # themselves come from fdml's end-corrected transform on the band grid.
    E, w_fft, input_db, peak = _input_energy(record["de"], dt, omega)
    tot = float(np.sum(E))
    frac = float(np.sum(E[(w_fft >= lo) & (w_fft <= hi)]) / tot) if tot > 0 else 0.0
    low_mask = input_db < -LOW_INPUT_DB
    low_input = _intervals(omega, low_mask)

    # --- coherence ---------------------------------------------------------------------------
    coh, coh_w, method, thr = _coherence(record, outputs, lo, hi)

    # --- verdict ----------------------------------------------------------------------------
    independent = (hi - lo) * T / (2 * math.pi) + 1.0
    good = ~low_mask
    if coh_w.size:
        coherent = np.zeros(coh_w.size, bool)
        for g in coh.values():
            coherent |= _coherent(g, thr)
        good &= np.interp(omega, coh_w, coherent.astype(float)) >= 0.5
    useful = float(np.sum(good)) * step * T / (2 * math.pi) if omega.size > 1 else float(np.sum(good))
    useful = min(useful, independent)
    n_out = len(outputs)
    required = max(1, math.ceil(n_params / (2 * n_out)))
    sufficient = useful >= required and peak > 0

    head = _headline(peak, sufficient, useful, n_params, n_out, required, frac, band, low_input, coh, thr)
    if "too short" in method:
        head.append(method)
    if not any(c.holds or c.clipped for c in chans if c.name != "de"):
        findings.append("no dropouts or saturation in any measured channel")
    findings = head + findings + findings_low + [f"sampling {1 / dt:.4g} Hz, jitter {jitter:.2g} of dt"]

    return QualityReport(
        name=record.name,
        n=n,
        dt=dt,
        duration=T,
        jitter=jitter,
        channels=tuple(chans),
        band=(lo, hi, step),
        omega=omega,
        input_db=input_db,
        input_energy_fraction=frac,
        low_input=tuple(low_input),
        coherence=coh,
        coherence_omega=coh_w,
        coherence_method=method,
        coherence_threshold=thr,
        independent_frequencies=independent,
        useful_frequencies=useful,
        required_frequencies=required,
        n_params=int(n_params),
        sufficient=bool(sufficient),
        findings=tuple(findings),
    )


def _channel_findings(record: Record, outputs, hi: float):
    """Each channel's quantisation, holds and clipping; findings on the fitted channels and on the others."""
    findings: list[str] = []
    findings_low: list[str] = []
    chans = [_channel(k, record[k], record.dt, is_input=(k == "de")) for k in SIGNALS if k in record.signals]
    f_hi_hz = hi / (2 * math.pi)
    for c in chans:
        name = c.name
        if c.change_rate < 2 * f_hi_hz and c.n_levels > 1:
            msg = (
                f"{name} changes value only {c.change_rate:.3g} times per second ({c.n_levels} levels, step "
                f"{c.resolution:.3g} {c.unit}): it cannot follow motion above about {c.change_rate / 2:.3g} Hz, "
                f"and the band reaches {f_hi_hz:.3g} Hz"
            )
            (findings if name in ("de", *outputs) else findings_low).append(msg)
        if name == "de":  # the input's holds and flat tops are its steps
            continue
        if c.repeat_fraction > 0.5:
            msg = (
                f"{name} repeats its previous value in {100 * c.repeat_fraction:.0f} % of the samples "
                f"({c.n_levels} levels, step {c.resolution:.3g} {c.unit}): a slow update or a coarse resolution"
            )
            (findings if name in outputs else findings_low).append(msg)
        if c.holds:
            start, longest = max(c.holds, key=lambda h: h[1])
            findings.append(
                f"{name} holds its value {len(c.holds)} time(s) while the signal moves "
                f"(dropouts; {sum(h[1] for h in c.holds):.3g} s in all, longest {longest:.3g} s at "
                f"t = {start:.4g} s)"
            )
        if c.clipped:
            findings.append(
                f"{name} is flat at its {' and '.join(c.clipped)} value while heading further: "
                "possible sensor saturation"
            )
    return chans, findings, findings_low


def _headline(peak, sufficient, useful, n_params, n_out, required, frac, band, low_input, coh, thr) -> list[str]:
    """The verdict's first findings: sufficiency of excitation, input energy in the band, coherence."""
    lo, hi, _step = band
    head = []
    if peak == 0:
        head.append("the elevator does not move: the record carries no input; no parameter can be identified")
    else:
        head.append(
            f"excitation {'sufficient: about' if sufficient else 'INSUFFICIENT: only about'} {useful:.1f} "
            f"independent frequencies in the band carry input within {LOW_INPUT_DB:g} dB of its peak with "
            f"coherent outputs; {n_params} parameters with {n_out} outputs need at least {required}"
            + ("" if sufficient else ": widen the band, lengthen the record or fly a richer input")
        )
    head.append(f"{100 * frac:.0f} % of the elevator's energy lies inside the band {lo:g}-{hi:g} rad/s")
    if low_input:
        head.append(
            f"the input is more than {LOW_INPUT_DB:g} dB below its peak at {_spans(low_input)} rad/s: "
            "those frequencies carry almost no information"
        )
    for k, g in coh.items():
        if g.size:
            good_frac = float(np.mean(_coherent(g, thr)))
            if good_frac < 0.5:
                head.append(
                    f"coherence de -> {k} is below {GOOD_COHERENCE:g} at {100 * (1 - good_frac):.0f} % "
                    f"of the band (median {np.median(g):.2f}): noise or nonlinearity dominate there"
                )
    return head


def _input_energy(u: np.ndarray, dt: float, omega: np.ndarray):
    """Energy spectrum of an input as the estimator sees it (trim = first sample removed).

    Returns ``(E, w_fft, input_db, peak)``: the energy on a dense grid (8x
    zero-padded FFT, dt X_k ~ the Fourier integral) at ``w_fft`` rad/s, the
    level at ``omega`` (fdml's end-corrected transform) in dB below the peak
    over all frequencies, and that peak (0 for an input that never moves).
    """
    from . import fourier

    x = np.asarray(u, dtype=float) - u[0]
    E = np.abs(dt * np.fft.rfft(x, 8 * x.size)) ** 2
    w_fft = 2 * np.pi * np.fft.rfftfreq(8 * x.size, dt)
    P = np.abs(fourier.finite_fourier_transform(x, dt, omega)) ** 2
    peak = float(max(np.max(E), np.max(P)))
    with np.errstate(divide="ignore"):
        input_db = 10 * np.log10(P / peak) if peak > 0 else np.full(P.shape, -np.inf)
    return E, w_fft, input_db, peak


def unexcited(u: np.ndarray, dt: float, omega: np.ndarray) -> bool:
    """True if an input carries no power in the band.

    It never moves, or every band frequency is more than :data:`LOW_INPUT_DB`
    below its peak (the measure of :func:`check_quality`).

    Parameters
    ----------
    u : numpy.ndarray
        The input history, shape (n,) (any unit).
    dt : float
        Sample interval, s.
    omega : numpy.ndarray
        Band frequencies, rad/s.

    Returns
    -------
    bool
        Whether the input leaves the band unexcited.
    """
    _, _, input_db, peak = _input_energy(u, dt, omega)
    return peak == 0 or bool(np.all(input_db < -LOW_INPUT_DB))


# --- channel checks ---------------------------------------------------------------------------
def _runs(x: np.ndarray, dust: float = 0.0):
    """(start index, length) of runs of equal consecutive values (steps <= ``dust`` count as equal)."""
    change = np.flatnonzero(np.abs(np.diff(x)) > dust) + 1
    starts = np.concatenate([[0], change])
    return starts, np.diff(np.append(starts, x.size))


def _resolution(x: np.ndarray) -> tuple[float, float]:
    """(resolution, dust): the smallest genuine step, and the size below which steps are rounding dust.

    Steps below 1e-3 of the median non-zero step are rounding of printed or
    converted values (e.g. 0.00344005 against 0.00344006 in a file written
    to 8 decimals), not quantisation; the resolution is the smallest step
    above that.
    """
    dx = np.abs(np.diff(x))
    nz = dx[dx > 0]
    if not nz.size:
        return 0.0, 0.0
    dust = 1e-3 * float(np.median(nz))
    cand = nz[nz > dust]
    return (float(np.min(cand)) if cand.size else float(np.min(nz))), dust


def _channel(name: str, x: np.ndarray, dt: float, is_input: bool) -> ChannelQuality:
    res, dust = _resolution(x)
    changed = np.abs(np.diff(x)) > dust  # a record has at least 4 samples
    starts, lens = _runs(x, dust)
    n_levels = np.unique(np.round(x[starts] / res) if res > 0 else x[starts]).size
    holds = []
    xmax, xmin = float(np.max(x)), float(np.min(x))
    for s, L in zip(starts, lens):
        if L < 3 or s == 0 or s + L >= x.size or res == 0:
            continue
        if abs(x[s] - xmax) <= dust or abs(x[s] - xmin) <= dust:
            continue  # a flat top at an extreme is judged as saturation below
        D = abs(x[s + L] - x[s - 1])
        if D > 2 * res * (L + 1) / (L - 1):
            holds.append((float(s * dt), float((L - 1) * dt)))
    flat_max, clip_max = _flat(x, lens, starts, xmax, res, dust, dt)
    flat_min, clip_min = _flat(x, lens, starts, xmin, res, dust, dt)
    clipped = tuple(k for k, c in (("max", clip_max), ("min", clip_min)) if c)
    flags = []
    if holds:
        flags.append("held values" + (" (held input levels)" if is_input else " (dropouts)"))
    if clipped:
        flags.append(
            "flat top at " + "/".join(clipped) + (" (step input, by design)" if is_input else " (saturation?)")
        )
    return ChannelQuality(
        name=name,
        unit=SIGNALS.get(name, ""),
        resolution=res,
        n_levels=n_levels,
        change_rate=int(np.sum(changed)) / (dt * (x.size - 1)),
        repeat_fraction=float(np.mean(~changed)),
        holds=tuple(holds),
        flat_max=flat_max,
        flat_min=flat_min,
        clipped=clipped,
        flags=tuple(flags),
    )


def _flat(x, lens, starts, level, res, dust, dt):
    """Longest run at ``level`` (s) and whether it looks clipped."""
    best, where = 0, None
    for s, L in zip(starts, lens):
        if np.any(np.abs(x[s : s + L] - level) <= dust) and L > best:
            best, where = L, s
    if where is None:
        return 0.0, False
    dur = float((best - 1) * dt)
    if best < 3:
        return dur, False
    m = int(min(max(3, best // 2), 10))  # a few samples each side: the approach, not the wider signal
    i0, i1 = where, where + best
    left = np.arange(max(0, i0 - m), i0)
    right = np.arange(i1, min(x.size, i1 + m))
    if left.size < 2 or right.size < 2:
        return dur, False
    idx = np.concatenate([left, right])
    tt = (idx - (i0 + i1) / 2) * dt
    A = np.column_stack([np.ones_like(tt), tt, tt**2])
    coef, *_ = np.linalg.lstsq(A, x[idx], rcond=None)
    fit_rms = float(np.sqrt(np.mean((A @ coef - x[idx]) ** 2)))
    c0, c1, c2 = coef
    sign = 1.0 if level >= np.mean(x) else -1.0
    if c2 * sign >= 0:  # not curving back: no peak between the sides
        return dur, False
    tv = -c1 / (2 * c2)
    if abs(tv) > (best + 1) * dt:
        return dur, False
    vertex = c0 + c1 * tv + c2 * tv**2
    return dur, bool(sign * (vertex - level) > max(3 * res, 3 * fit_rms))  # peaks beyond the flat level


def _coherent(g: np.ndarray, thr: float) -> np.ndarray:
    """Where a coherence estimate is good: above both GOOD_COHERENCE and the significance threshold."""
    return g >= max(GOOD_COHERENCE, thr)


def _spans(intervals) -> str:
    return ", ".join(f"{a:.3g}" if a == b else f"{a:.3g}-{b:.3g}" for a, b in intervals)


def _intervals(omega, mask):
    """(first, last) frequency of each run of ``mask``, rad/s."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(float(np.round(omega[i], 10)), float(np.round(omega[j - 1], 10))) for i, j in edges.reshape(-1, 2)]


# --- coherence ----------------------------------------------------------------------------------
def _welch(x: np.ndarray, Y: np.ndarray, fs: float, nper: int, nover: int):
    """Welch auto and cross spectra of an input and several outputs, up to a common scale.

    Periodic Hann window, each segment's mean removed, segments ``nper - nover`` apart, the
    segment periodograms averaged: :func:`scipy.signal.welch` and :func:`scipy.signal.csd` with
    ``window="hann", detrend="constant"``, without their common density scaling (a coherence
    is a ratio, so it cancels). Written on numpy because importing scipy.signal costs about
    1 s, more than a whole fit (issue 20); ``tests/test_quality.py`` checks it against scipy.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Input samples.
    Y : ndarray, shape (n_out, n)
        Output samples.
    fs : float
        Sample rate, Hz.
    nper, nover : int
        Segment length and overlap, samples.

    Returns
    -------
    f : ndarray, shape (nper // 2 + 1,)
        Frequencies, Hz.
    Pxx : ndarray, shape (nper // 2 + 1,)
        Input auto spectrum.
    Pyy : ndarray, shape (n_out, nper // 2 + 1)
        Output auto spectra.
    Pxy : ndarray, shape (n_out, nper // 2 + 1)
        Cross spectra, conj(X) Y as scipy.signal.csd has them.
    """
    step = nper - nover
    starts = np.arange(0, x.size - nper + 1, step)
    idx = starts[:, None] + np.arange(nper)[None, :]
    win = 0.5 - 0.5 * np.cos(2 * math.pi * np.arange(nper) / nper)  # periodic Hann

    def segments(v):
        seg = v[..., idx]  # (..., n_seg, nper)
        return np.fft.rfft((seg - seg.mean(axis=-1, keepdims=True)) * win, axis=-1)

    X, Z = segments(x), segments(Y)
    Pxx = np.mean(np.abs(X) ** 2, axis=0)
    Pyy = np.mean(np.abs(Z) ** 2, axis=-2)
    Pxy = np.mean(np.conj(X)[None] * Z, axis=-2)
    return np.fft.rfftfreq(nper, 1.0 / fs), Pxx, Pyy, Pxy


def _coherence(record: Record, outputs, lo: float, hi: float):
    """Coherence of the elevator with each output in the band (Welch, or Daniell for short records: see
    :func:`check_quality`); returns (by output, frequencies rad/s, method, 5 % significance threshold)."""
    n, dt = record.n, record.dt
    fs = 1.0 / dt
    de = record["de"]
    names = [k for k in outputs if k in record.signals]
    Y = np.vstack([record[k] for k in names]) if names else np.zeros((0, n))
    nper = int(2 * n / (WELCH_SEGMENTS + 1))
    welch = False
    if nper >= 16:
        w1 = 2 * math.pi * fs / nper
        w_grid = np.arange(lo, hi + 1e-12, (hi - lo) / 100 if hi > lo else 1.0)
        covered = float(np.mean(w_grid >= w1))
        bins = w1 * np.arange(1, nper // 2 + 1)
        n_in_band = int(np.sum((bins >= lo) & (bins <= hi)))
        welch = covered >= 0.5 and n_in_band >= MIN_COHERENCE_ESTIMATES
    if welch:
        nover = nper // 2
        n_seg = 1 + (n - nper) // (nper - nover)
        # one Welch pass over the elevator and all outputs (what scipy.signal.coherence
        # computes output by output, in three passes each)
        f, Pxx, Pyy, Pxy = _welch(de, Y, fs, nper, nover)
        w = 2 * math.pi * f
        thr = 1 - COHERENCE_ALPHA ** (1 / max(n_seg - 1, 1))
        method = (
            f"Welch, {nper}-sample Hann segments ({nper * dt:.3g} s), 50 % "
            f"overlap, {n_seg} segments: resolution {w1:.3g} rad/s; 5 % significance threshold "
            f"{thr:.2f}"
        )
        if covered < 1.0:
            method += f"; band frequencies below {w1:.3g} rad/s are not resolved by these segments"
    else:
        # Daniell: whole-record FFT, smoothed over DANIELL_BINS adjacent bins; the
        # spectrum is mirrored about zero frequency (S(-k) = conj S(k)) so the
        # lowest bins are smoothed over as many bins as the others.
        m = DANIELL_BINS
        h = m // 2
        X = np.fft.rfft(de - np.mean(de))
        w = 2 * math.pi * np.fft.rfftfreq(n, dt)
        ker = np.ones(m)

        def smooth(S):
            ext = np.concatenate([np.conj(S[1 : h + 1][::-1]), S, np.conj(S[-h - 1 : -1][::-1])])
            return np.convolve(ext, ker, mode="valid")

        Z = [np.fft.rfft(y - np.mean(y)) for y in Y]
        Pxx = smooth(np.abs(X) ** 2).real
        Pyy = [smooth(np.abs(z) ** 2).real for z in Z]
        Pxy = [smooth(X * np.conj(z)) for z in Z]
        thr = 1 - COHERENCE_ALPHA ** (1 / (m - 1))
        reason = (
            f"Welch segments short enough for {WELCH_SEGMENTS} averages ({nper * dt:.3g} s) resolve only "
            f"{2 * math.pi / (nper * dt):.3g} rad/s"
            if nper >= 16
            else "too few samples for Welch segments"
        )
        method = (
            f"record too short for Welch coherence over this band ({record.duration:.3g} s; {reason}): "
            f"coherence from the whole-record FFT smoothed over {m} adjacent bins (Daniell), resolution "
            f"{m * (2 * math.pi / (n * dt)):.3g} rad/s, {m} averages, 5 % significance threshold {thr:.2f}"
        )
    sel = (w >= lo) & (w <= hi) & (w > 0)
    coh = {}
    for k, syy, sxy in zip(names, Pyy, Pxy):
        with np.errstate(invalid="ignore", divide="ignore"):
            coh[k] = np.nan_to_num((np.abs(sxy) ** 2 / (Pxx * syy))[sel])
    return coh, w[sel], method, thr
