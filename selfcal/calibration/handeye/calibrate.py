"""Hand-eye calibration from a robot's flange poses: camera, hand-eye and board mount.

Setups (:mod:`selfcal.estimation.pose_chain`): eye-in-hand (``X = T_flange_cam``, ``B =
T_base_board``) and eye-to-hand (``X = T_base_cam``, ``B = T_flange_board``); the robot's
reported flange poses ``T_base_flange`` are taken as they are: without joint readings there are
no kinematics to identify.

Route: the camera stage (:func:`selfcal.calibration.board.calibrate.calibrate_board`: OpenCV's calibration
refined by the bundle adjustment, one free board pose per view) -> the linear start of ``X`` and
``B`` from its board poses (:func:`selfcal.calibration.handeye.linear.linear_hand_eye`) -> the one solver on
corner reprojection through the pose chain (:class:`selfcal.estimation.pose_chain.PoseChainBlock`):
a robust pass (soft-L1, 1 px), the outliers (beyond ``max(3 px, 4.5 sigma)``) dropped, a plain
least-squares pass whose covariance ``sigma^2 (J^T J)^-1`` gives the standard deviations. Twice:
the *nominal* holds the camera of the camera stage and fits ``X`` and ``B`` (the fair
reference: everything but what the calibration adds fitted by the same objective), the
*calibrated* frees the camera's parameters too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.calibrate import BoardCalibration, calibrate_board
from selfcal.calibration.handeye.linear import linear_hand_eye, turn_misfit_deg
from selfcal.camera import CameraModel
from selfcal.camera.camera_set import std_by_name
from selfcal.errors import EstimationError, InputError
from selfcal.estimation.pose_chain import PoseChainBlock, local_pose
from selfcal.estimation.reprojection import robust_sigma
from selfcal.solver import Loss, ParameterBlock, Problem, SolverOptions, covariance, solve
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = ["HandEyeFit", "HandEyeCalibration", "HandEyeMisfitError", "calibrate_hand_eye",
           "chain_motions", "predict_corners", "FRAMES", "MISFIT_PX", "MISFIT_RATIO"]  # fmt: skip

FRAMES = {
    "eye-in-hand": ("flange -> camera", "base -> board"),
    "eye-to-hand": ("base -> camera", "flange -> board"),
}
"""What ``X`` (the hand-eye) and ``B`` (the board mount) are in each setup."""

MISFIT_PX = 5.0
MISFIT_RATIO = 10.0
"""The hand-eye fit's RMS beyond ``max(MISFIT_PX, MISFIT_RATIO x the camera stage's)`` means the
poses do not explain the images (a real arm's pose noise gives 1-2x: 1.85x on ical-charuco; the
wrong ``--setup`` gives 178 px there)."""
_TURN_DEG = 1.0
"""Median turn misfit (deg) beyond which the orientations are not the robot's (0.1-0.2 real)."""


class HandEyeMisfitError(EstimationError):
    """The flange poses do not explain the board poses (the message says what the checks found)."""


def chain_motions(setup: str, T_base_flange: np.ndarray) -> np.ndarray:
    """The motions ``A_i`` (n, 4, 4) of the pose chain of ``setup`` from the flange poses."""
    if setup == "eye-to-hand":
        return np.asarray(T_base_flange, float)
    if setup == "eye-in-hand":
        return inv_pose(np.asarray(T_base_flange, float))
    raise InputError(f"unknown setup {setup!r}; use {list(FRAMES)}")


@dataclass(frozen=True)
class HandEyeFit:
    """One fit: ``camera`` (and ``camera_std`` of its free parameters; empty when held),
    ``X`` / ``B`` (4, 4) m, their standard deviations ``X_std`` / ``B_std`` (6,) as the local
    parameters ``[w (rad), v (m)]`` (rotation about the base axes of each frame's parent, then
    translation), ``rms_px`` over the inliers, ``inlier`` (k,) of the observation rows,
    ``sigma_px`` the fitted noise per coordinate, ``iterations``."""

    camera: CameraModel
    camera_std: dict[str, float]
    X: np.ndarray
    B: np.ndarray
    X_std: np.ndarray
    B_std: np.ndarray
    rms_px: float
    inlier: np.ndarray
    sigma_px: float
    iterations: int


@dataclass(frozen=True)
class HandEyeCalibration:
    """Result of :func:`calibrate_hand_eye`: the ``setup``, the ``camera_stage``, the linear
    start ``X0`` / ``B0``, the ``nominal`` (camera held) and ``calibrated`` (camera free) fits,
    ``used`` (n,) the views in them."""

    setup: str
    camera_stage: BoardCalibration
    X0: np.ndarray
    B0: np.ndarray
    nominal: HandEyeFit
    calibrated: HandEyeFit
    used: np.ndarray


def predict_corners(camera: CameraModel, X: np.ndarray, B: np.ndarray, A: np.ndarray,
                    view: np.ndarray, points: np.ndarray) -> np.ndarray:  # fmt: skip
    """Pixels (k, 2) of the board ``points`` (k, 3) m in the views ``view`` (k,) through the
    pose chain ``X^-1 A_i B``; NaN behind the camera."""
    T = inv_pose(X)[None] @ np.asarray(A)[view] @ B
    Xc = np.einsum("kij,kj->ki", T[:, :3, :3], points) + T[:, :3, 3]
    uv = camera.project(Xc)
    return np.where(Xc[:, 2:3] > 0, uv, np.nan)


def _fit(cam0: CameraModel, hold_camera: bool, A: np.ndarray, X0: np.ndarray, B0: np.ndarray,
         view: np.ndarray, points: np.ndarray, uv: np.ndarray, outlier_px: float,
         max_iter: int) -> HandEyeFit:  # fmt: skip
    free0 = cam0.free_values()
    active = np.ones(len(view), bool)
    X, B, cam = X0, B0, cam0
    sol = prob = None
    for loss in ("soft_l1", "linear"):
        block = PoseChainBlock(cam0, A, X, B, view[active], points[active], uv[active],
                               Loss(loss, 1.0))  # fmt: skip
        params = [
            ParameterBlock(
                "intrinsics", cam.free_values(), held=np.full(len(free0), hold_camera)
            ),  # fmt: skip
            ParameterBlock("X", np.zeros(6)),
            ParameterBlock("B", np.zeros(6)),
        ]
        prob = Problem(params, [block])
        sol = solve(prob, SolverOptions(tol=1e-12, max_iterations=max_iter))
        if sol.status <= 0:
            raise EstimationError(
                f"the hand-eye fit on corner reprojection ({loss} loss, camera "
                f"{'held' if hold_camera else 'free'}) did not converge within {max_iter} "
                f"iterations from the linear start ({sol.message})",
                fix="check that every pose row belongs to its image and that --setup is right",
            )
        cam = cam0.with_free_values(sol.values["intrinsics"])
        X, B = local_pose(X, sol.values["X"]), local_pose(B, sol.values["B"])
        if loss == "soft_l1":
            e = np.linalg.norm(predict_corners(cam, X, B, A, view, points) - uv, axis=1)
            e = np.where(np.isfinite(e), e, np.inf)
            active = e < max(outlier_px, 4.5 * robust_sigma(e[np.isfinite(e)]))
    assert sol is not None and prob is not None
    r = sol.residuals["pose_chain"]
    dof = max(r.size - prob.n, 1)
    sigma2 = float(np.sum(r**2)) / dof
    blocks = ["X", "B"] + ([] if hold_camera else ["intrinsics"])
    cov = covariance(prob, sol.x, blocks, sigma2=sigma2)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    cam_std = {} if hold_camera else std_by_name(cam, cov[12:, 12:])
    return HandEyeFit(camera=cam, camera_std=cam_std, X=X, B=B, X_std=std[:6], B_std=std[6:12],
                      rms_px=float(np.sqrt(np.mean(np.sum(r**2, axis=1)))), inlier=active,
                      sigma_px=float(np.sqrt(sigma2)), iterations=sol.iterations)  # fmt: skip


def calibrate_hand_eye(
    board: Board,
    features: Sequence[Features],
    T_base_flange: np.ndarray,
    setup: str,
    width: int,
    height: int,
    *,
    model: str = "opencv",
    free: Sequence[str] = ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"),
    names: Sequence[str] | None = None,
    outlier_px: float = 3.0,
    max_iter: int = 100,
) -> HandEyeCalibration:
    """Calibrate the camera (``model``, parameters ``free``), the hand-eye and the board mount
    of ``setup`` from the board ``features`` of one image per pose and the flange poses
    ``T_base_flange`` (n, 4, 4) m (see the module docstring); ``names`` name the images.

    Raises:
        selfcal.calibration.board.calibrate.BoardInputError / BoardMismatchError: as the camera stage.
        selfcal.calibration.handeye.linear.HandEyeStartError: the motions do not determine the hand-eye.
        EstimationError: a fit did not converge.
    """
    T_base_flange = np.asarray(T_base_flange, float)
    if len(T_base_flange) != len(features):
        raise InputError(f"{len(features)} images but {len(T_base_flange)} poses")
    A = chain_motions(setup, T_base_flange)
    stage = calibrate_board(board, features, width, height, free=free, model=model, names=names)
    used = stage.used
    X0, B0 = linear_hand_eye(A[used], stage.T_cam_board[used])
    view = stage.view
    points = board.points(stage.feature)
    uv = np.concatenate([features[i].uv for i in np.flatnonzero(used).tolist()])
    turn = turn_misfit_deg(T_base_flange[used], stage.T_cam_board[used])
    if turn > _TURN_DEG:
        raise HandEyeMisfitError(
            f"the flange poses do not fit the board poses the camera sees: the robot's motions "
            f"and the camera's turn by angles that differ by {turn:.1f} deg (median over the "
            "pairs of images; a real arm: 0.1-0.2 deg), whatever the setup and hand-eye",
            fix="check the orientation columns and --rotation (quaternion order, Euler "
            "convention, degrees or radians) and that every pose row belongs to its image",
        )
    try:
        nominal = _fit(stage.camera, True, A, X0, B0, view, points, uv, outlier_px, max_iter)
        rms = nominal.rms_px
    except EstimationError:
        rms = float("inf")
    if rms > max(MISFIT_PX, MISFIT_RATIO * stage.rms_px):
        _explain_misfit(setup, rms, stage, T_base_flange, view, points, uv, outlier_px, max_iter)
    calibrated = _fit(stage.camera, False, A, nominal.X, nominal.B, view, points, uv, outlier_px,
                      max_iter)  # fmt: skip
    return HandEyeCalibration(setup=setup, camera_stage=stage, X0=X0, B0=B0, nominal=nominal,
                              calibrated=calibrated, used=used)  # fmt: skip


def _explain_misfit(setup: str, rms_px: float, stage: BoardCalibration, T_base_flange: np.ndarray,
                    view: np.ndarray, points: np.ndarray, uv: np.ndarray, outlier_px: float,
                    max_iter: int) -> None:  # fmt: skip
    """Raise :class:`HandEyeMisfitError` saying what the data checks show: the other setup's
    fit, else what to check (the turn angles of the motions agreed before)."""
    used = stage.used
    other = "eye-in-hand" if setup == "eye-to-hand" else "eye-to-hand"
    A = chain_motions(other, T_base_flange)
    try:
        X0, B0 = linear_hand_eye(A[used], stage.T_cam_board[used])
        other_px = _fit(stage.camera, True, A, X0, B0, view, points, uv, outlier_px,
                        max_iter).rms_px  # fmt: skip
    except EstimationError:
        other_px = float("inf")
    fit = "does not converge" if not np.isfinite(rms_px) else f"leaves {rms_px:.1f} px RMS"
    head = (f"the flange poses do not explain the board poses as {setup}: the hand-eye fit "
            f"{fit} where the camera alone fits {stage.rms_px:.2f} px")  # fmt: skip
    if other_px < max(MISFIT_PX, MISFIT_RATIO * stage.rms_px):
        raise HandEyeMisfitError(
            f"{head}; as {other} they fit ({other_px:.2f} px)",
            fix=f"import the dataset again with --setup {other} (or, if the setup is {setup}, "
            "the poses are flange -> base: give their inverse, base -> flange)",
        )
    raise HandEyeMisfitError(
        f"{head} ({other}: {other_px:.1f} px); the motions' turn angles agree, so the "
        "orientations and the pairing look right",
        fix="check the positions' unit (--pose-units, x_mm or x_m), that the poses are base -> "
        "flange (not their inverse) and that the board did not move on its mount",
    )
