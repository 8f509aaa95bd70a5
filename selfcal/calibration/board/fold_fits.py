"""The fold fits of a board calibration's parameter selection (issue #29): the chosen
candidate fitted without each arm configuration (:mod:`selfcal.calibration.board.param_selection`,
its folds :mod:`selfcal.calibration.board.folds`) and the Cramer-Rao bounds of each fold's fit
on its training frames, rebuilt in one place (:mod:`selfcal.calibration.board.accuracy`'s model
error and share, the real drift benchmark ``selfcal.benchmarks.drift.real_folds``). SI.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from selfcal.calibration.board.bounds import BoardCramerRao, board_cramer_rao
from selfcal.calibration.board.nominal_fit import standard_gauge
from selfcal.calibration.board.param_selection import Selection
from selfcal.calibration.board.refine import BoardObservations, Refinement

__all__ = ["fold_bounds", "frame_features"]


def frame_features(obs: BoardObservations, frames: np.ndarray) -> list[list]:
    """Every camera's features of the frames ``frames`` (m,) bool, in order."""
    k = np.flatnonzero(frames).tolist()
    return [[fc[i] for i in k] for fc in (obs.features, *obs.rig_features)]


def fold_bounds(obs: BoardObservations, selection: Selection, offsets: np.ndarray,
                T_tool_point: np.ndarray, pixel_sigma_px: float,
                ) -> Iterator[tuple[np.ndarray, Refinement, BoardCramerRao]]:  # fmt: skip
    """Every fitted fold of the chosen candidate that counts (none without folds): its held-out
    frames ``out`` (m,) bool, its fit and the Cramer-Rao bounds of that fit on its training
    frames (the calibration's own rule, ``offsets`` (n,) rad its gauge, the corner noise
    ``pixel_sigma_px``), in the fold order. A fold that leaves out more than half of the frames
    does not count (:meth:`Selection.counts`,
    :func:`selfcal.calibration.board.folds.counted_folds`): its fit on the rest stands for a
    smaller experiment than the calibration, so its error at the frames it left out is not the
    calibration's, neither for the selection nor for the model error and the held share read
    from these folds."""
    if selection.fold_of is None:
        return
    for f, (fit, free_idx, offset_joints) in sorted(
        selection.candidates[selection.chosen].fold_fits.items()
    ):
        if not selection.counts(f):
            continue
        out = selection.fold_of == f
        train = obs.used & ~out
        cr = board_cramer_rao(
            obs.board, fit.cameras, standard_gauge(fit.model, offsets), obs.q[train],
            frame_features(obs, train), pixel_sigma_px, joint_sigma=obs.joint_sigma,
            T_first_cam=None if obs.rig is None else fit.T_first_cam, free_idx=free_idx,
            offset_joints=offset_joints, eye_to_hand=obs.eye_to_hand, T_tool_point=T_tool_point,
        )  # fmt: skip
        yield out, fit, cr
