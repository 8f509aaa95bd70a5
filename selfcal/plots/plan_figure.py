"""``PLAN/plan.png``: what ``selfcal plan`` forecasts for its plan against a random plan of the
same size (or, ``--add``, for the dataset before and after the added postures), issue #30.

One panel: for each posture set the distribution of the calibration's tool-point RMS error over
the workspace (mm) over the forecast's draws of the arm within its deviation and of the noise,
the selection deciding in each (:func:`selfcal.calibration.board.plan.spread.selection_spread`),
as the share of draws at most a given error (an empirical distribution function), its median
and 90th percentile marked and written in the legend; a dashed line at the error without
calibrating the kinematics; the error axis logarithmic where the sets lie far apart. Every number
comes from the run's draws.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from selfcal.calibration.board.plan.spread import SelectionSpread
from selfcal.plots.plotting import legend_outside, new_figure, stack_layout

__all__ = ["LOG_RATIO", "plan_spread_figure", "spread_words"]

LOG_RATIO = 10.0
"""The error axis is logarithmic where one set's median is more than this many times
another's (a poorly identified dataset before and after ``--add``: 40 mm and 0.2 mm)."""


def spread_words(sp: SelectionSpread) -> str:
    """The median and 90th percentile of ``sp``'s draws in words, as the command's lines and
    the figure's legend give them: ``"median 0.627 mm, 90th percentile 0.941 mm"``."""
    return (f"median {1000 * sp.percentile(50):.3f} mm, "
            f"90th percentile {1000 * sp.percentile(90):.3f} mm")  # fmt: skip


def plan_spread_figure(curves: list[tuple[str, SelectionSpread]], reference_mm: float,
                       reference_what: str, title: str) -> Any:  # fmt: skip
    """The figure (module docstring) of ``curves``, (label, draws) of each posture set (the
    plan's first; a label such as "plan of 12"), ``reference_mm`` the
    error without calibrating the kinematics (mm) and ``reference_what`` what it is (e.g. "the
    chain as drawn"); ``title`` above the panel. A Figure on its own Agg canvas (save it with
    :func:`selfcal.plots.plotting.save_figure`)."""
    fig = new_figure(10.5, 4.2)
    ax = fig.subplots(1, 1)
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    top, low, medians = reference_mm, reference_mm, []
    for (label, sp), colour in zip(curves, colours):
        x = 1000.0 * np.sort(sp.tool_m)
        share = np.arange(1, len(x) + 1) / len(x)
        words = (f"{label}:\n{spread_words(sp)}\n(a smaller parameter set kept in "
                 f"{100 * sp.smaller_share:.0f} % of draws)")  # fmt: skip
        ax.step(x, share, where="post", color=colour, label=words)
        marks = [1000.0 * sp.percentile(50), 1000.0 * sp.percentile(90)]
        ax.plot(marks, [0.5, 0.9], "o", color=colour, markersize=5)
        finite = x[np.isfinite(x)]
        top, low = max(top, float(finite.max())), min(low, float(finite.min()))
        medians.append(marks[0])
    ax.axvline(reference_mm, color="k", linestyle="--",
               label=f"without calibrating the kinematics:\npredicted RMS {reference_mm:.3f} mm "
               f"({reference_what})")  # fmt: skip
    ax.axhline(0.5, color="0.7", linewidth=0.6)
    ax.axhline(0.9, color="0.7", linewidth=0.6)
    if max(medians) > LOG_RATIO * min(medians):  # sets far apart: each seen on a log axis
        ax.set_xscale("log")
        ax.set_xlim(0.8 * low, 1.25 * top)
    else:
        ax.set_xlim(0.0, 1.1 * top)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("tool-point RMS error over the workspace (mm)")
    ax.set_ylabel("share of draws at most this error")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    legend_outside(ax)
    stack_layout(fig)
    return fig
