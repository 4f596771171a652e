"""The diagnosis figure: gap map before and after, and Bode overlays against the data."""

from __future__ import annotations

import numpy as np

from ..channels import OUTPUTS
from ..plotting import figure_legend, phase_on_one_branch

__all__ = ["plot_report"]

_CH = {"alpha": r"$\alpha$", "q": "$q$", "az": "$a_z$"}
#: What a gap-map cell shows, written above the diagnosis in the figure.
_MAP_KEY = (
    "Gap map, per output and band: the excess coherent energy of the residual over the noise floor, in "
    "floor units (noise alone gives about 0, and negative values, less than noise alone); then the "
    "measured/model gain (dB) and phase (deg); * significant after Holm.  After: the same with the "
    "final model."
)


def _map_array(cells, channels, nb):
    X = np.array([np.nan if c.get("excess") is None else c["excess"] for c in cells], float)
    sig = np.array([bool(c.get("significant")) for c in cells])
    return X.reshape(len(channels), nb), sig.reshape(len(channels), nb)


def _draw_map(ax, cells, channels, edges, title, vmax):
    nb = len(edges) - 1
    X, sig = _map_array(cells, channels, nb)
    V = np.log10(1.0 + np.maximum(np.nan_to_num(X, nan=0.0), 0.0))
    im = ax.imshow(V, aspect="auto", cmap="magma_r", vmin=0, vmax=vmax, origin="upper")
    for i, c in enumerate(cells):
        r, b = divmod(i, nb)
        txt = "-" if c.get("excess") is None else f"{c['excess']:.0f}"
        if c.get("gain_db") is not None and c.get("phase_deg") is not None:
            txt += f"\n{c['gain_db']:+.1f} dB\n{c['phase_deg']:+.1f}°"
        color = "white" if V[r, b] > 0.6 * vmax else "black"
        ax.text(b, r, txt + (" *" if sig[r, b] else ""), ha="center", va="center", fontsize=7, color=color)
    ax.set_xticks(range(nb))
    ax.set_xticklabels([f"{edges[i]:.2g}-{edges[i + 1]:.2g}" for i in range(nb)], fontsize=7)
    ax.set_yticks(range(len(channels)))
    ax.set_yticklabels([_CH.get(c, c) for c in channels])
    ax.set_xlabel("band, rad/s")
    ax.set_title(title, fontsize=9)
    return im


def plot_report(rep, path=None):
    """Figure of a :class:`~fdml.diagnose.report.DiagnosisReport`; saved to ``path`` when given.

    Top: the gap map (excess coherent energy in noise-floor units, with the
    band's gain and phase error; * = significant after Holm) before and after
    the final model.  Below: magnitude and phase of the elevator frequency
    response per output, the data (model plus residual over input at the
    independent frequencies) against the base and the final models.

    Parameters
    ----------
    rep : DiagnosisReport
        A diagnosis with its ``details`` (a fresh one, not one read from JSON).
    path : str or Path, optional
        Image file to write (atomically; the figure is then closed).

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    import matplotlib

    if path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    det = rep.details
    data, base, final = det["data"], det["base_fit"], det["final_fit"]
    channels, edges = det["channels"], det["edges"]
    fig = plt.figure(figsize=(11, 9), constrained_layout=True)
    gs = fig.add_gridspec(3, 3, height_ratios=[1.0, 1.1, 1.1])
    X0, _ = _map_array(rep.location, channels, len(edges) - 1)
    vmax = max(float(np.nanmax(np.log10(1 + np.maximum(np.nan_to_num(X0), 0)))) if np.isfinite(X0).any() else 1, 1)
    ax0 = fig.add_subplot(gs[0, 0:1])
    _draw_map(ax0, rep.location, channels, edges, "gap map, base model", vmax)
    ax1 = fig.add_subplot(gs[0, 1:2])
    lab = "+".join(s["key"] for s in rep.selected) or "(no effect accepted)"
    im = _draw_map(ax1, rep.location_after or rep.location, channels, edges, f"after: {lab}", vmax)
    fig.colorbar(im, ax=[ax0, ax1], label="log10(1 + excess)", shrink=0.8)
    axt = fig.add_subplot(gs[0, 2])
    axt.axis("off")
    # Bode overlays (elevator column) at the independent frequencies
    rows = np.flatnonzero(data.stacked_dft())
    om = data.stacked_omega()[rows]
    order = np.argsort(om)
    u = np.concatenate([d.u[:, 0] for d in data.spectra])[rows]
    e = base.full_residual()[rows]
    Gb = np.concatenate([base.model.evaluate(d.omega).G[:, :, 0] for d in data.spectra])[rows]
    Gf = np.concatenate([final.model.evaluate(d.omega).G[:, :, 0] for d in data.spectra])[rows]
    good = np.abs(u) > 0.05 * np.max(np.abs(u))
    Gd = Gb + e / np.where(good, u, 1.0)[:, None]
    bode = []
    for j, ch in enumerate(OUTPUTS):
        axm = fig.add_subplot(gs[1, j])
        axp = fig.add_subplot(gs[2, j], sharex=axm)
        k = order[good[order]]
        # the base model unwrapped along frequency; the data and the final model on its branch
        ph_b, ph_d, ph_f = phase_on_one_branch(Gb[order, j], Gd[order, j], Gf[order, j])
        axm.semilogx(om[k], 20 * np.log10(np.abs(Gd[k, j])), "k.", ms=4, label="data")
        axp.semilogx(om[k], ph_d[good[order]], "k.", ms=4)
        for G, ph, st, name in ((Gb, ph_b, "C0-", "base"), (Gf, ph_f, "C3--", "final")):
            axm.semilogx(om[order], 20 * np.log10(np.abs(G[order, j])), st, lw=1.2, label=name)
            axp.semilogx(om[order], ph, st, lw=1.2)
        axm.set_title(f"{_CH[ch]} / $\\delta_e$", fontsize=9)
        axm.set_ylabel("dB")
        axp.set_ylabel("deg")
        axp.set_xlabel("rad/s")
        for x in edges[1:-1]:
            axm.axvline(x, color="0.8", lw=0.6)
            axp.axvline(x, color="0.8", lw=0.6)
        bode.append(axm)
    figure_legend(fig, bode[:1], ncol=3)
    _fit_text(axt, _MAP_KEY + "\n\n" + rep.text, fontsize=6.5)
    if path is not None:
        from ..outputs import atomic_savefig

        atomic_savefig(fig, path, dpi=110, close=True)
    return fig


def _wrap(text: str, width: int) -> str:
    """Each paragraph of ``text`` wrapped to ``width`` characters."""
    import textwrap

    return "\n".join("\n".join(textwrap.wrap(p, width)) if p else "" for p in text.split("\n"))


def _fit_text(ax, text: str, fontsize: float) -> None:
    """Write ``text`` into ``ax`` (an axes without a plot) from its top left, wrapped and sized to fit inside it.

    The axes' box is known only once the layout has run, so the figure is laid
    out first; then the widest wrap whose drawn box lies inside the axes is
    kept, at a smaller font when no wrap fits.  The text takes no part in the
    layout (the axes' cell gives its room).
    """
    fig = ax.figure
    fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    box = ax.get_window_extent(renderer)
    t = ax.text(0, 1, "", va="top", ha="left", fontsize=fontsize, transform=ax.transAxes)
    t.set_in_layout(False)
    size = fontsize
    while True:
        for width in range(100, 24, -4):
            t.set_text(_wrap(text, width))
            t.set_fontsize(size)
            tb = t.get_window_extent(renderer)
            if tb.x1 <= box.x1 and tb.y0 >= box.y0:
                return
        if size <= 4.0:
            return  # the smallest font and wrap: shown as far as it goes
        size -= 0.5
