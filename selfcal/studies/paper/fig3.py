"""``fig3.png`` of ``selfcal paper``: the tool-tip position errors per position and axis, the
paper's Fig. 3 beside the simulation's (and what the paper could not show: errors from the truth).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from selfcal.config.paper_data import AXES
from selfcal.plots.plotting import legend_outside, pyplot, save_figure

__all__ = ["fig3", "fig3_figure"]


def fig3(path: Path, rows: list[dict]) -> None:
    """Draw :func:`fig3_figure` of ``rows`` into ``path``."""
    fig = fig3_figure(rows)
    save_figure(fig, path, dpi=110)
    pyplot().close(fig)


def fig3_figure(rows: list[dict]) -> Any:
    """The figure of ``fig3.png``: ``rows`` are the Table IV rows of ``selfcal paper`` (one per
    position and axis, errors in mm). Legends beside the panels, outside the data."""
    plt = pyplot()

    def grid(key: str) -> np.ndarray:
        a = np.zeros((5, 3))
        for r in rows:
            a[r["position"] - 1, AXES.index(r["axis"][-1])] = r[key]
        return a

    fig, axs = plt.subplots(2, 2, figsize=(14, 8), constrained_layout=True)
    pos = np.arange(1, 6)
    w = 0.26
    colors = ("tab:blue", "tab:orange", "tab:green")

    def bars(ax, a: np.ndarray, title: str, ylabel: str = "error (mm)") -> None:
        for k in range(3):
            ax.bar(pos + (k - 1) * w, a[:, k], w, label=f"p_{AXES[k]}", color=colors[k])
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xticks(pos)
        ax.set_xlabel("tool-tip position (Table II row)")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=10)
        ax.grid(axis="y", alpha=0.3)

    printed, recomputed = grid("paper_error_printed"), grid("paper_error_recomputed")
    bars(axs[0, 0], printed, "(a) paper, Table IV / Fig. 3: measured - desired (as printed)")
    bad = np.argwhere(np.abs(printed - recomputed) > 0.005)
    for i, k in bad:
        x = pos[i] + (k - 1) * w
        axs[0, 0].plot(x, recomputed[i, k], "kx", ms=9, mew=2)
        axs[0, 0].annotate(
            f"typo: {printed[i, k]:+.2f}\nmeasured-desired\n= {recomputed[i, k]:+.2f}",
            (x, recomputed[i, k]),
            textcoords="offset points",
            xytext=(8, -30),
            fontsize=8,
        )
    legend_outside(axs[0, 0])
    bars(
        axs[0, 1],
        grid("error_measured_minus_desired"),
        "(b) ours: camera-measured - desired (the paper's quantity)",
    )
    bars(
        axs[1, 0],
        grid("calibrated_error_minus_true"),
        "(c) ours, after calibration: calibrated model - truth",
    )
    norms = {
        "nominal model - truth": np.linalg.norm(grid("nominal_error_desired_minus_true"), axis=1),
        "camera-measured - truth": np.linalg.norm(grid("camera_error_measured_minus_true"), axis=1),
        "calibrated model - truth": np.linalg.norm(grid("calibrated_error_minus_true"), axis=1),
    }
    ax = axs[1, 1]
    for k, (lab, v) in enumerate(norms.items()):
        ax.bar(pos + (k - 1) * w, v, w, label=lab, color=("0.5", "tab:purple", "tab:red")[k])
    ax.set_yscale("log")
    ax.set_xticks(pos)
    ax.set_xlabel("tool-tip position (Table II row)")
    ax.set_ylabel("|error| (mm, log scale)")
    ax.set_title(
        "(d) ours, against the simulator's truth (what the paper could not show)", fontsize=10
    )
    legend_outside(ax)
    ax.grid(axis="y", alpha=0.3, which="both")
    for a in axs[0, 1], axs[1, 0]:
        legend_outside(a)
    fig.suptitle("Tool-tip position errors per position and axis (paper Fig. 3 and simulation)")
    return fig
