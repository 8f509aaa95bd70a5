"""A held-out check of a dataset without a second one: leave some poses out.

Every ``every``-th frame, the frames taken in the lexicographic order of their joint readings
(the first joint first; :func:`held_out_frames`), is held out, so the rows' order in
``joints.csv`` does not choose them (issue #29; frames of equal joints keep their order);
the rest is calibrated afresh (the same
method as the full calibration) and the held-out frames are predicted from their joint readings
alone with that calibration (:func:`selfcal.calibration.field.evaluate.evaluate_field` for the ArUco field,
:func:`selfcal.calibration.board.evaluate.evaluate_board` for a board): the reprojection RMS (px) of images the fit
never saw, of the calibrated model and of the nominal reference. ``selfcal report`` runs it on
real data (no truth), where no second dataset was taken for ``selfcal evaluate``.
The fresh calibration's warnings are issued again, each naming that calibration (not the
dataset's ``calibration.json``, whose warnings the report lists), and a board's records which
candidate its selection chose: it may differ from the full calibration's.
"""

from __future__ import annotations

import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.calibration.board.dataset import calibrate_board_dataset
from selfcal.calibration.board.evaluate import Evaluation, evaluate_board
from selfcal.calibration.field.calibrate import calibrate
from selfcal.calibration.field.evaluate import evaluate_field
from selfcal.io.dataset import Dataset, DatasetError
from selfcal.io.dataset_subset import subset_dataset

__all__ = ["HoldOut", "held_out_frames", "leave_poses_out", "MIN_FIT_FRAMES"]

MIN_FIT_FRAMES = 8
"""Fewest frames left to fit (the calibration needs 6 postures; 8 leaves a margin)."""


@dataclass(frozen=True)
class HoldOut:
    """The frames held out and fitted (dataset indices) and the evaluation of the held-out ones
    with the calibration of the others; ``chosen``: the candidate that calibration's selection
    chose (a board's ``selection.chosen``, e.g. "+ joint offsets"; None for the field or a
    calibration without a selection)."""

    held_out: tuple[int, ...]
    fitted: tuple[int, ...]
    evaluation: Evaluation
    chosen: str | None = None


def held_out_frames(joints: np.ndarray, every: int) -> np.ndarray:
    """(m,) bool: the frames of the joint readings ``joints`` (m, n) (any unit) the check holds
    out: every ``every``-th, from the first, in the lexicographic order of the readings (the
    first joint first; a stable sort, so frames of equal readings keep their order). A
    permutation of rows of distinct readings permutes the answer alike; among frames of equal
    readings (a configuration recorded more than once) which one is held out follows the rows'
    order, and the held-out readings are the same either way."""
    joints = np.atleast_2d(np.asarray(joints, dtype=float))
    take = np.zeros(len(joints), dtype=bool)
    take[np.lexsort(joints.T[::-1])[::every]] = True
    return take


def leave_poses_out(root: str | Path, *, every: int = 5, method: str = "joint") -> HoldOut:
    """Calibrate ``root`` without every ``every``-th frame and predict those (module docstring).

    Raises:
        DatasetError: ``every`` < 2, or fewer than :data:`MIN_FIT_FRAMES` frames would be left
            to fit.
        EstimationError, InputError: from the calibration of the subset or the evaluation.
    """
    if every < 2:
        raise DatasetError(f"leave-poses-out: every = {every}; hold out every 2nd frame or fewer")
    ds = Dataset.open(root)
    take = held_out_frames(ds.joints_deg, every)
    held = sorted(int(i) for i in ds.indices[take])
    fit = [int(i) for i in ds.indices[~take]]
    if len(fit) < MIN_FIT_FRAMES:
        raise DatasetError(
            f"{ds.root}: {len(ds.indices)} frames leave {len(fit)} to fit when every {every}th is held "
            f"out; the check needs {MIN_FIT_FRAMES}",
            fix="take more frames, or a second dataset for `selfcal evaluate`",
        )
    chosen = None
    with (
        tempfile.TemporaryDirectory(prefix="selfcal-holdout-") as tmp,
        warnings.catch_warnings(record=True) as caught,
    ):
        warnings.simplefilter("always")
        fit_ds = subset_dataset(ds.root, fit, Path(tmp) / "fit")
        held_ds = subset_dataset(ds.root, held, Path(tmp) / "held")
        if ds.info.board is None:
            # the subset lacks frames of the planned trajectory on purpose
            cal = calibrate(fit_ds.root, method=method, allow_missing_frames=True)
            ev = evaluate_field(cal, fit_ds.root, held_ds.root)
        else:
            board_cal = calibrate_board_dataset(fit_ds.root, allow_missing_frames=True)
            ev = evaluate_board(board_cal, "leave-poses-out fit", held_ds.root)
            chosen = (board_cal.selection or {}).get("chosen")
    # the warnings of a calibration the user did not ask for, said as such: printed bare they read
    # as the dataset's own calibration's, with other numbers
    whose = (f"the held-out check's calibration of {len(fit)} of {len(ds.indices)} frames "
             f"(every {every}th held out; not {ds.root / 'calibration.json'})")  # fmt: skip
    for w in caught:
        warnings.warn(f"{whose}: {w.message}", w.category, stacklevel=2)
    return HoldOut(tuple(held), tuple(fit), ev, chosen)
