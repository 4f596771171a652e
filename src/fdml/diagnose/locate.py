"""Locate: the gap map, channel by frequency band.

For each output channel c and band b, on the independent DFT points of every
record in the band (see :mod:`fdml.diagnose.data`), the fitted model's
residual e_c is regressed on

* a *coherent* part: the model's forced response to each input j,
  ``y_jc(w) = G_jc(w) u_j(w)``, times a low-order polynomial in w
  (Legendre, level and slope across the band): ``delta_j(w) y_jc(w)`` is a
  relative error of the model's frequency response, i.e. gain and phase;
* a *transient* part per record: a constant (what is left of Klein's boundary
  terms after the fit).

The residual energy splits into the coherent part (input-correlated model
error: it would repeat on a repeated manoeuvre; the coefficients are shared
by all records) and the incoherent remainder.  The remainder, divided by its
degrees of freedom, is the **noise floor** of the cell: the part of the
misfit that is neither a smooth function of frequency times the input nor a
transient.  It is estimated per cell, so it follows coloured noise from band
to band and does not depend on the model being right (model error that is
smooth over the band goes to the coherent part).  Under "no model error" the
ratio of the coherent energy per coefficient to the floor is exactly
F(2 k_C, 2 nu) distributed for noise that is white within the band (the
p-value of the cell; it ignores the fit's leverage, which makes it slightly
conservative).

Per cell the report gives the excess (coherent energy in floor units minus
its noise-only expectation, so 0 under no error), the gain error in dB and
phase error in degrees of the model against this nonparametric estimate of
the frequency response (the band average of 1 + delta_de), their 95 %
confidence bounds, the p-value, Holm's adjusted p-value across the cells
("significant", family level alpha) and Benjamini-Hochberg's q-value.  A cell
whose gain error cannot be resolved to better than 3 dB (one standard error)
is marked "insufficient excitation" and is not tested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import stats

from ..channels import OUTPUTS
from ..jsoncodec import Fields
from ..score import bh, holm  # the family-wise corrections live with the score tests
from .data import AnalysisData

__all__ = ["Cell", "GapMap", "default_bands", "gap_map", "cell_design", "holm", "bh"]

#: Largest standard error of the cell gain error (dB) for the cell to be testable.
MAX_GAIN_SE_DB = 3.0
#: Polynomial order of the relative error across a band (level + slope).
COHERENT_ORDER = 2
#: Transient terms per record and band (a constant).
TRANSIENT_ORDER = 1
#: A cell's error figures of its primary input, in the order :func:`evaluate_cell` computes them.
_ERROR_FIELDS = ("gain_db", "gain_db_ci", "phase_deg", "phase_deg_ci", "gain_se_db")


def default_bands(data: AnalysisData, n_target: int = 5, min_bins: int | None = None) -> np.ndarray:
    """Band edges (rad/s): log-spaced over the analysis band, merged until each holds enough DFT points.

    ``min_bins`` defaults to ``max(10, 3 * regressors)``: at least three
    independent frequencies per regression coefficient, so that the floor has
    two thirds of the cell's degrees of freedom.

    Parameters
    ----------
    data : AnalysisData
        The records' spectra and analysis band.
    n_target : int, optional
        Bands before merging.
    min_bins : int, optional
        Fewest DFT points per band.

    Returns
    -------
    numpy.ndarray
        The band edges, rad/s.
    """
    lo, hi = data.band
    om = data.stacked_omega()[data.stacked_dft()]
    k = COHERENT_ORDER * len(data.inputs) + TRANSIENT_ORDER * data.n_records
    need = min_bins if min_bins is not None else max(10, 3 * k)
    edges = list(np.geomspace(lo, hi, n_target + 1))
    while len(edges) > 2:
        c = np.histogram(om, edges)[0]  # frequencies per band, the last band closed at its upper edge
        i = int(np.argmin(c))
        if c[i] >= need:
            break
        # merge the smallest band with its smaller neighbour
        right = i == 0 or (i < len(c) - 1 and c[i + 1] < c[i - 1])
        del edges[i + 1 if right else i]
    return np.asarray(edges, float)


@dataclass
class Cell:
    """One channel x band cell of the gap map.

    Energies and the floor are in the squared unit of the channel's transform
    (alpha rad s, q rad, az g s).

    Parameters
    ----------
    channel : str
        Output channel.
    band : tuple
        ``(lo, hi)``, rad/s.
    n : int
        DFT points in the cell.
    residual_power : float
        Mean |e|^2 per DFT point.
    coherent : float
        Coherent energy (sum over the points).
    incoherent : float
        Incoherent energy (sum over the points).
    floor : float
        Noise floor per point (incoherent energy / dof).
    dof : int
        Complex degrees of freedom of the floor.
    k : int
        Complex coherent coefficients.
    F : float
        F statistic of the coherent part, F(2 k, 2 dof) under no model error.
    p : float or None
        Its p-value (None when the cell is not testable).
    excess : float
        Coherent energy in floor units minus its noise-only expectation (0 under no error).
    gain_db : float or None
        Gain error of the model against the data, dB, input ``de``.
    gain_db_ci : tuple or None
        Its 95 % confidence bounds, dB.
    phase_deg : float or None
        Phase error, deg.
    phase_deg_ci : tuple or None
        Its 95 % confidence bounds, deg.
    gain_se_db : float or None
        Standard error of the gain error, dB.
    excitation : str
        ``"ok"``, ``"insufficient excitation"`` or ``"too few frequencies"``.
    p_holm : float or None
        Holm-adjusted p-value across the cells.
    q_bh : float or None
        Benjamini-Hochberg q-value across the cells.
    significant : bool
        Whether ``p_holm`` is below the map's alpha.
    extra : dict
        Gain (dB) and phase (deg) errors of the other inputs, ``gain_db_<input>``, ``phase_deg_<input>``.
    """

    channel: str
    band: tuple
    n: int  # DFT points
    residual_power: float  # mean |e|^2 per DFT point
    coherent: float  # coherent energy (sum over points)
    incoherent: float  # incoherent energy (sum)
    floor: float  # noise floor per point (incoherent / dof)
    dof: int  # complex dof of the floor
    k: int  # complex coherent coefficients
    F: float = math.nan
    p: float | None = None
    excess: float = math.nan  # coherent energy / floor - expectation (noise units)
    gain_db: float | None = None
    gain_db_ci: tuple | None = None
    phase_deg: float | None = None
    phase_deg_ci: tuple | None = None
    gain_se_db: float | None = None
    excitation: str = "ok"
    p_holm: float | None = None
    q_bh: float | None = None
    significant: bool = False
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The cell as plain JSON data (non-finite numbers as None).

        Returns
        -------
        dict
            The cell's figures, with ``coherent_fraction``, ``noise_floor`` and ``floor_dof`` (real).
        """

        def num(x):
            return None if x is None or not math.isfinite(x) else float(x)

        return {
            "channel": self.channel,
            "band": [round(self.band[0], 6), round(self.band[1], 6)],
            "excess": num(self.excess),
            "gain_db": num(self.gain_db),
            "gain_db_ci": None if self.gain_db_ci is None else [num(v) for v in self.gain_db_ci],
            "phase_deg": num(self.phase_deg),
            "phase_deg_ci": None if self.phase_deg_ci is None else [num(v) for v in self.phase_deg_ci],
            "significant": bool(self.significant),
            "p_value": num(self.p),
            "p_holm": num(self.p_holm),
            "q_bh": num(self.q_bh),
            "coherent_fraction": num(self.coherent / (self.coherent + self.incoherent))
            if (self.coherent + self.incoherent) > 0
            else None,
            "noise_floor": num(self.floor),
            "floor_dof": int(2 * self.dof),
            "excitation": self.excitation,
            "n_freq": int(self.n),
            **self.extra,
        }

    @classmethod
    def from_dict(cls, d, *, source: str = "gap-map cell") -> Cell:
        """Inverse of :meth:`to_dict`, as far as it goes; a bad key raises a one-line FdmlError naming ``source``.

        :meth:`to_dict` keeps the figures a report shows, not every field:
        the band comes back rounded to 6 decimals and a non-finite number as
        None (NaN for ``excess`` and ``noise_floor``); ``coherent`` and
        ``incoherent`` come back as the coherent fraction and its complement
        (their ratio, not their size); ``residual_power``, ``F``,
        ``gain_se_db`` are NaN, None and None and ``k`` is 0, as they are not
        written.  Every key beyond the known ones (``gain_db_<input>``,
        ``phase_deg_<input>``) goes to ``extra``.  So ``to_dict`` of the cell
        read back equals ``d``.

        Parameters
        ----------
        d : dict
            As written by :meth:`to_dict`.
        source : str, optional
            What ``d`` came from, for the message.

        Returns
        -------
        Cell
            The cell.
        """
        f = Fields(d, source)
        frac = f.number("coherent_fraction", allow_none=True)
        return cls(
            channel=f.string("channel"),
            band=f.numbers("band", length=2),
            n=f.integer("n_freq", minimum=0),
            residual_power=math.nan,
            coherent=0.0 if frac is None else frac,
            incoherent=0.0 if frac is None else 1.0 - frac,
            floor=_nan_if_none(f.number("noise_floor", allow_none=True)),
            dof=f.integer("floor_dof", minimum=0) // 2,
            k=0,
            p=f.number("p_value", allow_none=True),
            excess=_nan_if_none(f.number("excess", allow_none=True)),
            gain_db=f.number("gain_db", allow_none=True),
            gain_db_ci=_pair_or_none(f, "gain_db_ci"),
            phase_deg=f.number("phase_deg", allow_none=True),
            phase_deg_ci=_pair_or_none(f, "phase_deg_ci"),
            excitation=f.string("excitation"),
            p_holm=f.number("p_holm", allow_none=True),
            q_bh=f.number("q_bh", allow_none=True),
            significant=f.boolean("significant"),
            extra={k: f.number(k, allow_none=True) for k in f.doc if k not in _CELL_KEYS},
        )


#: The keys :meth:`Cell.to_dict` always writes (the others are ``extra``).
_CELL_KEYS = frozenset(
    "channel band excess gain_db gain_db_ci phase_deg phase_deg_ci significant p_value p_holm q_bh "
    "coherent_fraction noise_floor floor_dof excitation n_freq".split()
)


def _nan_if_none(x: float | None) -> float:
    return math.nan if x is None else x


def _pair_or_none(f: Fields, key: str) -> tuple | None:
    """A pair of numbers or nulls (None for NaN), or None."""
    v = f.raw(key)
    if v is None:
        return None
    if not isinstance(v, list) or len(v) != 2:
        raise f.error(key, "must be a pair of numbers or null")
    pair = Fields({"0": v[0], "1": v[1]}, f.source, f"{f.name(key)}.")
    return (pair.number("0", allow_none=True), pair.number("1", allow_none=True))


@dataclass
class GapMap:
    """All cells, with the multiple-testing correction applied.

    Parameters
    ----------
    cells : list of Cell
        Channel by channel, bands in order within each.
    edges : numpy.ndarray
        Band edges, rad/s.
    channels : tuple of str
        The channels mapped.
    alpha : float
        Family-wise level of the Holm correction.
    method : str
        How the noise floor was estimated (for reports).
    """

    cells: list
    edges: np.ndarray
    channels: tuple
    alpha: float
    method: str = (
        "noise floor per cell: residual energy not coherent with the inputs (band regression on "
        "independent DFT points; model-free for errors smooth across the band)"
    )

    def cell(self, channel: str, b: int) -> Cell:
        """The cell of ``channel`` in band number ``b``.

        Parameters
        ----------
        channel : str
            A channel of the map.
        b : int
            Band index, from 0.

        Returns
        -------
        Cell
            The cell.
        """
        return self.cells[self.channels.index(channel) * (self.edges.size - 1) + b]

    def flagged(self) -> list:
        """The cells whose gap is significant.

        Returns
        -------
        list of Cell
            In map order.
        """
        return [c for c in self.cells if c.significant]

    def to_list(self) -> list:
        """Every cell as plain JSON data, channel by channel.

        Returns
        -------
        list of dict
            One :meth:`Cell.to_dict` per cell.
        """
        return [c.to_dict() for c in self.cells]


def _legendre(x: np.ndarray, order: int) -> np.ndarray:
    return np.polynomial.legendre.legvander(x, max(order - 1, 0))[:, :order]


def band_rows(data: AnalysisData, lo: float, hi: float, last: bool) -> tuple[np.ndarray, np.ndarray]:
    """The stacked DFT rows in the band [lo, hi), and their log frequency mapped onto [-1, 1].

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    lo, hi : float
        Band edges, rad/s.
    last : bool
        Whether this is the last band (closed at ``hi``).

    Returns
    -------
    rows : numpy.ndarray
        Indices into the stacked analysis rows.
    x : numpy.ndarray
        ``2 (ln w - ln lo) / (ln hi - ln lo) - 1`` at those rows.
    """
    om = data.stacked_omega()
    inb = (om >= lo) & ((om <= hi) if last else (om < hi))
    rows = np.flatnonzero(inb & data.stacked_dft())
    return rows, 2.0 * (np.log(om[rows]) - math.log(lo)) / (math.log(hi) - math.log(lo)) - 1.0


@dataclass
class CellDesign:
    """Rows and regressors of one cell (shared by before/after evaluations).

    Parameters
    ----------
    rows : numpy.ndarray
        Indices into the stacked analysis rows.
    XT : numpy.ndarray
        Transient regressors, shape (n, kT).
    XC : numpy.ndarray
        Coherent regressors, shape (n, kC).
    weights : list
        Per input: (column slice, band-average weights over its coefficients).
    inputs : list of str
        The inputs with coherent regressors.
    """

    rows: np.ndarray  # indices into the stacked analysis rows
    XT: np.ndarray  # transient regressors (n, kT)
    XC: np.ndarray  # coherent regressors (n, kC)
    weights: list  # per input: (column slice, band-average weights over coefficients)
    inputs: list


def cell_design(data: AnalysisData, forced: np.ndarray, c: int, lo: float, hi: float, last: bool) -> CellDesign:
    """Regressors of cell (channel c, band [lo, hi)) on the stacked DFT rows.

    ``forced`` has shape (N, 3, n_in): the model's forced response y_jc per row.

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    forced : numpy.ndarray
        The model's forced response, shape (N, 3, n_in) (:func:`forced_response`).
    c : int
        Output index (0 alpha, 1 q, 2 az).
    lo, hi : float
        Band edges, rad/s.
    last : bool
        Whether this is the last band (closed at ``hi``).

    Returns
    -------
    CellDesign
        The cell's rows and its transient and coherent regressors.
    """
    rows, x = band_rows(data, lo, hi, last)
    rec = data.stacked_record()[rows]
    cols_T = [_legendre(x, TRANSIENT_ORDER) * (rec == r)[:, None] for r in np.unique(rec)]
    XT = np.hstack(cols_T).astype(complex) if cols_T else np.zeros((rows.size, 0), complex)
    cols_C, weights, used = [], [], []
    off = 0
    for j, name in enumerate(data.inputs):
        y = forced[rows, c, j]
        if not np.any(np.abs(y) > 0):
            continue
        P = _legendre(x, COHERENT_ORDER)
        cols_C.append(P * y[:, None])
        w = np.abs(y) ** 2
        avg = (P * w[:, None]).sum(axis=0) / max(w.sum(), 1e-300)  # |y|^2-weighted band average of delta
        weights.append((slice(off, off + P.shape[1]), avg))
        used.append(name)
        off += P.shape[1]
    XC = np.hstack(cols_C) if cols_C else np.zeros((rows.size, 0), complex)
    return CellDesign(rows, XT, XC, weights, used)


def _lstsq_rss(X, e):
    if X.shape[1] == 0:
        return float(np.vdot(e, e).real), None
    coef, *_ = np.linalg.lstsq(X, e, rcond=None)
    res = e - X @ coef
    return float(np.vdot(res, res).real), coef


def evaluate_cell(design: CellDesign, e: np.ndarray, channel: str, band: tuple, floor: float | None = None):
    """Regress the residual of one cell; returns a :class:`Cell` (``floor`` fixes the noise floor).

    Parameters
    ----------
    design : CellDesign
        The cell's rows and regressors.
    e : numpy.ndarray
        Residual of the channel on the stacked rows, shape (N,), complex.
    channel : str
        The channel.
    band : tuple
        ``(lo, hi)``, rad/s.
    floor : float, optional
        Noise floor to hold (default: the cell's own).

    Returns
    -------
    Cell
        The cell, not yet corrected for multiple testing.
    """
    n = design.rows.size
    kT, kC = design.XT.shape[1], design.XC.shape[1]
    dof = n - kT - kC
    ee = e[design.rows]
    total = float(np.vdot(ee, ee).real)
    rss0, _ = _lstsq_rss(design.XT, ee)
    X = np.hstack([design.XT, design.XC])
    rss1, coef = _lstsq_rss(X, ee)
    coherent = max(rss0 - rss1, 0.0)
    empty = Cell(
        channel, band, n, total / max(n, 1), coherent, rss1, math.nan, dof, kC, excitation="too few frequencies"
    )
    if dof < 2 or kC == 0:
        return empty
    s2 = rss1 / dof if floor is None else floor
    if not s2 > 0:
        return empty
    F = (coherent / kC) / s2
    excess = coherent / s2 - kC * dof / (dof - 1)
    # gain/phase of the model against the data, input de (the first input used)
    cov = s2 * np.linalg.pinv(X.conj().T @ X)
    out = {}
    for (sl, avg), name in zip(design.weights, design.inputs):
        idx = np.arange(kT + sl.start, kT + sl.stop)
        z = 1.0 + complex(avg @ coef[idx])
        var = float(np.real(avg.conj() @ cov[np.ix_(idx, idx)] @ avg))
        se = math.sqrt(max(var, 0.0) / 2.0) / max(abs(z), 1e-12)  # per real component, relative
        gdb = 20 * math.log10(max(abs(z), 1e-12))
        ph = math.degrees(math.atan2(z.imag, z.real))
        se_db = 20 / math.log(10) * se
        se_deg = math.degrees(se)
        out[name] = (gdb, (gdb - 1.96 * se_db, gdb + 1.96 * se_db), ph, (ph - 1.96 * se_deg, ph + 1.96 * se_deg), se_db)
    prim: dict[str, Any] = dict(zip(_ERROR_FIELDS, out.get("de") or next(iter(out.values()))))
    excitation = "ok" if prim["gain_se_db"] <= MAX_GAIN_SE_DB else "insufficient excitation"
    p = float(stats.f.sf(F, 2 * kC, 2 * dof)) if excitation == "ok" else None  # an untested cell has none
    extra = {
        f"{k}_{name}": v[i] for name, v in out.items() if name != "de" for k, i in (("gain_db", 0), ("phase_deg", 2))
    }
    return replace(empty, floor=s2, F=F, p=p, excess=excess, excitation=excitation, extra=extra, **prim)


def forced_response(data: AnalysisData, model, values=None) -> np.ndarray:
    """``G_jc(w) u_j(w)`` on the stacked rows, shape (N, 3, n_in).

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    model : Model
        The model.
    values : mapping, optional
        Parameter values overriding the model's.

    Returns
    -------
    numpy.ndarray
        Complex, shape (N, 3, n_in): alpha (rad s), q (rad), az (g s) per input.
    """
    out = []
    for d in data.spectra:
        G = model.evaluate(d.omega, values).G[:, :, : d.u.shape[1]]
        out.append(G * d.u[:, None, :])
    return np.concatenate(out)


def gap_map(
    data: AnalysisData,
    residual: np.ndarray,
    forced: np.ndarray,
    edges: np.ndarray,
    *,
    channels=OUTPUTS,
    alpha: float = 0.05,
    floors: dict | None = None,
    designs: dict | None = None,
) -> GapMap:
    """The gap map of one fit.

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    residual : ndarray, shape (N, 3)
        Residuals z - y on the stacked analysis rows (all three outputs;
        columns of outputs that were not fitted are ignored via ``channels``).
    forced : ndarray, shape (N, 3, n_in)
        The model's forced response (see :func:`forced_response`).
    edges : ndarray
        Band edges, rad/s.
    channels : sequence of str, optional
        Channels mapped (default alpha, q, az).
    alpha : float, optional
        Family-wise level of the Holm correction.
    floors : dict, optional
        ``{(channel, band index): floor}`` to hold the noise floors of another
        map (for before/after comparisons).
    designs : dict, optional
        ``{(channel, band index): CellDesign}``, reused and filled in place.

    Returns
    -------
    GapMap
        Every cell, tested and corrected.
    """

    cells = []
    nb = edges.size - 1
    designs = {} if designs is None else designs
    rows = tuple(data.spectra[0].outputs)  # the residual's columns: the spectra's output rows
    for ch in channels:
        c = rows.index(ch)
        for b in range(nb):
            key = (ch, b)
            if key not in designs:
                designs[key] = cell_design(data, forced, c, edges[b], edges[b + 1], b == nb - 1)
            fl = None if floors is None else floors.get(key)
            cells.append(evaluate_cell(designs[key], residual[:, c], ch, (edges[b], edges[b + 1]), fl))
    p = np.array([c.p if c.p is not None else np.nan for c in cells])
    for cell, a, b_ in zip(cells, holm(p), bh(p)):
        cell.p_holm = None if not np.isfinite(a) else float(a)
        cell.q_bh = None if not np.isfinite(b_) else float(b_)
        cell.significant = bool(np.isfinite(a) and a < alpha)
    return GapMap(cells, np.asarray(edges), tuple(channels), alpha)
