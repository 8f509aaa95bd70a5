"""Hand-eye calibration from a robot's flange poses: camera, hand-eye and board mount.

Setups (:mod:`selfcal.estimation.pose_chain`): eye-in-hand (``X = T_flange_cam``, ``B =
T_base_board``) and eye-to-hand (``X = T_base_cam``, ``B = T_flange_board``); the robot's
reported flange poses ``T_base_flange`` are its measurements: without joint readings there are
no kinematics to identify.

Route: the camera stage (:func:`selfcal.calibration.board.calibrate.calibrate_board`: OpenCV's calibration
refined by the bundle adjustment, one free board pose per view) -> the linear start of ``X`` and
``B`` from its board poses (:func:`selfcal.calibration.handeye.linear.linear_hand_eye`) -> the one solver on
corner reprojection through the pose chain (:class:`selfcal.estimation.pose_chain.PoseChainBlock`):
a robust pass (soft-L1, 1 px), the outliers (beyond ``max(3 px, 4.5 sigma)``) dropped, a plain
least-squares pass whose covariance ``sigma^2 (J^T J)^-1`` gives the standard deviations
(:mod:`selfcal.calibration.handeye.fit`). Twice: the *nominal* holds the camera of the camera
stage and fits ``X`` and ``B`` (the fair reference: everything but what the calibration adds
fitted by the same objective), the *calibrated* frees the camera's parameters too.

The flange poses (``pose_noise``, :mod:`selfcal.calibration.handeye.eiv`): the fit with them
exact comes first (the checks that the poses explain the images run on it); then, unless the
caller says they are exact, each pose gets a correction with a prior of the pose noise (given,
or estimated by variance components), and with ``"auto"`` the corrections are dropped when
they predict left-out views from their reported poses worse than the exact poses
(:func:`selfcal.calibration.handeye.fit.choose_pose_noise`). The calibrated fit weighs the poses
as the nominal chose, with the nominal's sigmas.

The camera (``camera``, :mod:`selfcal.calibration.handeye.camera_refinement`): with ``"auto"`` the
answer holds the camera stage's camera (the nominal is the answer) unless refining it predicts
left-out views better by more than the pose noise's margin, each fold's held camera calibrated
on its training images alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from selfcal.calibration.board.calibrate import BoardCalibration, calibrate_board
from selfcal.calibration.handeye.camera_refinement import CAMERA_MODES, CameraChoice, choose_camera
from selfcal.calibration.handeye.eiv import EXACT, PoseNoise
from selfcal.calibration.handeye.fit import (
    HandEyeFit,
    PoseChoice,
    choose_pose_noise,
    fit_pose_chain,
    predict_corners,
)
from selfcal.calibration.handeye.linear import linear_hand_eye, turn_misfit_deg
from selfcal.errors import EstimationError, InputError, UsageError
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = ["HandEyeFit", "HandEyeCalibration", "HandEyeMisfitError", "calibrate_hand_eye",
           "chain_motions", "predict_corners", "FRAMES", "MISFIT_PX", "MISFIT_RATIO",
           "POSE_NOISE_MODES", "CAMERA_MODES", "CameraChoice"]  # fmt: skip

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
POSE_NOISE_MODES = ("auto", "estimate")
"""The pose noise :func:`calibrate_hand_eye` finds itself (besides given sigmas)."""
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
class HandEyeCalibration:
    """Result of :func:`calibrate_hand_eye`: the ``setup``, the ``camera_stage``, the linear
    start ``X0`` / ``B0``, the ``nominal`` (camera held) and ``calibrated`` (camera free) fits,
    ``used`` (n,) the views in them, ``pose_choice`` the cross-validation that chose between the
    exact flange poses and their corrections (None: the caller gave the pose noise);
    ``camera_refined`` whether ``calibrated`` refines the camera (else it is the nominal),
    ``camera_choice`` the cross-validation that chose (None: the caller chose) and ``refined``
    the fit with the camera refined (``calibrated`` when chosen; None when ``camera`` was
    ``"held"``)."""

    setup: str
    camera_stage: BoardCalibration
    X0: np.ndarray
    B0: np.ndarray
    nominal: HandEyeFit
    calibrated: HandEyeFit
    used: np.ndarray
    pose_choice: PoseChoice | None = None
    camera_refined: bool = True
    camera_choice: CameraChoice | None = None
    refined: HandEyeFit | None = None


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
    pose_noise: PoseNoise | str = "auto",
    camera: str = "auto",
) -> HandEyeCalibration:
    """Calibrate the camera (``model``, parameters ``free``), the hand-eye and the board mount
    of ``setup`` from the board ``features`` of one image per pose and the flange poses
    ``T_base_flange`` (n, 4, 4) m (see the module docstring); ``names`` name the images;
    ``pose_noise`` (:mod:`selfcal.calibration.handeye.eiv`): the flange poses' sigmas per axis
    (:data:`selfcal.calibration.handeye.eiv.EXACT`: the poses taken as exact), ``"estimate"``:
    estimated from the residuals, ``"auto"``: estimated, and the corrections dropped when they
    predict left-out views worse than the exact poses
    (:func:`selfcal.calibration.handeye.fit.choose_pose_noise`); ``camera``: ``"refined"`` the
    answer refines the camera, ``"held"`` holds the camera stage's (the answer is the nominal),
    ``"auto"``: held unless refining predicts left-out views better by more than
    :data:`selfcal.calibration.handeye.fit.CV_MARGIN`
    (:func:`selfcal.calibration.handeye.camera_refinement.choose_camera`).

    Raises:
        selfcal.calibration.board.calibrate.BoardInputError / BoardMismatchError: as the camera stage.
        selfcal.calibration.handeye.linear.HandEyeStartError: the motions do not determine the hand-eye.
        EstimationError: a fit did not converge.
    """
    T_base_flange = np.asarray(T_base_flange, float)
    if not isinstance(pose_noise, PoseNoise) and pose_noise not in POSE_NOISE_MODES:
        raise UsageError(f"pose_noise {pose_noise!r}: give a PoseNoise or one of "
                         f"{', '.join(POSE_NOISE_MODES)}")  # fmt: skip
    if camera not in CAMERA_MODES:
        raise UsageError(f"camera {camera!r}: give one of {', '.join(CAMERA_MODES)}")
    given = pose_noise if isinstance(pose_noise, PoseNoise) else None
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
        exact = fit_pose_chain(stage.camera, True, A, X0, B0, view, points, uv, outlier_px, max_iter,
                     setup=setup, pose_noise=EXACT, camera_cov=stage.cov)  # fmt: skip
        rms = exact.rms_px
    except EstimationError:
        rms = float("inf")
    if rms > max(MISFIT_PX, MISFIT_RATIO * stage.rms_px):
        _explain_misfit(setup, rms, stage, T_base_flange, view, points, uv, outlier_px, max_iter)
    nominal, choice = exact, None
    if given is None or not given.exact:
        eiv = fit_pose_chain(stage.camera, True, A, exact.X, exact.B, view, points, uv,
                             outlier_px, max_iter, setup=setup, pose_noise=given,
                             start_px=exact.sigma_px, camera_cov=stage.cov)  # fmt: skip
        if pose_noise == "auto":
            choice = choose_pose_noise(stage.camera, A, exact, eiv, view, points, uv, outlier_px,
                                       max_iter, setup=setup)  # fmt: skip
        nominal = eiv if choice is None or choice.eiv else exact
    noise = nominal.pose_noise
    refined = cam_choice = None
    if camera != "held":
        refined = fit_pose_chain(stage.camera, False, A, nominal.X, nominal.B, view, points, uv,
                                 outlier_px, max_iter, setup=setup, pose_noise=noise,
                                 start_px=nominal.sigma_px)  # fmt: skip
        refined = replace(refined, pose_noise_estimated=nominal.pose_noise_estimated)
    if camera == "auto" and refined is not None:
        cam_choice = choose_camera(stage, board, A, nominal, refined, view, points, uv,
                                   outlier_px, max_iter, setup)  # fmt: skip
    chosen = camera == "refined" or (cam_choice is not None and cam_choice.refined)
    return HandEyeCalibration(setup=setup, camera_stage=stage, X0=X0, B0=B0, nominal=nominal,
                              calibrated=refined if chosen and refined else nominal, used=used,
                              pose_choice=choice, camera_refined=chosen,
                              camera_choice=cam_choice, refined=refined)  # fmt: skip


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
        other_px = fit_pose_chain(stage.camera, True, A, X0, B0, view, points, uv, outlier_px,
                        max_iter, setup=other, pose_noise=EXACT).rms_px  # fmt: skip
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
