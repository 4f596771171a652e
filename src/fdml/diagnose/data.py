"""The analysis grid: spectra at twice the independent frequency spacing.

The Fourier coefficients of white noise over a record of length T are
independent only at spacings 2 pi/T (docs/theory.md section 7).  Every test here
counts independent frequencies, so the diagnosis builds its own grid per
record,

    omega_k = (2 pi / T) k / K,   K = ``oversample`` (default 2),

and uses it as follows:

* the fits (base model and candidates) use all K-grid points: with K = 2 the
  boundary terms x(0) and x(T) of Klein's transient are separable
  (exp(-j omega T) alternates between +1 and -1; on the exact 2 pi/T grid they
  are collinear) and the output-bias regressor is nonzero;
* likelihood-ratio statistics are divided by K (the K-grid sum counts every
  independent frequency K times for signatures that are smooth over 2 pi/T;
  verified by simulation in tests/test_diagnose_stats.py);
* the gap map uses only the DFT points (k a multiple of K), whose noise is
  independent, so its F tests are exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..channels import INPUTS
from ..errors import BandError, RecordError
from ..fourier import check_band
from ..record import Record
from ..spectral import band_numbers, spectra

__all__ = ["AnalysisData", "analysis_data", "parse_diag_band", "DEFAULT_DIAG_BAND"]

#: Default analysis band, rad/s: fdml's default fit band (docs/theory.md 11.2: 0-10 rad/s).
DEFAULT_DIAG_BAND = (0.1, 10.0)


def parse_diag_band(band) -> tuple[float, float]:
    """``(lo, hi)`` from ``(lo, hi)``, ``(lo, hi, step)`` or ``"LO:HI[:STEP]"`` (rad/s).

    A step is accepted for compatibility with ``fdml fit --band`` and ignored:
    the diagnosis uses the spacing 2 pi/(K T) of each record (see module doc).

    Parameters
    ----------
    band : tuple, str or None
        The band (None: :data:`DEFAULT_DIAG_BAND`).

    Returns
    -------
    lo : float
        Lowest frequency, rad/s.
    hi : float
        Highest frequency, rad/s.
    """
    if band is None:
        return DEFAULT_DIAG_BAND
    lo, hi = band_numbers(band, (2, 3), example="0.3:12")[:2]
    check_band(lo, hi, None, what="band", positive=True)  # fdml's one band check (no grid here)
    if not lo < hi:
        raise BandError(f"band must satisfy 0 < lo < hi (rad/s), got {lo:g}:{hi:g}")
    return lo, hi


@dataclass(frozen=True)
class AnalysisData:
    """Spectra of the records on the analysis grid.

    Parameters
    ----------
    spectra : tuple of FrequencyData
        One per record, on its K-grid inside the band.
    dft : tuple of ndarray of bool
        Per record, which grid points are DFT points (independent spacing).
    oversample : int
        Grid points K per independent frequency spacing 2 pi/T.
    band : (float, float)
        Analysis band, rad/s.
    inputs : tuple of str
        Inputs present in every record (``de`` and possibly ``alpha_w``).
    """

    spectra: tuple
    dft: tuple
    oversample: int
    band: tuple
    inputs: tuple

    @property
    def n_records(self) -> int:
        """Number of records analysed together."""
        return len(self.spectra)

    @property
    def n_dft(self) -> int:
        """Independent frequencies (DFT points) over all records."""
        return int(sum(int(m.sum()) for m in self.dft))

    def stacked_omega(self) -> np.ndarray:
        """Frequencies of the stacked residual rows (records in order).

        Returns
        -------
        numpy.ndarray
            Shape (N,), rad/s.
        """
        return np.concatenate([d.omega for d in self.spectra])

    def stacked_dft(self) -> np.ndarray:
        """Which stacked rows are DFT points (independent frequencies), records in order.

        Returns
        -------
        numpy.ndarray
            Shape (N,), bool.
        """
        return np.concatenate(self.dft)

    def stacked_record(self) -> np.ndarray:
        """For each stacked frequency, the index of its record.

        Returns
        -------
        numpy.ndarray
            Shape (N,), int.
        """
        return np.concatenate([np.full(d.m, i) for i, d in enumerate(self.spectra)])

    def names(self) -> list[str]:
        """The records' names, in order.

        Returns
        -------
        list of str
            One name per record.
        """
        return [d.name for d in self.spectra]


def _grid(T: float, lo: float, hi: float, K: int) -> tuple[np.ndarray, np.ndarray]:
    step = 2.0 * math.pi / (K * T)
    k0 = max(int(math.ceil(lo / step - 1e-9)), 1)
    k1 = int(math.floor(hi / step + 1e-9))
    k = np.arange(k0, k1 + 1)
    return k * step, (k % K) == 0


def analysis_data(
    records, band=None, *, oversample: int = 2, trim: str = "first", gust: bool | None = None, outputs=None
) -> AnalysisData:
    """Transform records onto the analysis grid.

    Parameters
    ----------
    records : Record or sequence of Record
        The flight records.
    band : tuple or str, optional
        ``(lo, hi)`` rad/s (default 0.1-10); see :func:`parse_diag_band`.
    oversample : int, optional
        K >= 1 (default 2).
    trim : str, optional
        Trim removal passed to :func:`fdml.spectral.spectra`.
    gust : bool, optional
        Keep the alpha_w input (default: when every record has it).
    outputs : sequence of str, optional
        The model's output rows (theta, q_dot beside alpha, q and a_z), as :func:`fdml.spectral.spectra`.

    Returns
    -------
    AnalysisData
        The spectra on each record's K-grid and the masks of its DFT points.
    """
    items = [records] if isinstance(records, Record) else list(records or [])
    if not items:
        raise RecordError("no records were given to diagnose")
    for r in items:
        if not isinstance(r, Record):
            raise RecordError(f"diagnose needs fdml Records, got {type(r).__name__}")
    if int(oversample) != oversample or oversample < 1:
        raise BandError(f"oversample must be a positive integer, got {oversample!r}")
    K = int(oversample)
    lo, hi = parse_diag_band(band)
    out, masks = [], []
    names = [r.name for r in items]
    for i, r in enumerate(items):
        omega, dft = _grid(r.duration, lo, hi, K)
        if int(dft.sum()) < 2:
            raise BandError(
                f"record {r.name!r} ({r.duration:.3g} s) has fewer than two independent frequencies "
                f"(spacing 2 pi/T = {2 * math.pi / r.duration:.3g} rad/s) in the band {lo:g}-{hi:g} rad/s: "
                "too short for a diagnosis in this band"
            )
        d = spectra(r, omega, trim=trim, outputs=outputs)
        if names.count(r.name) > 1:
            d = replace(d, name=f"{r.name}#{i}")
        out.append(d)
        masks.append(dft)
    has_gust = all("alpha_w" in d.inputs for d in out)
    gust = has_gust if gust is None else gust
    if gust and not has_gust:
        raise RecordError("the model has a gust input but not every record has an alpha_w column")
    if not gust:
        out = [replace(d, u=d.u[:, :1], inputs=("de",)) if d.u.shape[1] > 1 else d for d in out]
    return AnalysisData(tuple(out), tuple(masks), K, (lo, hi), INPUTS if gust else INPUTS[:1])
