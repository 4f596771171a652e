"""Steady versus unsteady: one call fits both models and sets the derivatives side by side.

Wells-Keskar Tables 1 and 3 compare the six derivatives of a quasi-steady fit
with those implied by the unsteady fit (docs/theory.md sections 6, 10, 11).  The
steady column is, by default, the conventional six-derivative model (docs/theory.md
section 10 shows this is what the paper fitted); ``steady_model="steady"``
uses the quasi-steady Wells-Keskar parameterisation instead.
"""

from __future__ import annotations

from dataclasses import dataclass

from .aircraft import Aircraft, load_aircraft
from .estimate import fit
from .models import make_model
from .models.wells_keskar import ALTERNATE_NAMES
from .results import FitResult

__all__ = ["Comparison", "compare_steady_unsteady", "ALTERNATE_NAMES"]


def _column(res: FitResult) -> dict[str, tuple[float, float]]:
    out = {}
    for n in ALTERNATE_NAMES:
        if n in res.names:
            i = res.names.index(n)
            out[n] = (float(res.values[i]), float(res.stderr[i]))
        elif n in res.derived:
            out[n] = res.derived[n]
    return out


@dataclass(frozen=True)
class Comparison:
    """Steady and unsteady fits of the same data, with their derivative sets.

    Attributes
    ----------
    steady, unsteady : FitResult
    steady_set, unsteady_set : dict
        ``{name: (value, stderr)}`` for the six derivatives (alternate set).
    """

    steady: FitResult
    unsteady: FitResult
    steady_set: dict
    unsteady_set: dict

    def shift(self, name: str) -> float:
        """Steady minus unsteady value of a derivative."""
        return self.steady_set[name][0] - self.unsteady_set[name][0]

    def table(self, reference: dict | None = None, digits: int = 4):
        """Side-by-side table; ``reference`` adds columns ``{name: (unsteady, steady)}``.

        Returns a :class:`fdml.summary.Summary`: a ``str`` holding the text
        table, which also renders as Markdown, HTML, LaTeX and a pandas
        DataFrame (``as_markdown()``, ``as_html()``, ``as_latex()``, ``to_frame()``).
        """
        from .summary import comparison_summary

        return comparison_summary(self, reference, digits=digits)

    def _repr_html_(self) -> str:
        return self.table().as_html()

    def to_dict(self) -> dict:
        """JSON-ready dict of the two derivative sets and both fits."""
        return {
            "unsteady": {k: {"value": v, "stderr": s} for k, (v, s) in self.unsteady_set.items()},
            "steady": {k: {"value": v, "stderr": s} for k, (v, s) in self.steady_set.items()},
            "fits": {"unsteady": self.unsteady.to_dict(), "steady": self.steady.to_dict()},
        }


def compare_steady_unsteady(
    data,
    aircraft: Aircraft | str,
    *,
    gust: bool = False,
    steady_model: str = "derivatives",
    unsteady_options: dict | None = None,
    **fit_kwargs,
) -> Comparison:
    """Fit the unsteady and a steady model to the same data; return both derivative sets.

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
    **fit_kwargs
        Passed to :func:`fdml.fit` for both fits (band, outputs, boundary, ...).

    Returns
    -------
    Comparison
    """
    ac = load_aircraft(aircraft)
    mu = make_model("unsteady", ac, gust=gust, **(unsteady_options or {}))
    ms = make_model(steady_model, ac, gust=gust)
    ru = fit(data, mu, **fit_kwargs)
    rs = fit(data, ms, **fit_kwargs)
    return Comparison(steady=rs, unsteady=ru, steady_set=_column(rs), unsteady_set=_column(ru))
