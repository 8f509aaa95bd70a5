"""What ``selfcal plan --add`` forecasts over and with (:mod:`selfcal.cli.plan`): the workspace
of the dataset and the deviation of its held parameters, sized from its calibration's folds
unless ``--deviation-mm`` / ``--deviation-deg`` are given
(:mod:`selfcal.calibration.board.plan.add_ground`)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from selfcal.calibration.board.plan.add import DatasetPlan
from selfcal.calibration.board.plan.add_ground import (
    DatasetWorkspace,
    dataset_workspace,
    sized_deviation,
)
from selfcal.calibration.board.plan.ground import PlanOptions
from selfcal.io.board_calibration import read_board_calibration

__all__ = ["add_ground"]


def add_ground(
    args: argparse.Namespace, root: str | Path, plan: DatasetPlan, options: PlanOptions
) -> tuple[PlanOptions, DatasetWorkspace, dict]:
    """``options`` with the deviation ``--add`` forecasts with (``args.deviation_mm`` and
    ``args.deviation_deg`` set to it, mm and deg, for the files that quote them), the workspace
    of the dataset in ``root`` and plan.json's ``deviation`` (its ``words`` say which and why)."""
    ws = dataset_workspace(plan, options.workspace, seed=options.seed + 1)
    if args.deviation_given:
        return options, ws, {"source": "given", "words": (
            f"deviation +-{args.deviation_mm:g} mm, +-{args.deviation_deg:g} deg, as given")}  # fmt: skip
    sized = sized_deviation(plan, read_board_calibration(root).selection, options)
    args.deviation_mm = sized.deviation.translation_m * 1e3
    args.deviation_deg = float(np.degrees(sized.deviation.rotation_rad))
    return dataclasses.replace(options, deviation=sized.deviation), ws, sized.to_json()
