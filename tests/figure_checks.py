"""Layout checks of rendered matplotlib figures (used by the figure tests): no text leaves the canvas, no
legend covers plotted data (lines in data coordinates, bars, scatter points and filled areas of any axes)."""
from __future__ import annotations

import numpy as np

TOL_PX = 1.0


def captured_figures(monkeypatch):
    """A list that collects every figure passed to pyplot.close (the figure functions close what they save)."""
    import matplotlib.pyplot as plt

    figures = []
    monkeypatch.setattr(plt, "close", lambda fig=None: figures.append(fig))
    return figures


def _data_points(ax):
    """Display coordinates of the data an axes shows (lines and patches in data coordinates, collections)."""
    from matplotlib.collections import PolyCollection, PathCollection
    from matplotlib.patches import Rectangle

    pts = []
    for line in ax.get_lines():
        if not line.get_visible() or line.get_transform() != ax.transData:
            continue              # axhline/axvline and the like: reference lines spanning the axes
        xy = np.column_stack([np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)])
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if len(xy):
            pts.append(ax.transData.transform(xy))
    for p in ax.patches:
        if isinstance(p, Rectangle) and p.get_visible() and p.get_transform() != ax.transAxes:
            bb = p.get_window_extent()
            pts.append(np.array([[bb.x0, bb.y0], [bb.x1, bb.y1], [bb.x0, bb.y1], [bb.x1, bb.y0],
                                 [(bb.x0 + bb.x1) / 2, (bb.y0 + bb.y1) / 2]]))
    for c in ax.collections:
        if not c.get_visible():
            continue
        if isinstance(c, PathCollection) and len(c.get_offsets()):
            pts.append(c.get_offset_transform().transform(c.get_offsets()))
        elif isinstance(c, PolyCollection):
            for path in c.get_paths():
                pts.append(c.get_transform().transform(path.vertices[::max(1, len(path.vertices) // 400)]))
    if not pts:
        return np.zeros((0, 2))
    xy = np.vstack(pts)
    inside = ax.get_window_extent()            # what the axes clips away is not shown
    keep = ((xy[:, 0] >= inside.x0 - TOL_PX) & (xy[:, 0] <= inside.x1 + TOL_PX)
            & (xy[:, 1] >= inside.y0 - TOL_PX) & (xy[:, 1] <= inside.y1 + TOL_PX))
    return xy[keep]


def _drawn_texts(fig):
    """The texts the figure draws: its own, its legends', and per axes the titles, labels, annotations and the
    tick labels of the ticks in view (matplotlib keeps label objects for ticks it does not draw)."""
    texts = list(fig.texts) + ([fig._suptitle] if fig._suptitle is not None else [])
    for leg in fig.legends:
        texts += leg.get_texts()
    axes = [a for a in fig.axes if a.get_visible()]
    axes += [c for a in axes for c in a.child_axes if c.get_visible()]
    for a in axes:
        texts += [a.title, a._left_title, a._right_title, a.xaxis.label, a.yaxis.label] + list(a.texts)
        if a.get_legend() is not None:
            texts += a.get_legend().get_texts()
        for axis in (a.xaxis, a.yaxis):
            for tick in axis._update_ticks():
                texts += [t for t in (tick.label1, tick.label2) if t.get_visible()]
    return texts


def layout_problems(fig) -> list[str]:
    """What is wrong with a figure's layout: texts off the canvas, legends over data."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    canvas = fig.bbox
    problems = []
    for t in _drawn_texts(fig):
        if not t.get_visible() or not t.get_text().strip():
            continue
        bb = t.get_window_extent(r)
        if bb.x0 < canvas.x0 - TOL_PX or bb.y0 < canvas.y0 - TOL_PX or bb.x1 > canvas.x1 + TOL_PX \
                or bb.y1 > canvas.y1 + TOL_PX:
            problems.append(f"text {t.get_text()[:40]!r} leaves the canvas ({bb})")
    legends = list(fig.legends) + [a.get_legend() for a in fig.axes if a.get_legend() is not None]
    axes = [a for a in fig.axes if a.get_visible()]
    axes += [c for a in axes for c in a.child_axes if c.get_visible()]          # insets
    for leg in legends:
        bb = leg.get_window_extent(r)
        for a in axes:
            xy = _data_points(a)
            hit = ((xy[:, 0] > bb.x0 + TOL_PX) & (xy[:, 0] < bb.x1 - TOL_PX)
                   & (xy[:, 1] > bb.y0 + TOL_PX) & (xy[:, 1] < bb.y1 - TOL_PX))
            if hit.any():
                title = a.get_title() or a.get_ylabel()
                problems.append(f"legend {[t.get_text() for t in leg.get_texts()][:3]} covers {hit.sum()} data points "
                                f"of the axes {title[:40]!r}")
    return problems


def assert_clean(fig, sizes=((1.0, 1.0), (0.7, 0.8), (1.4, 1.2))):
    """No layout problem at the figure's size and scaled by each (width, height) factor (several sizes)."""
    w, h = fig.get_size_inches()
    found = []
    for fx, fy in sizes:
        fig.set_size_inches(w * fx, h * fy)
        found += [f"at {fx:g}x{fy:g}: {p}" for p in layout_problems(fig)]
    fig.set_size_inches(w, h)
    assert not found, "\n".join(found[:12])
