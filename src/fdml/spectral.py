"""From a record to its spectra: trim removal and the finite Fourier transform.

:func:`spectra` turns a :class:`~fdml.record.Record` into
:class:`FrequencyData`: the transforms (docs/theory.md Eq. 11) of the outputs and
inputs at the chosen frequencies, the measured boundary values used by Klein's
boundary terms (docs/theory.md section 7), the transform of a unit constant (the
regressor of an output bias), and what is needed to carry white time-domain
noise through the transform into the estimator's covariance.  It knows nothing
of models.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from . import fourier
from .channels import ALL_OUTPUTS, GUST, INPUTS, OUTPUTS, boundary_channels, row_space
from .errors import BandError, RecordError
from .jsoncodec import Codec, Spec, complexes, floats, integer, nested, numbers, text, texts
from .record import TRIM_MODES, Record

__all__ = ["FrequencyData", "spectra", "parse_band", "band_numbers", "DEFAULT_BAND", "DEFAULT_STEP"]

#: The paper's grid: 0.1 to 10 rad/s at 0.1 rad/s ("10 points per radian").
DEFAULT_BAND = (0.1, 10.0, 0.1)
#: The step of a band given without one (``LO:HI``), rad/s: the default band's.
DEFAULT_STEP = DEFAULT_BAND[2]


def parse_band(
    band, *, what: str = "band", positive: bool = True, dt: float | None = None
) -> tuple[float, float, float]:
    """Normalise and check a band given as ``"LO:HI[:STEP]"`` or ``(lo, hi[, step])`` (rad/s).

    fdml's one band syntax, for every command and call that takes a band: without a
    step, the step is :data:`DEFAULT_STEP` (0.1 rad/s, the default band's).

    The one band parser of the commands and the library calls that take a
    grid (the fit, the checks, the response, the experiment design).

    Parameters
    ----------
    band : tuple, str or None
        None gives :data:`DEFAULT_BAND`.
    what : str, optional
        How the band is named in messages (``"--band"`` on the command line).
    positive : bool, optional
        Require ``lo > 0`` (default: a fit band; the output-bias regressor is
        singular at 0 rad/s).  ``fdml response`` accepts 0.
    dt : float, optional
        Sample interval, s: refuse a band whose upper edge is not below the
        Nyquist frequency pi/dt.

    Returns
    -------
    lo : float
        Lowest frequency, rad/s.
    hi : float
        Highest frequency, rad/s.
    step : float
        Frequency step, rad/s.

    Raises
    ------
    BandError
        A malformed band, one :func:`fdml.fourier.check_band` refuses
        (non-finite, ``hi < lo``, ``step <= 0``, too many frequencies), or
        one reaching the Nyquist frequency, so a command can refuse it
        before any work starts.
    """
    if band is None:
        return DEFAULT_BAND
    lo, hi, *given = band_numbers(band, (2, 3), what=what, example="0.1:10:0.1")
    step = given[0] if given else DEFAULT_STEP
    lo, hi, step, _ = fourier.check_band(lo, hi, step, what=what, positive=positive)
    if dt is not None and hi >= math.pi / dt:
        raise BandError(
            f"{what} edge {hi:g} rad/s is not below the Nyquist frequency pi/dt = {math.pi / dt:.4g} rad/s; "
            "lower the band or sample faster"
        )
    return lo, hi, step


def band_numbers(band, sizes: tuple[int, ...], *, what: str = "band", example: str) -> list[float]:
    """The numbers of a band written ``"A:B[:C]"`` or given as a sequence, before any range check.

    Parameters
    ----------
    band : str or sequence
        ``"LO:HI:STEP"`` (or ``"LO:HI"``) or a sequence of numbers, rad/s.
    sizes : tuple of int
        How many numbers are accepted: ``(3,)`` for LO:HI:STEP, ``(2, 3)`` for LO:HI with an optional step.
    what : str, optional
        How the band is named in messages (``"--band"`` on the command line).
    example : str
        A valid band, shown in the message for a malformed string.

    Returns
    -------
    list of float
        The numbers, rad/s, as many as given.

    Raises
    ------
    BandError
        A string or sequence with another count of parts, or parts that are not numbers.
    """
    forms: dict[tuple[int, ...], str] = {(3,): "LO:HI:STEP", (2,): "LO:HI"}
    form = forms.get(tuple(sizes), "LO:HI[:STEP]")
    if isinstance(band, str):
        parts = band.split(":")
        if len(parts) not in sizes:
            raise BandError(f"{what} {band!r} must be {form} in rad/s, e.g. {example}")
        try:
            return [float(x) for x in parts]
        except ValueError:
            raise BandError(f"{what} {band!r} must be numbers {form} in rad/s") from None
    try:
        vals = [float(x) for x in band]
    except (TypeError, ValueError):
        vals = []
    if len(vals) not in sizes:
        raise BandError(f"{what} {band!r} must be {form} in rad/s, as a string or a sequence of numbers")
    return vals


def _edge_steps_field(f, key: str, done: dict) -> np.ndarray:
    """The steps' sizes of a spectra object in JSON: one per entry of ``edges`` (absent: none)."""
    n = len(done.get("edges", ()))
    steps = f.floats(key, (None,))
    if steps.size != n:
        raise f.error(key, f"has {steps.size} values for the {n} elevator steps of 'edges'")
    return steps


def _outputs_field(f, key: str, done: dict) -> tuple[str, ...]:
    """The outputs of a spectra object in JSON, in row order, matching its ``z`` columns and ``x0``, ``xT``."""
    rows = f.strings(key, choices=ALL_OUTPUTS)
    if rows != row_space(rows):
        raise f.error(key, f"is {list(rows)}: outputs in the order {', '.join(row_space(rows))} expected")
    if done["z"].shape[1] != len(rows):
        raise f.error("z", f"has {done['z'].shape[1]} columns for the {len(rows)} outputs {', '.join(rows)}")
    nb = len(boundary_channels(rows))
    for k in ("x0", "xT"):
        if done[k].size != nb:
            raise f.error(k, f"has {done[k].size} values for the {nb} boundary channels of outputs {', '.join(rows)}")
    return rows


@dataclass(frozen=True)
class FrequencyData(Codec):
    """Spectra of one record at a set of frequencies.

    Parameters
    ----------
    name : str
        Record name.
    omega : ndarray, shape (m,)
        Frequencies, rad/s.
    z : ndarray, shape (m, n_y)
        Measured output transforms, one column per output of ``outputs``
        (alpha rad s, q rad, az g s[, theta rad s, qdot rad]).
    u : ndarray, shape (m, n_in)
        Input transforms (de[, alpha_w]), rad s.
    inputs : tuple of str
        Names of the columns of ``u``.
    x0, xT : ndarray, shape (n_b,)
        Measured alpha (rad), q (rad/s)[, theta (rad)] at the first and last
        sample, after trim removal (for measured boundary terms): the channels
        of :func:`fdml.channels.boundary_channels`.
    T : float
        Record length (n - 1) dt, s.
    dt : float
        Sample interval, s.
    n : int
        Number of samples.
    ones : ndarray, shape (m,)
        Transform of a unit constant over the record: the regressor of an
        output bias (``(1 - exp(-j w T))/(j w)`` to the accuracy of the
        end-corrected quadrature).
    trim_mode : str
        How trim was removed (``first``, ``mean``, ``none``).
    trim_samples : int
        Samples averaged to find trim (1 for ``first``, 0 for ``none``).
    end_correction : str
        End correction used by the transform.
    band : tuple
        (lo, hi, step), rad/s, when built from a band.
    end_offset : ndarray, shape (n_y,)
        ``|x(T) - trim| / max|x - trim|`` per output: how far from trim it ends.
    meta : dict
        The record's meta data (airspeed, source, trim values).
    outputs : tuple of str
        The outputs of the columns of ``z`` (:func:`fdml.channels.row_space`).
    edges : ndarray, shape (K,)
        Middles of the sample intervals in which the elevator steps
        (:func:`fdml.fourier.step_edges`), s from the first sample: where the
        transform puts steps whose time the record does not keep.
    edge_steps : ndarray, shape (K,)
        The elevator's change across each of those intervals, rad.
    record : Record or None
        The time-domain record as given (before trim removal), kept for
        time-domain cross-checks, plots and reports.
    """

    name: str
    omega: np.ndarray
    z: np.ndarray
    u: np.ndarray
    inputs: tuple
    x0: np.ndarray
    xT: np.ndarray
    T: float
    dt: float
    n: int
    ones: np.ndarray
    trim_mode: str = "first"
    trim_samples: int = 1
    end_correction: str = "cubic"
    band: tuple | None = None
    end_offset: np.ndarray = field(default_factory=lambda: np.zeros(len(OUTPUTS)))
    meta: dict = field(default_factory=dict)
    outputs: tuple = OUTPUTS
    edges: np.ndarray = field(default_factory=lambda: np.zeros(0))
    edge_steps: np.ndarray = field(default_factory=lambda: np.zeros(0))
    record: Record | None = field(default=None, repr=False, compare=False)

    json_fields = {
        "omega": floats(None),
        "z": complexes("omega", None),
        "u": complexes("omega", None),
        "inputs": texts(),
        "x0": floats(None),  # alpha, q[, theta]: the boundary channels of the outputs (checked with them)
        "xT": floats(None),
        "n": integer(0),
        "ones": complexes("omega"),
        "trim_mode": text(TRIM_MODES),
        "trim_samples": integer(0),
        "end_correction": text(fourier.END_CORRECTIONS),
        "band": numbers(3, none=True),
        "end_offset": floats(None),
        "outputs": Spec(_outputs_field),
        "edges": floats(None),
        "edge_steps": Spec(_edge_steps_field),
        "record": nested(Record, none=True),
    }
    json_source = "spectra"

    @property
    def m(self) -> int:
        """Number of frequencies."""
        return self.omega.size

    def boundary(self) -> np.ndarray:
        """Measured boundary vector d = x(0) - x(T) exp(-j w T), shape (m, n_b) (docs/theory.md section 7).

        Returns
        -------
        numpy.ndarray
            Complex, shape (m, n_b): the alpha (rad s), q (rad)[, theta (rad s)] columns.
        """
        from .models.measurement import boundary_vector, end_shift

        return boundary_vector(self.x0, self.xT, end_shift(self.omega, self.T))

    def independent_frequencies(self) -> float:
        """Approximate number of independent frequencies, (band width) T / (2 pi) + 1.

        Returns
        -------
        float
            The number (not rounded).
        """
        return (self.omega.max() - self.omega.min()) * self.T / (2 * math.pi) + 1.0

    # --- noise propagation ------------------------------------------------------------
    def trim_vector(self) -> np.ndarray | None:
        """Weights l with trimmed x = x - (l . x) 1, or None when no trim was removed.

        Returns
        -------
        numpy.ndarray or None
            Shape (n,): ``1 / trim_samples`` on the leading ``trim_samples`` samples, 0 elsewhere.
        """
        if self.trim_mode == "none" or self.trim_samples == 0:
            return None
        ell = np.zeros(self.n)
        ell[: self.trim_samples] = 1.0 / self.trim_samples
        return ell

    def noise_gain(self, include_trim: bool = True) -> np.ndarray:
        """E|v(w_i)|^2 for unit-variance white noise on a channel, shape (m,).

        ``v = F P e`` where F is the end-corrected transform and P the trim
        removal; so ``s_i = ||F_i||^2 - 2 Re(conj(b_i) (F l)_i) + |b_i|^2 ||l||^2``
        with ``b = F 1``.  ``||F_i||^2`` is exact: the weights of interior
        samples all have modulus ``dt |W(w dt)|``, and the end-corrected
        samples are taken from a short record.  With ``include_trim=False``
        only ``||F_i||^2`` is returned: the trim error is a constant offset, so
        a fit with output biases absorbs it completely.

        Parameters
        ----------
        include_trim : bool, optional
            Include the error of the trim removal.

        Returns
        -------
        numpy.ndarray
            The expected power ``s_i``, shape (m,), in s^2 per unit noise variance.
        """
        if self.n >= 16 and self.end_correction in fourier.END_CORRECTIONS:
            # interior weights dt W e^{-j theta n}; the first K samples carry dt (W e^{-j theta k} + a_k)
            # and the last K the conjugate pattern, whose modulus is the same
            theta, W, a, _ = fourier._setup(self.n, self.dt, self.omega, self.end_correction)
            K = a.shape[1]
            k = np.arange(K)
            ends = np.abs(W[:, None] * np.exp(-1j * np.outer(theta, k)) + a) ** 2
            row = self.dt**2 * (W**2 * (self.n - 2 * K) + 2 * ends.sum(axis=1))
        else:
            row = np.sum(
                np.abs(fourier.transform_weights(self.n, self.dt, self.omega, end_correction=self.end_correction)) ** 2,
                axis=1,
            )
        ell = self.trim_vector()
        if ell is None or not include_trim:
            return row
        Fl = fourier.finite_fourier_transform(ell, self.dt, self.omega, end_correction=self.end_correction)
        b = self.ones
        return row - 2.0 * np.real(np.conj(b) * Fl) + np.abs(b) ** 2 * float(ell @ ell)

    def noise_gram(self) -> tuple[np.ndarray, np.ndarray]:
        """(Psi, Phi) = ((F P)(F P)^H, (F P)(F P)^T), shape (m, m) each, in O(m^2) work.

        With v = F P e for unit white noise e, ``E{v v^H} = Psi`` and
        ``E{v v^T} = Phi``.  ``P = I - 1 l^T`` removes the trim, so
        ``F P (F P)^H = F F^H - f b^H - b f^H + |l|^2 b b^H`` with ``b = F 1``
        and ``f = F l`` (:func:`fdml.fourier.gram`, ``leading_transform``).

        Kept, like :func:`fdml.fourier.gram`, per (n, dt, grid, end correction,
        trim samples, ``ones``) for grids of at most 256 frequencies, so the
        records of a study or of a joint fit on one grid share them.

        Returns
        -------
        Psi : numpy.ndarray
            ``E{v v^H}``, complex, shape (m, m), s^2 per unit noise variance (read-only).
        Phi : numpy.ndarray
            ``E{v v^T}``, complex, shape (m, m), s^2 per unit noise variance (read-only).
        """
        L = 0 if self.trim_vector() is None else self.trim_samples
        if self.m > fourier._MEMO_MAX_GRAM:
            return _noise_gram(self.n, self.dt, self.omega, self.end_correction, L, self.ones)
        key = fourier._memo_key(self.n, self.dt, self.omega, self.end_correction)
        return _noise_gram_memo(*key, L, np.ascontiguousarray(self.ones, dtype=complex).tobytes())

    def noise_adjoint(self, y: np.ndarray) -> np.ndarray:
        """Apply ``(F P)^T`` to frequency-domain weights: ``sum_i (F P)_in y_i``.

        Parameters
        ----------
        y : ndarray, shape (m, k)
            Complex weights, one column per combination of the frequencies.

        Returns
        -------
        ndarray, shape (n, k), complex
            Row n holds how a unit noise sample at time n enters ``sum_i y_i v_i``.
        """
        # F^T y = conj(F^H conj(y))
        out = np.conj(
            fourier.fourier_adjoint(np.conj(y), self.n, self.dt, self.omega, end_correction=self.end_correction)
        )
        ell = self.trim_vector()
        if ell is not None:
            out = out - ell[:, None] * out.sum(axis=0, keepdims=True)  # P^T = I - l 1^T
        return out


@functools.lru_cache(maxsize=fourier._MEMO_SIZE)
def _noise_gram_memo(n, dt, omega_bytes, end_correction, L, ones_bytes):
    omega, ones = np.frombuffer(omega_bytes), np.frombuffer(ones_bytes, dtype=complex)
    return _noise_gram(n, dt, omega, end_correction, L, ones)


def _noise_gram(n, dt, omega, end_correction, L, ones):
    """(Psi, Phi) of :meth:`FrequencyData.noise_gram`, read-only; ``L`` leading samples make the trim (0: none)."""
    GH, GT = fourier.gram(n, dt, omega, end_correction=end_correction)
    if L == 0:
        return GH, GT
    f = fourier.leading_transform(np.full(L, 1.0 / L), n, dt, omega, end_correction=end_correction)  # F l
    b = ones
    l2 = 1.0 / L  # |l|^2
    Psi = GH - np.outer(f, b.conj()) - np.outer(b, f.conj()) + l2 * np.outer(b, b.conj())
    Phi = GT - np.outer(f, b) - np.outer(b, f) + l2 * np.outer(b, b)
    return fourier._read_only(Psi, Phi)


def spectra(
    record: Record,
    omega=None,
    *,
    band=None,
    trim: str = "first",
    trim_window: float = 0.5,
    end_correction: str = "cubic",
    method: str = "auto",
    outputs=None,
) -> FrequencyData:
    """Transform a record to the frequency domain.

    Parameters
    ----------
    record : Record
        Time histories (SI, radians, a_z in g).
    omega : array_like, optional
        Frequencies, rad/s.  Default: the band grid.
    band : tuple or str, optional
        ``(lo, hi, step)`` rad/s or ``"LO:HI:STEP"``; default 0.1:10:0.1.
    trim : {"first", "mean", "none"}, optional
        Trim removal: first sample (default), mean of the leading
        ``trim_window`` seconds, or none (the record is already perturbations).
    trim_window : float, optional
        Leading window for ``trim="mean"``, s.
    end_correction : {"cubic", "trapezoid", "none"}, optional
        End correction of the finite Fourier integral (default cubic).
    method : {"auto", "czt", "direct"}, optional
        Transform algorithm.
    outputs : sequence of str, optional
        Outputs beyond alpha, q and a_z to transform (``theta``, ``qdot``:
        :func:`fdml.channels.row_space`); the record must hold them.

    Returns
    -------
    FrequencyData
        The spectra of the record's outputs and inputs at the frequencies.
    """
    if not isinstance(record, Record):
        raise RecordError(f"expected an fdml Record, got {type(record).__name__}")
    band_t = None
    if omega is None:
        band_t = parse_band(band)
        omega = fourier.omega_band(*band_t)
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    if omega.size == 0:
        raise BandError("the frequency band is empty")
    if np.any(omega <= 0):
        raise BandError(f"frequencies must be positive rad/s; got {omega.min():g}")
    nyq = record.nyquist
    if omega.max() > nyq:
        raise BandError(
            f"band reaches {omega.max():g} rad/s, above the Nyquist frequency {nyq:.4g} rad/s "
            f"of record {record.name!r} (dt = {record.dt:g} s)"
        )
    if record.duration * omega.max() < 2 * math.pi:
        raise BandError(
            f"record {record.name!r} is {record.duration:.3g} s long, shorter than one period "
            f"({2 * math.pi / omega.max():.3g} s) of the highest band frequency {omega.max():g} rad/s: "
            "too few samples for this band"
        )
    rows = _rows(record, outputs)
    rec = record.remove_trim(trim, window=trim_window)
    outs = np.column_stack([rec[k] for k in rows])
    inputs = INPUTS if rec.has(GUST) else INPUTS[:1]
    ins = [rec[k] for k in inputs]
    X = fourier.finite_fourier_transform(
        np.column_stack([outs, *ins, np.ones(rec.n)]), rec.dt, omega, method=method, end_correction=end_correction
    )
    steps = fourier.step_edges(rec["de"])
    peak = np.max(np.abs(outs), axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        end_offset = np.where(peak > 0, np.abs(outs[-1]) / peak, 0.0)
    return FrequencyData(
        name=rec.name,
        omega=omega,
        z=X[:, : len(rows)],
        u=X[:, len(rows) : len(rows) + len(inputs)],
        inputs=inputs,
        x0=np.array([rec[c][0] for c in boundary_channels(rows)]),
        xT=np.array([rec[c][-1] for c in boundary_channels(rows)]),
        T=rec.duration,
        dt=rec.dt,
        n=rec.n,
        ones=X[:, -1],
        trim_mode=trim,
        trim_samples=int(rec.meta.get("trim_samples", 0)) if trim != "none" else 0,
        end_correction=end_correction,
        band=band_t,
        end_offset=end_offset,
        meta=dict(rec.meta),
        outputs=rows,
        edges=(steps + 0.5) * rec.dt,
        edge_steps=rec["de"][steps + 1] - rec["de"][steps],
        record=record,
    )


def _rows(record: Record, outputs) -> tuple[str, ...]:
    """:func:`fdml.channels.row_space` of ``outputs``, each held by ``record`` (else a RecordError naming it)."""
    try:
        rows = row_space(outputs)
    except ValueError as exc:
        raise RecordError(str(exc)) from None
    missing = [k for k in rows if not record.has(k)]
    if missing:
        raise RecordError(f"record {record.name!r} has no {', '.join(missing)} column: it cannot be fitted there")
    return rows
