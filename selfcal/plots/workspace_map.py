"""``figures/workspace_accuracy.png``: the predicted 95 % tool-point error over the workspace
(issue #29).

Two views of the predicted tool points of the sampled joint vectors (top: x-y, side: x-z, in the
calibration's output frame, mm), coloured by their predicted 95 % position error; the three
regions of :mod:`selfcal.kinematics.tool_error` by marker (inside the calibrated region, at its
edge, elsewhere in the joint limits) and the calibration postures as black crosses. Every number
comes from the run's :class:`selfcal.kinematics.tool_error.ToolErrorModel`.
"""

from __future__ import annotations

import textwrap
from typing import Any

import numpy as np

from selfcal.kinematics.tool_error import ToolErrorModel, WorkspaceSample
from selfcal.plots.plotting import pyplot

__all__ = ["workspace_map_figure"]

TITLE_CHARS = 150
"""Characters per line of the title at its 10 pt across the 12-inch figure."""

_REGIONS = (
    ("workspace", "v", 10, "elsewhere within the joint limits"),
    ("edge", "^", 16, "edge of the calibrated region"),
    ("inside", "o", 16, "inside the calibrated region"),
)


def workspace_map_figure(
    em: ToolErrorModel, sample: WorkspaceSample, q_cal: np.ndarray, title: str, frame: str
) -> Any:
    """The workspace map (module docstring) of ``em`` over ``sample`` with the calibration
    postures ``q_cal`` (m, n) rad / m; ``title``: e.g. the report's accuracy line; ``frame``: the
    name of ``em``'s output frame (e.g. "tracker frame")."""
    plt = pyplot()
    groups = [(getattr(sample, name), *rest) for name, *rest in _REGIONS]
    preds = [em.predicted(q) if len(q) else None for q, *_ in groups]
    values = np.concatenate([p["position_95_mm"] for p in preds if p is not None])
    vmin, vmax = float(values.min()), float(values.max())
    cal = em.tool_positions(q_cal) * 1e3
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.6), constrained_layout=True)
    sc = None
    for ax, (i, j), view in zip(axes, ((0, 1), (0, 2)), ("(a) top view", "(b) side view")):
        for (_, marker, size, label), p in zip(groups, preds):
            if p is None:
                continue
            xyz = p["position_mm"]
            sc = ax.scatter(xyz[:, i], xyz[:, j], c=p["position_95_mm"], s=size, marker=marker,
                            cmap="viridis", vmin=vmin, vmax=vmax, label=label, linewidths=0)  # fmt: skip
        ax.scatter(cal[:, i], cal[:, j], marker="x", color="k", s=30, linewidths=1.2,
                   label=f"calibration postures ({len(cal)})")  # fmt: skip
        ax.set_xlabel(f"{'xyz'[i]} (mm)")
        ax.set_ylabel(f"{'xyz'[j]} (mm)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"{view}: predicted tool points, {frame}")
        ax.grid(alpha=0.3)
    bar = fig.colorbar(sc, ax=list(axes), label="predicted 95 % position error", shrink=0.9)
    bar.ax.set_xlabel("mm")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=4, fontsize=8)
    # the report's accuracy line runs past 300 characters on real data: wrapped, not cut off
    fig.suptitle(textwrap.fill(title, TITLE_CHARS), fontsize=10)
    return fig
