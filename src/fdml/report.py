"""A fit report in a folder: figures (PNG) and a Markdown page that links them.

:func:`write_report` takes a :class:`~fdml.results.FitResult` or the JSON file
it was saved to and writes, per record, the measured-against-fitted spectra
with their Cramer-Rao band, the time-domain cross-check and the residual
spectra, plus the parameter correlation matrix, and ``report.md`` with the
summary table, the derived set, correlations, warnings, the convergence
history and the figure links.  Files are written under temporary names and
renamed into place only when all of them are done
(:class:`fdml.outputs.StagedOutputs`), so a failed report never leaves a
half-written set; the folder and every file in it are checked first, so a
report never writes over the result it reads.  ``fdml report RESULT.json``
calls it.

Figures are drawn on :class:`matplotlib.figure.Figure` objects directly (no
pyplot), so the report neither needs a display nor touches pyplot's state.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["write_report"]


def _load(result_or_path):
    from .results import FitResult, load_result

    if isinstance(result_or_path, FitResult):
        return result_or_path, None
    path = Path(result_or_path)
    return load_result(path), path


def _default_dir(source: Path | None) -> Path:
    return Path("fdml-report") if source is None else source.with_name(source.stem + "-report")


_TIME_CAPTION = "Time histories: measured against the model simulated in the time domain from the estimate"


def _figure(figsize, dpi: int, constrained: bool = True):
    """A figure at the resolution it is saved at (text extents, and so the layout, depend on it)."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, dpi=dpi, layout="constrained" if constrained else None)


def write_report(
    result_or_path, out_dir=None, *, freq_unit: str = "rad/s", dpi: int = 110, trim_window: float | None = None
) -> dict:
    """Write a fit's figures and a Markdown report into a folder.

    Parameters
    ----------
    result_or_path : FitResult or str or Path
        A fit, or a result JSON file written by :meth:`FitResult.to_json`.
    out_dir : str or Path, optional
        Folder (created if needed).  Default ``<RESULT>-report`` beside the
        JSON file, or ``./fdml-report`` for a FitResult.
    freq_unit : {"rad/s", "Hz"}, optional
        Frequency axis of the spectra figures.
    dpi : int, optional
        Resolution of the PNG files.
    trim_window : float, optional
        Leading window of ``trim="mean"`` fits, s (for the time histories);
        default the fit's own (``FitResult.options``).

    Returns
    -------
    dict of str to Path
        ``report`` (report.md), ``correlation`` and, per record,
        ``spectra``, ``time_histories``, ``residual_spectra`` (suffixed
        ``_<i>`` when the fit has several records).  A time-history figure
        that cannot be drawn (a fit given spectra only, or an unsteady-model
        record whose inputs step at t = 0) is left out and the report says why.
    """
    from .errors import FdmlError
    from .outputs import StagedOutputs, check_output_folder
    from .plotting import plot_correlation, plot_residual_spectra, plot_spectra, plot_time_histories, settle_layout

    res, source = _load(result_or_path)
    out = Path(out_dir) if out_dir is not None else _default_dir(source)
    inputs = [] if source is None else [source]
    # every output checked before any drawing
    check_output_folder(out, dict.fromkeys(_file_names(len(res.spectra)), "report file"), inputs, what="report folder")
    staged = StagedOutputs(inputs)  # nothing is renamed into place before every file is written
    pending: dict[str, Path] = {}  # key (the file's stem) -> final path
    figures: list[tuple[str, str, str]] = []  # (record label, caption, file name)
    notes: list[str] = []

    def save(fig, stem: str, rname: str, caption: str) -> None:
        pending[stem] = staged.savefig(fig, out / f"{stem}.png", dpi=dpi, format="png")
        figures.append((rname, caption, f"{stem}.png"))

    n_out = len(res.outputs)
    with staged:
        for i, spec in enumerate(res.spectra):
            sfx = f"_{i}" if len(res.spectra) > 1 else ""
            rname = spec.name
            fig = _figure((4.2 * n_out, 6.4), dpi)
            axes = fig.subplots(2, n_out, sharex=True, squeeze=False)
            title = f"{rname}: measured and fitted spectra ({res.kind}), 2-sigma band"
            plot_spectra(res, record=i, freq_unit=freq_unit, axes=axes, title=title)
            save(fig, "spectra" + sfx, rname, "Measured against fitted spectra with the 2-sigma Cramer-Rao band")
            if spec.record is None:
                notes.append(
                    f"record {rname}: time histories not drawn (the fit was given spectra, not time-domain records)"
                )
            else:
                try:
                    fig = _figure((8, 2.0 * 4 + 1.0), dpi)
                    axes = fig.subplots(4, 1, sharex=True, squeeze=False)
                    title = f"{rname}: measured and simulated from the estimate"
                    plot_time_histories(res, record=i, axes=axes, trim_window=trim_window, title=title)
                    save(fig, "time_histories" + sfx, rname, _TIME_CAPTION)
                except FdmlError as exc:  # the report goes on without this figure
                    notes.append(f"record {rname}: time histories not drawn ({exc})")
            fig = _figure((4.2 * n_out, 3.8), dpi)
            axes = fig.subplots(1, n_out, squeeze=False)
            title = f"{rname}: residual spectra and the noise floor implied by R"
            plot_residual_spectra(res, record=i, freq_unit=freq_unit, axes=axes, title=title)
            save(fig, "residual_spectra" + sfx, rname, "Residual spectra |z - y| with sqrt(R_kk) and its 95 % level")
        size = max(3.5, 0.45 * len(res.names) + 1.8)
        fig = _figure((size + 1.0, size), dpi, constrained=False)
        plot_correlation(res, ax=fig.subplots())
        settle_layout(fig)  # a fixed-aspect heat map with a colour bar
        save(fig, "correlation", "", "Correlation of the estimates")
        text = _markdown(res, source, figures, notes)
        pending["report"] = staged.write_text(out / "report.md", text, what="report file")
    return {"report": pending.pop("report"), **pending}


def _file_names(n_records: int) -> list[str]:
    """Every file name a report of ``n_records`` records may write."""
    sfx = [f"_{i}" for i in range(n_records)] if n_records > 1 else [""]
    stems = [f"{k}{s}" for s in sfx for k in ("spectra", "time_histories", "residual_spectra")]
    return ["report.md", "correlation.png"] + [f"{s}.png" for s in stems]


def _markdown(res, source, figures, notes) -> str:
    from . import __version__

    s = res.summary()
    s = type(s)(s.title, s.header, s.tables, [n for n in s.notes if n[0] != "warnings"], digits=s.digits)
    lines = [f"# fdml report: {res.model.describe()}", ""]
    lines.append(f"fdml {__version__}." if source is None else f"Result file: `{source.name}` (fdml {__version__}).")
    lines += ["", "## Summary", "", s.as_markdown().replace("### ", "#### ", 1), ""]  # warnings: below, once
    lines += ["## Convergence", ""]
    verdict = "stopped by the callback" if res.stopped else "converged" if res.converged else "NOT converged"
    lines.append(f"{verdict} after {res.iterations} iterations ({res.method}, stop rule {res.stop!r}): {res.message}.")
    lines += ["", "| iteration | J = det R | relative change |", "|---:|---:|---:|"]
    for k, (prev, J) in enumerate(zip((None, *res.cost_history), res.cost_history)):
        rel = "" if prev is None or prev == 0 else f"{(J - prev) / prev:+.3g}"
        lines.append(f"| {k} | {J:.6g} | {rel} |")
    lines += ["", "## Warnings", ""]
    lines += [f"- {w}" for w in (*res.warnings, *notes)] or ["None."]
    lines += ["", "## Figures", ""]
    current = None
    for rec, caption, fname in figures:
        if rec and rec != current:
            lines += [f"### Record `{rec}`", ""]
            current = rec
        elif not rec and current is not None:
            lines += ["### All records", ""]
            current = None
        lines += [f"**{caption}**", "", f"![{caption}]({fname})", ""]
    return "\n".join(lines).rstrip() + "\n"
