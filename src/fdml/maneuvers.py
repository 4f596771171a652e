"""Elevator and gust input generators (pure functions, SI units).

Elevator inputs ``de`` are in rad (trailing edge down positive, docs/theory.md
section 1); gust inputs are the vertical gust angle ``alpha_w = w_g / U`` in
rad (positive for an up-gust, docs/theory.md section 8).  Every generator takes a
time vector ``t`` (s) and returns an array of the same shape.

* :func:`doublet` and :func:`three_two_one_one` are step sequences whose edges
  may be smoothed by a raised-cosine ramp of duration ``rise``: real elevators
  are rate limited, and smooth edges make Fourier cross-checks converge.
* :func:`multisine` is a sum of harmonics of the record length (flat or
  shaped amplitudes; Schroeder, random or minimum-crest-factor phases),
  scaled to a given peak; ``stride``/``offset`` give several inputs mutually
  orthogonal (interleaved) harmonics.
* :func:`sweep` is a linear or logarithmic frequency sweep.
* :func:`dryden_gust` samples the Dryden vertical-turbulence process exactly.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import numpy as np
from scipy import linalg, optimize, signal

from .constants import DEG
from .errors import ParameterError

__all__ = [
    "time_vector",
    "doublet",
    "three_two_one_one",
    "multisine",
    "multisine_frequencies",
    "min_crest_phases",
    "schroeder_phases",
    "crest_factor",
    "relative_peak_factor",
    "sweep",
    "dryden_gust",
    "dryden_psd",
    "make_input",
    "INPUT_KINDS",
    "DRYDEN_L",
]

#: Default elevator amplitude, rad (1 deg).
DEFAULT_AMPLITUDE = DEG
#: Dryden vertical scale length above 2000 ft, m (MIL-F-8785C: L_w = 1750 ft).
DRYDEN_L = 533.4
#: Relative time tolerance for an edge falling on a sample (float rounding of k*dt).
_EDGE_RTOL = 1e-9


# --- time ---------------------------------------------------------------------


def time_vector(duration: float, dt: float) -> np.ndarray:
    """Uniform time vector from 0 s.

    Parameters
    ----------
    duration : float
        Record length T, s (> 0).
    dt : float
        Sample interval, s (> 0).

    Returns
    -------
    ndarray, shape (n,)
        ``t = k dt`` for k = 0 .. n-1 with ``n = round(duration/dt) + 1``, s.
    """
    duration, dt = _positive(duration, "duration (s)"), _positive(dt, "dt (s)")
    n = int(round(duration / dt)) + 1
    if n < 2:
        raise ParameterError(f"duration {duration} s is shorter than one step dt = {dt} s")
    return np.arange(n) * dt


# --- step sequences ------------------------------------------------------------


def _smooth_step(t: np.ndarray, edge: float, rise: float) -> np.ndarray:
    """0 before ``edge``, 1 after, with a raised-cosine ramp of length ``rise`` centred on it.

    The ramp ``(1 - cos(pi (t - edge + rise/2) / rise)) / 2`` is C1 (zero slope at
    both ends), and centring it keeps the half-way crossing at the nominal edge
    (so every pulse width) and, being antisymmetric about it, keeps the integral
    of the input up to any time outside a ramp.  With ``rise = 0`` the step
    takes its new value at ``t >= edge`` (to within float rounding of k dt).
    """
    if rise <= 0.0:
        tol = _EDGE_RTOL * max(1.0, abs(edge))
        return (t >= edge - tol).astype(float)
    x = np.clip((t - edge + 0.5 * rise) / rise, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * x))


def _pulse_train(t, amplitude: float, start: float, widths, signs, rise: float) -> np.ndarray:
    """Sum of smoothed steps: consecutive pulses of ``widths`` (s) and ``signs``."""
    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(t)):
        raise ParameterError("t has non-finite values")
    amplitude = _finite(amplitude, "amplitude (rad)")
    start = _finite(start, "start (s)")
    rise = _finite(rise, "rise (s)")
    if rise < 0:
        raise ParameterError(f"rise time must be >= 0 s, got {rise}")
    if rise > min(widths) * (1.0 + 1e-12):
        raise ParameterError(
            f"rise time {rise} s exceeds the shortest pulse width {min(widths)} s; the edge ramps would overlap"
        )
    levels = np.concatenate([[0.0], np.asarray(signs, float), [0.0]])
    edges = start + np.concatenate([[0.0], np.cumsum(widths)])
    return amplitude * sum(jump * _smooth_step(t, edge, rise) for edge, jump in zip(edges, np.diff(levels)))


def doublet(
    t, amplitude: float = DEFAULT_AMPLITUDE, start: float = 1.0, width: float = 0.5, rise: float = 0.0
) -> np.ndarray:
    """Elevator doublet: +amplitude for ``width`` s, then -amplitude for ``width`` s.

    Parameters
    ----------
    t : array_like
        Time, s (any shape: the input is a pure function of t).
    amplitude : float, optional
        Pulse height, rad (default 1 deg); a negative value flips both pulses.
    start : float, optional
        Time of the first edge, s.
    width : float, optional
        Width of each pulse, s (at half amplitude when ``rise > 0``).
    rise : float, optional
        Duration of the raised-cosine ramp centred on each edge, s
        (0 <= rise <= width).  Pulse widths (between half-way crossings) and the
        integral of de up to any time outside a ramp are unchanged by it.

    Returns
    -------
    ndarray
        The elevator deflection de(t), rad, shaped like t.
    """
    width = _positive(width, "width (s)")
    return _pulse_train(t, amplitude, start, [width, width], [1.0, -1.0], rise)


def three_two_one_one(
    t, amplitude: float = DEFAULT_AMPLITUDE, start: float = 1.0, unit: float = 0.4, rise: float = 0.0
) -> np.ndarray:
    """Elevator 3-2-1-1: pulses of 3, 2, 1 and 1 units with signs +, -, +, -.

    Parameters
    ----------
    t : array_like
        Time, s (any shape).
    amplitude : float, optional
        Pulse height, rad (default 1 deg).
    start : float, optional
        Time of the first edge, s.
    unit : float, optional
        The time unit, s; the manoeuvre lasts 7 units.
    rise : float, optional
        Raised-cosine edge ramp, s (0 <= rise <= unit), centred on each edge.

    Returns
    -------
    ndarray
        The elevator deflection de(t), rad, shaped like t.
    """
    unit = _positive(unit, "unit (s)")
    return _pulse_train(t, amplitude, start, [3 * unit, 2 * unit, unit, unit], [1.0, -1.0, 1.0, -1.0], rise)


# --- multisine -----------------------------------------------------------------


def multisine(
    t,
    amplitude: float = DEFAULT_AMPLITUDE,
    omega_lo: float = 0.5,
    omega_hi: float = 10.0,
    n_components: int | None = None,
    phases="schroeder",
    rng=None,
    zero_start: bool = True,
    amplitudes=None,
    stride: int = 1,
    offset: int = 0,
) -> np.ndarray:
    """Multisine: harmonics of 2 pi / T inside a band, peak-scaled.

    ``u(t) = sum_k cos(omega_k t + phi_k)``, scaled so that ``max |u| = amplitude``
    on the samples, with ``omega_k = 2 pi k / T`` and ``T = t[-1] - t[0]``: every
    component completes whole periods over the record, so the finite Fourier
    transform over [0, T] sees each at exactly one frequency, and the signal has
    no power outside the chosen harmonics.

    Parameters
    ----------
    t : array_like, shape (n,)
        Uniform time, s.
    amplitude : float, optional
        Peak ``|u|`` on the samples, rad.
    omega_lo, omega_hi : float, optional
        Band edges, rad/s (0 < omega_lo < omega_hi < pi/dt).
    n_components : int, optional
        Number of harmonics, spread evenly over those inside the band (all of
        them by default).
    phases : {"schroeder", "random", "min-crest"} or array_like, optional
        Schroeder (1970) phases ``phi_k = -pi k (k - 1) / K`` (low crest factor),
        uniform random phases drawn from ``rng``, phases optimised for the
        minimum crest factor (:func:`min_crest_phases`), or explicit phases (rad).
    rng : numpy.random.Generator, optional
        Needed for ``phases="random"``.
    zero_start : bool, optional
        Shift the time origin of the periodic signal to an upward zero crossing
        so that the input starts (and, being periodic over T, ends) at zero, as
        flight-test multisines do; the amplitude spectrum and crest factor are
        unchanged.  A step at t = 0 would otherwise excite the singular F-term
        of docs/theory.md Eq. 2 at t = T.
    amplitudes : array_like, optional
        Relative amplitude of each harmonic (default flat); the peak scaling
        applies on top.
    stride, offset : int, optional
        Keep the harmonics whose index (counted from the first in the band) is
        ``offset`` modulo ``stride``: inputs with the same stride and different
        offsets have mutually orthogonal harmonics over the record.

    Returns
    -------
    ndarray, shape (n,)
        The input u(t), rad.
    """
    t = _time(t)
    amplitude = _finite(amplitude, "amplitude (rad)")
    omega_k = multisine_frequencies(t, omega_lo, omega_hi, n_components, stride=stride, offset=offset)
    K = omega_k.size
    amps = np.ones(K) if amplitudes is None else np.asarray(amplitudes, dtype=float)
    if amps.shape != (K,) or not np.all(np.isfinite(amps)) or np.any(amps < 0) or not np.any(amps):
        raise ParameterError(f"multisine amplitudes: {K} finite values >= 0, not all zero, are needed")
    if isinstance(phases, str):
        if phases in ("schroeder", "min-crest"):
            phi = schroeder_phases(amps)
            if phases == "min-crest":
                phi = min_crest_phases(omega_k, amps, t - t[0], phi)
        elif phases == "random":
            if rng is None:
                raise ParameterError("random multisine phases need rng (a numpy Generator)")
            phi = rng.uniform(-np.pi, np.pi, K)
        else:
            raise ParameterError(f"unknown phases {phases!r}; use 'schroeder', 'random' or an array")
    else:
        phi = np.asarray(phases, dtype=float)
        if phi.shape != (K,):
            raise ParameterError(f"{phi.size} phases given for {K} multisine components")
    tau = t - t[0]
    if zero_start:
        phi = phi + omega_k * _upward_zero(omega_k, phi, tau[-1], amps)
    u = np.cos(np.outer(tau, omega_k) + phi) @ amps
    if zero_start:
        u[[0, -1]] = 0.0  # the crossing is found to ~1e-16 of the peak; make it exact
    return amplitude * u / np.max(np.abs(u))


def multisine_frequencies(
    t, omega_lo: float, omega_hi: float, n_components: int | None = None, *, stride: int = 1, offset: int = 0
) -> np.ndarray:
    """The multisine harmonics ``2 pi k / T`` inside [omega_lo, omega_hi], rad/s.

    Parameters
    ----------
    t : array_like
        Uniform time, s; ``T = t[-1] - t[0]``.
    omega_lo, omega_hi : float
        Band, rad/s.
    n_components : int, optional
        How many to keep (evenly spread); all by default.
    stride, offset : int, optional
        Keep every ``stride``-th harmonic of the band starting at the
        ``offset``-th (0-based): interleaved, mutually orthogonal sets.

    Returns
    -------
    ndarray
        Frequencies, rad/s, ascending.
    """
    t = _time(t)
    T = t[-1] - t[0]
    lo, hi = _band(t, omega_lo, omega_hi, "multisine")
    d = 2.0 * np.pi / T
    k = np.arange(math.ceil(lo / d - 1e-9), math.floor(hi / d + 1e-9) + 1)
    if k.size == 0:
        raise ParameterError(f"no harmonic of 2 pi/T = {d:.4g} rad/s lies in [{lo}, {hi}] rad/s; lengthen the record")
    if isinstance(stride, bool) or int(stride) != stride or stride < 1 or not 0 <= int(offset) < stride:
        raise ParameterError(
            f"multisine stride {stride!r} and offset {offset!r}: need stride >= 1, 0 <= offset < stride"
        )
    k = k[int(offset) :: int(stride)]
    if k.size == 0:
        raise ParameterError(f"the band holds no harmonic for offset {offset} of stride {stride}; lengthen the record")
    if n_components is not None:
        n = int(n_components)
        if n < 1 or n > k.size:
            raise ParameterError(
                f"n_components = {n_components}: the band holds {k.size} harmonics of 2 pi/T = {d:.4g} rad/s"
            )
        k = k[np.round(np.linspace(0, k.size - 1, n)).astype(int)]
    return k * d


def schroeder_phases(amplitudes) -> np.ndarray:
    """Schroeder (1970) phases for harmonics of relative amplitudes a_k, rad.

    ``phi_k = phi_1 - 2 pi sum_{l<k} (k - l) p_l`` with power fractions
    ``p_l = a_l^2 / sum a^2``; for a flat spectrum this is ``-pi k (k - 1) / K``.

    Parameters
    ----------
    amplitudes : array_like, shape (K,)
        Relative amplitudes a_k of the harmonics.

    Returns
    -------
    numpy.ndarray, shape (K,)
        The phases phi_k, rad (phi_1 = 0).
    """
    a = np.asarray(amplitudes, dtype=float)
    p = a**2 / np.sum(a**2)
    k = np.arange(1, a.size + 1)
    # sum_{l<k} (k - l) p_l for every k at once: a lower-triangular weight matrix
    W = np.clip(k[:, None] - k[None, :], 0, None)
    return -2.0 * np.pi * (W @ p)


def crest_factor(u) -> float:
    """Crest factor max|u| / rms(u) (sqrt 2 for one sinusoid).

    Parameters
    ----------
    u : array_like
        A signal (any unit).

    Returns
    -------
    float
        The crest factor, dimensionless.
    """
    u = np.asarray(u, dtype=float)
    return float(np.max(np.abs(u)) / np.sqrt(np.mean(u**2)))


def relative_peak_factor(u) -> float:
    """Morelli's relative peak factor (max u - min u) / (2 sqrt(2) rms(u)): 1 for one sinusoid.

    Parameters
    ----------
    u : array_like
        A signal (any unit).

    Returns
    -------
    float
        The relative peak factor, dimensionless.
    """
    u = np.asarray(u, dtype=float)
    return float((np.max(u) - np.min(u)) / (2.0 * math.sqrt(2.0) * np.sqrt(np.mean(u**2))))


#: Iterations of the clipping algorithm of :func:`min_crest_phases`.
_CLIP_ITERATIONS = 1000
#: Clipping level as a fraction of the current peak (0.9 gave the lowest crest factors of 0.7-0.95
#: on flat 2-45-harmonic multisines).
_CLIP_LEVEL = 0.9


def min_crest_phases(omega, amplitudes, tau, phases=None, iterations: int = _CLIP_ITERATIONS) -> np.ndarray:
    """Phases that lower the crest factor of ``sum a_k cos(omega_k tau + phi_k)`` by iterative clipping.

    Van den Bos's clipping algorithm (as in the flight-test multisine
    literature, e.g. Morelli's relative-peak-factor optimisation): clip the
    signal at 90 % of its peak, take the phases of the clipped signal's
    Fourier coefficients at the harmonics, keep the amplitudes, repeat (FFT
    over one period, so each pass is O(n log n)); the best phases met are kept.  The amplitude spectrum is
    never changed, so the information the input carries (which depends on the
    power per harmonic only) is kept while its peak falls.

    Parameters
    ----------
    omega : ndarray, shape (K,)
        Harmonic frequencies, rad/s (multiples of 2 pi / T).
    amplitudes : ndarray, shape (K,)
        Relative amplitudes.
    tau : ndarray, shape (n,)
        Time from the record start, s.
    phases : ndarray, optional
        Start phases (default Schroeder's).
    iterations : int, optional
        Clipping passes.

    Returns
    -------
    ndarray, shape (K,)
        The phases of the lowest crest factor met, rad.
    """
    a = np.asarray(amplitudes, dtype=float)
    phi = schroeder_phases(a) if phases is None else np.asarray(phases, dtype=float)
    tau = np.asarray(tau, dtype=float)
    n = tau.size - 1  # one period of the harmonics: the last sample repeats the first
    bins = np.asarray(omega) * tau[-1] / (2.0 * np.pi)
    k = np.round(bins).astype(int)
    if np.any(np.abs(bins - k) > 1e-6) or np.any(k < 1) or np.any(k >= n / 2):
        raise ParameterError("min-crest phases need harmonics of 2 pi/T below the Nyquist frequency")
    best, best_cf = phi, math.inf
    spec = np.zeros(n // 2 + 1, complex)
    for _ in range(iterations):
        spec[k] = a * np.exp(1j * phi)
        u = np.fft.irfft(spec, n)  # sum a_k cos(omega_k tau + phi_k) up to a constant factor, O(n log n)
        peak, rms = np.max(np.abs(u)), np.sqrt(np.mean(u**2))
        cf = peak / rms
        if cf < best_cf - 1e-9:
            best, best_cf = phi, cf
        level = _CLIP_LEVEL * peak
        phi = np.angle(np.fft.rfft(np.clip(u, -level, level))[k])  # the clipped signal's phases at the harmonics
    return best


def sweep(
    t,
    amplitude: float = DEFAULT_AMPLITUDE,
    omega_lo: float = 0.5,
    omega_hi: float = 10.0,
    kind: str = "linear",
    taper: float = 0.05,
) -> np.ndarray:
    """Frequency sweep ``amplitude sin(phi(t))`` from omega_lo to omega_hi over the record.

    Linear: ``omega(t) = omega_lo + (omega_hi - omega_lo) t / T``; logarithmic:
    ``omega(t) = omega_lo (omega_hi / omega_lo)^(t / T)`` (more time at low
    frequency, as CIFER's sweeps).  It starts at zero; a raised-cosine taper
    over the last ``taper`` fraction of the record brings it back to zero.

    Parameters
    ----------
    t : array_like, shape (n,)
        Uniform time, s.
    amplitude : float, optional
        Peak, rad.
    omega_lo, omega_hi : float, optional
        Start and end frequencies, rad/s (0 < omega_lo < omega_hi < pi/dt).
    kind : {"linear", "log"}, optional
    taper : float, optional
        Fraction of the record (0..0.5) tapered to zero at the end.

    Returns
    -------
    ndarray, shape (n,)
        The input u(t), rad.
    """
    t = _time(t)
    amplitude = _finite(amplitude, "amplitude (rad)")
    lo, hi = _band(t, omega_lo, omega_hi, "sweep")
    tau = t - t[0]
    T = tau[-1]
    if not 0.0 <= taper <= 0.5:
        raise ParameterError(f"sweep taper must be a fraction in [0, 0.5], got {taper!r}")
    if kind == "linear":
        phase = lo * tau + 0.5 * (hi - lo) * tau**2 / T
    elif kind == "log":
        r = math.log(hi / lo)
        phase = lo * T / r * np.expm1(r * tau / T)
    else:
        raise ParameterError(f"unknown sweep kind {kind!r}; use 'linear' or 'log'")
    w = np.ones_like(tau)
    if taper > 0:
        x = np.clip((T - tau) / (taper * T), 0.0, 1.0)
        w = 0.5 * (1.0 - np.cos(np.pi * x))
    return amplitude * np.sin(phase) * w


def _upward_zero(omega, phi, T: float, a) -> float:
    """First time in [0, T) where sum a_k cos(omega_k t + phi_k) crosses zero upwards."""
    f = lambda x: float(np.cos(omega * x + phi) @ a)  # noqa: E731
    grid = np.linspace(0.0, T, 64 * omega.size + 64)
    vals = np.cos(np.outer(grid, omega) + phi) @ a
    up = np.nonzero((vals[:-1] < 0) & (vals[1:] >= 0))[0]
    if up.size == 0:  # pragma: no cover - a zero-mean periodic signal always crosses
        raise ParameterError("the multisine has no zero crossing")
    i = up[0]
    return optimize.brentq(f, grid[i], grid[i + 1], xtol=1e-15 * max(T, 1.0), rtol=4 * np.finfo(float).eps)


# --- Dryden turbulence -------------------------------------------------------------


def dryden_psd(omega, sigma: float, U: float, L: float = DRYDEN_L):
    """One-sided Dryden vertical-gust spectrum of w_g, (m/s)^2 per rad/s.

    ``Phi(omega) = sigma^2 (L / (pi U)) (1 + 3 (L omega/U)^2) / (1 + (L omega/U)^2)^2``
    (MIL-F-8785C with the spatial frequency Omega = omega / U), normalised so
    that ``integral_0^inf Phi d omega = sigma^2``.  It equals ``|H(j omega)|^2``
    of the shaping filter of :func:`dryden_gust`.

    Parameters
    ----------
    omega : array_like
        Angular frequency, rad/s.
    sigma : float
        RMS vertical gust velocity, m/s.
    U : float
        Airspeed, m/s.
    L : float, optional
        Vertical scale length, m.

    Returns
    -------
    ndarray
        Phi(omega), (m/s)^2 / (rad/s).
    """
    x = (L / U) * np.asarray(omega, dtype=float)
    return sigma**2 * (L / (np.pi * U)) * (1.0 + 3.0 * x**2) / (1.0 + x**2) ** 2


def _dryden_state_space(U: float, L: float):
    """Controllable form of the unit-RMS H(s) = sqrt(L/(pi U)) (1 + sqrt3 a s)/(1 + a s)^2, a = L/U."""
    a = L / U
    k = math.sqrt(L / (math.pi * U))
    # H(s) = (k/a^2) (1 + sqrt3 a s) / (s^2 + (2/a) s + 1/a^2)
    A = np.array([[0.0, 1.0], [-1.0 / a**2, -2.0 / a]])
    B = np.array([[0.0], [1.0]])
    C = (k / a**2) * np.array([[1.0, math.sqrt(3.0) * a]])
    return A, B, C


def dryden_gust(
    t, sigma: float, U: float, L: float = DRYDEN_L, *, rng, stationary: bool = True, method: str = "exact"
) -> np.ndarray:
    """Vertical Dryden turbulence as a gust angle ``alpha_w = w_g / U``, rad.

    The gust velocity is the output of the Dryden vertical shaping filter

        H(s) = sigma sqrt(L/(pi U)) (1 + sqrt(3) (L/U) s) / (1 + (L/U) s)^2

    driven by continuous white noise of two-sided intensity pi (so that the
    one-sided spectrum of w_g is ``|H(j omega)|^2 = Phi(omega)`` of
    :func:`dryden_psd` and its variance is sigma^2).  The autocorrelation of w_g
    is ``sigma^2 (1 - U tau/(2L)) exp(-U tau/L)``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Uniform time, s.
    sigma : float
        RMS of the vertical gust velocity w_g, m/s (>= 0).
    U : float
        Airspeed, m/s.
    L : float, optional
        Scale length, m (default 533.4 m = 1750 ft, MIL-F-8785C above 2000 ft).
    rng : numpy.random.Generator
        Source of the white noise (required; the global RNG is never used).
    stationary : bool, optional
        Draw the initial filter state from its stationary distribution, so that
        the record is stationary from t = 0 (default); otherwise start at zero.
    method : {"exact", "zoh"}, optional
        ``exact``: the exact discretisation of the stochastic filter (Van Loan's
        matrix exponential), whose samples have exactly the Dryden
        autocovariance at every lag.  ``zoh``: the filter driven by white noise
        held constant over each step (variance pi/dt), exact for that input;
        its variance differs from sigma^2 by a relative O(U dt / L).

    Returns
    -------
    ndarray, shape (n,)
        The gust angle alpha_w(t) = w_g(t) / U, rad.
    """
    t = _time(t)
    sigma = _finite(sigma, "sigma (m/s)")
    if sigma < 0:
        raise ParameterError(f"gust RMS sigma must be >= 0 m/s, got {sigma}")
    U, L = _positive(U, "airspeed U (m/s)"), _positive(L, "scale length L (m)")
    if rng is None or not isinstance(rng, np.random.Generator):
        raise ParameterError("dryden_gust needs rng, a numpy Generator (np.random.default_rng(seed))")
    dt = _uniform_step(t)
    A, B, C = _dryden_state_space(U, L)  # unit RMS: sigma scales the output
    q = np.pi  # two-sided intensity of the driving noise
    n = t.size
    if method == "exact":
        # Van Loan (1978): expm([[-A, q B B^T], [0, A^T]] dt) gives Phi and Qd.
        E = linalg.expm(np.block([[-A, q * (B @ B.T)], [np.zeros((2, 2)), A.T]]) * dt)
        Phi = E[2:, 2:].T
        Qd = Phi @ E[:2, 2:]
        Qd = 0.5 * (Qd + Qd.T)
        Gw = np.linalg.cholesky(Qd + 1e-300 * np.eye(2))
        w = rng.standard_normal((n, 2)) @ Gw.T
    elif method == "zoh":
        E = linalg.expm(np.block([[A, B], [np.zeros((1, 3))]]) * dt)
        Phi, Gam = E[:2, :2], E[:2, 2:]
        w = (rng.standard_normal((n, 1)) * math.sqrt(q / dt)) @ Gam.T
    else:
        raise ParameterError(f"unknown Dryden discretisation {method!r}; use 'exact' or 'zoh'")
    x0 = np.zeros(2)
    if stationary:
        P = linalg.solve_continuous_lyapunov(A, -q * (B @ B.T))  # A P + P A^T + q B B^T = 0
        x0 = np.linalg.cholesky(0.5 * (P + P.T)) @ rng.standard_normal(2)
    # x_{k+1} = Phi x_k + w_k, y_k = c x_k, as two IIR filters: c (zI - Phi)^-1 e_j =
    # (a_j z^-1 + b_j z^-2) / (1 - tr(Phi) z^-1 + det(Phi) z^-2).  The initial state enters as
    # one extra drive sample before w_0 (x_0 = Phi 0 + x0), hence the one-sample shift.
    c = C[0]
    den = np.array([1.0, -np.trace(Phi), np.linalg.det(Phi)])
    adj = np.array([[-Phi[1, 1], Phi[0, 1]], [Phi[1, 0], -Phi[0, 0]]])  # adj(zI - Phi) = z I + adj
    drive = np.vstack([x0, w[:-1]])
    y = sum(signal.lfilter([0.0, c[j], c @ adj[:, j]], den, drive[:, j]) for j in range(2))
    return sigma * y / U


# --- dispatch ---------------------------------------------------------------------

#: Input kinds understood by :func:`make_input`.
INPUT_KINDS = ("doublet", "3211", "multisine", "sweep")
#: The generator of each kind.
_GENERATORS: dict[str, Callable[..., np.ndarray]] = dict(
    zip(INPUT_KINDS, (doublet, three_two_one_one, multisine, sweep))
)


def make_input(kind: str, t, amplitude: float = DEFAULT_AMPLITUDE, **kw) -> np.ndarray:
    """Build an elevator input by name.

    Parameters
    ----------
    kind : {"doublet", "3211", "multisine", "sweep"}
        The generator: :func:`doublet`, :func:`three_two_one_one`, :func:`multisine`
        or :func:`sweep`.
    t : array_like, shape (n,)
        Time, s.
    amplitude : float, optional
        Pulse height or multisine peak, rad.
    **kw
        Further keywords of the generator (``start``, ``width``, ``unit``,
        ``rise``, ``omega_lo``, ``omega_hi``, ``n_components``, ``phases``,
        ``rng``); an unknown keyword raises :class:`~fdml.errors.ParameterError`.

    Returns
    -------
    ndarray, shape (n,)
        The elevator deflection de(t), rad.
    """
    fn = _GENERATORS.get(kind) if isinstance(kind, str) else None
    if fn is None:
        raise ParameterError(f"unknown input kind {kind!r}; kinds: {', '.join(INPUT_KINDS)}")
    allowed = set(inspect.signature(fn).parameters) - {"t", "amplitude"}
    bad = sorted(set(kw) - allowed)
    if bad:
        raise ParameterError(f"{kind} input: unknown option(s) {', '.join(bad)}; options: {', '.join(sorted(allowed))}")
    return fn(t, amplitude, **kw)


# --- checks --------------------------------------------------------------------------


def _finite(x, label: str) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ParameterError(f"{label} must be a number, got {x!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{label} must be finite, got {x!r}")
    return v


def _positive(x, label: str) -> float:
    v = _finite(x, label)
    if v <= 0:
        raise ParameterError(f"{label} must be positive, got {x!r}")
    return v


def _band(t: np.ndarray, omega_lo, omega_hi, what: str) -> tuple[float, float]:
    """Band edges checked: positive, increasing, the upper one below the Nyquist frequency of t."""
    lo, hi = _positive(omega_lo, "omega_lo (rad/s)"), _positive(omega_hi, "omega_hi (rad/s)")
    if not lo < hi:
        raise ParameterError(f"{what} band [{lo}, {hi}] rad/s is empty")
    nyq = np.pi * (t.size - 1) / (t[-1] - t[0])
    if hi >= nyq:
        raise ParameterError(f"{what} band edge {hi} rad/s is not below the Nyquist frequency {nyq:.4g} rad/s")
    return lo, hi


def _time(t) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ParameterError(f"t must be a 1-D time vector with at least 2 samples, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ParameterError("t has non-finite values")
    if np.any(np.diff(t) <= 0):
        raise ParameterError("t must be strictly increasing")
    return t


def _uniform_step(t: np.ndarray) -> float:
    dt = (t[-1] - t[0]) / (t.size - 1)
    if np.max(np.abs(np.diff(t) - dt)) > 1e-6 * dt:
        raise ParameterError("t must be uniformly spaced (use fdml.maneuvers.time_vector)")
    return float(dt)
