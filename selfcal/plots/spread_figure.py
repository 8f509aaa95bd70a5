"""The figure of ``selfcal calibrate --spread N`` (``DIR/figures/spread.png``, issue #29): per
region of the workspace (inside the calibrated region, its edge, the workspace, the calibration
postures) the run-to-run spread of the tool point over the bootstrap refits (RMS over the
region's joint vectors and their 95th percentile), the jackknife's over the folds beside it, and
the predicted RMS error of the accuracy block, each bar labelled with its number (mm), all from
the ``accuracy`` block of the run's ``calibration.json``."""

from __future__ import annotations

from typing import Any

import numpy as np

from selfcal.plots.plotting import legend_outside, new_figure, stack_layout

__all__ = ["spread_figure"]

_REGIONS = (
    ("inside", "inside"),
    ("edge", "edge"),
    ("workspace", "workspace"),
    ("calibration_postures", "calibration\npostures"),
)


def _value(block: dict | None, region: str, key: str) -> float:
    """``block["regions"][region][key]`` (mm), NaN when absent (an older block, an empty
    region)."""
    got = ((block or {}).get("regions") or {}).get(region) or {}
    v = got.get(key)
    return float("nan") if v is None else float(v)


def spread_figure(accuracy: dict) -> Any:
    """The figure (module docstring) of a board calibration's ``accuracy`` block with its
    ``bootstrap_spread``; a Figure on its own Agg canvas (save it with
    :func:`selfcal.plots.job_figures.write_figure`)."""
    boot = accuracy["bootstrap_spread"]
    jack = accuracy.get("spread")
    bars = [
        ("bootstrap: RMS over the region", boot, "spread_mm_rms", "tab:blue"),
        ("bootstrap: 95th percentile", boot, "spread_mm_p95", "lightsteelblue"),
        ("jackknife over the folds: RMS", jack, "spread_mm_rms", "tab:orange"),
        ("predicted RMS error\n(covariance and model error)", accuracy, "position_rms_mm", "0.5"),
    ]
    fig = new_figure(10.5, 4.2)
    ax = fig.subplots(1, 1)
    x = np.arange(len(_REGIONS))
    width = 0.8 / len(bars)
    top = 0.0
    for j, (label, block, key, colour) in enumerate(bars):
        values = np.array([_value(block, r, key) for r, _ in _REGIONS])
        pos = x - 0.4 + (j + 0.5) * width
        ax.bar(pos, np.nan_to_num(values), width, color=colour, label=label)
        for p, v in zip(pos, values):
            if np.isfinite(v):
                ax.text(p, v, f"{v:.3f}", ha="center", va="bottom", fontsize=7)
                top = max(top, v)
    ax.set_xticks(x, [name for _, name in _REGIONS])
    ax.set_ylim(0.0, 1.15 * top if top > 0 else 1.0)
    ax.set_xlabel("region of the accuracy block's workspace sample, and the calibration postures")
    ax.set_ylabel("tool-point spread (mm)")
    failed = boot.get("failed", 0)
    ax.set_title(
        f"run-to-run spread of the tool point: {boot['resamplings']} bootstrap refits of "
        f"{boot.get('configurations', '?')} arm configurations (seed {boot.get('seed', '?')}, "
        f"{failed} failed)",
        fontsize=9,
    )
    ax.grid(alpha=0.3, axis="y")
    legend_outside(ax)
    stack_layout(fig, bottom=0.8)  # the two-line tick label and the axis label
    return fig
