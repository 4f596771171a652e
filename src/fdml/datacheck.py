"""The data check that runs inside every fit: units, signs, channels, response.

A record whose labels lie gives plausible numbers: an elevator in degrees read
as radians scales every control derivative by 1/57.3, a swapped pair of
channels still "converges".  :func:`check_data` looks for these cheaply enough
to be always on (about a millisecond a record; ``benchmarks/bench_datacheck.py``):

* **physical ranges** (``units.<signal>``): an elevator or angle of attack
  beyond 0.6 rad, a pitch rate beyond 3 rad/s, an a_z perturbation beyond 6 g;
* **the kinematic identity of the short period** (docs/theory.md Eq. 5,
  ``alpha_dot = q + (g/U) a_z``), fitted by one least-squares regression on the
  record's spectra in the band (Eq. 11 transforms; boundary and bias terms as
  nuisance regressors, so that it works on perturbation records and on
  records with trim alike).  Its two slopes are compared with every
  combination of the usual labelling errors (alpha in degrees, q in deg/s,
  a_z in m/s^2, a flipped sign); the nearest combination names the error
  (``units.alpha``, ``units.q``, ``units.az``, ``sign.q``, ``sign.az``), and a
  permutation of the outputs that satisfies the identity far better than the
  labelled order names swapped channels (``channels.swapped``);
* **response** (``response.<output>``): the output's coherence with the
  elevator stays below its significance threshold over most of the band, and
  the outputs do not satisfy the kinematic identity either (a record in strong
  turbulence is coherent with the elevator over little of the band, but its
  outputs still satisfy Eq. 5);
* **the phugoid** (``phugoid.in_band``, an estimation finding): a record that
  carries the airspeed and the pitch attitude and holds at least one cycle of
  the phugoid whose frequency lies in (or near the bottom of) the band.  The
  frequency is measured, not assumed: the flight-path angle gamma = theta - alpha
  obeys gamma_dot = d (V - V0) + (alpha and elevator terms), the lift's change
  with speed, and with the along-path balance V_dot = -g gamma this is
  Lanchester's phugoid, omega^2 = g d (:func:`phugoid_frequency`).  The
  short-period models have neither speed nor attitude states, so the phugoid
  is model error inside the band; the finding gives a window and a band that
  leave it out.

A small time shift between channels (the Twin Otter's 21 ms alpha lag) moves
the slopes by a few per cent only and is left to the diagnosis.  Findings are
:class:`~fdml.findings.Finding` objects with stable codes.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from .channels import OUTPUTS, REQUIRED, SIGNALS
from .constants import G0
from .findings import Finding
from .jsoncodec import Codec, nested, nested_list, number_map, numbers, texts
from .record import Record

__all__ = [
    "check_data",
    "DataCheck",
    "KinematicFit",
    "RANGE_LIMITS",
    "DEG",
    "UNIT_TOLERANCE",
    "phugoid_frequency",
    "PHUGOID_BAND_FACTOR",
]

#: One degree in radians' reciprocal: the factor a degree-valued channel carries.
DEG = 180.0 / math.pi
#: Largest plausible short-period magnitudes (SI; a_z as a perturbation about its mean).
#: 0.6 rad = 34 deg exceeds every elevator's travel and any angle of attack flown in a
#: short-period test; 3 rad/s = 172 deg/s exceeds any longitudinal pitch rate of a
#: transport or general-aviation aircraft; 6 g is beyond their structural limits.
#: A degree-valued 1 deg elevator reads 1.0 "rad", a 2 deg/s pitch rate 2 "rad/s".
RANGE_LIMITS = {"de": (0.6, "deg", DEG), "alpha": (0.6, "deg", DEG), "q": (3.0, "deg/s", DEG), "az": (6.0, "m/s^2", G0)}
#: A slope of the kinematic identity is matched to a labelling hypothesis when it lies
#: within this factor of the hypothesis's slope.  The errors it looks for are factors of
#: 57.3, 9.81 or -1; an alpha vane's upwash factor (1.0-1.2), a time shift of a few tens of
#: ms (|e^{-jw tau}| phase, a few per cent at the band's upper end) and noise in the
#: regressors stay well inside a factor of 2.
UNIT_TOLERANCE = 2.0
#: Labelling hypotheses: (scale on alpha, scale on q, scale on a_z) of the measured channel
#: relative to fdml's units and signs.
_ALPHA_SCALES = (1.0, DEG)
_Q_SCALES = (1.0, -1.0, DEG, -DEG)
_AZ_SCALES = (1.0, -1.0, G0, -G0)
#: A permutation of the outputs is taken as the true channel order when it leaves less than
#: this fraction of the labelled order's unexplained variance, and explains at least
#: ``_SWAP_MIN_FIT`` of the variance of alpha_dot itself.
_SWAP_MARGIN = 0.25
_SWAP_MIN_FIT = 0.8
#: Below this fraction of explained variance the identity says nothing about units (the
#: outputs are noise, or the band holds no response); the response check speaks then.
_MIN_FIT = 0.5
#: Outputs that satisfy the identity this well are real motion: low coherence with the
#: elevator then means turbulence or other unmeasured inputs, which the fit's noise model
#: and the diagnosis handle, not a dead or wrong channel.
_VOUCH_FIT = 0.9
#: An output fails the response check when its coherence with the elevator exceeds the
#: 5 % significance threshold at fewer than this fraction of the band's estimates.
_MIN_COHERENT_FRACTION = 0.2
#: The phugoid's regression (gamma on the integrals of the speed, alpha and elevator
#: perturbations) must explain this fraction of the flight-path angle's variance, and the
#: speed term at least ``_PHUGOID_SPEED_SHARE`` of what the other terms leave: otherwise the
#: record shows no speed-driven flight-path motion, and no phugoid is claimed.
_PHUGOID_MIN_FIT = 0.9
_PHUGOID_SPEED_SHARE = 0.5
#: The band that leaves the phugoid out starts at this multiple of its frequency: a
#: second-order mode's response |w_n^2 / (w_n^2 - w^2)| has fallen to 1/8 there.
PHUGOID_BAND_FACTOR = 3.0


@dataclass(frozen=True)
class KinematicFit(Codec):
    """The regression ``j w alpha = a q + b a_z + nuisance`` on a record's spectra.

    Parameters
    ----------
    order : tuple of str
        Channels used as (alpha, q, a_z), in that role: ``("alpha", "q", "az")``
        unless a permutation fitted better.
    slope_q : float
        ``a``, dimensionless; 1 for a record in fdml's units and signs.
    slope_az : float
        ``b``, rad/s per g; g/U for a record in fdml's units and signs.
    expected_az : float or None
        The value g/U, rad/s per g, when the airspeed is known.
    fit : float
        Fraction of the weighted variance of ``j w alpha`` explained.
    fit_labelled : float
        The same for the labelled channel order.
    scales : tuple of float
        The labelling hypothesis nearest the slopes: measured/true scale of
        alpha, q and a_z (1, 1, 1 when the record is as labelled).
    """

    order: tuple
    slope_q: float
    slope_az: float
    expected_az: float | None
    fit: float
    fit_labelled: float
    scales: tuple = (1.0, 1.0, 1.0)

    json_fields = {"order": texts(length=3), "scales": numbers(3)}
    json_extra = ("implied_airspeed",)  # written for readers of the file; derived from the slope, not read
    json_source = "kinematic fit"

    @property
    def implied_airspeed(self) -> float:
        """The airspeed the a_z slope implies (as labelled), g / slope_az, m/s."""
        return G0 / self.slope_az if self.slope_az != 0 else math.inf


@dataclass(frozen=True)
class DataCheck(Codec):
    """Outcome of :func:`check_data` for one record.

    Parameters
    ----------
    record : str
        Record name.
    findings : tuple of Finding
        What the check found (units, signs, coherence).
    kinematics : KinematicFit or None
        None when the record is too short for its band, or lacks an output.
    coherent_fraction : dict
        Per output, the fraction of the band's coherence estimates above the
        5 % significance threshold.
    threshold : float
        That threshold.
    elapsed : float
        Time the check took, s.
    """

    record: str
    findings: tuple = ()
    kinematics: KinematicFit | None = None
    coherent_fraction: dict = field(default_factory=dict)
    threshold: float = math.nan
    elapsed: float = 0.0

    json_fields = {
        "findings": nested_list(Finding),
        "kinematics": nested(KinematicFit, none=True),
        "coherent_fraction": number_map(),
    }
    json_source = "data check"

    @property
    def codes(self) -> tuple:
        """The findings' codes."""
        return tuple(f.code for f in self.findings)

    def summary(self) -> str:
        """A few lines for the terminal.

        Returns
        -------
        str
            The findings, the kinematic slopes and the coherent fractions.
        """
        lines = [
            f"data check of {self.record}: "
            + ("no findings" if not self.findings else f"{len(self.findings)} finding(s)")
        ]
        k = self.kinematics
        if k is not None:
            exp = (
                f" (implies U = {k.implied_airspeed:.4g} m/s; give the airspeed to check it)"
                if k.expected_az is None
                else f" (expected g/U = {k.expected_az:.4g})"
            )
            lines.append(
                f"  kinematics alpha_dot = a q + b a_z: a = {k.slope_q:.4g} (expected 1), "
                f"b = {k.slope_az:.4g} rad/s/g{exp}, {100 * k.fit:.1f} % explained"
            )
        if self.coherent_fraction:
            lines.append(
                "  coherent with the elevator over "
                + ", ".join(f"{o} {100 * v:.0f} %" for o, v in self.coherent_fraction.items())
                + f" of the band (5 % threshold {self.threshold:.2f})"
            )
        lines.extend(f"  {f}" for f in self.findings)
        return "\n".join(lines)


def check_data(record: Record, *, band=None, airspeed: float | None = None, data=None) -> DataCheck:
    """Check a record for wrong units, signs and channels, and for no response.

    Parameters
    ----------
    record : Record
        The record as read (trim removed or not).
    band : tuple or str, optional
        ``(lo, hi, step)`` rad/s or ``"LO:HI:STEP"``; default the fit's default band.
    airspeed : float, optional
        True airspeed U, m/s; default the record's ``meta["U"]``.  Without it
        the a_z slope is checked for its sign only.
    data : FrequencyData, optional
        The record's spectra, when already computed (a fit passes its own).

    Returns
    -------
    DataCheck
        The findings, the kinematic fit and the coherent fractions of the record.
    """
    t0 = time.perf_counter()
    findings = []
    U = airspeed if airspeed is not None else record.meta.get("U")
    U = float(U) if U is not None and np.isfinite(U) and U > 0 else None
    data = _spectra_or_none(record, band) if data is None else data
    kin = None if data is None else _kinematic_fit(data, U)
    if kin is not None:
        findings.extend(_kinematic_findings(kin, record.name))
    # a range finding adds nothing to a kinematic finding of the same code (which has the factor)
    findings.extend(f for f in _range_findings(record) if f.code not in {g.code for g in findings})
    frac, thr = _coherent_fraction(record, data)
    if kin is None or kin.fit < _VOUCH_FIT:
        findings.extend(_response_findings(frac, thr, record.name))
    findings.extend(_phugoid_findings(record, _band_of(band, data)))
    return DataCheck(
        record=record.name,
        findings=tuple(findings),
        kinematics=kin,
        coherent_fraction=frac,
        threshold=thr,
        elapsed=time.perf_counter() - t0,
    )


# --- physical ranges -------------------------------------------------------------------------
def _range_findings(record: Record):
    for sig, (limit, unit, factor) in RANGE_LIMITS.items():
        if not record.has(sig):
            continue
        x = record[sig]
        size = float(np.max(np.abs(x - np.mean(x)))) if sig == "az" else float(np.max(np.abs(x)))
        if size > limit:
            what = "perturbation " if sig == "az" else ""
            yield Finding(
                f"units.{'elevator' if sig == 'de' else sig}",
                f"{sig} {what}reaches {size:.3g} {SIGNALS[sig]}, beyond the plausible {limit:g} {SIGNALS[sig]} of a "
                f"short-period manoeuvre: it looks like {unit} where {SIGNALS[sig]} is due",
                record=record.name,
                value=size,
                expected=limit,
            )


# --- kinematic identity ----------------------------------------------------------------------
def _spectra_or_none(record: Record, band):
    from .errors import FdmlError
    from .spectral import spectra

    if not all(record.has(k) for k in REQUIRED):
        return None
    try:
        return spectra(record, band=band, trim="none")
    except FdmlError:  # band beyond this record: the fit itself says so
        return None


def _nuisance(data) -> np.ndarray:
    """Regressors of alpha(0), alpha(T) e^{-jwT} and constant biases (Eq. 11 boundary terms)."""
    w = data.omega
    cols = [np.ones_like(w, dtype=complex), np.exp(-1j * w * data.T), data.ones]
    if "alpha_w" in data.inputs:  # the vane sees the gust angle: its rate enters alpha_dot
        cols.append(1j * w * data.u[:, list(data.inputs).index("alpha_w")])
    return np.column_stack(cols)


def _regress(y: np.ndarray, X: np.ndarray, wts: np.ndarray) -> tuple[np.ndarray, float]:
    """Real coefficients of the complex regression y ~ X, weighted; (coefficients, R^2)."""
    Xr = np.vstack([(X * wts[:, None]).real, (X * wts[:, None]).imag])
    yr = np.concatenate([(y * wts).real, (y * wts).imag])
    beta, *_ = np.linalg.lstsq(Xr, yr, rcond=None)
    ss = float(yr @ yr)
    resid = yr - Xr @ beta
    return beta, (1.0 - float(resid @ resid) / ss) if ss > 0 else 0.0


def _kinematic_fit(data, U: float | None) -> KinematicFit:
    # Weight each frequency by the elevator's amplitude there: where the input carries no
    # power the regressors are mostly noise, which would bias the slopes toward zero.
    wts = np.abs(data.u[:, 0])
    wts = wts / wts.max() if wts.max() > 0 else np.ones_like(wts)
    N = _nuisance(data)
    jw = 1j * data.omega
    fits = {}
    for perm in itertools.permutations(range(3)):
        y = jw * data.z[:, perm[0]]
        # j w q absorbs the sensors' distance from the centre of gravity: an accelerometer
        # at x_a reads a_z + (x_a/g) q_dot, a vane at x_v reads alpha + (x_v/U) q.
        X = np.column_stack([data.z[:, perm[1]], data.z[:, perm[2]], jw * data.z[:, perm[1]], N])
        beta, r2 = _regress(y, X, wts)
        fits[perm] = (beta[0], beta[1], r2)
    expected = G0 / U if U else None
    perm = _channel_order(fits, expected)
    a, b, r2 = fits[perm]
    return KinematicFit(
        order=tuple(OUTPUTS[i] for i in perm),
        slope_q=float(a),
        slope_az=float(b),
        expected_az=expected,
        fit=float(r2),
        fit_labelled=float(fits[(0, 1, 2)][2]),
        scales=_nearest_scales(a, b, expected),
    )


def _channel_order(fits: dict, expected: float | None) -> tuple:
    """The order of the outputs in which they satisfy Eq. 5: the labelled one unless another fits.

    Another order counts only when its slopes are those of a labelling hypothesis and it
    explains alpha_dot at least ``_SWAP_MIN_FIT``; it replaces the labelled order when that
    leaves ``1/_SWAP_MARGIN`` times more unexplained, or when the labelled order's slopes
    match no hypothesis while the other order fits about as well (q and a_z exchanged fit
    equally well, with the slopes exchanged: a = g/U, b = 1).
    """
    lab = (0, 1, 2)
    r_lab = fits[lab][2]
    lab_ok = bool(_nearest_scales(fits[lab][0], fits[lab][1], expected))
    plausible = [
        p
        for p in fits
        if p != lab and fits[p][2] >= _SWAP_MIN_FIT and _nearest_scales(fits[p][0], fits[p][1], expected)
    ]
    if not plausible:
        return lab
    best = max(plausible, key=lambda p: fits[p][2])
    miss = 1 - fits[best][2]
    return best if miss < _SWAP_MARGIN * (1 - r_lab) or (not lab_ok and miss <= max(2 * (1 - r_lab), 0.02)) else lab


def _nearest_scales(a: float, b: float, expected_az: float | None) -> tuple:
    """The labelling hypothesis (s_alpha, s_q, s_az) nearest the slopes, or () when none is near.

    With measured channels s_alpha alpha, s_q q, s_az a_z, Eq. 5 becomes
    ``j w (s_alpha alpha) = (s_alpha/s_q)(s_q q) + (s_alpha g/U / s_az)(s_az a_z)``.
    """
    best: tuple = ()
    dist = math.inf
    for sa, sq, sz in itertools.product(_ALPHA_SCALES, _Q_SCALES, _AZ_SCALES):
        ea = sa / sq
        if a * ea <= 0 or b * sz <= 0:
            continue
        d = abs(math.log(a / ea))
        if expected_az is not None:
            d = max(d, abs(math.log(b / (sa * expected_az / sz))))
        elif abs(sz) != 1.0:  # without U the a_z scale is not observable: keep its sign only
            continue
        if d < dist:
            best, dist = (sa, sq, sz), d
    return best if dist < math.log(UNIT_TOLERANCE) else ()


def _pct(x: float) -> str:
    return f"{100 * x:.2g} %"


def _kinematic_findings(k: KinematicFit, name: str):
    if k.fit < _MIN_FIT and k.fit_labelled < _MIN_FIT:
        return  # no usable identity: the outputs do not respond (the response check says so)
    found = partial(Finding, record=name)
    exp_b = "" if k.expected_az is None else f" and {k.expected_az:.4g} rad/s per g (g/U)"
    slopes = (
        f"alpha_dot = {k.slope_q:.4g} q + {k.slope_az:.4g} a_z in the band (expected 1{exp_b}; "
        f"{100 * k.fit:.0f} % of alpha_dot explained)"
    )
    if k.order != OUTPUTS:
        labels = ", ".join(f"{lab} holds {true}" for lab, true in zip(k.order, OUTPUTS) if lab != true)
        yield found(
            "channels.swapped",
            f"the outputs satisfy the kinematic identity (docs/theory.md Eq. 5) only when relabelled: "
            f"{labels} (relabelled, {_pct(1 - k.fit)} of alpha_dot is left unexplained; as "
            f"labelled, {_pct(1 - k.fit_labelled)})",
            value=k.fit,
            expected=k.fit_labelled,
        )
    if not k.scales:
        yield found(
            "kinematics.inconsistent",
            f"alpha, q and a_z do not satisfy the kinematic identity (docs/theory.md Eq. 5): {slopes}; "
            "no single unit or sign error explains it (check units, signs and the airspeed)",
            value=k.slope_q,
            expected=1.0,
        )
        return
    sa, sq, sz = k.scales
    if sa != 1.0:
        factor = abs(k.slope_q * sq)
        text = (
            f"alpha looks like degrees: {slopes}; both slopes carry a factor of about {factor:.3g} (57.3 for degrees)"
        )
        yield found("units.alpha", text, value=factor, expected=DEG)
    if abs(sq) != 1.0:
        factor = abs(sa / k.slope_q)
        text = f"q looks like deg/s: {slopes}; the q slope is 1/{factor:.3g} (1/57.3 for deg/s)"
        yield found("units.q", text, value=factor, expected=DEG)
    if sq < 0:
        text = f"q has the wrong sign (nose up must be positive): {slopes}"
        yield found("sign.q", text, value=k.slope_q, expected=1.0)
    if abs(sz) != 1.0:
        factor = abs(sa * k.expected_az / k.slope_az)
        text = f"a_z looks like m/s^2 where g is due: {slopes}; the a_z slope is g/U divided by {factor:.3g}"
        text += " (9.81 for m/s^2)"
        yield found("units.az", text, value=factor, expected=G0)
    if sz < 0:
        text = (
            "a_z has the wrong sign (fdml's a_z is positive down, docs/theory.md Eq. 5; "
            f"a record's a_n is positive up): {slopes}"
        )
        yield found("sign.az", text, value=k.slope_az, expected=k.expected_az)


# --- response to the input -------------------------------------------------------------------
def _coherent_fraction(record: Record, data) -> tuple[dict, float]:
    from .quality import _coherence

    if data is None or not record.has("de"):
        return {}, math.nan
    lo, hi = float(data.omega.min()), float(data.omega.max())
    try:
        coh, _, _, thr = _coherence(record, OUTPUTS, lo, hi)  # the outputs the record has
    except (ValueError, FloatingPointError):  # degenerate record (constant input): quality reports it
        return {}, math.nan
    return {k: float(np.mean(v > thr)) if v.size else math.nan for k, v in coh.items()}, float(thr)


def _response_findings(frac: dict, thr: float, name: str):
    for out, f in frac.items():
        if np.isfinite(f) and f < _MIN_COHERENT_FRACTION:
            yield Finding(
                f"response.{out}",
                f"{out} does not respond to the elevator: its coherence with it exceeds the 5 % "
                f"significance threshold {thr:.2f} at only {100 * f:.0f} % of the band (a dead or "
                "disconnected sensor, a wrong column, or no excitation in this band)",
                record=name,
                value=f,
                expected=1.0,
            )


# --- the phugoid -----------------------------------------------------------------------------
def _cumulative(x: np.ndarray, dt: float) -> np.ndarray:
    """The running trapezoid integral of ``x`` from the first sample (0 there)."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * dt)])


def phugoid_frequency(record: Record) -> float | None:
    """The phugoid's natural frequency measured in a record, rad/s, or None when it shows none.

    The flight-path angle gamma = theta - alpha changes with the lift, which
    grows with speed: ``gamma_dot = d (V - V0) + e (alpha - alpha0) +
    f (de - de0)`` (the elevator term where the record has it).  Integrated
    from the first sample, this is one linear regression of ``gamma - gamma0``
    on the running integrals of the perturbations and on time (a constant
    rate: trim and sensor offsets).  With the along-path balance
    ``V_dot = -g gamma`` of a trimmed aircraft, the speed and flight-path
    angle form Lanchester's phugoid, ``omega^2 = g d`` (for a lift slope
    d = 2 g/U^2 this is the classic sqrt(2) g/U).

    Parameters
    ----------
    record : Record
        A record with ``V`` (m/s), ``theta`` and ``alpha`` (rad).

    Returns
    -------
    float or None
        The frequency omega, rad/s; None when the record lacks a channel, the regression
        explains less than 90 % of gamma's variation, the speed term adds less
        than half of what the others leave, or d is not positive.
    """
    if not all(record.has(k) for k in ("V", "theta", "alpha")):
        return None
    gamma = record["theta"] - record["alpha"]
    y = gamma - gamma[0]
    t = record.t - record.t[0]
    # the running integrals of the speed, alpha and elevator perturbations, the speed's first
    integrals = [_cumulative(record[k] - record[k][0], record.dt) for k in ("V", "alpha", "de") if record.has(k)]
    X = np.column_stack([*integrals, t])
    ss = float(y @ y)
    if ss == 0.0:
        return None
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    left = float(np.sum((y - X @ beta) ** 2))
    beta0, *_ = np.linalg.lstsq(X[:, 1:], y, rcond=None)
    left0 = float(np.sum((y - X[:, 1:] @ beta0) ** 2))
    if 1.0 - left / ss < _PHUGOID_MIN_FIT or left0 <= 0 or 1.0 - left / left0 < _PHUGOID_SPEED_SHARE:
        return None
    d = float(beta[0])
    return math.sqrt(G0 * d) if d > 0 else None


def _band_of(band, data) -> tuple[float, float, float] | None:
    """(lo, hi, step) rad/s of the band the check ran on, or None when there is none."""
    from .errors import FdmlError
    from .spectral import parse_band

    if data is not None:
        w = np.asarray(data.omega, float)
        return float(w.min()), float(w.max()), float(np.min(np.diff(w))) if w.size > 1 else 0.0
    try:
        return parse_band(band)
    except FdmlError:
        return None


def _up(x: float) -> float:
    """``x`` rounded up to two significant digits."""
    scale = 10.0 ** (math.floor(math.log10(x)) - 1)
    return math.ceil(x / scale - 1e-9) * scale


def _phugoid_findings(record: Record, band):
    """``phugoid.in_band`` when the record holds a full phugoid cycle whose frequency the band reaches."""
    w = phugoid_frequency(record)
    if w is None or band is None:
        return
    lo, hi, step = band
    period = 2.0 * math.pi / w
    if record.duration < period or lo >= PHUGOID_BAND_FACTOR * w:
        return  # less than one cycle (the boundary terms absorb a part-swing), or the band starts above it
    t0 = float(record.t[0])
    t1 = t0 + math.floor(0.5 * period)
    new_lo = _up(PHUGOID_BAND_FACTOR * w)
    yield Finding(
        "phugoid.in_band",
        f"the record holds {record.duration / period:.1f} cycles of the phugoid, at {w:.2g} rad/s "
        f"(period {period:.0f} s; gamma_dot on the speed change, Lanchester's omega^2 = g d), and the band "
        f"starts at {lo:g} rad/s: the short-period model has no phugoid, so it is model error there. Fit "
        f"a window of at most half a period, t = {t0:g}-{t1:g} s (--t0 {t0:g} --t1 {t1:g}), or start the band "
        f"at {PHUGOID_BAND_FACTOR:g} x {w:.2g} = {new_lo:g} rad/s (--band {new_lo:g}:{hi:g}:{step:g})",
        kind="estimation",
        record=record.name,
        value=w,
        expected=lo,
    )
