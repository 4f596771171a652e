"""Steady versus unsteady: one call fits both models, sets the derivatives side by side and weighs the evidence.

Wells-Keskar Tables 1 and 3 compare the six derivatives of a quasi-steady fit
with those implied by the unsteady fit (docs/theory.md sections 6, 10, 11).  The
steady column is, by default, the conventional six-derivative model (docs/theory.md
section 10 shows this is what the paper fitted); ``steady_model="steady"``
uses the quasi-steady Wells-Keskar parameterisation instead.

The evidence (:func:`vuong_test`): the two models are not nested, so a
likelihood-ratio test does not apply; Vuong's (1989) test for non-nested
models compares their per-frequency log-likelihood contributions (the terms
of the concentrated likelihood whose sum is -N ln det R, docs/theory.md Eqs. 20-25).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .aircraft import Aircraft, lag_provenance, load_aircraft
from .errors import FdmlError
from .estimate import fit
from .jsoncodec import SKIP, Codec, Fields, Spec, nested
from .jsoncodec import text as choose
from .models import make_model
from .models.wells_keskar import ALTERNATE_NAMES
from .results import FitResult

__all__ = [
    "Comparison",
    "Evidence",
    "check_records_for_compare",
    "compare_steady_unsteady",
    "vuong_test",
    "ALTERNATE_NAMES",
    "COMPARISON_FORMAT",
]

#: JSON format identifier and version of a saved comparison.
COMPARISON_FORMAT = ("fdml.Comparison", 1)
#: Two-sided level of the evidence test: below it one model is favoured.
EVIDENCE_LEVEL = 0.05


def _column(res: FitResult) -> dict[str, tuple[float, float]]:
    out = {}
    for n in ALTERNATE_NAMES:
        if n in res.names:
            i = res.names.index(n)
            out[n] = (float(res.values[i]), float(res.stderr[i]))
        elif n in res.derived:
            out[n] = res.derived[n]
    return out


# --- the evidence ----------------------------------------------------------------------------
def loglik_contributions(res: FitResult) -> list[np.ndarray]:
    """Per-frequency log-likelihood contributions of a fit, one array per record.

    The complex-Gaussian density of the residual v_i = z_i - y_i at frequency
    i with the fit's concentrated covariance R (Eq. 24, over all records):
    ``l_i = -ln det(pi R) - v_i^H R^-1 v_i``; their sum is the concentrated
    log-likelihood ``-N ln det(pi R) - N n`` whose maximum is the minimum of
    ln det R (Eqs. 20-25).
    """
    if not res.spectra:
        raise FdmlError("the fit holds no spectra: the evidence needs the fitted spectra")
    idx = [res.model.outputs.index(o) for o in res.outputs]
    V = [s.z[:, idx] - res.fitted_spectra(r)[:, idx] for r, s in enumerate(res.spectra)]
    allv = np.concatenate(V)
    R = allv.T @ allv.conj() / allv.shape[0]  # Eq. 24
    Rinv = np.linalg.inv(R)
    _, ld = np.linalg.slogdet(math.pi * R)
    return [-ld - np.real(np.einsum("ij,jk,ik->i", v.conj(), Rinv, v)) for v in V]


def correlation_span(res: FitResult) -> list[int]:
    """Frequencies per record that share information: ceil(2 pi / (T d omega)), at least 1.

    The finite Fourier transform of a record of length T correlates
    frequencies closer than 2 pi / T (the Dirichlet kernel's main lobe), so a
    grid finer than that has fewer independent frequencies than points.
    """
    return [span_of(s.omega, s.T) for s in res.spectra]


def span_of(omega, T: float) -> int:
    """ceil(2 pi / (T d omega)), at least 1: grid frequencies (rad/s) per independent one for a record of T s."""
    w = np.asarray(omega, float)
    dw = float(np.median(np.diff(w))) if w.size > 1 else math.inf
    return max(1, math.ceil(2 * math.pi / (float(T) * dw) - 1e-9))


def _long_run_variance(d: np.ndarray, span: int) -> float:
    """N times the Bartlett-weighted (Newey-West) long-run variance of the centred ``d``, lags < ``span``."""
    n = d.size
    total = float(d @ d)
    for k in range(1, min(span, n)):  # a few lags, not a loop over frequencies
        total += 2.0 * (1.0 - k / span) * float(d[k:] @ d[:-k])
    return max(total, 0.0)


@dataclass(frozen=True)
class Evidence(Codec):
    """Which model the data favour: Vuong's test on per-frequency log-likelihoods.

    Parameters
    ----------
    statistic : float
        Vuong's z: the summed log-likelihood difference (unsteady minus steady,
        with Schwarz's correction for unequal parameter counts) over its
        standard deviation; N(0, 1) when the models fit equally well.
    p_value : float
        Two-sided p-value of the statistic.
    favoured : {"steady", "unsteady", "neither"}
        The better-fitting model when ``p_value < level``, else "neither".
    level : float
        Two-sided level of the test (default 0.05).
    n_freq : int
        Frequencies summed over records.
    span : int
        Largest correlation span (frequencies) used in the variance.
    distance : float
        Largest ``|shift|`` of the six derivatives in standard errors: how far a
        steady fit would be biased if the truth were unsteady.
    method : str
        The test's name and variance estimator, for reports.
    """

    statistic: float
    p_value: float
    favoured: str
    level: float = EVIDENCE_LEVEL
    n_freq: int = 0
    span: int = 1
    distance: float = math.nan
    method: str = "Vuong (1989) non-nested test, Newey-West variance over the frequency correlation span"

    json_fields = {"favoured": choose(("steady", "unsteady", "neither"))}
    json_source = "comparison evidence"

    def text(self) -> str:
        """One paragraph: statistic, p-value, the verdict and, for "neither", the distance.

        Returns
        -------
        str
            The paragraph.
        """
        head = (
            f"Vuong z = {self.statistic:+.3g} (positive favours unsteady), p = {self.p_value:.3g}, "
            f"{self.n_freq} frequencies, correlation span {self.span}: "
        )
        if self.favoured == "neither":
            return head + (
                f"neither favoured at the {100 * self.level:g} % level; the derivative sets are "
                f"{self.distance:.2g} standard errors apart at most (the bias of a steady fit if the truth is unsteady)"
            )
        return head + f"the {self.favoured} model is favoured"


def vuong_test(steady: FitResult, unsteady: FitResult, *, level: float = EVIDENCE_LEVEL, distance=math.nan) -> Evidence:
    """Vuong's non-nested test of two fits of the same spectra.

    Assumption: frequencies more than 2 pi / T apart are independent, and the
    dependence of nearer ones is captured by a Bartlett (Newey-West) long-run
    variance over that span (:func:`correlation_span`); records are independent.

    Parameters
    ----------
    steady, unsteady : FitResult
        The two fits, of the same spectra (same records, band and outputs).
    level : float, optional
        Two-sided level below which one model is favoured (default 0.05).
    distance : float, optional
        Largest derivative shift in standard errors, kept for the report.

    Returns
    -------
    Evidence
        The statistic, its p-value and the verdict.
    """
    from scipy.stats import norm

    lu, ls = loglik_contributions(unsteady), loglik_contributions(steady)
    if [x.size for x in lu] != [x.size for x in ls]:
        raise FdmlError("the two fits are not of the same spectra: the evidence needs the same frequencies")
    d = [a - b for a, b in zip(lu, ls)]
    n = int(sum(x.size for x in d))
    spans = correlation_span(unsteady)
    mean = sum(float(x.sum()) for x in d) / n
    var = sum(_long_run_variance(x - mean, L) for x, L in zip(d, spans))
    n_eff = sum(x.size / L for x, L in zip(d, spans))
    k_u, k_s = len(unsteady.names), len(steady.names)
    total = n * mean - 0.5 * (k_u - k_s) * math.log(max(n_eff, 1.0))  # Schwarz correction (0 for equal counts)
    if not var > 1e-12 * max(1.0, abs(n * mean)):
        z, p = 0.0, 1.0  # identical fits: nothing to tell apart
    else:
        z = total / math.sqrt(var)
        p = float(2 * norm.sf(abs(z)))
    favoured = "neither" if p >= level else ("unsteady" if z > 0 else "steady")
    return Evidence(float(z), p, favoured, level, n, max(spans), float(distance))


# --- the records ------------------------------------------------------------------------------
#: Relative difference of geometry (S_w, c_w, b) above which two records are of different aircraft.
GEOMETRY_TOLERANCE = 0.01


def check_records_for_compare(records, *, gust: bool = False) -> None:
    """Refuse, in one line, records a joint steady/unsteady comparison cannot use.

    ``--gust`` needs alpha_w in every record; a joint fit needs one aircraft
    (the records' ``meta["aircraft"]`` and their geometry S_w, c_w, b agree
    within :data:`GEOMETRY_TOLERANCE`).

    Parameters
    ----------
    records : sequence of Record
        The records to be fitted together.
    gust : bool, optional
        Whether the gust input alpha_w is to be used.
    """
    if gust:
        lacking = [r.name for r in records if "alpha_w" not in r.signals]
        if lacking:
            raise FdmlError(
                f"--gust needs the gust angle alpha_w in every record; {', '.join(lacking)} has none "
                "(give a record with an alpha_w column, or drop --gust)"
            )
    names = {str(r.meta["aircraft"]) for r in records if r.meta.get("aircraft")}
    if len(names) > 1:
        raise FdmlError(
            f"the records mix aircraft ({', '.join(sorted(names))}): compare one aircraft's records at a time"
        )
    for key in ("S_w", "c_w", "b"):
        vals = [(r.name, float(r.meta[key])) for r in records if isinstance(r.meta.get(key), (int, float))]
        if vals and max(v for _, v in vals) > (1 + GEOMETRY_TOLERANCE) * min(v for _, v in vals):
            listed = ", ".join(f"{n} {v:g}" for n, v in vals)
            raise FdmlError(f"the records mix aircraft: their {key} differ ({listed}); compare one aircraft at a time")


# --- the comparison --------------------------------------------------------------------------
def _fit_field() -> Spec:
    """A full fit (:meth:`FitResult.from_dict`, its messages naming the comparison and the key)."""
    return Spec(lambda f, k, done: FitResult.from_dict(f.raw(k), source=f"{f.source}: {k}"))


@dataclass(frozen=True)
class Comparison(Codec):
    """Steady and unsteady fits of the same data, their derivative sets and the evidence.

    Parameters
    ----------
    steady, unsteady : FitResult
        The fits of the steady and the unsteady model.
    steady_set, unsteady_set : dict
        ``{name: (value, stderr)}`` for the six derivatives (alternate set).
    evidence : Evidence
        Which model the data favour (computed from the fits when not given).
    """

    steady: FitResult
    unsteady: FitResult
    steady_set: dict = field(default_factory=dict)
    unsteady_set: dict = field(default_factory=dict)
    evidence: Evidence | None = None

    json_fields = {
        **dict.fromkeys(("steady", "unsteady"), _fit_field()),
        **dict.fromkeys(("steady_set", "unsteady_set"), SKIP),  # derived from the fits
        "evidence": nested(Evidence, none=True),
    }
    json_extra = ("shifts",)
    json_format = COMPARISON_FORMAT
    json_source = "fdml comparison"

    def __post_init__(self) -> None:
        if not self.steady_set:
            object.__setattr__(self, "steady_set", _column(self.steady))
        if not self.unsteady_set:
            object.__setattr__(self, "unsteady_set", _column(self.unsteady))
        if self.evidence is None and self.steady.spectra and self.unsteady.spectra:
            object.__setattr__(self, "evidence", vuong_test(self.steady, self.unsteady, distance=self.distance))

    def shift(self, name: str) -> float:
        """Steady minus unsteady value of a derivative.

        Parameters
        ----------
        name : str
            A derivative of the alternate set.

        Returns
        -------
        float
            The difference, in the derivative's unit.
        """
        return self.steady_set[name][0] - self.unsteady_set[name][0]

    @property
    def shifts(self) -> dict:
        """Per derivative: ``value`` (steady - unsteady), ``stderr`` (combined) and ``in_stderr``."""
        out = {}
        for n in ALTERNATE_NAMES:
            if n in self.steady_set and n in self.unsteady_set:
                sig = math.hypot(self.steady_set[n][1], self.unsteady_set[n][1])
                z = self.shift(n) / sig if sig > 0 and math.isfinite(sig) else math.nan
                out[n] = {"value": self.shift(n), "stderr": sig, "in_stderr": z}
        return out

    @property
    def distance(self) -> float:
        """Largest ``|shift|`` in standard errors over the six derivatives."""
        zs = [abs(v["in_stderr"]) for v in self.shifts.values() if math.isfinite(v["in_stderr"])]
        return max(zs) if zs else math.nan

    def fit_quality(self) -> dict:
        """Each fit's ln det R and residual RMS per output.

        Returns
        -------
        dict
            ``{model: {"ln_det_R", "rms": {output: residual RMS}}}``, the RMS of
            ``|z - y|`` over the frequencies, in the output's spectral units
            (rad s, rad, g s).
        """
        out = {}
        for key, res in (("steady", self.steady), ("unsteady", self.unsteady)):
            V = res.resid  # z - y at the estimate, records stacked, the fitted outputs
            rms = np.sqrt(np.mean(np.abs(V) ** 2, axis=0)) if V.size else np.full(len(res.outputs), math.nan)
            out[key] = {"ln_det_R": float(np.linalg.slogdet(res.R)[1]), "rms": dict(zip(res.outputs, rms.tolist()))}
        return out

    def summary(self, reference: dict | None = None, digits: int = 4):
        """Side-by-side table (WK Tables 1 and 3), fit quality and the evidence.

        Parameters
        ----------
        reference : dict, optional
            Published values ``{name: (unsteady, steady)}``, shown as extra columns.
        digits : int, optional
            Significant digits of values.

        Returns
        -------
        fdml.summary.Summary
            The table as text, also rendered as Markdown, HTML, LaTeX or a DataFrame.
        """
        from .summary import Summary, comparison_summary

        base = comparison_summary(self, reference, digits=digits)
        extra = []
        if self.steady.spectra and self.unsteady.spectra:
            for key, q in self.fit_quality().items():
                rms = ", ".join(f"{o} {v:.3g}" for o, v in q["rms"].items())
                extra.append((f"{key} fit", f"ln det R {q['ln_det_R']:.4g}; residual RMS {rms}"))
        if self.evidence is not None:
            extra.append(("evidence", self.evidence.text()))
        return Summary(base.title, base.header + tuple(extra), base.tables, base.notes, digits=digits)

    #: The old name of :meth:`summary`.
    table = summary

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def brief(self) -> dict:
        """The JSON of ``fdml compare --json``.

        Returns
        -------
        dict
            ``steady`` and ``unsteady`` (each as ``fdml fit --json``), ``shifts``,
            ``evidence`` and ``fit_quality``.
        """
        return {
            "steady": self.steady.brief(),
            "unsteady": self.unsteady.brief(),
            "shifts": self.shifts,
            "evidence": None if self.evidence is None else self.evidence.to_dict(),
            "fit_quality": self.fit_quality() if self.steady.spectra else None,
        }

    @classmethod
    def from_dict(cls, d, *, source: str | None = "fdml comparison", **given) -> "Comparison":
        """Inverse of ``to_dict`` (:class:`~fdml.jsoncodec.Codec`: format ``fdml.Comparison`` version 1).

        Both full fits and the evidence are read; the shifts, written beside them, are recomputed from the fits.

        Parameters
        ----------
        d : dict
            As written by ``to_dict``.
        source : str, optional
            What ``d`` came from, named in a one-line error.
        **given
            Field values the dict does not hold.

        Returns
        -------
        Comparison
            The comparison ``d`` describes.
        """
        f = Fields(d, cls.json_source if source is None else source)
        if f.raw("format", None) != COMPARISON_FORMAT[0]:
            raise f.error("format", f"is not {COMPARISON_FORMAT[0]!r}: not an fdml comparison")
        f.version("version", COMPARISON_FORMAT[1])
        return cls.from_fields(f, **given)

    def plot(self, *, record: int = 0, fig=None):
        """Data spectra with both fits (top) and the derivative shifts with +-2 sigma bounds (bottom).

        Parameters
        ----------
        record : int, optional
            Which record's spectra to show.
        fig : matplotlib.figure.Figure, optional
            Figure to draw into (default: a new one).

        Returns
        -------
        matplotlib.figure.Figure
            The figure.
        """
        import matplotlib.pyplot as plt

        from .plotting import plot_spectra

        n_out = len(self.unsteady.outputs)
        fig = fig or plt.figure(figsize=(4.2 * n_out, 9.5), layout="constrained")  # room for every label
        grid = fig.add_gridspec(3, n_out, height_ratios=(1.0, 0.7, 0.8))
        axes = np.array([[fig.add_subplot(grid[i, j]) for j in range(n_out)] for i in range(2)])
        plot_spectra([self.unsteady, self.steady], ["unsteady fit", "steady fit"], record=record, axes=axes)
        ax = fig.add_subplot(grid[2, :])
        sh = self.shifts
        names = list(sh)
        z = np.array([sh[n]["in_stderr"] for n in names])
        ax.axhspan(-2, 2, color="0.9", label="+-2 standard errors")
        ax.bar(range(len(names)), z, color="C3")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xticks(range(len(names)), names)
        ax.set_ylabel("shift / stderr")
        title, ev = "steady - unsteady", self.evidence
        if ev is not None:
            title += f"; evidence: {ev.favoured} favoured (z = {ev.statistic:+.2f}, p = {ev.p_value:.2g})"
        ax.set_title(title)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)  # beside the bars, not over them
        return fig


def compare_steady_unsteady(
    data,
    aircraft: Aircraft | str,
    *,
    gust: bool = False,
    steady_model: str = "derivatives",
    unsteady_options: dict | None = None,
    effects=(),
    **fit_kwargs,
) -> Comparison:
    """Fit the unsteady and a steady model to the same data; return both derivative sets and the evidence.

    Parameters
    ----------
    data : Record, FrequencyData or list
        As for :func:`fdml.fit`.
    aircraft : Aircraft or str
        Preset name, JSON file, or :class:`~fdml.aircraft.Aircraft`.
    gust : bool, optional
        Fit the gust column too (the data must carry alpha_w).
    steady_model : {"derivatives", "steady"}, optional
    unsteady_options : dict, optional
        Options for the unsteady model (``tail_lag_chord``, ``gust_lag``, ...).
    effects : sequence, optional
        Effects made part of both models (``fdml effects`` lists them).
    **fit_kwargs
        Passed to :func:`fdml.fit` for both fits (band, outputs, boundary, ...).

    Returns
    -------
    Comparison
        Both fits and their derivative sets.
    """
    if steady_model not in ("derivatives", "steady"):
        raise FdmlError(f"steady_model must be 'derivatives' or 'steady', got {steady_model!r}")
    ac = load_aircraft(aircraft)
    mu = make_model("unsteady", ac, gust=gust, effects=effects, **(unsteady_options or {}))
    ms = make_model(steady_model, ac, gust=gust, effects=effects)
    ru = fit(data, mu, **fit_kwargs)
    # one input for both: the elevator steps' timing as the richer model's fit settled it (section 7a)
    rs = fit(data, ms, **{**fit_kwargs, "input_edges": ru.options.get("input_edges", "none")})
    ru = replace(ru, provenance={**ru.provenance, "lag_constants": lag_provenance(ac)})  # where the lags came from
    return Comparison(steady=rs, unsteady=ru)
