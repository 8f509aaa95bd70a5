"""Camera calibration from a board of known geometry (Zhang), refined on the one solver.

Route: the views in which the board is found (:class:`selfcal.target.boards.Board`, at least
``board.min_features`` features) -> ``cv2.calibrateCamera`` (Zhang's planar homographies and
OpenCV's refinement) as the initial guess of the camera and of every board pose -> the project's
bundle adjustment (:func:`selfcal.estimation.bundle_adjust.bundle_adjust`) over the camera's free parameters
and one pose per view (:class:`selfcal.estimation.pose_models.ViewPoses`) with the board's points
held at their declared positions: the board frame is the world and its geometry gives the scale
(no known distance is needed). A robust pass (soft-L1) is followed by a plain least-squares pass
on the inliers; the covariance of the free camera parameters is ``sigma^2 (J^T J)^-1`` at the
solution.

Frames and units: ``T_cam_board`` maps board coordinates (m, :mod:`selfcal.target.boards`) to the
OpenCV camera frame; pixels in the OpenCV convention. The camera is any model of
:data:`selfcal.camera.MODELS` -- the pinhole (``fx``, ``mu``, ``cx``, ``cy``), Brown-Conrady
(``"opencv"``: plus ``k1, k2, p1, p2, k3 ...``) or the fisheye -- with its ``free`` parameters:
OpenCV's calibration (``cv2.calibrateCamera`` / ``cv2.fisheye.calibrate``, the held parameters
fixed by its flags) gives the initial intrinsics and distortion, the bundle adjustment refines
every free parameter (the lens Jacobians of :mod:`selfcal.camera.lens`). A model OpenCV does not
calibrate (the double sphere, :data:`selfcal.camera.REGISTRY`) starts from its rays instead
(:func:`ray_start`: each of its guesses refined, the lowest cost kept; ``diagnostics["start"]``
is ``"rays"``) and is refined the same way. Both starts are in
:mod:`selfcal.calibration.board.camera_start`.

Bad input: images without the board are skipped with a :class:`BoardNotFoundWarning` that names
and counts them, and :class:`BoardInputError` follows when fewer than ``min_views`` remain; a fit
whose residuals show that the declared geometry is not the printed one raises
:class:`BoardMismatchError` naming the target file and its keys.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.board.camera_start import (
    OpenCVCalibration,
    opencv_calibration,
    ray_start,
)
from selfcal.camera import CameraModel, Pinhole, entry
from selfcal.errors import InitialCameraWarning, InputError, SelfCalWarning
from selfcal.estimation.bundle_adjust import bundle_adjust, intrinsics_covariance
from selfcal.estimation.pose_models import ViewPoses
from selfcal.estimation.reprojection import robust_sigma
from selfcal.target.base import Features
from selfcal.target.boards import Board

__all__ = [
    "BoardCalibration",
    "BoardInputError",
    "BoardMismatchError",
    "BoardNotFoundWarning",
    "InitialCameraWarning",
    "MAX_OUTLIER_SHARE",
    "OUTLIER_PX",
    "OUTLIER_SIGMAS",
    "OpenCVCalibration",
    "ROBUST_LOSS",
    "ROBUST_SCALE_PX",
    "calibrate_board",
    "opencv_calibration",
    "outlier_limit_px",
    "ray_start",
]

_FIX_FILES = "see docs/targets.md"


class BoardInputError(InputError):
    """Too few images show the board to calibrate from (the message names them)."""


class BoardMismatchError(InputError):
    """The detections do not fit the board's declared geometry (the message names the target
    file and its keys)."""


class BoardNotFoundWarning(SelfCalWarning):
    """Some images do not show the board (or too little of it); they are skipped."""


@dataclass
class BoardCalibration:
    """Result of :func:`calibrate_board`.

    ``camera``: the estimated camera (its ``free`` parameters adjusted); ``std`` / ``cov``: the
    free parameters' standard deviations and covariance (fitted noise); ``T_cam_board`` (V, 4,
    4) for every view given (NaN where not used), ``used`` (V,) bool; ``residuals`` (k, 2) px
    (projected - observed) of the rows ``view``, ``feature`` of the final pass, ``inlier`` (k,);
    ``rms_px``: the 2-D RMS over the inliers (``rms_all_px`` over every row, as OpenCV
    reports it); ``sigma_px``: the fitted noise per coordinate;
    ``skipped``: names of the views without the board; ``opencv``: the initial guess."""

    camera: CameraModel
    std: dict[str, float]
    cov: np.ndarray
    T_cam_board: np.ndarray
    used: np.ndarray
    view: np.ndarray
    feature: np.ndarray
    residuals: np.ndarray
    inlier: np.ndarray
    rms_px: float
    rms_all_px: float
    sigma_px: float
    skipped: tuple[str, ...]
    opencv: OpenCVCalibration
    diagnostics: dict = field(default_factory=dict)


def _usable(
    board: Board, features: Sequence[Features], names: Sequence[str] | None, min_views: int
) -> tuple[np.ndarray, tuple[str, ...]]:
    """(V,) which views show enough of the board, and the names of the others (warned);
    :class:`BoardInputError` when fewer than ``min_views`` remain."""
    names = [f"view {i}" for i in range(len(features))] if names is None else list(names)
    ok = np.array([len(f) >= board.min_features for f in features], dtype=bool)
    skipped = tuple(n for n, k in zip(names, ok, strict=True) if not k)
    if skipped:
        more = " ..." if len(skipped) > 8 else ""
        warnings.warn(
            f"{len(skipped)} of {len(features)} image(s) do not show the {board.describe()} "
            f"(fewer than {board.min_features} features) and are skipped: "
            f"{', '.join(skipped[:8])}{more}",
            BoardNotFoundWarning,
            stacklevel=3,
        )
    if ok.sum() < min_views:
        hint = (
            "check the target file's keys (inner_corners, pattern or tags are counted as "
            "[columns, rows] of inner corners / circles / tags) and that the images show the "
            "whole board"
            if not ok.any()
            else "add images that show the board"
        )
        raise BoardInputError(
            f"only {int(ok.sum())} of {len(features)} image(s) show the {board.describe()}; "
            f"calibration needs at least {min_views}",
            fix=hint,
        )
    return ok, skipped


OUTLIER_PX = 3.0
"""A feature is an outlier where its 2-D reprojection error (px) after the robust fit of its
view's pose and the camera is at least ``max(OUTLIER_PX, OUTLIER_SIGMAS * robust sigma)``
(:func:`outlier_limit_px`, the one place the rule is written: :func:`calibrate_board`; the
drift check drops new corners by it, :func:`selfcal.calibration.drift.outliers.view_outliers`)."""
OUTLIER_SIGMAS = 4.5
"""The robust sigmas (:func:`selfcal.estimation.reprojection.robust_sigma`) of the outlier rule
(:data:`OUTLIER_PX`)."""
ROBUST_LOSS = "soft_l1"
"""The loss of the first, robust pass (:func:`calibrate_board`; the drift check's outlier fit,
:func:`selfcal.calibration.drift.outliers.view_outliers`, uses it too): on each feature's 2-D
reprojection error, scale :data:`ROBUST_SCALE_PX`."""
ROBUST_SCALE_PX = 1.0
"""The scale (px) of :data:`ROBUST_LOSS`."""
MAX_OUTLIER_SHARE = 0.25
"""The largest share of the features the outlier rule may reject: beyond it the declared
geometry is not the board's (:class:`BoardMismatchError`)."""


def outlier_limit_px(kept_px: np.ndarray, floor_px: float = OUTLIER_PX) -> float:
    """The outlier rule's limit (px): ``max(floor_px, OUTLIER_SIGMAS * robust sigma)``, the
    robust sigma (:func:`selfcal.estimation.reprojection.robust_sigma`) of the 2-D reprojection
    errors ``kept_px`` (k,) px of the rows still kept; a row is an outlier where its error is at
    least the limit (:data:`OUTLIER_PX`; :func:`calibrate_board` and the drift check's
    :func:`selfcal.calibration.drift.outliers.view_outliers`)."""
    return max(floor_px, OUTLIER_SIGMAS * robust_sigma(kept_px))


def calibrate_board(
    board: Board,
    features: Sequence[Features],
    width: int,
    height: int,
    *,
    free: Sequence[str] = ("fx", "mu", "cx", "cy"),
    model: str = "pinhole",
    names: Sequence[str] | None = None,
    min_views: int = 3,
    outlier_px: float = OUTLIER_PX,
    mismatch_px: float = 3.0,
    max_nfev: int = 200,
    initial: Pinhole | None = None,
) -> BoardCalibration:
    """Calibrate the camera ``model`` (parameters ``free``, OpenCV names; the others held at
    the image centre, aspect 1, no distortion) and the board pose of every view from the
    board's detected ``features`` (one per image; ``names`` for messages) in ``width`` x
    ``height`` px images (see the module docstring). ``initial``: a camera of ``model`` to
    start from (a ROS CameraInfo's calibration): OpenCV's calibration runs from it and from its
    own start, and the start that fits the views better (OpenCV's RMS; the initial camera on a
    tie) goes on to the refinement; the other way round an :class:`InitialCameraWarning` says
    so. ``diagnostics["start"]`` says which: ``"initial"`` or ``"opencv"``.

    Raises:
        BoardInputError: fewer than ``min_views`` views show the board.
        BoardMismatchError: the inlier residuals exceed ``mismatch_px`` (RMS, 2-D) or more than
            a quarter of the features are outliers: the declared geometry is not the board's.
    """
    ok, skipped = _usable(board, features, names, min_views)
    idx = np.flatnonzero(ok).tolist()
    _check_ids(board, [features[i] for i in idx])
    if not entry(model).opencv:
        cv_res = ray_start(board, [features[i] for i in idx], width, height, free, model, initial)
        start = "rays"
    else:
        cv_res = opencv_calibration(board, [features[i] for i in idx], width, height, free, model)
        start = "opencv"
    if initial is not None and entry(model).opencv:
        cv_init = opencv_calibration(board, [features[i] for i in idx], width, height, free,
                                     model, initial)  # fmt: skip
        if cv_init.rms_px <= cv_res.rms_px * (1 + 1e-9) or not np.isfinite(cv_res.rms_px):
            cv_res, start = cv_init, "initial"
        else:
            warnings.warn(
                f"the initial camera (fx = {initial.fx:.1f} px) fits the {board.describe()} "
                f"worse than OpenCV's own start (RMS {cv_init.rms_px:.3f} px vs "
                f"{cv_res.rms_px:.3f} px after OpenCV's calibration): started from OpenCV's "
                "(check the camera_info of the recording: another lens or resolution?)",
                InitialCameraWarning,
                stacklevel=2,
            )
    V = len(features)
    T0 = np.full((V, 4, 4), np.nan)
    T0[idx] = cv_res.T_cam_board
    view = np.concatenate([np.full(len(features[i]), i) for i in idx])
    fid = np.concatenate([features[i].ids for i in idx])
    uv = np.concatenate([features[i].uv for i in idx])
    pts_ids, pidx = np.unique(fid, return_inverse=True)
    X = board.points(pts_ids)
    poses = ViewPoses(T0, ok)
    camera = cv_res.camera
    active = np.ones(len(view), bool)
    res = None
    for loss in (ROBUST_LOSS, "linear"):
        res = bundle_adjust(
            poses, poses.initial_params(), X, view[active], pidx[active], uv[active], camera,
            fix_points=True, loss=loss, f_scale_px=ROBUST_SCALE_PX, max_nfev=max_nfev,
        )  # fmt: skip
        camera = res.camera
        poses = ViewPoses(np.where(ok[:, None, None], res.T_cam_world, np.nan), ok)
        if loss == ROBUST_LOSS:  # reclassify every row with the robust estimate
            e = _errors(camera, res.T_cam_world, X, view, pidx, uv)
            active = e < outlier_limit_px(e[active], outlier_px)
    assert res is not None and res.jac is not None  # the analytic Jacobian of ViewPoses
    e_all = _errors(camera, res.T_cam_world, X, view, pidx, uv)
    rms = float(np.sqrt(np.mean(e_all[active] ** 2)))
    _check_geometry(board, rms, active, mismatch_px)
    cov, _ = intrinsics_covariance(res.jac, res.residuals, res.n_intrinsics)
    std = dict(zip(camera.free, np.sqrt(np.clip(np.diag(cov), 0, None)).tolist(), strict=True))
    r_out = np.full((len(view), 2), np.nan)
    r_out[active] = res.residuals
    dof = max(res.residuals.size - res.jac.shape[1], 1)
    T = np.where(ok[:, None, None], res.T_cam_world, np.nan)
    return BoardCalibration(
        camera=camera, std=std, cov=cov, T_cam_board=T, used=ok, view=view,
        feature=fid, residuals=r_out, inlier=active, rms_px=rms,
        rms_all_px=float(np.sqrt(np.mean(e_all**2))),
        sigma_px=float(np.sqrt(np.sum(res.residuals**2) / dof)), skipped=skipped,
        opencv=cv_res, diagnostics={"nfev": res.nfev, "status": res.status, "start": start},
    )  # fmt: skip


def _errors(camera, T_cam_world, X, view, pidx, uv) -> np.ndarray:
    """2-D reprojection error (k,) px of every row; inf where the model does not project the
    point (behind a perspective camera)."""
    T = T_cam_world[view]
    Xc = np.einsum("kij,kj->ki", T[:, :3, :3], X[pidx]) + T[:, :3, 3]
    e = np.linalg.norm(camera.project(Xc) - uv, axis=1)
    return np.where(camera.valid(Xc), e, np.inf)


_KEYS = {
    "Chessboard": "inner_corners, square_mm",
    "Charuco": "inner_corners, square_mm, marker_mm, dictionary",
    "CirclesGrid": "pattern, spacing_mm",
    "AprilGrid": "tags, tag_mm, spacing_ratio",
}


def _mismatch(board: Board, what: str) -> BoardMismatchError:
    keys = _KEYS.get(type(board).__name__, "its keys")
    return BoardMismatchError(
        f"the detections do not fit the {board.describe()}: {what}; the declared geometry is "
        "not the printed board's",
        fix=f"check {keys} in {board.source or 'the target file'} against the printed board "
        f"(and that the lens has no strong distortion); {_FIX_FILES}",
    )


def _check_ids(board: Board, features: Sequence[Features]) -> None:
    """:class:`BoardMismatchError` for feature ids the declared board does not have."""
    ids = np.unique(np.concatenate([f.ids for f in features]))
    bad = ids[np.isnan(board.points(ids)).any(axis=1)]
    if len(bad):
        raise _mismatch(board, f"feature ids {bad[:8].tolist()} are not on the declared board")


def _check_geometry(board: Board, rms: float, active: np.ndarray, mismatch_px: float) -> None:
    """:class:`BoardMismatchError` when the fit shows the declared geometry is not the board's."""
    frac_out = 1.0 - float(np.mean(active))
    if rms <= mismatch_px and frac_out <= MAX_OUTLIER_SHARE:
        return
    raise _mismatch(
        board,
        f"reprojection RMS {rms:.2f} px over the inliers (limit {mismatch_px:g} px), "
        f"{100 * frac_out:.0f} % of the features rejected as outliers",
    )
