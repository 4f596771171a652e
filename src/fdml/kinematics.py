r"""What alpha, q and a_z say about their own sensors: the short-period identity.

Whatever the aerodynamics, the angle of attack, the pitch rate and the normal
acceleration measured at one station obey docs/theory.md Eq. 5,
``a_z = (U/g)(alpha_dot - q)``.  Its finite Fourier transform (Eq. 11, with
Klein's boundary terms of docs/theory.md section 7) is

    s alpha~(s) = q~(s) + (g/U) a_z~(s) + alpha(T) e^{-sT} - alpha(0)        (s = j omega)

and it holds at every frequency of every record, so it tests the *sensors*
without any aerodynamic model.  The sensor errors fdml's library knows enter it
as (measured from true, per output c):

* a channel recorded ``tau_c`` late: ``y~_c,m = exp(-s tau_c) y~_c``; only the
  lags *relative* to each other are seen (a common lag of all three is the
  elevator's delay, invisible here);
* an alpha vane ``d`` metres ahead of the accelerometer: it reads
  ``alpha - d q/U`` (Eq. 5 holds at any one station, so only the difference of
  the two sensors' positions is seen: a vane offset x and an accelerometer
  offset -x are one and the same to these three channels);
* scale factors: only their ratios are seen; the two ratios
  ``kappa_alpha = K_q/K_alpha`` and ``kappa_az = K_q/K_az`` are estimated as
  nuisance parameters with every hypothesis (a wrong airspeed U goes to
  ``kappa_az`` too), and reported.

Undoing a hypothesis's sensor terms on the measured spectra, the identity's
residual is

    e(s) = kappa_alpha s alpha~_acc(s) - q~(s) - kappa_az (g/U) a_z~(s) - b0 - b1 e^{-sT} - b2 1~(s)

with ``alpha~_acc = exp(s tau_alpha) alpha~_m + (d/U) q~`` the angle of attack at
the accelerometer's station, ``b0, b1`` the boundary terms and ``b2`` the
transform of a constant (biases of q and a_z), all real and per record.  The
cost is the complex-Gaussian ``-2 ln L = 2 sum |e|^2 / v(omega)`` counted on
independent frequencies (a grid ``K`` times finer than ``2 pi/T`` counts each
one ``K`` times; :mod:`fdml.adequacy` does the same), with the equation error's
variance ``v = a + b omega^2`` (white sensor noise on alpha enters times omega;
``a, b >= 0`` by maximum likelihood) estimated from the residuals of the best
single pattern when that is significant, of no pattern otherwise, and then held,
so that cost differences are likelihood ratios.  A lag moves the record's ends
too; their measured values enter as known (:func:`_corrected`), so that a lag's
likelihood ratio has its chi-bar-square law at zero lag.

:func:`kinematic_evidence` tries every *sensor pattern* of the library -- each
timing group of :data:`fdml.models.effect_library.TIMING_GROUPS` and the vane
offset -- one at a time, each with its size free.  A pattern is *settled* when
its likelihood ratio against no pattern is significant at :data:`LEVEL` and no
other pattern explains the identity equally (:func:`fdml.score.equally`);
settled patterns enter the model as known, and a second round looks for a
second pattern on top.  A significant pattern that another explains equally is
reported as an alias set.  :meth:`KinematicEvidence.check` tells whether any
candidate's sensor terms contradict the identity.

:mod:`fdml.flightpath` is the full, time-domain compatibility check (with
theta, V, h and a_x: absolute angles, biases, the q scale against theta); the
identity here is its short-period, frequency-domain part, fast enough for
every fit, on the spectra the fit already has.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .channels import OUTPUTS, boundary_channels
from .constants import G0
from .errors import FdmlError
from .fourier import step_edges
from .jsoncodec import Fields
from .models.effects import applied_effects, get_effect
from .score import equally
from .tails import chi2_sf

__all__ = [
    "LEVEL",
    "MAX_SHIFT",
    "resolution",
    "flight_path_findings",
    "FLIGHT_PATH_CHANNELS",
    "input_resolution",
    "unresolved_edges",
    "SensorTerms",
    "Pattern",
    "KinematicFinding",
    "SensorEffect",
    "KinematicEvidence",
    "kinematic_evidence",
    "sensor_terms",
    "known_terms",
    "members",
]

#: Level at which the identity settles a sensor pattern or contradicts a candidate: 1e-3, about
#: the three standard errors at which :mod:`fdml.flightpath` calls a sensor parameter significant.
LEVEL = 1e-3
#: Largest relative time shift searched, s (the flight-path check's default).
MAX_SHIFT = 0.25
#: Largest vane offset searched, m (|x| > 50 m lies outside any airframe).
MAX_OFFSET = 50.0
#: Largest scale-factor error searched (measured / true - 1).
MAX_SCALE = 0.5
#: A record resolves time to a fraction of its sample interval: timing errors below a quarter of it
#: (and vane offsets x whose x/U is below it) are interpolation-level, whatever their significance.
TIME_RESOLUTION = 0.25
#: Scale-factor errors below this are at the level to which sensors are calibrated.
SCALE_RESOLUTION = 0.005


def unresolved_edges(u: np.ndarray) -> int:
    """How many edges of a sampled input happen within one sample interval (a step between samples).

    Such an edge's time is known only to +-dt/2: a fit that interpolates the record puts it mid-way,
    and an elevator delay of up to half a sample then stands for where the steps really were
    (:func:`fdml.fourier.step_edges`).

    Parameters
    ----------
    u : numpy.ndarray
        The input's samples.

    Returns
    -------
    int
        The number of unresolved edges.
    """
    return int(step_edges(u).size)


def input_resolution(records, dt: float) -> float:
    """The input timing these records resolve, s.

    Half a sample when any elevator steps between two samples (:func:`unresolved_edges`), else a
    quarter (:func:`resolution`).

    Parameters
    ----------
    records : sequence of Record or None
        The time-domain records (None entries are skipped).
    dt : float
        Sample interval, s.

    Returns
    -------
    float
        The floor of an input delay or lag, s.
    """
    stepped = any(r is not None and r.has("de") and unresolved_edges(r["de"]) for r in records)
    return (0.5 if stepped else TIME_RESOLUTION) * dt


#: Channels the full, time-domain flight-path reconstruction (:mod:`fdml.flightpath`) uses beyond
#: alpha, q and a_z.
FLIGHT_PATH_CHANNELS = ("theta", "V", "h", "ax")


def flight_path_findings(records) -> list:
    """The time-domain flight-path reconstruction's significant sensor findings, per record.

    Run on every record that has theta (and the trim kept, a_z near -1 g): what it determines beyond
    the short-period identity (the q scale against theta, the absolute alpha bias from h, ...).
    It models no vane offset: a vane x ahead of the accelerometer reads there as an alpha lag of
    about x/U.

    Parameters
    ----------
    records : sequence of Record
        The records.

    Returns
    -------
    list of dict
        Per record: ``record``, ``missing`` (channels of :data:`FLIGHT_PATH_CHANNELS` it lacks),
        and either ``significant`` (``name``, ``value``, ``stderr``, ``unit``, ``description`` of
        each parameter :data:`fdml.flightpath.SIGNIFICANT` standard errors from nominal) or
        ``note`` (why it was not run).
    """
    from .flightpath import SIGNIFICANT, check_compatibility

    out = []
    for r in records:
        entry: dict = {"record": r.name, "missing": [c for c in FLIGHT_PATH_CHANNELS if not r.has(c)]}
        if not r.has("theta"):
            entry["note"] = "no theta: the short-period identity alone"
        else:
            try:
                c = check_compatibility(r)
                entry["significant"] = [
                    {"name": k, "value": p.value, "stderr": p.stderr, "unit": p.unit, "description": p.description}
                    for k, p in c.params.items()
                    if p.stderr > 0 and abs(p.value - p.nominal) > SIGNIFICANT * p.stderr
                ]
            except (FdmlError, np.linalg.LinAlgError, ValueError) as exc:  # reported, never fatal
                entry["note"] = f"not run: {exc}"
        out.append(entry)
    return out


def resolution(unit: str, dt: float, U: float) -> float | None:
    """The smallest sensor-error size these data resolve, by the parameter's unit (None: no floor).

    A time (s): a quarter of the sample interval; a lever arm (m): the offset whose x/U is that
    time; a scale error: :data:`SCALE_RESOLUTION`.

    Parameters
    ----------
    unit : str
        The parameter's unit: ``s``, ``m`` or ``-``.
    dt : float
        Sample interval, s.
    U : float
        Airspeed, m/s.

    Returns
    -------
    float or None
        The floor, in ``unit``.
    """
    return {"s": TIME_RESOLUTION * dt, "m": TIME_RESOLUTION * dt * U, "-": SCALE_RESOLUTION}.get(unit)


#: The identity is read from MIN_CYCLES cycles over the record up (omega >= MIN_CYCLES 2 pi/T): below,
#: a frequency is not resolved by the record, its transform is leakage of the record's ends and drift,
#: and the identity's linearisation about trim (the flight-path angle and airspeed terms it drops) is
#: weakest there.
MIN_CYCLES = 1.0


@dataclass(frozen=True)
class SensorTerms:
    """The sensor errors of one hypothesis, as the three outputs see them.

    Parameters
    ----------
    lags : tuple of float
        Time each output (alpha, q, a_z) is recorded late, s.
    offset : float
        The alpha vane's distance ahead of the accelerometer, m (vane offset minus
        accelerometer offset).
    scales : tuple of float
        Scale factor of each output (measured / true), dimensionless.
    """

    lags: tuple = (0.0, 0.0, 0.0)
    offset: float = 0.0
    scales: tuple = (1.0, 1.0, 1.0)

    def __add__(self, other: SensorTerms) -> SensorTerms:
        return SensorTerms(
            tuple(a + b for a, b in zip(self.lags, other.lags)),
            self.offset + other.offset,
            tuple(a * b for a, b in zip(self.scales, other.scales)),
        )

    @property
    def empty(self) -> bool:
        """True when the terms are invisible to the identity (no relative lag, no offset)."""
        rel = np.ptp(np.asarray(self.lags, float))
        return rel == 0.0 and self.offset == 0.0 and all(k == self.scales[0] for k in self.scales)


def sensor_terms(effect, values: dict) -> SensorTerms | None:
    """The sensor terms of a library effect at ``values`` (None: not a sensor effect).

    The elevator's delay and the actuator's lag act on every output alike, so their terms are empty;
    aerodynamic effects and a structural mode are not sensor errors (None).

    Parameters
    ----------
    effect : Effect
        A library effect (``time_delay``, ``sensor_offset``, ``sensor_scale``, ...).
    values : dict
        Its parameter values, by name, in their units.

    Returns
    -------
    SensorTerms or None
        The terms.
    """
    name, chans = effect.name, effect.channel.split(",")
    if name in ("time_delay", "actuator_lag") and chans == ["de"]:
        return SensorTerms()
    if name == "time_delay" and all(c in OUTPUTS for c in chans):
        tau = float(values["tau_" + "_".join(chans)])
        return SensorTerms(lags=tuple(tau if c in chans else 0.0 for c in OUTPUTS))
    if name == "sensor_offset" and chans == ["alpha"]:
        return SensorTerms(offset=float(values["x_alpha"]))
    if name == "sensor_offset" and chans == ["az"]:
        return SensorTerms(offset=-float(values["x_az"]))
    if name == "sensor_scale" and chans[0] in OUTPUTS:
        k = 1.0 + float(values["k_" + chans[0]])
        return SensorTerms(scales=tuple(k if c == chans[0] else 1.0 for c in OUTPUTS))
    return None


def known_terms(model) -> SensorTerms:
    """The sensor terms of the effects a model holds fixed (known sensor positions, settled effects).

    Parameters
    ----------
    model : Model
        The model.

    Returns
    -------
    SensorTerms
        Their sum (empty when there are none).
    """
    vals = model.parameters.values
    out = SensorTerms()
    for e in applied_effects(model):
        names = [p.name for p in e.param_list(model)]
        if names and all(not model.parameters[n].free for n in names):
            t = sensor_terms(e, {n: vals[n] for n in names})
            if t is not None:
                out = out + t
    return out


@dataclass(frozen=True)
class Pattern:
    """A one-parameter sensor hypothesis the identity can test: which effects it stands for and its terms.

    Parameters
    ----------
    keys : tuple of str
        The library effects it stands for (two for a vane offset: the alpha vane x or the
        accelerometer -x, one and the same to the identity).
    param : str
        The size's name (the first effect's parameter).
    unit : str
        Its unit.
    bounds : tuple of float
        Searched range of the size.
    lags : tuple of float
        Lag of each output (alpha, q, a_z) per unit size.
    offset : float
        Vane offset per unit size.
    scale : int or None
        The output (0 alpha, 1 q, 2 a_z) whose scale factor is 1 + size, for a scale pattern.
    """

    keys: tuple
    param: str
    unit: str
    bounds: tuple
    lags: tuple = (0.0, 0.0, 0.0)
    offset: float = 0.0
    scale: int | None = None  # the output whose scale factor is 1 + size

    def terms(self, size: float) -> SensorTerms:
        """The sensor terms at ``size`` (in :attr:`unit`).

        Parameters
        ----------
        size : float
            The pattern's size.

        Returns
        -------
        SensorTerms
            Its terms.
        """
        scales = tuple(1.0 + size if i == self.scale else 1.0 for i in range(3))
        return SensorTerms(tuple(size * x for x in self.lags), size * self.offset, scales)

    def batch(self, base: SensorTerms, sizes: np.ndarray) -> tuple:
        """``base`` plus the pattern at each of ``sizes``, as the arrays of :func:`_batch`.

        Parameters
        ----------
        base : SensorTerms
            The terms the pattern is added to.
        sizes : array_like
            Sizes of the pattern, in :attr:`unit`.

        Returns
        -------
        tuple of numpy.ndarray
            Lags (G, 3), offsets (G,) and scales (G, 3).
        """
        sizes = np.asarray(sizes, float)[:, None]
        lags = np.asarray(base.lags, float) + sizes * np.asarray(self.lags, float)
        off = base.offset + sizes[:, 0] * self.offset
        sc = np.tile(np.asarray(base.scales, float), (sizes.shape[0], 1))
        if self.scale is not None:
            sc[:, self.scale] *= 1.0 + sizes[:, 0]
        return lags, off, sc

    def values(self, size: float) -> dict:
        """``{key: {param: value}}`` of every effect the pattern stands for, at ``size``.

        Parameters
        ----------
        size : float
            The pattern's size.

        Returns
        -------
        dict
            Per effect key, its parameter values.
        """
        if self.offset:
            return {"sensor_offset@alpha": {"x_alpha": size}, "sensor_offset@az": {"x_az": -size}}
        return {self.keys[0]: {self.param: size}}


def patterns() -> tuple:
    """The library's sensor patterns: every timing group (a lag, >= 0), the vane offset and each scale factor.

    Returns
    -------
    tuple of Pattern
        The patterns, timing first.
    """
    from .models.effect_library import TIMING_GROUPS

    out = [
        Pattern(
            ("time_delay@" + ",".join(g),),
            "tau_" + "_".join(g),
            "s",
            (0.0, MAX_SHIFT),
            lags=tuple(1.0 if c in g else 0.0 for c in OUTPUTS),
        )
        for g in TIMING_GROUPS
    ]
    out.append(
        Pattern(("sensor_offset@alpha", "sensor_offset@az"), "x_alpha", "m", (-MAX_OFFSET, MAX_OFFSET), offset=1.0)
    )
    out += [
        Pattern((f"sensor_scale@{c}",), f"k_{c}", "-", (-MAX_SCALE, MAX_SCALE), scale=i) for i, c in enumerate(OUTPUTS)
    ]
    return tuple(out)


# --- the identity's cost ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Record:
    """One record's spectra as the identity reads them."""

    T: float  # record length, s
    s: np.ndarray  # j omega
    A: np.ndarray
    Q: np.ndarray
    Z: np.ndarray
    # (m, 3 + K) nuisance regressors: 1, exp(-sT), transform of a constant, and exp(-s t_k) of each elevator
    # step between samples (a_z jumps with the elevator; its transform puts the jump mid-interval: theory 7a)
    N: np.ndarray
    # (3, 2) measured x(0), x(T) of alpha (rad), q (rad/s), a_z (g) after trim: the ends a lag moves
    ends: np.ndarray
    K: float  # grid points per independent frequency


def _records(spectra) -> list:
    out = []
    for d in spectra:
        keep = np.asarray(d.omega, float) >= MIN_CYCLES * 2 * math.pi / d.T
        om = np.asarray(d.omega, float)[keep]
        s = 1j * om
        step = float(np.median(np.diff(om))) if om.size > 1 else 2 * math.pi / d.T
        K = max(1.0, 2 * math.pi / (d.T * step))
        steps = np.exp(-np.outer(s, np.asarray(getattr(d, "edges", ()), float)))
        N = np.column_stack([np.ones_like(s), np.exp(-s * d.T), np.asarray(d.ones)[keep], steps])
        z = np.asarray(d.z)[keep]
        A, Q, Z = (z[:, list(d.outputs).index(c)] for c in OUTPUTS)  # by name: theta or q_dot may be beside
        out.append(_Record(float(d.T), s, A, Q, Z, N, _ends(d), K))
    return out


def _ends(d) -> np.ndarray:
    """(3, 2): each output's first and last value after trim, from the spectra's boundary values (alpha,
    q) and their record (a_z; zeros without one: a_z's lag then moves its ends by ``tau x`` in the
    boundary nuisance's span, and only the second-order ``s tau^2`` part is left unmodelled)."""
    out = np.zeros((3, 2))
    rows = boundary_channels(d.outputs)
    for j, c in enumerate(OUTPUTS):
        if c in rows:
            out[j] = d.x0[rows.index(c)], d.xT[rows.index(c)]
        elif d.record is not None and c in d.record.signals:
            x, ell = np.asarray(d.record[c], float), d.trim_vector()  # the trim as the spectra removed it
            trim = 0.0 if ell is None else float(ell @ x)
            out[j] = x[0] - trim, x[-1] - trim
    return out


def _corrected(r: _Record, c: float, lags: np.ndarray, offset: np.ndarray, scales: np.ndarray):
    """The spectra with sensor terms undone, for a batch of G hypotheses: alpha at the accelerometer's
    station, q, a_z, each of shape (G, m).  ``lags``, ``scales``: (G, 3); ``offset``: (G,), m.

    A channel recorded tau late, x_m(t) = x(t - tau), has over the record ``x~ = exp(s tau) x~_m -
    (exp(s tau) - 1)/s (x(0) - x(T) exp(-sT))`` to first order over the tau-long end pieces, with the
    measured ends (:attr:`_Record.ends`) for x(0) and x(T): known values, not free coefficients, which
    near tau = 0 would fit two directions of noise per lagged channel.
    """
    # exp(s tau) of each output's lag, shape (G, m), or None where no hypothesis lags it
    shifts = [np.exp(r.s[None, :] * lags[:, j : j + 1]) if np.any(lags[:, j]) else None for j in range(3)]
    eT = np.exp(-r.s * r.T)

    def undo(x, j):  # the lag (with its record ends) and the scale of output j undone
        e = shifts[j]
        if e is None:
            return x[None, :] / scales[:, j : j + 1]
        x0, xT = r.ends[j]
        return (e * x - (e - 1.0) / r.s * (x0 - xT * eT)) / scales[:, j : j + 1]

    Q = undo(r.Q, 1)
    A = undo(r.A, 0) + (offset[:, None] * c / G0) * Q  # d/U = d c/g
    return A, Q, undo(r.Z, 2)


def _batch(terms) -> tuple:
    """(lags (G, 3), offsets (G,), scales (G, 3)) of a sequence of SensorTerms."""
    return tuple(np.array([getattr(t, k) for t in terms], float) for k in ("lags", "offset", "scales"))


@dataclass(frozen=True)
class _Identity:
    """The identity on a set of records: cost of any sensor terms, with the equation-error variance held.

    Per record, ``weights`` are 1/sqrt(v(omega)) and ``basis`` an orthonormal basis of the weighted,
    real-stacked nuisance regressors, so that the residual after the best nuisance is a projection.
    """

    recs: tuple
    c: float  # g/U, 1/s per g
    weights: tuple
    basis: tuple

    def errors(self, terms) -> list:
        """Per record, the weighted residuals (G, 2m) of a batch of hypotheses after the nuisance.

        ``terms``: a sequence of SensorTerms, or the arrays of :func:`_batch`.
        """
        lags, off, sc = terms if isinstance(terms, tuple) else _batch(terms)
        out = []
        for r, w, B in zip(self.recs, self.weights, self.basis):
            A, Q, Z = _corrected(r, self.c, lags, off, sc)
            y = r.s * A - Q - self.c * Z
            ww = np.concatenate([w, w])
            yr = np.concatenate([y.real, y.imag], axis=1) * ww
            out.append(yr - (yr @ B) @ B.T)
        return out

    def costs(self, terms) -> np.ndarray:
        """-2 ln L on independent frequencies (module doc) of each hypothesis, shape (G,)."""
        return sum(2.0 * np.sum(e**2, axis=1) / r.K for r, e in zip(self.recs, self.errors(terms)))

    def terms_cost(self, t: SensorTerms) -> float:
        """The cost of one hypothesis."""
        return float(self.costs([t])[0])

    def scales(self, t: SensorTerms) -> dict:
        """kappa_alpha and kappa_az (K_q/K_alpha, K_q/K_az) with standard errors, all records pooled:
        ``q~ = kappa_alpha s alpha~_acc - kappa_az (g/U) a_z~ - b.N`` by weighted least squares."""
        lags, off, sc = _batch([t])
        xtx, xty = np.zeros((2, 2)), np.zeros(2)
        for r, w in zip(self.recs, self.weights):
            A, Q, Z = (x[0] for x in _corrected(r, self.c, lags, off, sc))
            X = np.column_stack([r.s * A, -self.c * Z, -r.N])
            ww = np.concatenate([w, w])
            Xr = np.vstack([X.real, X.imag]) * ww[:, None]
            yr = np.concatenate([Q.real, Q.imag]) * ww
            Qb, _ = np.linalg.qr(Xr[:, 2:])
            Xp = Xr[:, :2] - Qb @ (Qb.T @ Xr[:, :2])  # the nuisance projected out
            xtx += 2.0 * (Xp.T @ Xp) / r.K
            xty += 2.0 * (Xp.T @ yr) / r.K
        est = np.linalg.solve(xtx, xty)
        se = np.sqrt(np.clip(np.diag(np.linalg.pinv(xtx)), 0, None))
        return {"kappa_alpha": (float(est[0]), float(se[0])), "kappa_az": (float(est[1]), float(se[1]))}


def _identity(spectra, U: float, t: SensorTerms) -> _Identity:
    """The identity with its equation-error variance v = a + b omega^2 estimated at the terms ``t``."""
    recs = tuple(_records(spectra))
    c = G0 / float(U)
    flat = _Identity(recs, c, tuple(np.ones(r.s.size) for r in recs), tuple(_basis(r, np.ones(r.s.size)) for r in recs))
    ws = []
    for r, e in zip(recs, flat.errors([t])):
        m = r.s.size
        v = _variance(np.abs(r.s) ** 2, e[0, :m] ** 2 + e[0, m:] ** 2)
        ws.append(1.0 / np.sqrt(v))
    return _Identity(recs, c, tuple(ws), tuple(_basis(r, w) for r, w in zip(recs, ws)))


def _variance(w2: np.ndarray, p: np.ndarray, passes: int = 8) -> np.ndarray:
    """v = a + b omega^2 (a, b >= 0) from the residual powers ``p`` at ``w2`` = omega^2: maximum likelihood.

    ``p`` is exponentially distributed about v, so the fit is least squares weighted by 1/v^2, repeated
    (Fisher scoring), each pass with a and b kept non-negative (:func:`_nonnegative_fit`).  A plain
    least-squares fit often puts a below zero when the white part is small; cut to zero, it left v near
    zero at the lowest frequencies, whose weight then inflated every likelihood ratio that reads them.
    """
    X = np.column_stack([np.ones_like(w2), w2])
    floor = 1e-3 * max(float(np.median(p)), 1e-300)
    v = np.full_like(p, max(float(np.mean(p)), floor))
    for _ in range(passes):
        ab = _nonnegative_fit(X / v[:, None], p / v)
        v = np.maximum(X @ ab, floor)
    return v


def _nonnegative_fit(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """argmin ||X c - y|| over c >= 0 for two columns: the free fit, else the better one-column fit."""
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    if np.all(c >= 0):
        return c
    best, cost = np.zeros(2), float(y @ y)
    for k in range(2):
        ck = max(float(X[:, k] @ y) / max(float(X[:, k] @ X[:, k]), 1e-300), 0.0)
        r = y - ck * X[:, k]
        if r @ r < cost:
            best, cost = np.eye(2)[k] * ck, float(r @ r)
    return best


def _basis(r: _Record, w: np.ndarray) -> np.ndarray:
    ww = np.concatenate([w, w])
    Nr = np.vstack([r.N.real, r.N.imag]) * ww[:, None]
    q, _ = np.linalg.qr(Nr)
    return q


def _profile(idn: _Identity, base: SensorTerms, pat: Pattern, refine: int = 2) -> tuple[float, float, float]:
    """(size, cost, standard error) of ``pat`` on top of ``base``."""
    return _profiles(idn, base, [pat], refine)[0]


def _profiles(idn: _Identity, base: SensorTerms, pats: Sequence[Pattern], refine: int = 2) -> list:
    """:func:`_profile` of every pattern, their hypotheses costed together: one :meth:`_Identity.costs`
    call per round of requests (each profile's next step depends on its last costs only)."""
    steps = [(_lag_steps(base, p, refine, idn) if any(p.lags) else _linear_steps(base, p)) for p in pats]
    out: list = [None] * len(steps)
    asked = {i: next(st) for i, st in enumerate(steps)}
    while asked:
        batches = list(asked.values())
        costs = idn.costs(tuple(np.concatenate([b[k] for b in batches]) for k in range(3)))
        parts = np.split(costs, np.cumsum([len(b[1]) for b in batches])[:-1])
        waiting, asked = asked, {}
        for i, c in zip(waiting, parts):
            try:
                asked[i] = steps[i].send(c)
            except StopIteration as done:
                out[i] = done.value
    return out


def _linear_steps(base: SensorTerms, pat: Pattern):
    """The profile of an offset or a scale pattern, exactly: the identity's residual is affine in the
    offset, and in u = 1/(1 + size) for a scale (the output is divided by its scale factor; the
    record's ends move only with the lags), so the cost is a quadratic a u^2 + b u + c with a >= 0, known
    from three points.  A generator: it yields the hypotheses it needs costed (:func:`_profiles`)."""
    lo, hi = pat.bounds
    to_u = (lambda k: k) if pat.scale is None else (lambda k: 1.0 / (1.0 + k))
    u3 = np.array([to_u(lo), to_u(0.5 * (lo + hi)), to_u(hi)])
    a, b, c = np.polyfit(u3, (yield pat.batch(base, np.array([lo, 0.5 * (lo + hi), hi]))), 2)
    ulo, uhi = sorted((u3[0], u3[2]))
    u = float(np.clip(-b / (2 * a), ulo, uhi)) if a > 0 else min((ulo, uhi), key=lambda v: a * v**2 + b * v)
    x = u if pat.scale is None else 1.0 / u - 1.0
    # cost'' in the size: d2/dk2 of a u^2 + b u with du/dk = -u^2, d2u/dk2 = 2 u^3 for a scale
    curv = 2 * a if pat.scale is None else (2 * a * u + b) * 2 * u**3 + 2 * a * u**4
    (cost,) = yield pat.batch(base, np.array([x]))
    return float(x), float(cost), _stderr(curv)


def _lag_steps(base: SensorTerms, pat: Pattern, refine: int, idn: _Identity):
    """The profile of a lag: a grid fine enough for the records' highest frequency (the cost's shortest
    period in the lag is 2 pi / omega_max; eight points to it), ``refine`` grids four times finer
    around the best point, and the vertex of the parabola through the best point and its neighbours.
    A generator: it yields the hypotheses it needs costed (:func:`_profiles`)."""
    lo, hi = pat.bounds
    w_max = max(float(np.max(np.abs(r.s))) for r in idn.recs) * max(np.abs(pat.lags))
    grid = np.linspace(lo, hi, int(np.clip(math.ceil(8 * (hi - lo) * w_max / (2 * math.pi)) + 1, 11, 51)))
    for level in range(1 + refine):
        costs = yield pat.batch(base, grid)
        i = int(np.argmin(costs))
        if level < refine:
            grid = np.linspace(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)], 9)
    x = float(grid[i])
    if 0 < i < grid.size - 1:
        cm, c0, cp = costs[i - 1 : i + 2]
        if cp - 2 * c0 + cm > 0:
            half = 0.5 * (grid[1] - grid[0])
            x = float(np.clip(x - half * (cp - cm) / (cp - 2 * c0 + cm), grid[i - 1], grid[i + 1]))
    h = 1e-4 * (hi - lo)  # the cost is defined past the bounds (a lead): its curvature at x, at a bound too
    cm, c0, cp = yield pat.batch(base, np.array([x - h, x, x + h]))
    return x, float(c0), _stderr((cp - 2 * c0 + cm) / h**2)


def _stderr(curv: float) -> float:
    """The standard error of a size from the cost's curvature in it (cost = -2 ln L: var = 2 / cost'')."""
    return math.sqrt(2.0 / curv) if curv > 0 else math.inf


# --- the evidence --------------------------------------------------------------------------------


@dataclass(frozen=True)
class KinematicFinding:
    """One sensor pattern tested on the identity.

    Parameters
    ----------
    keys : tuple of str
        The library effects it stands for (``time_delay@alpha``; a vane offset stands for
        ``sensor_offset@alpha`` and ``sensor_offset@az``).
    param : str
        The size's name.
    value, stderr : float
        The size and its standard error, in ``unit``.
    unit : str
        ``s`` or ``m``.
    lr : float
        Likelihood ratio against the identity without it (with the settled patterns before it).
    p : float
        Its p-value (chi-bar-square for a lag whose null is on its bound, chi2(1) for an offset).
    round : int
        0 for the first search, 1 for a second pattern on top of a settled one.
    """

    keys: tuple
    param: str
    value: float
    stderr: float
    unit: str
    lr: float
    p: float
    round: int = 0

    @property
    def key(self) -> str:
        """The first effect key."""
        return self.keys[0]

    def describe(self) -> str:
        """One line: the pattern in words, its size and its likelihood ratio.

        Returns
        -------
        str
            The line.
        """
        if self.unit == "s":
            desc = get_effect(self.key).params[0].description or self.key
            size = f"{self.value * 1e3:.3g} +- {self.stderr * 1e3:.2g} ms"
            return f"{desc.replace('this long', size)} (LR {self.lr:.3g}, p {self.p:.2g})"
        if self.unit == "-":
            ch = self.param[2:].replace("az", "a_z")
            return (
                f"{ch} reads {1 + self.value:.4g} +- {self.stderr:.2g} times its true value, relative to the "
                f"other two (LR {self.lr:.3g}, p {self.p:.2g})"
            )
        return (
            f"the alpha vane {self.value:+.3g} +- {self.stderr:.2g} m ahead of the accelerometer "
            f"(a vane offset x_alpha = {self.value:+.3g} m or an accelerometer offset x_az = {-self.value:+.3g} m, "
            f"one and the same to alpha, q and a_z; LR {self.lr:.3g}, p {self.p:.2g})"
        )


@dataclass(frozen=True)
class SensorEffect:
    """A library effect the identity points to: the effect, its parameter's value and standard error.

    Parameters
    ----------
    key : str
        The effect's key (``sensor_offset@alpha``).
    param : str
        Its parameter.
    value, stderr : float
        The kinematic estimate and its standard error, in ``unit``.
    unit : str
        The parameter's unit.
    finding : KinematicFinding
        The pattern it came from.
    plausible : bool
        Whether the value lies in the parameter's plausible range.
    resolved : bool
        Whether the value is above the data's resolution (:func:`resolution`).
    """

    key: str
    param: str
    value: float
    stderr: float
    unit: str
    finding: KinematicFinding
    plausible: bool = True
    resolved: bool = True

    def effect(self):
        """The library effect.

        Returns
        -------
        Effect
            It.
        """
        return get_effect(self.key)

    def terms(self) -> SensorTerms:
        """Its sensor terms.

        Returns
        -------
        SensorTerms
            The terms at :attr:`value`.
        """
        t = sensor_terms(self.effect(), {self.param: self.value})
        assert t is not None  # every pattern stands for sensor effects
        return t

    def describe(self) -> str:
        """``sensor_offset@alpha x_alpha = 13.1 +- 0.3 m``.

        Returns
        -------
        str
            The line.
        """
        if self.unit == "s":
            return f"{self.key} {self.param} = {self.value * 1e3:.3g} +- {self.stderr * 1e3:.2g} ms"
        return f"{self.key} {self.param} = {self.value:.4g} +- {self.stderr:.2g} {self.unit}".rstrip()


def members(found: KinematicFinding, dt: float = 0.0, U: float = 0.0) -> list:
    """The library effects a finding stands for, each with its value, plausibility and resolution.

    Parameters
    ----------
    found : KinematicFinding
        A tested pattern.
    dt : float, optional
        Sample interval, s (0: no resolution floor).
    U : float, optional
        Airspeed, m/s.

    Returns
    -------
    list of SensorEffect
        One per library effect (two for a vane offset: the vane x and the accelerometer -x).
    """
    floor = resolution(found.unit, dt, U)
    out = []
    for key, vals in _pattern_of(found).values(found.value).items():
        ((name, v),) = vals.items()
        par = next(p for p in get_effect(key).params if p.name == name)
        ok = par.plausible is None or par.plausible[0] <= v <= par.plausible[1]
        res = floor is None or abs(v) >= floor
        out.append(SensorEffect(key, name, float(v), found.stderr, found.unit, found, bool(ok), bool(res)))
    return out


@dataclass(frozen=True)
class KinematicEvidence:
    """What the short-period identity says about the sensors of a set of records.

    Parameters
    ----------
    records : tuple of str
        The records' names.
    airspeed : float
        U, m/s, in g/U.
    tested : tuple of KinematicFinding
        Every pattern of the first search, largest LR first.
    settled : tuple of SensorEffect
        Sensor effects the identity determines: a pattern significant at :data:`LEVEL` that no other
        pattern explains equally, standing for one library effect with a plausible value (known
        sensor positions and plausible ranges separate a vane offset from an accelerometer offset).
    aliases : tuple of tuple of SensorEffect
        Significant patterns that others explain equally: each alias set's plausible members, best first.
    scales : dict
        ``kappa_alpha`` and ``kappa_az`` (K_q/K_alpha, K_q/K_az): ``(value, stderr)`` after the
        settled patterns.
    implausible : tuple of SensorEffect
        Members of a significant pattern's alias set whose values lie outside their plausible ranges.
    unresolved : tuple of SensorEffect
        Members significant but below the data's resolution (:func:`resolution`): set aside.
    known : SensorTerms
        Sensor terms known beforehand (sensor positions from the aircraft file), applied first.
    level : float
        The level of the tests.
    source : str
        What was used, in words.
    _identity : object, optional
        The identity on the records' spectra, for :meth:`check` (not written to JSON).
    """

    records: tuple
    airspeed: float
    tested: tuple
    settled: tuple
    aliases: tuple
    scales: dict
    implausible: tuple = ()
    unresolved: tuple = ()
    known: SensorTerms = SensorTerms()
    level: float = LEVEL
    source: str = "short-period identity (alpha, q and a_z; docs/theory.md Eq. 5)"
    _identity: _Identity | None = field(default=None, repr=False, compare=False)

    def settled_terms(self) -> SensorTerms:
        """The sensor terms of every settled pattern together.

        Returns
        -------
        SensorTerms
            Their sum.
        """
        return sum((m.terms() for m in self.settled), self.known)

    def check(self, terms: SensorTerms | None) -> tuple[float, float]:
        """Does a candidate's sensor part contradict the identity?  (LR, p) of undoing it.

        ``LR = cost(settled + terms) - cost(settled)``: how much worse the identity fits once the
        candidate's terms are undone than without them (a candidate that moves the sensors the wrong
        way).  Compared with doing nothing rather than with the best pattern, so that a correct
        candidate that explains only part of several sensor errors is not taken for a wrong one.  None
        terms (not a sensor effect) and empty ones give (0, 1).

        Parameters
        ----------
        terms : SensorTerms or None
            The candidate's sensor terms (:func:`sensor_terms`).

        Returns
        -------
        lr : float
            The worsening, chi2(1) under "consistent".
        p : float
            Its p-value.
        """
        if terms is None or terms.empty or self._identity is None:
            return 0.0, 1.0
        base = self.settled_terms()
        lr = max(self._identity.terms_cost(base + terms) - self._identity.terms_cost(base), 0.0)
        return float(lr), chi2_sf(lr, 1)

    def to_dict(self) -> dict:
        """The evidence as plain JSON data.

        Returns
        -------
        dict
            ``source``, ``records``, ``airspeed``, ``level``, ``settled`` and ``implausible`` (effect dicts),
            ``aliases`` (lists of effect dicts), ``tested`` (finding dicts) and ``scales``.
        """

        def sized(x) -> dict:  # a finding's or an effect's size
            return {k: getattr(x, k) for k in ("param", "value", "stderr", "unit")}

        def eff(m: SensorEffect) -> dict:
            return {"key": m.key, **sized(m), "lr": m.finding.lr}

        return {
            "source": self.source,
            "records": list(self.records),
            "airspeed": self.airspeed,
            "level": self.level,
            "settled": [eff(m) for m in self.settled],
            "aliases": [[eff(m) for m in a] for a in self.aliases],
            "implausible": [eff(m) for m in self.implausible],
            "unresolved": [eff(m) for m in self.unresolved],
            "tested": [{"keys": list(f.keys), **sized(f), "lr": f.lr, "p_value": f.p} for f in self.tested],
            "scales": {k: {"value": v, "stderr": e} for k, (v, e) in self.scales.items()},
        }

    @classmethod
    def from_dict(cls, d, *, source: str = "kinematic evidence") -> KinematicEvidence:
        """Inverse of :meth:`to_dict`, every key checked.

        A missing or mistyped key raises a one-line FdmlError naming ``source``.  The spectra are
        not written, so :meth:`check` of a read-back evidence finds no contradiction.

        Parameters
        ----------
        d : dict
            As written by :meth:`to_dict`.
        source : str, optional
            What ``d`` came from, for the message.

        Returns
        -------
        KinematicEvidence
            The evidence, without its spectra.
        """
        f = Fields(d, source)

        def sized(x) -> tuple[str, float, float, str]:  # param, value, stderr, unit
            return x.string("param"), x.number("value"), x.number("stderr"), x.string("unit")

        def finding(x) -> KinematicFinding:
            keys = tuple(x.raw("keys")) if x.raw("keys", None) is not None else (x.string("key"),)
            return KinematicFinding(keys, *sized(x), x.number("lr"), x.number("p_value", default=math.nan))

        def effect(x) -> SensorEffect:
            return SensorEffect(x.string("key"), *sized(x), finding(x))

        scales = f.mapping("scales")
        return cls(
            records=tuple(str(r) for r in f.raw("records")),
            airspeed=f.number("airspeed"),
            tested=tuple(finding(x) for x in f.items("tested")),
            settled=tuple(effect(x) for x in f.items("settled")),
            aliases=tuple(tuple(effect(Fields(y, source)) for y in a) for a in f.raw("aliases")),
            scales={k: (float(v["value"]), float(v["stderr"])) for k, v in scales.items()},
            implausible=tuple(effect(x) for x in f.items("implausible", default=[])),
            unresolved=tuple(effect(x) for x in f.items("unresolved", default=[])),
            level=f.number("level"),
            source=f.string("source"),
        )

    def lines(self) -> list:
        """Text lines: the settled patterns, the alias sets and the scale ratios.

        Returns
        -------
        list of str
            The lines.
        """
        out = [f"kinematics ({self.source}):"]
        for m in self.settled:
            out.append(f"  settled: {m.describe()}: {m.finding.describe()}")
            if m.key == "sensor_scale@az":  # kappa_az (g/U) a_z: a wrong U is the same pattern (module doc)
                out.append(f"    or the airspeed is {self.airspeed * (1 + m.value):.4g} m/s, not {self.airspeed:.4g}")
        for a in self.aliases:
            out.append(f"  not separable by the kinematics: {' or '.join(m.describe() for m in a)}")
        for m in self.implausible:
            out.append(f"  set aside, outside its plausible range: {m.describe()}")
        for m in self.unresolved:
            out.append(f"  set aside, below the data's resolution: {m.describe()}")
        if not self.settled and not self.aliases:
            out.append(f"  no sensor pattern at level {self.level:g} (largest: {self.tested[0].describe()})")
        ka, kz = self.scales["kappa_alpha"], self.scales["kappa_az"]
        out.append(
            f"  scale ratios K_q/K_alpha = {ka[0]:.4g} +- {ka[1]:.2g}, K_q/K_az = {kz[0]:.4g} +- {kz[1]:.2g} "
            f"(with U = {self.airspeed:.4g} m/s)"
        )
        return out


def _pattern_of(f: KinematicFinding) -> Pattern:
    return next(p for p in patterns() if p.keys == f.keys)


def _p_value(pat: Pattern, lr: float) -> float:
    if pat.bounds[0] == 0.0:  # a lag from its bound: 0.5 chi2_0 + 0.5 chi2_1
        return 0.5 * chi2_sf(lr, 1) if lr > 0 else 1.0
    return chi2_sf(lr, 1)


def _search(idn: _Identity, base: SensorTerms, rnd: int, refine: int = 2) -> list:
    """Every pattern on top of ``base``: findings, largest LR first."""
    c0 = idn.terms_cost(base)
    found = []
    for pat, (x, c, se) in zip(patterns(), _profiles(idn, base, patterns(), refine)):
        lr = max(c0 - c, 0.0)
        found.append(KinematicFinding(pat.keys, pat.param, x, se, pat.unit, lr, _p_value(pat, lr), rnd))
    found.sort(key=lambda f: -f.lr)
    return found


def _alias_set(found: list) -> list:
    """The findings that explain the identity equally with the best (:func:`equally`)."""
    best = found[0]
    return [f for f in found if f is best or equally(best.lr, f.lr)]


def kinematic_evidence(
    spectra, U: float, *, known: SensorTerms | None = None, level: float = LEVEL, max_rounds: int = 2
) -> KinematicEvidence:
    """The short-period identity's verdict on the sensors of ``spectra`` (module doc).

    Parameters
    ----------
    spectra : sequence of fdml.spectral.FrequencyData
        The records' spectra (trim removed, any grid); every one must carry alpha, q and a_z.
    U : float
        Airspeed, m/s.
    known : SensorTerms, optional
        Sensor terms known beforehand (sensor positions from the aircraft file).
    level : float, optional
        Level at which a pattern is settled (default :data:`LEVEL`).
    max_rounds : int, optional
        Settled patterns sought one after another (default 2).

    Returns
    -------
    KinematicEvidence
        The settled patterns, the alias sets and the scale ratios.
    """
    spectra = list(spectra)
    known = known or SensorTerms()
    # the equation-error variance from the residuals of the best single pattern when it is significant:
    # estimated under no pattern it would hold the very misfit the patterns explain, and cap every LR;
    # estimated after a pattern fitted to noise, it would lack that pattern's share and inflate them
    idn = _identity(spectra, U, known)
    first = _search(idn, known, 0, refine=0)[0]
    if first.p < level:
        idn = _identity(spectra, U, known + _pattern_of(first).terms(first.value))
    base = known
    settled, aliases, tested, implausible, unresolved = [], [], [], [], []
    dt = max(float(d.dt) for d in spectra)
    for rnd in range(max_rounds):
        found = _search(idn, base, rnd)
        if rnd == 0:
            tested = list(found)
        if found[0].p >= level:
            break
        # only patterns significant on their own count: the best may be set aside (below the resolution)
        # while the rest of its alias set is not significant at all, and none of those is a finding
        members_ = [m for f in _alias_set(found) if f.p < level for m in members(f, dt, U)]
        implausible += [m for m in members_ if not m.plausible]
        unresolved += [m for m in members_ if m.plausible and not m.resolved]
        members_ = [m for m in members_ if m.plausible and m.resolved]
        if len(members_) != 1:
            if members_:
                aliases.append(tuple(members_))
            break
        settled.append(members_[0])
        base = base + members_[0].terms()
        idn = _identity(spectra, U, base)  # the equation-error variance at the settled terms
    return KinematicEvidence(
        records=tuple(d.name for d in spectra),
        airspeed=float(U),
        tested=tuple(tested),
        settled=tuple(settled),
        aliases=tuple(aliases),
        scales=idn.scales(base),
        implausible=tuple(implausible),
        unresolved=tuple(unresolved),
        known=known,
        level=level,
        _identity=idn,
    )
