"""What ``selfcal plan`` forecasts beyond one number (issue #30): the spread of the calibration's
tool-point error over draws of the arm within its deviation and of the noise, the selection
deciding in each (:func:`selfcal.calibration.board.plan.spread.plan_spread`), for the plan and a
random plan of the same size (``--add``: the dataset before and after the added postures): the
command's third line (``--add``: its sixth), plan.json's ``forecast_draws`` section and PLAN/plan.png
(:mod:`selfcal.plots.plan_figure`)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the CLI's parser loads no numerical module (tests/unit/test_cli_imports.py)
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.plan.reference import NominalReference
    from selfcal.calibration.board.plan.spread import SelectionSpread
    from selfcal.calibration.board.plan.views import PlanSetup

__all__ = ["DrawSet", "Forecast", "forecast_draws"]

PROGRESS_EVERY = 20
"""The progress bar moves every this many draws (a redraw per draw costs more than a draw)."""


@dataclass(frozen=True)
class DrawSet:
    """A posture set to draw: ``key`` (plan.json's, e.g. "plan"), ``label`` (the line's and the
    figure's, e.g. "plan of 12"), ``q`` (m, n) rad in recording order, the first ``len(seen)``
    frames showing the board features ``seen`` (a dataset's), the others every feature."""

    key: str
    label: str
    q: np.ndarray
    seen: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True, eq=False)
class Forecast:
    """:func:`forecast_draws`' result: each set's (:class:`DrawSet`, draws), the draw count and
    the seed."""

    sets: tuple[tuple[DrawSet, SelectionSpread], ...]
    draws: int
    seed: int

    def line(self) -> str:
        """The command's line: each set's median and 90th percentile (mm)."""
        from selfcal.plots.plan_figure import spread_words

        parts = [f"{s.label}: {spread_words(sp)} (a smaller parameter set kept in "
                 f"{100 * sp.smaller_share:.0f} % of draws)" for s, sp in self.sets]  # fmt: skip
        return (f"forecast over {self.draws} draws of the arm within its deviation and of the "
                "noise, the selection deciding in each, " + "; ".join(parts))  # fmt: skip

    def behind(self, key: str, other: str) -> str | None:
        """A sentence for a warning when the set ``key``'s median (the plan's) is not below the
        set ``other``'s (a random plan's): by the draws the planner's choice does not pay at this
        size; None when it is below."""
        by = {s.key: (s, sp) for s, sp in self.sets}
        (a, sa), (b, sb) = by[key], by[other]
        ma, mb = sa.percentile(50), sb.percentile(50)
        if ma < mb:
            return None
        return (f"the forecast puts {a.label} (median {1000 * ma:.3f} mm) no better than "
                f"{b.label} (median {1000 * mb:.3f} mm): with so few postures the planner's "
                "choice does not pay; plan more postures (--count)")  # fmt: skip

    def section(self) -> dict:
        """plan.json's ``forecast_draws``: per set the median and 90th percentile (mm), their
        Monte Carlo standard errors and the share of draws keeping a smaller set."""
        doc: dict = {"draws": self.draws, "seed": self.seed}
        for s, sp in self.sets:
            doc[s.key] = {
                "label": s.label,
                "median_mm": round(1000 * sp.percentile(50), 4),
                "p90_mm": round(1000 * sp.percentile(90), 4),
                "median_standard_error_mm": round(1000 * sp.standard_error(50), 4),
                "p90_standard_error_mm": round(1000 * sp.standard_error(90), 4),
                "smaller_set_share": round(sp.smaller_share, 4),
            }
        doc["note"] = (
            "the calibration's tool-point RMS error over the workspace (after the best rigid "
            "alignment) in draws of the arm (every parameter uniform within the deviation) and "
            "of the corner and read-back noise, the selection's cross-validation and one-"
            "standard-error rule deciding in each (linearised at the drawing); seeded with "
            "--seed; standard errors: the Monte Carlo error of the percentiles from the draws"
        )
        return doc


def forecast_draws(
    args: argparse.Namespace,
    setup: PlanSetup,
    workspace: np.ndarray,
    sets: list[DrawSet],
    joint_sigma: np.ndarray | None,
    deviation: Deviation,
) -> Forecast:
    """The draws (module docstring) of each of ``sets`` on ``setup``, the error averaged over the
    ``workspace`` (w, n) rad, corner noise ``args.pixel_sigma``, the arm's ``deviation`` from
    its drawing, read-back noise ``joint_sigma`` (n,) rad, seeded with ``args.seed``; a progress bar on a terminal (stderr) unless ``--quiet`` or
    ``--json``."""
    from selfcal.calibration.board.plan.information import board_model
    from selfcal.calibration.board.plan.spread import DRAWS, plan_spread
    from selfcal.console.progress import Progress
    from selfcal.estimation.joint_report import aligned_tool_weight

    model = board_model(setup)
    G = aligned_tool_weight(model, workspace, setup.T_tool_tip)
    var = deviation.variance(model.joint_types)
    bar = Progress("forecast", enabled=not (args.quiet or args.json))
    bar.start(len(sets) * DRAWS)
    count = [0]

    def on_draw() -> None:
        count[0] += 1
        if count[0] % PROGRESS_EVERY == 0:
            bar.advance(PROGRESS_EVERY)

    try:
        got = tuple((s, plan_spread(setup, s.q, G, var, args.pixel_sigma, joint_sigma, s.seen,
                                    draws=DRAWS, seed=args.seed, on_draw=on_draw))
                    for s in sets)  # fmt: skip
    finally:
        bar.finish()
    return Forecast(got, DRAWS, args.seed)


def write_figure(forecast: Forecast, reference: NominalReference, title: str, path: Path) -> None:
    """PLAN/plan.png (:func:`selfcal.plots.plan_figure.plan_spread_figure`) of ``forecast``
    with the error without calibrating the kinematics ``reference``."""
    from selfcal.plots.plan_figure import plan_spread_figure
    from selfcal.plots.plotting import close_figure, save_figure

    fig = plan_spread_figure([(s.label, sp) for s, sp in forecast.sets],
                             reference.best_m * 1000.0, reference.what, title)  # fmt: skip
    try:
        save_figure(fig, path)
    finally:
        close_figure(fig)
