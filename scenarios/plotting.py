"""The one door to matplotlib for the plots (files only, never a window), and the two rules every
plot keeps: its legend sits outside the data (:func:`legend_outside`, checked by
:func:`legend_overlaps`) and its axes are labelled (:func:`unlabelled_axes`)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from calib.io.atomic import write_with_atomic

__all__ = [
    "pyplot",
    "save_figure",
    "legend_outside",
    "legend_overlaps",
    "unlabelled_axes",
    "figure_problems",
]


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the non-interactive Agg backend.

    Imported here, on first use, not at the top of the studies: it takes ~1 s
    (``python -X importtime``) and only the commands that draw need it.
    """
    import matplotlib  # optional and slow: see the docstring

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional and slow: see the docstring

    return plt


def save_figure(fig: Any, path: str | Path, **kwargs: Any) -> Path:
    """``fig.savefig`` to ``path`` atomically (:mod:`calib.io.atomic`), in the format of its
    extension."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    return write_with_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))


def legend_outside(ax: Any, **kwargs: Any) -> Any:
    """The legend of ``ax`` to the right of its axes box, where it covers no data (the figure
    must use ``constrained_layout`` to make room for it); returns the legend."""
    opts = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "borderaxespad": 0.0,
            "fontsize": 8}  # fmt: skip
    return ax.legend(**{**opts, **kwargs})


def _data_boxes(ax: Any) -> list[tuple[str, np.ndarray]]:
    """Display-space boxes ``[x0, y0, x1, y1]`` of the data drawn in ``ax``: one per line
    vertex (a point box), bar or patch, and collection path vertex."""
    from matplotlib.collections import Collection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    out: list[tuple[str, np.ndarray]] = []
    for art in ax.get_children():
        if not isinstance(art, Line2D | Patch | Collection) or not art.get_visible():
            continue
        if art is ax.patch or art in ax.spines.values():
            continue
        if isinstance(art, Line2D):
            xy = np.column_stack(art.get_data()).astype(float)
            pts = art.get_transform().transform(xy[np.isfinite(xy).all(axis=1)])
            if art.get_linestyle() not in ("None", "", " ") and len(pts) > 1:  # the segments too
                t = np.linspace(0.0, 1.0, 17)[:, None, None]
                pts = (pts[:-1] + t * (pts[1:] - pts[:-1])).reshape(-1, 2)
            out += [(f"line {art.get_label()!r}", np.r_[p, p]) for p in pts]
        elif isinstance(art, Patch):
            bb = art.get_window_extent()
            if bb.width > 0 and bb.height > 0:
                out.append((f"patch {art.get_label()!r}", np.array(bb.extents)))
        elif isinstance(art, Collection):
            tr = art.get_transform()
            for path in art.get_paths():
                v = tr.transform(path.vertices)
                out += [(f"collection {art.get_label()!r}", np.r_[p, p]) for p in v]
            offs = art.get_offsets()
            if len(offs):
                pts = art.get_offset_transform().transform(np.asarray(offs, float))
                out += [(f"points {art.get_label()!r}", np.r_[p, p]) for p in pts]
    return out


def legend_overlaps(fig: Any) -> list[str]:
    """What the legends of ``fig`` cover: one line per data element (line vertex, bar, patch,
    collection vertex) inside the legend box of its axes, or of a figure legend. Empty when
    every legend covers no data. Draws the figure to lay it out."""
    fig.canvas.draw()
    out = []
    for ax in fig.axes:
        legends = [lg for lg in (ax.get_legend(), *fig.legends) if lg is not None]
        data = _data_boxes(ax)
        for lg in legends:
            x0, y0, x1, y1 = lg.get_window_extent().extents
            for what, b in data:
                if b[0] <= x1 and b[2] >= x0 and b[1] <= y1 and b[3] >= y0:
                    out.append(f"{ax.get_title() or 'axes'}: legend covers {what}")
    return out


def unlabelled_axes(fig: Any) -> list[str]:
    """Axes of ``fig`` without an x or a y label, or with tick labels below 6 pt."""
    out = []
    for ax in fig.axes:
        name = ax.get_title() or "axes"
        if not ax.get_xlabel() or not ax.get_ylabel():
            out.append(f"{name}: x or y label missing")
        ticks = ax.get_xticklabels() + ax.get_yticklabels()
        if any(t.get_fontsize() < 6 for t in ticks):
            out.append(f"{name}: tick labels below 6 pt")
    return out


def figure_problems(fig: Any) -> list[str]:
    """:func:`legend_overlaps` and :func:`unlabelled_axes` of ``fig``, which is closed."""
    try:
        return legend_overlaps(fig) + unlabelled_axes(fig)
    finally:
        pyplot().close(fig)
