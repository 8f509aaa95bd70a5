"""The one door to matplotlib for the plots (files only, never a window), and the rules every
plot keeps: its legend sits outside the data (:func:`legend_outside`, checked by
:func:`legend_overlaps`), its axes are labelled (:func:`unlabelled_axes`) and nothing is cut off
at the figure's edge or drawn over another panel (:func:`layout_problems`).

Two ways to a figure: :func:`pyplot` with ``constrained_layout`` (the studies), or
:func:`new_figure` with fixed margins (:func:`stack_layout`; the main job's figures, drawn by
every ``selfcal run``): no pyplot, and one draw per file instead of a layout pass and a draw
(issue 17)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from selfcal.io.atomic import write_with_atomic

__all__ = [
    "pyplot",
    "new_figure",
    "stack_layout",
    "log_y",
    "close_figure",
    "save_figure",
    "figure_png",
    "PNG_COMPRESS_LEVEL",
    "TEXT_HINTING",
    "legend_outside",
    "legend_overlaps",
    "unlabelled_axes",
    "layout_problems",
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


TEXT_HINTING = "no_hinting"
"""Matplotlib's ``text.hinting`` for the project's figures, in force only while this module
measures or draws one (:func:`stack_layout`, :func:`save_figure`, :func:`figure_png`, the
checks): matplotlib reads the process-wide setting whenever it measures or draws a text, and a
program that imports :mod:`selfcal.plots` keeps its own for its own figures. Unhinted glyphs
are loaded and rendered by FreeType without its auto-hinter, which took about a tenth of the
main job's three figures' CPU (``selfcal run`` waits for them at its end); the text is placed
the same, its strokes look slightly softer, and the files are somewhat
larger (the glyphs' soft edges compress less than hinted ones; the commit that set it gives the
measurement)."""


@contextmanager
def _text_style() -> Iterator[None]:
    """:data:`TEXT_HINTING` while the block measures or draws text; the setting as it was
    after."""
    import matplotlib  # slow: see pyplot()

    with matplotlib.rc_context({"text.hinting": TEXT_HINTING}):
        yield


def new_figure(width_in: float, height_in: float, *, dpi: float = 110.0) -> Any:
    """A ``matplotlib.figure.Figure`` of ``width_in`` x ``height_in`` inches on its own Agg canvas,
    at the ``dpi`` its file is written at (:func:`save_figure` keeps it): no pyplot, no figure
    manager, nothing to close. Lay it out with :func:`stack_layout`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # slow: see pyplot()
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def stack_layout(
    fig: Any,
    *,
    left: float = 0.9,
    bottom: float = 0.55,
    top: float = 0.35,
    gap: float = 0.75,
    pad: float = 0.08,
) -> None:
    """Place the axes of ``fig`` (one column, made by ``fig.subplots(n, 1)``) at fixed margins
    in inches, no layout solver: ``left`` (y tick labels and label), ``bottom`` (x tick labels
    and label of the last axes), ``top`` (above the first axes: its title, and a suptitle),
    ``gap`` (between two axes: x labels of the upper, title of the lower); on the right the
    widest legend placed by :func:`legend_outside` and ``pad``. Measures only the legends' text;
    :func:`layout_problems` checks that the margins hold what they must."""
    w, h = fig.get_size_inches()
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    with _text_style():
        legend_w = max((lg.get_window_extent(renderer).width for lg in legends), default=0.0)
    legend_w /= fig.dpi
    # legend_outside anchors the legend 1% of the axes width right of it
    axes_w = (w - left - legend_w - pad) / (1.01 if legends else 1.0)
    n = len(fig.axes)
    axes_h = (h - top - bottom - (n - 1) * gap) / n
    fig.subplots_adjust(left=left / w, right=(left + axes_w) / w, bottom=bottom / h,
                        top=1.0 - top / h, hspace=gap / axes_h)  # fmt: skip


def log_y(ax: Any) -> None:
    """A log-scale y axis of ``ax`` that draws quickly: minor ticks at 2 and 5 per decade
    (unlabelled) and the decades as plain numbers (``0.01``, ``1e-05``). Matplotlib's default
    (eight minor ticks per decade, mathtext powers ``10^-2``) took a third of each of the main
    job's figures' draw (issue 17)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    ax.set_yscale("log")
    ax.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))


def close_figure(fig: Any) -> None:
    """Close ``fig`` if pyplot keeps it (:func:`pyplot`); a :func:`new_figure` needs nothing."""
    if getattr(fig.canvas, "manager", None) is not None:
        pyplot().close(fig)


PNG_COMPRESS_LEVEL = 1
"""zlib level of the PNG files :func:`save_figure` writes through Pillow (given options, or a
canvas other than Agg's; Pillow's default is 6): the same pixels in slightly larger files, for
less of the encoding's CPU. Without options a figure is :func:`figure_png`'s file."""


def save_figure(fig: Any, path: str | Path, **kwargs: Any) -> Path:
    """``fig.savefig`` to ``path`` atomically (:mod:`selfcal.io.atomic`), in the format of its
    extension; at the figure's own dpi unless ``dpi=`` says otherwise (drawn once: text laid out
    at another dpi is measured again); a PNG at :data:`PNG_COMPRESS_LEVEL` unless ``pil_kwargs``
    says otherwise. A PNG with no ``kwargs`` is the figure's canvas as drawn, encoded by
    :func:`selfcal.io.png.encode_png` (a drawing, RGB when every pixel is opaque; the pixels
    savefig writes, for about a twelfth of Pillow's encoding CPU, which was about a sixth of each
    of ``selfcal run``'s figures)."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    if fmt == "png" and not kwargs and hasattr(fig.canvas, "buffer_rgba"):  # an Agg canvas
        return write_with_atomic(path, lambda tmp: tmp.write_bytes(figure_png(fig)))
    kwargs.setdefault("dpi", "figure")
    if fmt == "png":
        kwargs.setdefault("pil_kwargs", {"compress_level": PNG_COMPRESS_LEVEL})
    with _text_style():
        return write_with_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))


def figure_png(fig: Any) -> bytes:
    """The PNG file of ``fig`` drawn on its Agg canvas at its own dpi (as :func:`save_figure`
    writes it without options): its pixels as ``savefig`` makes them, without their alpha
    channel when every pixel is opaque."""
    from selfcal.io.png import encode_png

    with _text_style():
        fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    img = rgba[..., :3] if (rgba[..., 3] == 255).all() else rgba
    return encode_png(img, drawing=True, dpi=float(fig.dpi))


def legend_outside(ax: Any, **kwargs: Any) -> Any:
    """The legend of ``ax`` to the right of its axes box, where it covers no data (the figure
    must make room for it: ``constrained_layout``, or :func:`stack_layout`); returns the
    legend."""
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
            offs = np.asarray(art.get_offsets(), float)
            if len(offs):
                pts = art.get_offset_transform().transform(offs)
                out += [(f"points {art.get_label()!r}", np.r_[p, p]) for p in pts]
    return out


def legend_overlaps(fig: Any) -> list[str]:
    """What the legends of ``fig`` cover: one line per data element (line vertex, bar, patch,
    collection vertex) inside the legend box of its axes, or of a figure legend. Empty when
    every legend covers no data. Draws the figure to lay it out."""
    with _text_style():
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


def layout_problems(fig: Any) -> list[str]:
    """What the layout of ``fig`` cuts off or overlaps: an axes with its ticks, labels, title and
    legend reaching out of the figure, two such axes boxes or a figure title (suptitle) and an
    axes box overlapping. Empty for a good layout. Draws the figure to lay it out."""
    with _text_style():
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        boxes = [(ax.get_title() or f"axes {k + 1}", ax.get_tightbbox(renderer))
                 for k, ax in enumerate(fig.axes)]  # fmt: skip
        boxes += [(f"figure text {t.get_text()!r}", t.get_window_extent(renderer))
                  for t in fig.texts if t.get_visible() and t.get_text()]  # fmt: skip
    page = fig.bbox
    out = []
    tol = 0.5  # px: a box that touches the edge is inside
    for name, b in boxes:
        if (
            b.x0 < page.x0 - tol
            or b.y0 < page.y0 - tol
            or b.x1 > page.x1 + tol
            or b.y1 > page.y1 + tol
        ):
            out.append(f"{name}: cut off at the figure's edge")
    for i, (n1, b1) in enumerate(boxes):
        for n2, b2 in boxes[i + 1 :]:
            if (
                min(b1.x1, b2.x1) - max(b1.x0, b2.x0) > tol
                and min(b1.y1, b2.y1) - max(b1.y0, b2.y0) > tol
            ):
                out.append(f"{n1} and {n2} overlap")
    return out


def figure_problems(fig: Any) -> list[str]:
    """:func:`legend_overlaps`, :func:`unlabelled_axes` and :func:`layout_problems` of ``fig``,
    which is closed."""
    try:
        return legend_overlaps(fig) + unlabelled_axes(fig) + layout_problems(fig)
    finally:
        close_figure(fig)
