"""What a user sees in a figure, checked from matplotlib's own geometry (the one helper the figure tests share).

:func:`layout_problems` draws the figure and reads, in display coordinates (pixels):

* every text that was drawn (``Text.draw`` is watched during the draw, so tick labels outside
  the view and hidden labels do not count) and its bounding box, ``Text.get_window_extent``;
* every axes' plotting area, ``Axes.bbox``;
* every legend's box, ``Legend.get_window_extent``;
* the plotted data: each ``Line2D`` in data coordinates through its transform, densified to
  one point per pixel along its segments and kept where it is drawn (inside its axes), and
  each bar of a bar chart.

and reports, one line each:

* a text whose box leaves the figure (clipped when saved);
* a text over the plotting area of an axes it does not belong to (a y-label over the
  neighbouring panel), or two texts of different axes that overlap;
* a legend that covers plotted data, in its own axes or any other.
"""

from __future__ import annotations

from unittest import mock

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.container import BarContainer
from matplotlib.text import Text

#: Pixels of slack: antialiasing and rounding of text extents.
TOL = 1.0


def _draw(fig):
    """Draw ``fig`` and return (renderer, the texts drawn, with their boxes)."""
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    drawn: list[Text] = []
    original = Text.draw

    def watch(self, renderer):
        if self.get_visible() and self.get_text().strip():
            drawn.append(self)
        return original(self, renderer)

    with mock.patch.object(Text, "draw", watch):
        canvas.draw()
    renderer = canvas.get_renderer()
    unique = list({id(t): t for t in drawn}.values())
    return renderer, [(t, t.get_window_extent(renderer)) for t in unique]


def _owners(fig) -> dict:
    """id(text) -> what it belongs to: its axes (tick labels, axis labels, title, legend, annotations), else
    its figure legend; a figure-level text (a suptitle) not in this map is its own."""
    out = {id(t): leg for leg in fig.legends for t in leg.findobj(Text)}
    out |= {id(t): ax for ax in fig.axes for t in ax.findobj(Text)}
    return out


def _name(t: Text, owner) -> str:
    if isinstance(owner, Axes):
        where = f"axes {owner.get_title()!r}" if owner.get_title() else "an untitled axes"
    else:
        where = "a figure legend" if owner is not t else "figure"
    return f"text {t.get_text()[:40]!r} ({where})"


def _overlap(a, b) -> bool:
    """Boxes overlapping by more than TOL pixels both ways."""
    return min(a.x1, b.x1) - max(a.x0, b.x0) > TOL and min(a.y1, b.y1) - max(a.y0, b.y0) > TOL


def _plot_areas(fig) -> list[Axes]:
    """Axes with a visible plotting area (an ``axis("off")`` panel holds text, not a plot)."""
    return [ax for ax in fig.axes if ax.get_visible() and ax.axison]


def _line_points(line, ax) -> np.ndarray:
    """The drawn points of a data line in pixels: one per pixel along each segment, inside its axes."""
    if not line.get_visible() or line.get_transform() != ax.transData:
        return np.empty((0, 2))  # axhline/axvline and the like are furniture, not data
    xy = np.column_stack([np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)])
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if xy.size == 0:
        return np.empty((0, 2))
    px = line.get_transform().transform(xy)
    if line.get_linestyle() not in ("None", "", " ") and len(px) > 1:
        steps = np.maximum(np.ceil(np.hypot(*np.diff(px, axis=0).T)).astype(int), 1)
        parts = [p0 + np.linspace(0, 1, n, endpoint=False)[:, None] * (p1 - p0) for p0, p1, n in zip(px, px[1:], steps)]
        px = np.vstack([*parts, px[-1:]])
    box = ax.bbox
    inside = (px[:, 0] >= box.x0) & (px[:, 0] <= box.x1) & (px[:, 1] >= box.y0) & (px[:, 1] <= box.y1)
    return px[inside]


def _legends(fig):
    out = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return out + list(fig.legends)


def layout_problems(fig) -> list[str]:
    """Every way ``fig`` hides what it shows: clipped text, text over other panels, legends over data."""
    renderer, texts = _draw(fig)
    owners = _owners(fig)
    owner = {id(t): owners.get(id(t), t) for t, _ in texts}
    name = {id(t): _name(t, owner[id(t)]) for t, _ in texts}
    W, H = fig.bbox.width, fig.bbox.height
    problems = []
    for t, box in texts:
        if box.x0 < -TOL or box.y0 < -TOL or box.x1 > W + TOL or box.y1 > H + TOL:
            problems.append(
                f"{name[id(t)]} leaves the figure: ({box.x0:.0f}, {box.y0:.0f})-({box.x1:.0f}, "
                f"{box.y1:.0f}) px in {W:.0f} x {H:.0f} px"
            )
    areas = _plot_areas(fig)
    for t, box in texts:
        for ax in areas:
            if ax is not owner[id(t)] and _overlap(box, ax.bbox):
                problems.append(f"{name[id(t)]} lies over the plotting area of another axes ({ax.get_title()!r})")
    for i, (t, box) in enumerate(texts):
        for u, other in texts[i + 1 :]:
            if owner[id(t)] is not owner[id(u)] and _overlap(box, other):
                problems.append(f"{name[id(t)]} overlaps {name[id(u)]}")
    for leg in _legends(fig):
        lb = leg.get_window_extent(renderer).padded(-TOL)
        for ax in fig.axes:
            pts = np.vstack([_line_points(line, ax) for line in ax.get_lines()] or [np.empty((0, 2))])
            hit = (pts[:, 0] > lb.x0) & (pts[:, 0] < lb.x1) & (pts[:, 1] > lb.y0) & (pts[:, 1] < lb.y1)
            if np.any(hit):
                problems.append(f"a legend covers {int(hit.sum())} px of the data of axes {ax.get_title()!r}")
            bars = [p for c in ax.containers if isinstance(c, BarContainer) for p in c.patches]
            if any(_overlap(lb, p.get_window_extent(renderer)) for p in bars):
                problems.append(f"a legend covers bars of axes {ax.get_title()!r}")
    return problems


def assert_layout(fig) -> None:
    """Fail, listing every problem :func:`layout_problems` finds in ``fig``."""
    problems = layout_problems(fig)
    assert not problems, "\n".join(problems)
