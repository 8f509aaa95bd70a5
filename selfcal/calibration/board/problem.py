"""The board refinement's least-squares problem, built in one place for the fit and its bounds.

Every camera's reprojection of the board's known corners through the kinematic poses (the first
camera's block is the adjustment's own; each further camera adds its reprojection block and its
intrinsics), plus the joint-reading prior when the joints are read with noise (their pixel sigma
over the joint sigma, px per rad or px per m). The board refinement (refine.py) solves it; the
Cramer-Rao bounds (bounds.py) take its covariance at the truth.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from selfcal.camera import CameraModel
from selfcal.estimation.bundle_adjust import _Problem as _AdjustmentProblem
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.estimation.reprojection import ReprojectionBlock
from selfcal.estimation.residuals import GaussianPriorBlock
from selfcal.solver import Loss, ParameterBlock, ResidualBlock
from selfcal.target.boards import Board

Rows = Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]


def board_problem(
    cameras: Sequence[CameraModel],
    poses: KinematicPoses,
    rows: Rows,
    board: Board,
    *,
    pixel_sigma_px: float,
    joint_sigma: float | np.ndarray | None,
    n_frames: int,
    term_blocks: Sequence[ResidualBlock] = (),
    term_params: Sequence[ParameterBlock] = (),
) -> _AdjustmentProblem:
    """The problem of ``cameras`` (the first is the chain's tool) seeing ``board`` through
    ``poses``: ``rows[c]`` = (view index in ``poses``' layout, board feature id, pixel (k, 2))
    of camera ``c``; ``joint_sigma`` (rad / m, scalar or (n,); None: exact read-back) weighs the
    joint corrections of the ``n_frames`` frames used against ``pixel_sigma_px`` (px). Unknowns
    start at the cameras' free values and the poses' initial parameters; the board is fixed.
    ``term_blocks``, ``term_params``: the measurement terms' residual and parameter blocks
    (:mod:`selfcal.calibration.board.terms`), after the images' and the prior."""
    ids = np.unique(np.concatenate([r[1] for r in rows]))
    extra: list[ResidualBlock] = []
    extra_params: list[ParameterBlock] = []
    for c in range(1, len(cameras)):
        v_c, f_c, uv_c = rows[c]
        extra.append(ReprojectionBlock(cameras[c], poses, v_c, np.searchsorted(ids, f_c), uv_c,
                                       Loss("linear"), name=f"reprojection{c}",
                                       intrinsics=f"intrinsics{c}"))  # fmt: skip
        extra_params.append(ParameterBlock(f"intrinsics{c}", cameras[c].free_values()))
    if joint_sigma is not None:
        js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (poses.model.n,))
        extra.append(GaussianPriorBlock("poses", poses.dq_cols,
                                        np.tile(pixel_sigma_px / js, n_frames)))  # fmt: skip
    extra += term_blocks
    extra_params += term_params
    view, feat0, uv = rows[0]
    x0 = np.concatenate([cameras[0].free_values(), poses.initial_params()])
    return _AdjustmentProblem(
        cameras[0], poses, view, np.searchsorted(ids, feat0), uv, len(ids), loss=Loss("linear"),
        x0=x0, extra=extra, fixed_points=board.points(ids), extra_params=extra_params,
    )  # fmt: skip
