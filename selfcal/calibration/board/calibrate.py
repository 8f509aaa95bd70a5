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
is ``"rays"``) and is refined the same way.

Bad input: images without the board are skipped with a :class:`BoardNotFoundWarning` that names
and counts them, and :class:`BoardInputError` follows when fewer than ``min_views`` remain; a fit
whose residuals show that the declared geometry is not the printed one raises
:class:`BoardMismatchError` naming the target file and its keys.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from selfcal.camera import (
    CameraModel,
    LensCamera,
    Pinhole,
    camera_model,
    canonical_free,
    entry,
    lens_names,
    ray_poses,
)
from selfcal.camera.pinhole import centered_principal_point
from selfcal.errors import EstimationError, InitialCameraWarning, InputError, SelfCalWarning
from selfcal.estimation.bundle_adjust import bundle_adjust, intrinsics_covariance
from selfcal.estimation.pose_models import ViewPoses
from selfcal.estimation.reprojection import robust_sigma
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.transforms import make_pose

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
    "calibrate_board",
    "opencv_calibration",
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


@dataclass(frozen=True)
class OpenCVCalibration:
    """OpenCV's calibration on the same views: ``camera`` (the model asked for), the standard
    deviations ``std`` of OpenCV's own parameters (``fx``, ``fy``, ``cx``, ``cy`` px, the lens
    coefficients; none from ``cv2.fisheye``), the board
    poses ``T_cam_board`` (n, 4, 4) of the views it was given and its reprojection ``rms_px``
    (OpenCV's: the root mean square of the 2-D reprojection error over all points)."""

    camera: CameraModel
    std: dict[str, float]
    T_cam_board: np.ndarray
    rms_px: float


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


def _pose(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    return make_pose(cv2.Rodrigues(np.asarray(rvec, dtype=float))[0], np.ravel(tvec))


_CV_STD_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
"""The first entries of ``calibrateCameraExtended``'s ``stdDeviationsIntrinsics``, in order."""


def _opencv_flags(model: str, free: Sequence[str]) -> int:
    """``cv2.calibrateCamera`` flags (Brown-Conrady) or ``cv2.fisheye.calibrate`` flags that
    hold every parameter of ``model`` not in ``free``."""
    if entry(model).opencv == "fisheye":  # OpenCV 5 keeps its flags in cv2, 4.x in cv2.fisheye
        flag = lambda n: getattr(cv2.fisheye, n, None) or getattr(cv2, n)  # noqa: E731
        flags = flag("CALIB_RECOMPUTE_EXTRINSIC") | flag("CALIB_USE_INTRINSIC_GUESS")
        if "skew" not in free:  # its alpha = skew / fx; calibrateCamera has no skew
            flags |= flag("CALIB_FIX_SKEW")
        for k in ("k1", "k2", "k3", "k4"):
            if k not in free:
                flags |= flag(f"CALIB_FIX_{k.upper()}")
        if "cx" not in free or "cy" not in free:
            flags |= flag("CALIB_FIX_PRINCIPAL_POINT")
        return flags
    flags = cv2.CALIB_USE_INTRINSIC_GUESS
    fix = {"k1": cv2.CALIB_FIX_K1, "k2": cv2.CALIB_FIX_K2, "k3": cv2.CALIB_FIX_K3,
           "k4": cv2.CALIB_FIX_K4, "k5": cv2.CALIB_FIX_K5, "k6": cv2.CALIB_FIX_K6}  # fmt: skip
    for k, f in fix.items():
        if k not in free:
            flags |= f
    if any(k in free for k in ("k4", "k5", "k6")):
        flags |= cv2.CALIB_RATIONAL_MODEL
    if "p1" not in free or "p2" not in free:  # OpenCV frees both tangential terms or neither
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    if "mu" not in free:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    if "cx" not in free or "cy" not in free:
        flags |= cv2.CALIB_FIX_PRINCIPAL_POINT
    return flags


_GOOD_START_PX = 1.0
"""RMS (px) of a fisheye start good enough to stop trying others (detector noise is 0.05-0.5)."""


def _fisheye_calibrate(obj, img, width: int, height: int, K0: np.ndarray, dist0: np.ndarray,
                       flags: int, criteria: tuple, *, starts: bool) -> tuple:  # fmt: skip
    """``cv2.fisheye.calibrate`` from ``K0`` and, with ``starts``, from the focal lengths of
    fields of view 40-180 deg across the shorter side (equidistant: ``f = (side / 2) / half
    angle``): the homographies' pinhole focal length that ``K0`` holds is several times a wide
    fisheye's (3325 px for 512 px measured), from where OpenCV's solver fails (an assertion in
    ``InitExtrinsics``). The first start that fits within :data:`_GOOD_START_PX`, else the one
    with the lowest RMS, wins; all failing raises the first error."""
    obj64 = [o.reshape(1, -1, 3).astype(np.float64) for o in obj]  # the shapes it accepts
    img64 = [i.reshape(1, -1, 2).astype(np.float64) for i in img]
    focal = [float(K0[0, 0])]
    if starts:  # half fields of view, the middle ones first
        half_deg = (60.0, 45.0, 75.0, 90.0, 30.0, 20.0)
        focal += [0.5 * min(width, height) / np.radians(a) for a in half_deg]
    best, first_error = None, None
    for f in focal:
        if best is not None and best[0] < _GOOD_START_PX:
            break
        K = K0.copy()
        K[0, 0] = K[1, 1] = f
        try:
            out = cv2.fisheye.calibrate(obj64, img64, (width, height), K, dist0.copy(),
                                        flags=flags, criteria=criteria)  # fmt: skip
        except cv2.error as exc:
            first_error = first_error or exc
            continue
        if np.isfinite(out[0]) and (best is None or out[0] < best[0]):
            best = out
    if best is None:
        assert first_error is not None
        raise first_error
    return best


def opencv_calibration(
    board: Board,
    features: Sequence[Features],
    width: int,
    height: int,
    free: Sequence[str] = ("fx", "mu", "cx", "cy"),
    model: str = "pinhole",
    initial: Pinhole | None = None,
) -> OpenCVCalibration:
    """OpenCV's calibration of the camera ``model`` (``"pinhole"``, ``"opencv"``,
    ``"fisheye"``; :data:`selfcal.camera.MODELS`) with parameters ``free`` from the views
    ``features``: ``cv2.calibrateCameraExtended`` (the pinhole with its distortion held at zero,
    or Brown-Conrady) or ``cv2.fisheye.calibrate``, every parameter not in ``free`` held (the
    principal point at the image centre, aspect 1, lens coefficients 0). ``initial``: a camera
    of ``model`` to start from instead (its K and lens coefficients; the held parameters keep its
    values)."""
    if not entry(model).opencv:
        raise InputError(f"OpenCV does not calibrate the camera model {model!r}",
                         fix="use ray_start for its start")  # fmt: skip
    obj = [board.points(f.ids).astype(np.float32) for f in features]
    img = [f.uv.astype(np.float32).reshape(-1, 1, 2) for f in features]
    cx0, cy0 = centered_principal_point(width, height)
    # the initial focal length from the homographies (OpenCV's own initialisation)
    K0 = cv2.initCameraMatrix2D(obj, img, (width, height), aspectRatio=1.0)
    K0[0, 2], K0[1, 2] = cx0, cy0
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    names = lens_names(model)
    flags = _opencv_flags(model, free)
    guess = np.zeros(len(names))
    if initial is not None:
        if initial.model_name != model:
            raise InputError(f"initial camera {initial.model_name!r}, model {model!r}")
        K0 = np.array(initial.K, dtype=np.float64)
        if isinstance(initial, LensCamera):
            guess = np.asarray(initial.coeffs, float)[: len(names)]
        if "k4" in names and np.any(guess[5:8] != 0):
            flags |= cv2.CALIB_RATIONAL_MODEL  # keep its k4-k6 (held unless free)
    if entry(model).opencv == "fisheye":
        out = _fisheye_calibrate(obj, img, width, height, K0, guess[:4], flags, criteria,
                                 starts=initial is None)  # fmt: skip
        rms, K, dist, rvecs, tvecs = out[0], out[1], np.ravel(out[2]), out[3], out[4]
        std = {}  # cv2.fisheye gives no standard deviations
    else:
        dist0 = np.zeros(8 if flags & cv2.CALIB_RATIONAL_MODEL else 5)
        dist0[: min(len(dist0), len(guess))] = guess[: len(dist0)]
        ext = cv2.calibrateCameraExtended(
            obj, img, (width, height), K0, dist0, flags=flags, criteria=criteria,
        )  # fmt: skip
        rms, K, dist, rvecs, tvecs = ext[0], ext[1], np.ravel(ext[2]), ext[3], ext[4]
        s = np.ravel(ext[5])
        std = {n: float(v) for n, v in zip(_CV_STD_NAMES[: 4 + len(names)], s, strict=False)}
    fx, fy = float(K[0, 0]), float(K[1, 1])
    coeffs = {n: float(dist[k]) if k < len(dist) else 0.0 for k, n in enumerate(names)}
    camera = camera_model(model, fx=fx, mu=fy / fx, cx=float(K[0, 2]), cy=float(K[1, 2]),
                          width=width, height=height, coeffs=coeffs, free=tuple(free),
                          skew=float(K[0, 1]))  # fmt: skip
    T = np.stack([_pose(r, t) for r, t in zip(rvecs, tvecs, strict=True)])
    return OpenCVCalibration(camera, std, T, float(rms))


def ray_start(
    board: Board,
    features: Sequence[Features],
    width: int,
    height: int,
    free: Sequence[str],
    model: str,
    initial: Pinhole | None = None,
    max_nfev: int = 200,
) -> OpenCVCalibration:
    """The start of a camera ``model`` OpenCV does not calibrate (the double sphere) from the
    views ``features``: every guess of the model (:meth:`selfcal.camera.CameraModel.starts`;
    ``initial``, a camera of ``model``, first) gives the views' poses through its rays
    (:func:`selfcal.camera.ray_poses`) and is refined from there by the bundle adjustment
    (soft-L1, the board held); the lowest cost wins (a model whose parameters trade off has
    local minima). Held in the form of OpenCV's result (no standard deviations; ``rms_px`` the
    winner's).

    Raises:
        EstimationError: no guess gave every view a pose or a finite refinement (the message
            names how many were tried and the first reason).
    """
    cls = entry(model).cls
    if initial is not None and initial.model_name != model:
        raise InputError(f"initial camera {initial.model_name!r}, model {model!r}")
    guesses = cls.starts(width, height, canonical_free(free))
    if initial is not None:
        guesses.insert(0, dataclasses.replace(initial, free=guesses[0].free))
    view = np.concatenate([np.full(len(f), i) for i, f in enumerate(features)])
    pts_ids, pidx = np.unique(np.concatenate([f.ids for f in features]), return_inverse=True)
    X, uv = board.points(pts_ids), np.concatenate([f.uv for f in features])
    best, reasons = None, []
    for guess in guesses:
        try:
            r = ray_poses(guess, [board.points(f.ids) for f in features],
                          [f.uv for f in features])  # fmt: skip
            poses = ViewPoses(r.T_cam_target, np.ones(len(features), bool))
            res = bundle_adjust(poses, poses.initial_params(), X, view, pidx, uv, guess,
                                fix_points=True, loss="soft_l1", f_scale_px=1.0,
                                max_nfev=max_nfev)  # fmt: skip
        except EstimationError as exc:
            reasons.append(exc.message)
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise EstimationError(
            f"no start of the {model} camera: none of {len(guesses)} guesses fitted the views "
            f"({reasons[0]})",
            fix="check the camera model, the image size and the target file",
        )
    e = np.linalg.norm(best.residuals, axis=-1)
    return OpenCVCalibration(best.camera, {}, best.T_cam_world, float(np.sqrt(np.mean(e**2))))


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
(:func:`calibrate_board`; the drift check drops new corners by the same rule,
:func:`selfcal.calibration.drift.outliers.view_outliers`)."""
OUTLIER_SIGMAS = 4.5
"""The robust sigmas (:func:`selfcal.estimation.reprojection.robust_sigma`) of the outlier rule
(:data:`OUTLIER_PX`)."""
MAX_OUTLIER_SHARE = 0.25
"""The largest share of the features the outlier rule may reject: beyond it the declared
geometry is not the board's (:class:`BoardMismatchError`)."""


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
    for loss in ("soft_l1", "linear"):
        res = bundle_adjust(
            poses, poses.initial_params(), X, view[active], pidx[active], uv[active], camera,
            fix_points=True, loss=loss, f_scale_px=1.0, max_nfev=max_nfev,
        )  # fmt: skip
        camera = res.camera
        poses = ViewPoses(np.where(ok[:, None, None], res.T_cam_world, np.nan), ok)
        if loss == "soft_l1":  # reclassify every row with the robust estimate
            e = _errors(camera, res.T_cam_world, X, view, pidx, uv)
            sigma = robust_sigma(e[active])
            active = e < max(outlier_px, OUTLIER_SIGMAS * sigma)
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
