"""Figures of fits, with matplotlib (imported only when a plot is made).

Every function takes ``axes=`` (or makes its own figure), returns
``(figure, axes)`` and never calls ``show()``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["plot_spectra"]

_LABELS = {"alpha": r"$\tilde\alpha$ (rad s)", "q": r"$\tilde q$ (rad)", "az": r"$\tilde a_z$ (g s)"}


def _freq(omega: np.ndarray, unit: str):
    if unit == "rad/s":
        return omega, "frequency (rad/s)"
    if unit == "Hz":
        return omega / (2 * np.pi), "frequency (Hz)"
    raise ValueError(f"freq_unit must be 'rad/s' or 'Hz', got {unit!r}")


def plot_spectra(results, labels: Sequence[str] | None = None, *, record: int = 0,
                 outputs: Sequence[str] | None = None, freq_unit: str = "rad/s", axes=None,
                 title: str | None = None):
    """Measured against fitted output spectra, magnitude and phase (the layout of WK Figs. 3-5).

    Magnitudes are those of the output spectra; phases are taken relative to
    the elevator spectrum, i.e. the phase of the transfer function.

    Parameters
    ----------
    results : FitResult or sequence of FitResult
        Fits of the same record; the measured spectra are taken from the first.
    labels : sequence of str, optional
        Legend entries for the fits (default: model kinds).
    record : int, optional
        Which record of a multi-record fit.
    outputs : sequence of str, optional
        Outputs to show (default: those of the first fit).
    freq_unit : {"rad/s", "Hz"}, optional
    axes : array of Axes, shape (2, n_outputs), optional
        Magnitude row and phase row; made if not given.
    title : str, optional

    Returns
    -------
    fig : matplotlib.figure.Figure
    axes : ndarray of Axes, shape (2, n_outputs)
    """
    import matplotlib.pyplot as plt

    if not isinstance(results, (list, tuple)):
        results = [results]
    labels = list(labels) if labels is not None else [r.kind for r in results]
    outputs = list(outputs or results[0].outputs)
    spec = results[0].spectra[record]
    f, flabel = _freq(spec["omega"], freq_unit)
    if axes is None:
        fig, axes = plt.subplots(2, len(outputs), figsize=(4.2 * len(outputs), 6), sharex=True, squeeze=False)
    else:
        axes = np.asarray(axes).reshape(2, len(outputs))
        fig = axes[0, 0].figure
    names = ("alpha", "q", "az")
    # phase relative to the elevator spectrum: removes the manoeuvre's timing
    # (exp(-j w t_0)) without dividing magnitudes by the input's spectral zeros
    ref = np.exp(-1j * np.angle(spec["u"][:, 0]))
    for j, out in enumerate(outputs):
        k = names.index(out)
        z = spec["z"][:, k]
        ax_m, ax_p = axes[0, j], axes[1, j]
        ax_m.semilogy(f, np.abs(z), "k.", ms=4, label="measured")
        ax_p.plot(f, np.degrees(np.unwrap(np.angle(z * ref))), "k.", ms=4)
        for res, lab in zip(results, labels):
            y = res.fitted_spectra(record)[:, k]
            ax_m.semilogy(f, np.abs(y), "-", lw=1.5, label=lab)
            ax_p.plot(f, np.degrees(np.unwrap(np.angle(y * ref))), "-", lw=1.5)
        ax_m.set_title(out)
        ax_m.set_ylabel("|" + _LABELS[out] + "|")
        ax_p.set_ylabel("phase re elevator (deg)")
        ax_p.set_xlabel(flabel)
        ax_m.grid(True, which="both", alpha=0.3)
        ax_p.grid(True, alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize="small")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig, axes
