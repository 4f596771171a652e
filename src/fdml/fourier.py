"""Finite Fourier transform of uniformly sampled records at arbitrary frequencies.

The transform of a record x(t) sampled at t_j = j dt (j = 0 .. n-1, t from the
first sample, T = (n-1) dt) is, at chosen angular frequencies w (rad/s) that are
generally not FFT bins (docs/theory.md Eq. 11),

    X(w) = integral_0^T x(t) exp(-j w t) dt.

With theta = w dt and M = n - 1, every supported quadrature has the form

    X(w) = dt * [ W(theta) * sum_j x_j exp(-j theta j)
                  + sum_k a_k(theta) x_k
                  + exp(-j theta M) * sum_k conj(a_k(theta)) x_{M-k} ],

where the endpoint coefficients a_k touch only the first and last K samples:

* ``"none"``: rectangle sum, W = 1, K = 0 (equals dt * FFT at FFT bins);
* ``"trapezoid"``: trapezoid rule, W = 1, a_0 = -1/2, K = 1 (order dt^2);
* ``"cubic"``: exact integral of the piecewise-cubic Lagrange interpolant of the
  samples (centred 4-point stencils inside, one-sided stencils on the first and
  last interval), the Filon construction of Numerical Recipes section 13.9
  with exp(+i w t) replaced by exp(-j w t); K = 4, order dt^4.

For "cubic", W and a_k are assembled from the moments
mu_q(theta) = integral_0^1 u^q exp(-j theta u) du (q = 0..3) of the Lagrange
basis polynomials.  The moments are summed as Taylor series for ``|theta| < 1`` and
by the closed-form recursion otherwise, so no quantity is ever divided by
theta^4 and small theta (including 0) loses nothing to cancellation.  For the
record, W(theta) = (6 + theta^2) (3 - 4 cos theta + cos 2 theta) / (3 theta^4).

The interior sum is evaluated either directly (chunked matrix products) or, on
evenly spaced frequency grids, by a blocked chirp-z transform
(Bluestein's algorithm on numpy.fft, as :class:`scipy.signal.ZoomFFT` does it)
in O(n log(n_omega)) operations.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.polynomial import polynomial as _poly

from fdml.errors import BandError, FdmlError, RecordError

__all__ = [
    "omega_band",
    "check_band",
    "MAX_BAND_FREQUENCIES",
    "finite_fourier_transform",
    "transform_weights",
    "fourier_adjoint",
    "is_evenly_spaced",
    "gram",
    "gram_form",
    "leading_transform",
    "transform_columns",
    "step_edges",
]

_METHODS = ("auto", "czt", "direct")
#: Number of endpoint-corrected samples at each end, per end correction.
_N_END = {"cubic": 4, "trapezoid": 1, "none": 0}
#: The end corrections of the finite Fourier integral.
END_CORRECTIONS = tuple(_N_END)
#: Peak bytes of temporaries per chunk of the direct sums.
_CHUNK_BYTES = 32 * 2**20
#: "auto" uses the chirp-z path when n * n_omega reaches this.  Measured: both
#: paths cost ~0.2 ms near n * m ~ 3e3 to 5e3; czt is x1.5 faster at 1e4, x4 at
#: 4e4, x20 at 3e5 (see benchmarks/bench_fourier.py).
_CZT_MIN_WORK = 10_000
#: The moments mu_q are summed as Taylor series below this |theta|.
_SERIES_MAX_THETA = 1.0
#: Terms of that series: the first neglected term is below 1/20! ~ 4e-19.
_SERIES_TERMS = 20
#: Largest number of frequencies in a band.  The estimator holds, per frequency,
#: a 3 x p complex sensitivity block and the spectra of every channel, so memory
#: grows linearly with the count: a steady-model fit of a 500-sample record on
#: 1e5 frequencies peaks at about 0.6 GB and 20 s (measured), so 1e6 would need
#: about 6 GB and end in MemoryError on a workstation.  1e5 is also far more than
#: the data carry: frequencies closer than 2 pi/T add no information, and even a
#: 1000 s record over 0-100 rad/s (beyond any short-period band) has only about
#: 16,000 independent ones.  The paper's grid has 100.
MAX_BAND_FREQUENCIES = 100_000
#: Transforms whose end weights and Gram matrices are kept, most recently used first
#: (a fit, its covariance and its adequacy check, and every record of a Monte Carlo
#: study or a multi-record fit share one grid and record length).
_MEMO_SIZE = 8
#: Largest grid whose end weights are kept (8 entries of at most 0.6 MB).
_MEMO_MAX_SETUP = 4096
#: Largest grid whose Gram matrices are kept: two (m, m) complex matrices, 2 MB at
#: m = 256, so at most 16 MB in all (and as much again for the trim-corrected ones of
#: :meth:`fdml.spectral.FrequencyData.noise_gram`).  Fit bands have about 100.
_MEMO_MAX_GRAM = 256
#: A sampled input steps between two samples when one interval carries more than this share of the
#: absolute change over the three intervals around it (a spike that returns carries half).
EDGE_SHARE = 0.8
#: ... counted when the step is at least this share of the input's range (smaller ones are quantisation).
EDGE_SIZE = 0.05


def _lagrange_basis(nodes):
    """Coefficients (ascending powers of u) of the Lagrange basis on ``nodes``."""
    nodes = np.asarray(nodes, dtype=float)
    others = [np.delete(nodes, i) for i in range(nodes.size)]
    return np.array([_poly.polyfromroots(rest) / np.prod(node - rest) for node, rest in zip(nodes, others)])


#: Interior interval [i, i+1] with u = s - i, stencil i-1 .. i+2 (rows r = -1..2).
_INTERIOR = _lagrange_basis([-1.0, 0.0, 1.0, 2.0])
#: First interval [0, 1], one-sided stencil 0 .. 3 (rows k = 0..3).
_FIRST = _lagrange_basis([0.0, 1.0, 2.0, 3.0])


def is_evenly_spaced(omega, rtol=1e-9):
    """Tell whether a 1-D grid has a constant, non-zero step.

    Parameters
    ----------
    omega : array_like, shape (m,)
        Grid values (any unit, e.g. rad/s); increasing or decreasing.
    rtol : float, optional
        Largest allowed deviation of any step from the mean step, relative to
        the mean step.

    Returns
    -------
    bool
        True for one point, two distinct points, and finite grids whose steps
        all equal (omega[-1] - omega[0]) / (m - 1) != 0 to within ``rtol``.
    """
    omega = np.asarray(omega, dtype=float)
    if omega.ndim != 1 or not np.all(np.isfinite(omega)):
        return False
    if omega.size < 2:
        return omega.size == 1
    step = (omega[-1] - omega[0]) / (omega.size - 1)
    return bool(step != 0 and np.max(np.abs(np.diff(omega) - step)) <= rtol * abs(step))


def omega_band(lo=0.1, hi=10.0, step=0.1):
    """Evenly spaced frequency grid lo, lo + step, ..., up to hi.

    Parameters
    ----------
    lo, hi : float
        First and largest admissible frequency, rad/s (0 <= lo <= hi).  ``hi``
        is included when it lies on the grid to within float rounding.
    step : float
        Grid step, rad/s (> 0).

    Returns
    -------
    numpy.ndarray, shape (m,)
        ``lo + step * arange(m)``, rad/s.

    Raises
    ------
    BandError
        Non-finite values, lo < 0, step <= 0, hi < lo, or more than
        :data:`MAX_BAND_FREQUENCIES` points (see :func:`check_band`).
    """
    lo, hi, step, count = check_band(lo, hi, step, what="omega_band")
    return lo + step * np.arange(count)


def check_band(lo, hi, step=None, *, what: str = "band", positive: bool = False):
    """Validate a band (rad/s) before anything is built from it.

    The one check behind every band fdml accepts (``--band``,
    ``band=``): :func:`omega_band`, :func:`fdml.spectral.parse_band` and the
    diagnosis band parser all call it.

    Parameters
    ----------
    lo, hi : float
        Lowest and highest frequency, rad/s (finite, ``0 <= lo <= hi``).
    step : float, optional
        Grid step, rad/s (finite, > 0); None for a band without a grid.
    what : str, optional
        How the band is named in messages (``--band``, ``omega_band``...).
    positive : bool, optional
        Require ``lo > 0`` (a fit band: the finite Fourier transform of the
        output bias is singular at 0 rad/s).

    Returns
    -------
    lo : float
        Lowest frequency, rad/s.
    hi : float
        Highest frequency, rad/s.
    step : float or None
        Grid step, rad/s.
    count : int
        The number of grid points (0 without a step).

    Raises
    ------
    BandError
        Non-finite values, a negative (or, with ``positive``, zero) ``lo``,
        ``hi < lo``, ``step <= 0``, or more than :data:`MAX_BAND_FREQUENCIES`
        grid points.
    """

    def number(name: str, value) -> float:
        try:
            x = math.nan if isinstance(value, (bool, str)) else float(value)
        except (TypeError, ValueError, OverflowError):
            x = math.nan
        if not math.isfinite(x):
            raise BandError(f"{what}: {name} = {value!r} is not a finite number (rad/s)")
        return x

    lo, hi = number("lo", lo), number("hi", hi)
    step = None if step is None else number("step", step)
    if lo < 0 or (positive and lo == 0):
        raise BandError(f"{what}: lo = {lo:g} rad/s must be {'positive' if positive else 'non-negative'}")
    if hi < lo:
        form = "LO:HI" if step is None else "LO:HI:STEP"
        raise BandError(f"{what}: hi = {hi:g} rad/s is below lo = {lo:g} rad/s (the band is {form})")
    if step is None:
        return lo, hi, None, 0
    if step <= 0:
        raise BandError(f"{what}: step = {step:g} rad/s must be positive")
    ratio = (hi - lo) / step  # may overflow to inf (1e300:1e308:1e-10): caught below
    count = (
        round(ratio)
        if ratio < MAX_BAND_FREQUENCIES and math.isclose(ratio, round(ratio), rel_tol=1e-9, abs_tol=1e-9)
        else math.floor(min(ratio, 1e300))
    )
    if count + 1 > MAX_BAND_FREQUENCIES:
        raise BandError(
            f"{what}: {lo:g}:{hi:g}:{step:g} rad/s has {ratio + 1:.3g} frequencies, more than "
            f"the {MAX_BAND_FREQUENCIES:,} fdml accepts; use a larger step or a narrower band"
        )
    return lo, hi, step, count + 1


def step_edges(u) -> np.ndarray:
    """The sample intervals in which a sampled input steps: its edges whose time the record does not keep.

    The transform integrates the interpolant of the samples, which puts a step that happened
    anywhere in the interval [t_k, t_k+1] at its middle, to first order in w dt (docs/theory.md
    section 7a): the step's time is known only to +-dt/2.  An interval counts when its change is
    at least :data:`EDGE_SIZE` of the input's range and more than :data:`EDGE_SHARE` of the absolute
    change over the three intervals around it (a raised-cosine or ramped edge spread over several
    samples does not count, nor does a one-sample spike).

    Parameters
    ----------
    u : array_like
        The input's samples, shape (n,).

    Returns
    -------
    numpy.ndarray
        Indices k of the intervals [t_k, t_k+1] that hold a step, increasing, int, shape (K,).
    """
    u = np.asarray(u, float)
    if u.size < 4:
        return np.zeros(0, int)
    d = np.abs(np.diff(u))
    big = d >= EDGE_SIZE * max(float(np.ptp(u)), 1e-300)
    around = d + np.r_[0.0, d[:-1]] + np.r_[d[1:], 0.0]
    return np.flatnonzero(big & (d > EDGE_SHARE * around))


def _moments(theta):
    """mu[:, q] = integral_0^1 u^q exp(-1j theta u) du for q = 0..3, shape (m, 4)."""
    z = -1j * theta
    mu = np.empty((theta.size, 4), dtype=complex)
    small = np.abs(theta) < _SERIES_MAX_THETA
    # Series: mu_q = sum_s z^s / (s! (q + s + 1)), summed by Horner in z.  Only as many
    # terms as the largest |theta| needs: the first omitted term |theta|^S / S! < 1e-17.
    tmax = float(np.max(np.abs(theta[small]))) if np.any(small) else 0.0
    nterms = 1
    term = 1.0
    while nterms < _SERIES_TERMS and term >= 1e-17:
        term *= tmax / nterms
        nterms += 1
    s = np.arange(nterms)[:, None]
    fact = np.cumprod(np.r_[1.0, np.arange(1.0, nterms)])[:, None]
    coef = 1.0 / (fact * (np.arange(4)[None, :] + s + 1))  # (S, 4)
    zs = z[small][:, None]
    acc = np.zeros((zs.shape[0], 4), dtype=complex)
    for row in coef[::-1]:
        acc *= zs
        acc += row
    mu[small] = acc
    # Closed form: mu_0 = (e^z - 1) / z, mu_q = (e^z - q mu_{q-1}) / z; the
    # recursion amplifies errors by at most q/|z| <= 3 per step here.
    zl = z[~small]
    ez = np.exp(zl)
    mu[~small, 0] = (ez - 1.0) / zl
    for q in range(1, 4):
        mu[~small, q] = (ez - q * mu[~small, q - 1]) / zl
    return mu


def _end_weights(theta, end_correction):
    """W (m,), left endpoint coefficients a (m, K); the right ones are conj(a)."""
    m = theta.size
    if end_correction == "none":
        return np.ones(m), np.zeros((m, 0), dtype=complex)
    if end_correction == "trapezoid":
        return np.ones(m), np.full((m, 1), -0.5, dtype=complex)
    mu = _moments(theta)
    ml = mu @ _INTERIOR.T  # columns r = -1, 0, 1, 2
    me = mu @ _FIRST.T  # columns k = 0, 1, 2, 3
    shift = np.exp(1j * np.outer(theta, [-1.0, 0.0, 1.0, 2.0]))
    weight = np.sum(shift * ml, axis=1).real  # the kernel is even: W is real
    e1, e2 = shift[:, 2], shift[:, 3]
    # a_k = (true first-interval weight) - (what W * sum leaves on s < 1).
    alpha = np.column_stack(
        [
            me[:, 0] - ml[:, 1] - e1 * ml[:, 2] - e2 * ml[:, 3],
            me[:, 1] - ml[:, 2] - e1 * ml[:, 3],
            me[:, 2] - ml[:, 3],
            me[:, 3],
        ]
    )
    return weight, alpha


def _check(dt, omega, end_correction, method, *, x=None, n=None):
    """Validate inputs; return (x as an (n, k) float/complex array or None, n, dt, omega)."""
    if end_correction not in _N_END:
        raise FdmlError(f"end_correction must be one of {sorted(_N_END)}, not {end_correction!r}")
    if method not in _METHODS:
        raise FdmlError(f"method must be one of {_METHODS}, not {method!r}")
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise RecordError(f"dt must be a positive number of seconds, not {dt!r}") from None
    if not (np.isfinite(dt) and dt > 0):
        raise RecordError(f"dt = {dt} s: the sample interval must be positive and finite")
    if x is None:
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool):
            raise RecordError(f"n must be an integer number of samples, not {n!r}")
        n = int(n)
    else:
        x = np.asarray(x)
        if x.ndim not in (1, 2) or not np.issubdtype(x.dtype, np.number):
            raise RecordError(f"x must be a numeric array of shape (n,) or (n, k), not {x.dtype} {x.shape}")
        bad = ~np.isfinite(x)
        if bad.any():
            first = np.argwhere(bad)[0]
            where = f"sample {first[0]} (t = {first[0] * dt:g} s)"
            where += f", column {first[1]}" if x.ndim == 2 else ""
            raise RecordError(f"x contains {int(bad.sum())} NaN/inf value(s); first at {where}")
        n = x.shape[0]
        x = x.reshape(n, -1)
        x = x if np.iscomplexobj(x) else x.astype(float)
    need = max(_N_END[end_correction], 1)
    if n < need:
        raise RecordError(f"the record has {n} sample(s); end_correction={end_correction!r} needs at least {need}")
    omega = np.asarray(omega)
    if omega.ndim != 1 or omega.size == 0 or np.iscomplexobj(omega):
        raise BandError(f"omega must be a non-empty, real 1-D array of rad/s, not {omega.dtype} of shape {omega.shape}")
    omega = omega.astype(float)
    if not np.all(np.isfinite(omega)):
        raise BandError(f"omega contains {int(np.sum(~np.isfinite(omega)))} NaN/inf value(s)")
    nyquist = math.pi / dt
    wmax = float(np.max(np.abs(omega)))
    if wmax > nyquist * (1 + 1e-12):
        raise BandError(
            f"|omega| up to {wmax:g} rad/s is above the Nyquist frequency pi/dt = {nyquist:g} rad/s (dt = {dt:g} s)"
        )
    return x, n, dt, omega


def _setup(n, dt, omega, end_correction):
    """theta (m,), W (m,), left end coefficients a (m, K), right ones exp(-j theta M) conj(a).

    Read-only arrays, kept per (n, dt, grid, end correction) for grids of at
    most :data:`_MEMO_MAX_SETUP` frequencies (:func:`_memo_key`).
    """
    if omega.size > _MEMO_MAX_SETUP:
        return _setup_arrays(n, dt, omega, end_correction)
    return _setup_memo(*_memo_key(n, dt, omega, end_correction))


def _memo_key(n, dt, omega, end_correction):
    """Hashable key of a transform: (n, dt, the grid's float64 bytes, end correction)."""
    return int(n), float(dt), np.ascontiguousarray(omega, dtype=float).tobytes(), end_correction


def _read_only(*arrays):
    for a in arrays:
        a.setflags(write=False)
    return arrays


@functools.lru_cache(maxsize=_MEMO_SIZE)
def _setup_memo(n, dt, omega_bytes, end_correction):
    return _read_only(*_setup_arrays(n, dt, np.frombuffer(omega_bytes), end_correction))


def _setup_arrays(n, dt, omega, end_correction):
    theta = omega * dt
    weight, alpha = _end_weights(theta, end_correction)
    return theta, weight, alpha, np.exp(-1j * theta * (n - 1))[:, None] * alpha.conj()


def _choose_method(n, omega, method):
    """Return "czt" or "direct" for a transform of n samples at ``omega``.

    A single frequency always takes the direct sum (it is one dot product).
    """
    if omega.size == 1:
        return "direct"
    even = is_evenly_spaced(omega)
    if method == "czt":
        if not even:
            raise BandError("method='czt' needs an evenly spaced omega grid (rtol 1e-9)")
        return "czt"
    if method == "auto" and even and n * omega.size >= _CZT_MIN_WORK:
        return "czt"
    return "direct"


def _block(n, m, step):
    """Time-block length of the blocked chirp-z sums, from n, m and the theta step.

    Blocks of about 4 m samples keep the FFT work near O(n log m); the chirp
    phase step * B^2 / 2 is kept below 2e3 rad where possible (B >= m always),
    so its rounding error stays near 2e3 eps ~ 2e-13 relative.
    """
    limit = math.sqrt(4e3 / abs(step))
    return int(min(n, max(m, min(max(4 * m, 1024), limit))))


def _expi(phase):
    """exp(1j * phase) through cos and sin written in place (faster than np.exp of a complex)."""
    out = np.empty(phase.shape, dtype=complex)
    np.cos(phase, out=out.real)
    np.sin(phase, out=out.imag)
    return out


_KERNEL_SPLIT = 64


def _kernel(theta, j0, j1, sign):
    """exp(sign * 1j * theta_i * j) for j0 <= j < j1, shape (m, j1 - j0).

    Factored as j = j0 + 64 a + b: exp(i theta (j0 + 64 a)) exp(i theta b), both
    factors evaluated exactly, so each entry costs one complex product instead
    of a cos and a sin, with an error of a few ulp (no accumulation over j).
    """
    n = j1 - j0
    split = _KERNEL_SPLIT
    na = -(-n // split)
    st = sign * theta
    coarse = _expi(np.multiply.outer(st, j0 + split * np.arange(na, dtype=float)))  # (m, na)
    fine = _expi(np.multiply.outer(st, np.arange(split, dtype=float)))  # (m, split)
    kernel = (coarse[:, :, None] * fine[:, None, :]).reshape(theta.size, na * split)
    return kernel[:, :n]


def _direct(v, theta, n, adjoint):
    """Chunked direct sums over time j < n, at most _CHUNK_BYTES of temporaries.

    Forward: sum_j v[j] exp(-1j theta_i j), v (n, k) -> (m, k).
    Adjoint: sum_i v[i] exp(+1j theta_i j), v (m, k) -> (n, k).
    """
    chunk = max(1, _CHUNK_BYTES // (24 * theta.size))  # float phase + complex kernel
    out = np.zeros((n if adjoint else theta.size, v.shape[1]), dtype=complex)
    for j0 in range(0, n, chunk):
        j1 = min(n, j0 + chunk)
        if adjoint:
            out[j0:j1] = _kernel(theta, j0, j1, 1.0).T @ v
        else:
            out += _kernel(theta, j0, j1, -1.0) @ v[j0:j1]
    return out


def _czt_layout(theta, n):
    """Step, block length, block count and block-start phases theta_i * b B, (b, m)."""
    step = (theta[-1] - theta[0]) / (theta.size - 1)
    size = _block(n, theta.size, step)
    nblock = -(-n // size)
    # Block offsets use the given theta_i, so grid rounding only acts within a block.
    return step, size, nblock, np.outer(np.arange(nblock) * float(size), theta)


def _fast_len(n):
    """Smallest 2^a 3^b 5^c >= n (a fast numpy FFT length)."""
    best = 1 << max(0, (n - 1).bit_length())
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            p2 = p35
            while p2 < n:
                p2 *= 2
            best = min(best, p2)
            p35 *= 3
        p5 *= 5
    return best


def _chirpz(x, step, m):
    """y_k = sum_j x_j exp(-1j step k j), k < m, along the last axis (Bluestein's chirp-z).

    Written with numpy.fft rather than :class:`scipy.signal.ZoomFFT` because
    importing scipy.signal costs 0.5-1 s (it imports scipy.stats), which would
    more than double the run time of a whole ``fdml fit``.  As in ZoomFFT, the
    chirp phases step * j^2 / 2 are computed directly (not as powers of
    exp(-1j step)), so their rounding does not grow with j^2.
    """
    n = x.shape[-1]
    L = _fast_len(n + m - 1)
    j = np.arange(n, dtype=float)
    a = x * _expi(-0.5 * step * j * j)
    lags = np.r_[np.arange(m, dtype=float), np.zeros(L - n - m + 1), np.arange(-(n - 1), 0, dtype=float)]
    b = _expi(0.5 * step * lags * lags)
    b[m : L - n + 1] = 0.0
    c = np.fft.ifft(np.fft.fft(a, L, axis=-1) * np.fft.fft(b), axis=-1)[..., :m]
    k = np.arange(m, dtype=float)
    return c * _expi(-0.5 * step * k * k)


def _czt_forward(x, theta):
    """Forward _direct on an even grid: blocked chirp-z, O(n log m)."""
    n, k = x.shape
    step, size, nblock, offset = _czt_layout(theta, n)
    padded = np.zeros((nblock * size, k), dtype=complex)
    padded[:n] = x
    blocks = padded.reshape(nblock, size, k).transpose(0, 2, 1)  # (b, k, j')
    blocks = blocks * np.exp(-1j * theta[0] * np.arange(size))
    zoomed = _chirpz(blocks, step, theta.size)  # sum_j' e^{-1j step i j'}
    return np.einsum("bkm,bm->mk", zoomed, np.exp(-1j * offset))


def _czt_adjoint(z, theta, n):
    """Adjoint _direct on an even grid: blocked inverse-direction chirp-z."""
    k = z.shape[1]
    step, size, nblock, offset = _czt_layout(theta, n)
    weighted = np.exp(1j * offset)[:, None, :] * z.T[None, :, :]  # (b, k, m)
    part = _chirpz(weighted, -step, size) * np.exp(1j * theta[0] * np.arange(size))  # e^{+1j step i j'}
    return part.transpose(0, 2, 1).reshape(nblock * size, k)[:n]


def finite_fourier_transform(x, dt, omega, *, method="auto", end_correction="cubic"):
    """Finite Fourier transform X(w) = integral_0^T x(t) exp(-j w t) dt.

    Parameters
    ----------
    x : array_like, shape (n,) or (n, k)
        Uniformly sampled record(s), time along axis 0, real or complex, any
        unit u; t = 0 at the first sample and T = (n - 1) dt.
    dt : float
        Sample interval, s (> 0).
    omega : array_like, shape (m,)
        Angular frequencies, rad/s, in any order, ``|omega| <= pi/dt``.
    method : {"auto", "czt", "direct"}
        How the interior sum is evaluated: "czt" (blocked chirp-z, needs an
        evenly spaced omega), "direct" (chunked matrix products), or "auto"
        (czt on even grids when n * m >= 1e4, else direct).
    end_correction : {"cubic", "trapezoid", "none"}
        Quadrature: exact integral of the piecewise-cubic interpolant (error
        O(dt^4), needs n >= 4), trapezoid rule (O(dt^2)), or the plain
        rectangle sum dt * sum_j x_j exp(-j w t_j).

    Returns
    -------
    numpy.ndarray, complex, shape (m,) or (m, k)
        X(omega), in u * s.

    Raises
    ------
    RecordError
        x is not finite or too short, dt is not positive and finite.
    BandError
        omega is empty, not finite, above the Nyquist frequency pi/dt, or not
        evenly spaced with method="czt".
    """
    x2, n, dt, omega = _check(dt, omega, end_correction, method, x=x)
    theta, weight, alpha, tail = _setup(n, dt, omega, end_correction)
    czt = _choose_method(n, omega, method) == "czt"
    out = weight[:, None] * (_czt_forward(x2, theta) if czt else _direct(x2, theta, n, adjoint=False))
    nend = alpha.shape[1]
    if nend:
        out += alpha @ x2[:nend] + tail @ x2[::-1][:nend]
    out *= dt
    return out[:, 0] if np.ndim(x) == 1 else out


def transform_weights(n, dt, omega, *, end_correction="cubic"):
    """Explicit matrix F with finite_fourier_transform(x) == F @ x (for small problems).

    Parameters
    ----------
    n : int
        Number of samples.
    dt : float
        Sample interval, s (> 0).
    omega : array_like, shape (m,)
        Angular frequencies, rad/s, ``|omega| <= pi/dt``.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        Quadrature, as in :func:`finite_fourier_transform`.

    Returns
    -------
    numpy.ndarray, complex, shape (m, n)
        Quadrature weights, s (16 m n bytes).
    """
    _, n, dt, omega = _check(dt, omega, end_correction, "direct", n=n)
    theta, weight, alpha, tail = _setup(n, dt, omega, end_correction)
    mat = _kernel(theta, 0, n, -1.0) * weight[:, None]
    nend = alpha.shape[1]
    mat[:, :nend] += alpha
    mat[:, ::-1][:, :nend] += tail
    return mat * dt


def transform_columns(n, dt, omega, cols, *, end_correction="cubic"):
    """Columns ``cols`` of the transform matrix F (:func:`transform_weights`), in O(m len(cols)) work.

    Parameters
    ----------
    n : int
        Number of samples.
    dt : float
        Sample interval, s (> 0).
    omega : array_like, shape (m,)
        Angular frequencies, rad/s, ``|omega| <= pi/dt``.
    cols : array_like of int, shape (c,)
        Sample indices, 0 <= col < n.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        Quadrature, as in :func:`finite_fourier_transform`.

    Returns
    -------
    numpy.ndarray, complex, shape (m, c)
        ``F[:, cols]``, s: the transform of a unit sample at each column.
    """
    _, n, dt, omega = _check(dt, omega, end_correction, "direct", n=n)
    cols = np.asarray(cols, dtype=int)
    if cols.ndim != 1 or np.any((cols < 0) | (cols >= n)):
        raise RecordError(f"cols must be sample indices 0 .. {n - 1}, not {cols!r}")
    theta, weight, alpha, tail = _setup(n, dt, omega, end_correction)
    out = weight[:, None] * _expi(-np.outer(theta, cols.astype(float)))
    for k in range(alpha.shape[1]):  # the end-corrected samples: a_k on the left, the tail on the right
        out[:, cols == k] += alpha[:, k : k + 1]
        out[:, cols == n - 1 - k] += tail[:, k : k + 1]
    return out * dt


def _dirichlet(x, n):
    """sum_{j<n} exp(-1j x j) = exp(-1j x (n-1)/2) sin(n x/2) / sin(x/2), n where x = 0."""
    half = 0.5 * x
    s2 = np.sin(half)
    phase = _expi(-(n - 1) * half)
    tiny = np.abs(s2) < 1e-14
    ratio = np.where(tiny, float(n), np.sin(n * half) / np.where(tiny, 1.0, s2))
    return phase * ratio


def gram(n, dt, omega, *, end_correction="cubic"):
    """Gram matrices F F^H and F F^T of the transform map F (m x n), in O(m^2) work.

    The interior weights dt W_i exp(-1j theta_i j) sum in closed form (a
    Dirichlet kernel); the 2K end-corrected samples are added explicitly.  Used
    to carry white time-domain noise into the covariance of estimates without
    touching the n samples: E{v v^H} = sigma^2 F F^H, E{v v^T} = sigma^2 F F^T.
    A record of fewer than 2K + 1 samples (no interior) takes the explicit
    weights instead (:func:`gram_form` says which).  The matrices are kept per
    (n, dt, grid, end correction) for grids of at most 256 frequencies and
    returned read-only, so a fit's passes, its records and its adequacy check
    build them once.

    Parameters
    ----------
    n : int
        Number of samples.
    dt : float
        Sample interval, s (> 0).
    omega : array_like, shape (m,)
        Angular frequencies, rad/s, ``|omega| <= pi/dt``.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        Quadrature, as in :func:`finite_fourier_transform`.

    Returns
    -------
    FFH : numpy.ndarray, complex, shape (m, m)
        F F^H, s^2 (read-only).
    FFT : numpy.ndarray, complex, shape (m, m)
        F F^T, s^2 (read-only).
    """
    _, n, dt, omega = _check(dt, omega, end_correction, "direct", n=n)
    if omega.size > _MEMO_MAX_GRAM:
        return _read_only(*_gram_arrays(n, dt, omega, end_correction))
    return _gram_memo(*_memo_key(n, dt, omega, end_correction))


def gram_form(n, end_correction="cubic") -> str:
    """How :func:`gram` sums a record of ``n`` samples: ``"closed form"`` or ``"direct sum"``.

    Parameters
    ----------
    n : int
        Number of samples.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        Quadrature, as in :func:`finite_fourier_transform`.

    Returns
    -------
    str
        ``"closed form"`` (Dirichlet sums of the interior plus the end
        columns) when the record has an interior sample between its two
        end-corrected stretches, else ``"direct sum"`` (the explicit weights).
    """
    return "closed form" if n >= 2 * _N_END[end_correction] + 1 else "direct sum"


@functools.lru_cache(maxsize=_MEMO_SIZE)
def _gram_memo(n, dt, omega_bytes, end_correction):
    return _read_only(*_gram_arrays(n, dt, np.frombuffer(omega_bytes), end_correction))


def _gram_arrays(n, dt, omega, end_correction):
    """:func:`gram` after its checks."""
    if gram_form(n, end_correction) == "direct sum":
        F = transform_weights(n, dt, omega, end_correction=end_correction)
        return F @ F.conj().T, F @ F.T
    theta, weight, alpha, tail = _setup(n, dt, omega, end_correction)
    nend = alpha.shape[1]
    ww = np.outer(weight, weight)
    m = theta.size
    if m > 2 and is_evenly_spaced(omega):
        # Toeplitz and Hankel structure: 2m - 1 kernel values each instead of m^2
        step = (theta[-1] - theta[0]) / (m - 1)
        i = np.arange(m)
        lag = np.arange(-(m - 1), m) * step
        FFH = ww * _dirichlet(lag, n)[i[:, None] - i[None, :] + m - 1]
        FFT = ww * _dirichlet(2 * theta[0] + np.arange(2 * m - 1) * step, n)[i[:, None] + i[None, :]]
    else:
        FFH = ww * _dirichlet(theta[:, None] - theta[None, :], n)
        FFT = ww * _dirichlet(theta[:, None] + theta[None, :], n)
    if nend:
        cols = np.r_[np.arange(nend), n - 1 - np.arange(nend)].astype(float)
        interior = weight[:, None] * _expi(-np.outer(theta, cols))  # (m, 2K)
        ends = np.concatenate([alpha, tail], axis=1)  # corrections at those columns
        FFH += interior @ ends.conj().T + ends @ interior.conj().T + ends @ ends.conj().T
        FFT += interior @ ends.T + ends @ interior.T + ends @ ends.T
    return FFH * dt**2, FFT * dt**2


def leading_transform(weights, n, dt, omega, *, end_correction="cubic"):
    """Transform of a vector that is zero after its first L samples, in O(m L) work.

    Parameters
    ----------
    weights : array_like, shape (L,)
        The leading samples (the rest of the n-sample record is zero).
    n : int
        Number of samples.
    dt : float
        Sample interval, s (> 0).
    omega : array_like, shape (m,)
        Angular frequencies, rad/s, ``|omega| <= pi/dt``.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        Quadrature, as in :func:`finite_fourier_transform`.

    Returns
    -------
    numpy.ndarray, complex, shape (m,)
        The transform, in the unit of ``weights`` times s.
    """
    w = np.asarray(weights, dtype=float)
    _, n, dt, omega = _check(dt, omega, end_correction, "direct", n=n)
    L = w.size
    theta, weight, alpha, tail = _setup(n, dt, omega, end_correction)
    nend = alpha.shape[1]
    if L > n - nend:  # the leading samples reach the end-corrected ones: the full transform
        return finite_fourier_transform(np.r_[w, np.zeros(n - L)], dt, omega, end_correction=end_correction)
    out = weight * (_kernel(theta, 0, L, -1.0) @ w)
    k = min(L, nend)
    out += alpha[:, :k] @ w[:k]
    return out * dt


def fourier_adjoint(y, n, dt, omega, *, method="auto", end_correction="cubic"):
    """Adjoint of the finite Fourier transform: F^H @ y, without forming F.

    Parameters
    ----------
    y : array_like, shape (m,) or (m, k)
        Values on the frequency grid, any unit v.
    n : int
        Number of time samples of the result.
    dt : float
        Sample interval, s (> 0).
    omega : array_like, shape (m,)
        Angular frequencies, rad/s, ``|omega| <= pi/dt``.
    method : {"auto", "czt", "direct"}, optional
        As in :func:`finite_fourier_transform`.  "czt" runs an inverse-direction
        blocked chirp-z over the time samples: O(n log m) time, O(n) memory;
        "direct" uses chunks of at most 32 MB.  F is never formed.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        Quadrature, as in :func:`finite_fourier_transform`.

    Returns
    -------
    numpy.ndarray, complex, shape (n,) or (n, k)
        The product conj(F).T @ y, in v * s, such that vdot(F x, y) == vdot(x, F^H y).
    """
    _, n, dt, omega = _check(dt, omega, end_correction, method, n=n)
    y = np.asarray(y)
    if y.ndim not in (1, 2) or y.shape[0] != omega.size or not np.all(np.isfinite(y)):
        raise BandError(f"y must be finite, of shape ({omega.size},) or ({omega.size}, k); got shape {y.shape}")
    y2 = y.reshape(omega.size, -1).astype(complex)
    theta, weight, alpha, tail = _setup(n, dt, omega, end_correction)
    czt = _choose_method(n, omega, method) == "czt"
    wy = weight[:, None] * y2
    out = _czt_adjoint(wy, theta, n) if czt else _direct(wy, theta, n, adjoint=True)
    nend = alpha.shape[1]
    out[:nend] += alpha.conj().T @ y2
    out[::-1][:nend] += tail.conj().T @ y2
    out *= dt
    return out[:, 0] if y.ndim == 1 else out
