"""Summaries of fits as text, Markdown, HTML, LaTeX and pandas DataFrames.

:func:`fit_summary` (behind :meth:`FitResult.summary`) and
:func:`comparison_summary` (behind :meth:`Comparison.table`) return a
:class:`Summary`: a ``str`` holding the plain-text table, so ``print(s)``,
``"at bound" in s`` and ``str(s)`` behave as they always did, which also
renders itself in the other formats:

* :meth:`Summary.as_text`, :meth:`Summary.as_markdown`,
  :meth:`Summary.as_html`, :meth:`Summary.as_latex`;
* :meth:`Summary.to_frame` (pandas, the optional ``pandas`` extra);
* ``_repr_html_`` and ``_repr_latex_``, so a summary renders as a table in a
  notebook.

The content is kept as data (a header of label/value pairs, tables of raw
numbers, notes), and each format is rendered from it; no format is parsed
from another.  The layout follows statsmodels' ``Summary`` and lmfit's fit
report: value, standard error, relative error, and flags that say why a
standard error is missing (fixed, at a bound, not identifiable).
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .channels import ALL_OUTPUTS, SIGNALS, boundary_channels
from .estimator_settings import SETTINGS
from .models.base import model_airspeed
from .models.conventional import DIMENSIONAL_UNITS
from .parameters import NUISANCE_ROLES, Role

__all__ = ["Summary", "Table", "Column", "fit_summary", "comparison_summary", "parameter_unit"]

#: Units of the nuisance terms and derived quantities that are not model parameters.
_EXTRA_UNITS = {
    **{f"bias_{o}": SIGNALS[o] for o in ALL_OUTPUTS},
    "bias_de": "rad",
    "bias_alpha_dot": "rad/s",
    "bias_q_dot": "rad/s^2",
    **{f"{end}_{c}": SIGNALS[c] for end in ("x0", "xT") for c in boundary_channels(ALL_OUTPUTS)},
    **DIMENSIONAL_UNITS,
    **dict.fromkeys(("Cz_a", "Cz_q", "Cz_de", "Cm_a", "Cm_q", "Cm_de", "Cz_adot_G", "Cm_adot_G"), "1/rad"),
}

_COV_TYPES = {
    "white": "white-noise sandwich (the Cramer-Rao bound at spacing 2 pi/T)",
    "colored": "coloured-residual sandwich (frequency-domain Morelli-Klein correction)",
    "naive": "naive (2 Re sum A^H R^-1 A)^-1, every frequency independent",
}


def parameter_unit(result, name: str) -> str:
    """Unit of an estimated, fixed or derived quantity of ``result`` ('' if unknown).

    Parameters
    ----------
    result : FitResult
        The fit.
    name : str
        The quantity's name (an estimate's, with its record suffix, a fixed parameter's or a derived one's).

    Returns
    -------
    str
        The unit (``"1/rad"``, ``"s"``, ...), or ``''``.
    """
    slot = result.slot(name) if hasattr(result, "slot") else None
    base = name if slot is None else slot.base
    params = result.model.parameters
    if base in params:
        unit = params[base].unit
        if unit:
            return unit
    if slot is not None and slot.role is Role.INPUT_EDGE:
        return "s"  # a step's timing (docs/theory.md section 7a)
    return _EXTRA_UNITS.get(base, "")


# --- the Summary object ------------------------------------------------------------------------


@dataclass(frozen=True)
class Column:
    """One column of a :class:`Table`.

    Parameters
    ----------
    key : str
        Column name in :meth:`Summary.to_frame`.
    label : str
        Heading in the rendered formats.
    kind : {"text", "num", "err", "pct", "z"}, optional
        How cells are formatted: text as is; ``num`` with the summary's
        significant digits; ``err`` (standard errors) with 4 significant
        digits; ``pct`` and ``z`` with two decimals.  Missing numbers (None,
        NaN) render as empty cells, infinities as ``inf``.
    """

    key: str
    label: str
    kind: str = "text"


@dataclass(frozen=True)
class Table:
    """A titled table of raw values (numbers stay numbers until rendered).

    Parameters
    ----------
    key : str
        Name used by :meth:`Summary.to_frame` (``"parameters"``, ``"derived"``, ...).
    title : str
        Heading in the rendered formats.
    columns : tuple of Column
        The first column is the row label (the DataFrame index).
    rows : tuple of tuple
        The cells, one tuple per row in the order of ``columns``.
    """

    key: str
    title: str
    columns: tuple
    rows: tuple


def _fmt(value, kind: str, digits: int) -> str:
    if kind == "text":
        return "" if value is None else str(value)
    if value is None or math.isnan(float(value)):
        return ""
    return format(float(value), {"num": f".{digits}g", "err": ".4g"}.get(kind, ".2f"))  # pct, z: .2f; inf as "inf"


#: LaTeX's special characters and how each is written as text.
_LATEX = str.maketrans(
    {**{ch: "\\" + ch for ch in "&%$#_{}"}, "\\": r"\textbackslash{}", "^": r"\^{}", "~": r"\textasciitilde{}"}
)


def _cells(t: Table, digits: int) -> list[list[str]]:
    """The table's rows, each cell formatted as its column says."""
    return [[_fmt(v, c.kind, digits) for v, c in zip(row, t.columns)] for row in t.rows]


#: HTML cell alignment, by whether the column holds text.
_ALIGN = {True: "left", False: "right"}


def _latex_escape(text: str) -> str:
    return str(text).translate(_LATEX)


def _md_escape(text: str) -> str:
    return str(text).replace("|", r"\|")


class Summary(str):
    """A fit summary: the plain-text table as a ``str``, renderable in other formats.

    Parameters
    ----------
    title : str
        Heading of the summary.
    header : sequence of (str, str)
        Label/value pairs describing the fit.
    tables : sequence of Table
        The tables, in order.
    notes : sequence of (str, sequence of str)
        Titled lists of remarks (warnings, fixed values, ...), rendered after
        the tables.
    digits : int, optional
        Significant digits of values (standard errors get 4).

    Notes
    -----
    Being a ``str``, a summary prints, compares and concatenates as its text
    form; ``repr()`` shows the table rather than a quoted string.
    """

    title: str  # type: ignore[assignment]  # the summary's title shadows str.title on purpose
    header: tuple
    tables: tuple
    notes: tuple
    digits: int

    def __new__(cls, title: str, header: Sequence = (), tables: Sequence = (), notes: Sequence = (), digits: int = 6):
        header = tuple((str(k), str(v)) for k, v in header)
        tables = tuple(tables)
        notes = tuple((str(t), tuple(str(x) for x in items)) for t, items in notes if items)
        text = _render_text(title, header, tables, notes, digits)
        obj = super().__new__(cls, text)
        obj.title, obj.header, obj.tables, obj.notes, obj.digits = title, header, tables, notes, digits
        return obj

    def __repr__(self) -> str:
        return self.as_text()

    def __reduce__(self):
        return (Summary, (self.title, self.header, self.tables, self.notes, self.digits))

    # --- formats -------------------------------------------------------------------------
    def as_text(self) -> str:
        """The plain-text table (the summary's ``str`` value).

        Returns
        -------
        str
            The text.
        """
        return str.__str__(self)

    def table(self, key: str) -> Table:
        """The table named ``key`` (``"parameters"``, ``"derived"``, ``"correlations"``, ...).

        Parameters
        ----------
        key : str
            The table's key.

        Returns
        -------
        Table
            The table.
        """
        for t in self.tables:
            if t.key == key:
                return t
        raise KeyError(f"no table {key!r} in this summary; tables: {', '.join(t.key for t in self.tables)}")

    def as_markdown(self) -> str:
        """GitHub-flavoured Markdown: a heading, a bullet list of the header, pipe tables.

        Returns
        -------
        str
            The Markdown text.
        """
        lines = [f"### {_md_escape(self.title)}", ""]
        lines += [f"- **{_md_escape(k)}**: {_md_escape(v)}" for k, v in self.header]
        for t in self.tables:
            lines += ["", f"**{_md_escape(t.title)}**", ""]
            lines.append("| " + " | ".join(_md_escape(c.label) for c in t.columns) + " |")
            lines.append("|" + "|".join(":---" if c.kind == "text" else "---:" for c in t.columns) + "|")
            lines += ["| " + " | ".join(map(_md_escape, cells)) + " |" for cells in _cells(t, self.digits)]
        for title, items in self.notes:
            lines += ["", f"**{_md_escape(title)}**", "", *(f"- {_md_escape(x)}" for x in items)]
        return "\n".join(lines) + "\n"

    def as_html(self) -> str:
        """An HTML fragment (well-formed XHTML: every tag closed, text escaped).

        Returns
        -------
        str
            The HTML fragment.
        """
        e = html.escape
        out = ['<div class="fdml-summary">', f"<h4>{e(self.title)}</h4>"]
        if self.header:
            out.append('<table class="fdml-header"><tbody>')
            out += [
                f'<tr><th style="text-align:left">{e(k)}</th><td style="text-align:left">{e(v)}</td></tr>'
                for k, v in self.header
            ]
            out.append("</tbody></table>")
        for t in self.tables:
            out.append(f'<table class="fdml-table fdml-{e(t.key)}">')
            out.append(f"<caption>{e(t.title)}</caption>")
            out.append("<thead><tr>" + "".join(f"<th>{e(c.label)}</th>" for c in t.columns) + "</tr></thead>")
            out.append("<tbody>")
            for cells in _cells(t, self.digits):
                tds = (
                    f'<td style="text-align:{_ALIGN[c.kind == "text"]}">{e(x)}</td>' for x, c in zip(cells, t.columns)
                )
                out.append("<tr>" + "".join(tds) + "</tr>")
            out.append("</tbody></table>")
        for title, items in self.notes:
            out.append(f"<p><b>{e(title)}</b></p><ul>" + "".join(f"<li>{e(x)}</li>" for x in items) + "</ul>")
        out.append("</div>")
        return "\n".join(out)

    def as_latex(self) -> str:
        """LaTeX: a ``center`` block of ``tabular`` environments (no packages needed).

        Returns
        -------
        str
            The LaTeX source.
        """
        x = _latex_escape
        out = [r"\begin{center}", r"\textbf{" + x(self.title) + r"}\\[4pt]"]
        if self.header:
            rows = [f"{x(k)} & {x(v)} \\\\" for k, v in self.header]
            out += [r"\begin{tabular}{ll}", r"\hline", *rows, r"\hline", r"\end{tabular}"]
        for t in self.tables:
            spec = "".join("l" if c.kind == "text" else "r" for c in t.columns)
            out += [
                "",
                r"\medskip",
                r"\textit{" + x(t.title) + r"}\\[2pt]",
                r"\begin{tabular}{" + spec + "}",
                r"\hline",
                " & ".join(x(c.label) for c in t.columns) + r" \\",
                r"\hline",
            ]
            out += [" & ".join(map(x, cells)) + r" \\" for cells in _cells(t, self.digits)]
            out += [r"\hline", r"\end{tabular}"]
        for title, items in self.notes:
            out += ["", r"\medskip", r"\textit{" + x(title) + r"}", r"\begin{itemize}"]
            out += [*(r"\item " + x(i) for i in items), r"\end{itemize}"]
        out.append(r"\end{center}")
        return "\n".join(out) + "\n"

    def to_frame(self, table: str | None = None):
        """A pandas DataFrame of one table, indexed by its first column.

        Parameters
        ----------
        table : str, optional
            Table key; default the first table (``"parameters"`` for a fit,
            ``"derivatives"`` for a comparison).

        Returns
        -------
        pandas.DataFrame
            Raw numbers (not rounded); missing values are NaN.  ``attrs`` holds
            the title and the header as a dict.

        Raises
        ------
        ImportError
            pandas is not installed (``pip install 'fdml[pandas]'``).
        """
        try:
            import pandas as pd
        except ImportError:  # pragma: no cover - exercised with pandas hidden
            raise ImportError(
                "Summary.to_frame needs pandas; install the optional extra: pip install 'fdml[pandas]'"
            ) from None
        t = self.tables[0] if table is None else self.table(table)
        numbers = {c.key: float for c in t.columns[1:] if c.kind != "text"}  # None: NaN
        frame = pd.DataFrame(list(t.rows), columns=[c.key for c in t.columns]).set_index(t.columns[0].key)
        frame = frame.astype(numbers)
        frame.attrs["title"] = self.title
        frame.attrs["header"] = dict(self.header)
        return frame

    # --- notebook hooks ---------------------------------------------------------------------
    def _repr_html_(self) -> str:
        return self.as_html()

    def _repr_latex_(self) -> str:
        return self.as_latex()


def _render_text(title, header, tables, notes, digits) -> str:
    lines = [title, "=" * min(max(len(title), 20), 100)]
    if header:
        w = max(len(k) for k, _ in header) + 1
        lines += [f"{k + ':':>{w}s} {v}" for k, v in header]
    for t in tables:
        cells = _cells(t, digits)
        widths = [max([len(c.label)] + [len(r[j]) for r in cells]) for j, c in enumerate(t.columns)]
        widths[0] = max(widths[0], 12)

        def line(items):
            cells = (s.ljust(w) if c.kind == "text" else s.rjust(w) for s, w, c in zip(items, widths, t.columns))
            return "  ".join(cells).rstrip()

        lines += ["", t.title, line([c.label for c in t.columns])]
        lines += [line(r) for r in cells]
    for title_, items in notes:
        lines += ["", f"{title_}:", *(f"  {x}" for x in items)]
    return "\n".join(lines)


# --- fits --------------------------------------------------------------------------------------


def _biases_used(res) -> list[str]:
    """Which bias terms a fit estimated, from the roles of its estimates and fixed parameters."""
    roles = {s.role for s in res.slots}
    outs = [b[len("bias_") :] for b in dict.fromkeys(s.base for s in res.slots if s.role is Role.OUTPUT_BIAS)]
    edges = sum(s.role is Role.INPUT_EDGE for s in res.slots)
    params = res.model.parameters
    fixed = [k for k, v in res.fixed.items() if k in params and params[k].role.nuisance and v != 0.0]
    used = [
        "output biases " + ",".join(outs) if outs else None,
        "state-equation biases" if Role.STATE_BIAS in roles else None,
        "elevator bias" if Role.INPUT_BIAS in roles else None,
        f"timing of {edges} elevator step(s) between samples" if edges else None,
        "fixed " + ", ".join(fixed) if fixed else None,
    ]
    return [u for u in used if u is not None]


#: Where a fit's airspeed came from (``FitResult.provenance["airspeed"]["source"]``), in words.
_AIRSPEED_SOURCES = {
    "record": "the record's mean airspeed",
    "--airspeed": "given with --airspeed",
    "aircraft": "the aircraft's U",
}


def _airspeed(res) -> str | None:
    """The fit's airspeed and where it came from, or None for a model without one."""
    given = (getattr(res, "provenance", None) or {}).get("airspeed")
    if isinstance(given, Mapping) and given.get("value") is not None:
        src = str(given.get("source"))
        return f"{float(given['value']):.4g} m/s ({_AIRSPEED_SOURCES.get(src, src)})"
    U = model_airspeed(res.model)
    if U is None:
        return None
    ac = getattr(res.model, "aircraft", None)
    return f"{U:.4g} m/s ({'aircraft ' + ac.name if ac is not None else 'given to the model'})"


def _band(res) -> str:
    """The fitted band (or frequencies) in words, with the number of frequencies."""
    if res.band is not None:
        lo, hi, step = res.band
        return (
            f"{lo:g}-{hi:g} rad/s, step {step:g} ({lo / (2 * math.pi):.3g}-{hi / (2 * math.pi):.3g} Hz); "
            f"{res.n_freq} frequencies"
        )
    if res.spectra:
        w = np.concatenate([s.omega for s in res.spectra])
        return f"{w.min():.4g}-{w.max():.4g} rad/s (given frequencies); {res.n_freq} frequencies"
    return f"{res.n_freq} frequencies"


def _header(res) -> list[tuple[str, str]]:
    verdict = "stopped by the callback" if res.stopped else "converged" if res.converged else "NOT converged"
    msg = res.message.removeprefix("converged: ").removeprefix("converged, ")
    h = [
        ("model", res.model.describe()),
        ("aircraft", getattr(getattr(res.model, "aircraft", None), "name", None) or None),
        ("airspeed", _airspeed(res)),
        ("records", ", ".join(res.records)),
        ("outputs", ", ".join(res.outputs)),
        ("band", _band(res)),
        ("boundary terms", res.boundary),
        ("biases", "; ".join(_biases_used(res)) or "no biases"),
        ("trim", ",".join(dict.fromkeys(str(d.trim_mode) for d in res.spectra)) or None),
        ("standard errors", f"{res.cov_type}: {_COV_TYPES.get(res.cov_type, res.cov_type)}"),
        ("method", f"{res.method}, stop rule {res.stop!r}"),
        ("convergence", f"{verdict} after {res.iterations} iterations: {msg}"),
        ("cost J = det R", f"{res.cost:.6g} (start {res.cost_history[0]:.6g})"),
        ("elapsed", f"{res.elapsed:.3g} s"),
    ]
    return [(k, v) for k, v in h if v is not None]  # no aircraft, airspeed or trim to tell: no line


def _flags(res, name: str, stderr: float) -> str:
    flags = {"at bound": name in res.at_bound, "not identifiable": not math.isfinite(stderr)}
    return ", ".join(f for f, on in flags.items() if on)


def _row(res, name: str, value: float, stderr: float, flags: str) -> tuple:
    """A row of the estimates' (or the derived set's) table."""
    return (name, value, stderr, _rel(value, stderr), flags, parameter_unit(res, name))


def _rel(value: float, stderr: float) -> float:
    if not math.isfinite(stderr):
        return math.inf
    if value == 0:
        return math.inf if stderr > 0 else 0.0
    return abs(stderr / value) * 100.0


_PARAM_COLUMNS = (
    Column("parameter", "parameter"),
    Column("value", "value", "num"),
    Column("stderr", "std err", "err"),
    Column("rel_err_pct", "rel err %", "pct"),
    Column("flags", "flags"),
    Column("unit", "unit"),
)


def _shown_fixed(res) -> dict:
    """Fixed parameters worth listing (zero biases and zero delays are absent terms, not choices)."""
    params = res.model.parameters
    absent = {Role.DELAY} | NUISANCE_ROLES
    return {k: v for k, v in res.fixed.items() if not (v == 0.0 and k in params and params[k].role in absent)}


def fit_summary(res, digits: int = 6) -> Summary:
    """The :class:`Summary` of a :class:`~fdml.results.FitResult`.

    Tables: ``parameters`` (estimates, then the listed fixed parameters
    flagged ``fixed``), ``derived`` (the alternate set with delta-method
    standard errors) and ``correlations`` (pairs at or above ``SETTINGS.correlation_listed``, 0.9); notes:
    the data check's findings (with their codes), the adequacy check
    (:mod:`fdml.adequacy`: flagged effects, or that nothing was flagged) and
    the warnings raised by the fit.

    Parameters
    ----------
    res : FitResult
        The fit.
    digits : int, optional
        Significant digits of values.

    Returns
    -------
    Summary
        The tables and notes.
    """
    rows = [
        _row(res, n, v, s, _flags(res, n, s)) for n, v, s in zip(res.names, res.values.tolist(), res.stderr.tolist())
    ]
    rows += [(k, float(v), None, None, "fixed", parameter_unit(res, k)) for k, v in _shown_fixed(res).items()]
    tables = [Table("parameters", "Estimates", _PARAM_COLUMNS, tuple(rows))]
    if res.derived:
        drows = tuple(
            _row(res, k, float(v), float(s), "" if math.isfinite(s) else "not identifiable")
            for k, (v, s) in res.derived.items()
        )
        dcols = (Column("quantity", "derived"),) + _PARAM_COLUMNS[1:]
        tables.append(Table("derived", "Derived set (delta method)", dcols, drows))
    listed = SETTINGS.correlation_listed  # the estimator's named thresholds
    corr = np.asarray(res.corr, float)
    below = zip(*np.tril_indices(len(res.names), -1))  # (i, j), j < i, row by row
    pairs = [(res.names[j], res.names[i], float(corr[i, j])) for i, j in below if abs(corr[i, j]) >= listed]
    if pairs:
        pairs.sort(key=lambda p: -abs(p[2]))
        ccols = (
            Column("parameter_1", "parameter"),
            Column("parameter_2", "with"),
            Column("correlation", "correlation", "z"),
        )
        tables.append(Table("correlations", f"Correlations |r| >= {listed:g}", ccols, tuple(pairs)))
    notes = [("data check", [str(f) for f in getattr(res, "findings", ())]), ("warnings", list(res.warnings))]
    if getattr(res, "adequacy", None) is not None:  # fdml.adequacy: score tests and residual checks
        notes.insert(1, ("adequacy", res.adequacy.lines()))
    title = f"fdml fit: {res.model.describe()}"
    return Summary(title, _header(res), tables, notes, digits=digits)


# --- steady versus unsteady ------------------------------------------------------------------


def comparison_summary(cmp, reference: Mapping | None = None, digits: int = 4) -> Summary:
    """The :class:`Summary` of a :class:`~fdml.compare.Comparison` (WK Tables 1 and 3 layout).

    Parameters
    ----------
    cmp : Comparison
        The steady and unsteady fits of one record.
    reference : mapping, optional
        ``{name: (unsteady, steady)}``, e.g. a paper's columns.
    digits : int, optional
        Significant digits of values.

    Returns
    -------
    Summary
        One table, ``derivatives``: unsteady and steady values with standard
        errors, and their difference in combined standard errors
        (``shift/sigma``).
    """
    from .models.wells_keskar import ALTERNATE_NAMES

    cols = [
        Column("derivative", "derivative"),
        Column("unsteady", "unsteady", "num"),
        Column("unsteady_stderr", "+/-", "err"),
        Column("steady", "steady", "num"),
        Column("steady_stderr", "+/-", "err"),
        Column("shift_sigma", "shift/sigma", "z"),
    ]
    if reference:
        cols += [Column("reference_unsteady", "paper unst.", "num"), Column("reference_steady", "paper steady", "num")]
    rows = []
    for n in ALTERNATE_NAMES:
        u, su = cmp.unsteady_set.get(n, (math.nan, math.nan))
        s, ss = cmp.steady_set.get(n, (math.nan, math.nan))
        sig = math.hypot(su, ss)
        z = (s - u) / sig if sig > 0 and math.isfinite(sig) else math.nan
        paper = reference.get(n, (math.nan, math.nan)) if reference else ()  # (unsteady, steady)
        rows.append((n, u, su, s, ss, z, *paper))
    header = [
        ("unsteady model", cmp.unsteady.model.describe()),
        ("steady model", cmp.steady.model.describe()),
        ("records", ", ".join(cmp.unsteady.records)),
        ("cost det R", f"unsteady {cmp.unsteady.cost:.4g}, steady {cmp.steady.cost:.4g}"),
        ("standard errors", f"{cmp.unsteady.cov_type}; q-derivatives per q c/(2U)"),
    ]
    notes = [("unsteady fit warnings", list(cmp.unsteady.warnings)), ("steady fit warnings", list(cmp.steady.warnings))]
    return Summary(
        "steady versus unsteady derivatives",
        header,
        [Table("derivatives", "Derivatives (1/rad)", tuple(cols), tuple(rows))],
        notes,
        digits=digits,
    )
