"""Whether the pose route's answer refines the camera or holds the board calibration's, by
cross-validation over the views (:func:`choose_camera`).

Refining the camera in the hand-eye fit lets the pose chain's errors (the flange poses' noise)
bend the intrinsics; holding it at the camera stage's keeps the camera the board alone
determines, with fewer parameters fitted through the flange poses: the default, left only when
refining predicts left-out views better by more than
:data:`selfcal.calibration.handeye.fit.CV_MARGIN` (the rule the flange poses' corrections are
chosen by, :func:`selfcal.calibration.handeye.fit.predict_better`). The comparison is fair only
when the held camera has not seen the left-out views: each fold's held camera is the board
calibration of its training images alone (:func:`fold_camera`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.calibrate import BoardCalibration
from selfcal.calibration.handeye.fit import (
    HandEyeFit,
    Predictor,
    chain_predictor,
    cross_validate,
    predict_better,
)
from selfcal.camera import CameraModel
from selfcal.choices import HANDEYE_CAMERA
from selfcal.errors import EstimationError, SelfCalError
from selfcal.estimation.bundle_adjust import bundle_adjust
from selfcal.estimation.pose_models import ViewPoses
from selfcal.target.boards import Board

__all__ = ["CAMERA_MODES", "CameraChoice", "choose_camera", "fold_camera"]

CAMERA_MODES = HANDEYE_CAMERA
"""How :func:`selfcal.calibration.handeye.calibrate.calibrate_hand_eye` treats the camera in its
answer: chosen by :func:`choose_camera`, always the camera stage's, always refined
(:data:`selfcal.choices.HANDEYE_CAMERA`, which ``selfcal calibrate --camera`` offers)."""


@dataclass(frozen=True)
class CameraChoice:
    """The cross-validation of :func:`choose_camera`: the held-out RMS (px) of the views'
    corners predicted from their flange poses by the fits without them, the camera held at the
    board calibration of the training images (``held_px``) and refined with the hand-eye
    (``refined_px``), over ``folds`` folds (each fold's RMS: ``held_fold_px``,
    ``refined_fold_px``); ``refined`` whether the answer refines the camera. ``held_failed``:
    the folds whose held camera could not be calibrated (:func:`fold_camera` failed); the two
    RMS are then over the folds where both predicted, and where none did the camera is held."""

    held_px: float
    refined_px: float
    folds: int
    refined: bool
    held_fold_px: tuple[float, ...] = ()
    refined_fold_px: tuple[float, ...] = ()
    held_failed: int = 0


def fold_camera(stage: BoardCalibration, board: Board, uv: np.ndarray, images: np.ndarray,
                max_nfev: int = 200) -> CameraModel:  # fmt: skip
    """The camera of the board calibration ``stage`` calibrated again on its ``images`` (view
    indices) alone: its bundle adjustment (the free camera parameters and one board pose per
    image, the board's points held) on those images' inlier rows, one least-squares pass started
    from ``stage``'s camera and board poses; ``uv`` (k, 2) px are ``stage``'s rows' pixels. The
    start only saves OpenCV's calibration and the robust pass: the minimum is the training
    images' own (the rows' inlier marks are the stage's, from all its images).

    Raises:
        EstimationError: the adjustment failed (the message says why).
    """
    keep = np.isin(stage.view, images) & stage.inlier
    ok = np.zeros(len(stage.used), bool)
    ok[np.unique(stage.view[keep])] = True
    ids, pidx = np.unique(stage.feature[keep], return_inverse=True)
    poses = ViewPoses(np.where(ok[:, None, None], stage.T_cam_board, np.nan), ok)
    try:
        res = bundle_adjust(poses, poses.initial_params(), board.points(ids), stage.view[keep],
                            pidx, uv[keep], stage.camera, fix_points=True, loss="linear",
                            max_nfev=max_nfev)  # fmt: skip
    except SelfCalError as exc:
        raise EstimationError(f"the fold's board calibration failed ({exc})") from exc
    if res.status <= 0:
        raise EstimationError(f"the fold's board calibration did not converge ({res.message})")
    return res.camera


def choose_camera(stage: BoardCalibration, board: Board, A: np.ndarray, nominal: HandEyeFit,
                  calibrated: HandEyeFit, view: np.ndarray, points: np.ndarray, uv: np.ndarray,
                  outlier_px: float, max_iter: int, setup: str,
                  folds: int = 8) -> CameraChoice:  # fmt: skip
    """Whether the ``calibrated`` fit (camera refined) predicts left-out views better than the
    ``nominal`` (the camera ``stage``'s camera held), both with the nominal's flange pose
    weights, on ``stage``'s rows ``view``, ``points``, ``uv`` (as
    :func:`selfcal.calibration.handeye.fit.fit_pose_chain`'s): each fold's held camera is the
    board calibration of its training images alone (:func:`fold_camera`), its hand-eye and
    board mount then fitted from the nominal's; the refined fit starts from ``calibrated``
    (:func:`selfcal.calibration.handeye.fit.cross_validate`, the inliers of both fits). The
    camera is refined only when that predicts better by more than
    :data:`selfcal.calibration.handeye.fit.CV_MARGIN`
    (:func:`selfcal.calibration.handeye.fit.predict_better`)."""
    noise, s_px = nominal.pose_noise, nominal.sigma_px

    def camera_of(train: np.ndarray) -> CameraModel:  # its own budget, not max_iter
        return fold_camera(stage, board, uv, np.unique(view[train]))

    predictors: dict[str, Predictor] = {
        "held": chain_predictor(camera_of, A, nominal, noise, s_px, view, points, uv,
                                outlier_px, max_iter, setup),
        "refined": chain_predictor(calibrated.camera, A, calibrated, noise, s_px, view, points,
                                   uv, outlier_px, max_iter, setup, hold_camera=False),
    }  # fmt: skip
    cv = cross_validate(view, nominal.inlier & calibrated.inlier, uv, predictors, folds)
    h, r = cv.rms["held"], cv.rms["refined"]
    held_f, ref_f = np.array(cv.fold_rms["held"]), np.array(cv.fold_rms["refined"])
    failed = int(np.sum(~np.isfinite(held_f)))
    if failed:  # a held camera not calibrated is no evidence for refining: compare the others
        both = np.isfinite(held_f) & np.isfinite(ref_f)
        n = np.array(cv.fold_count, float) * both
        if n.sum() == 0:
            return CameraChoice(h, r, cv.folds, False, cv.fold_rms["held"],
                                cv.fold_rms["refined"], failed)  # fmt: skip
        h = float(np.sqrt(np.sum(np.where(both, held_f, 0.0) ** 2 * n) / n.sum()))
        r = float(np.sqrt(np.sum(np.where(both, ref_f, 0.0) ** 2 * n) / n.sum()))
    return CameraChoice(h, r, cv.folds, predict_better(r, h), cv.fold_rms["held"],
                        cv.fold_rms["refined"], failed)  # fmt: skip
