"""The start of the board calibration's camera: OpenCV's calibration, or the model's rays.

The board calibration (:func:`selfcal.calibration.board.calibrate.calibrate_board`) refines one
of these on the one solver: OpenCV's calibration of the views (:func:`opencv_calibration`:
``cv2.calibrateCameraExtended`` for the pinhole and Brown-Conrady, ``cv2.fisheye.calibrate`` from
several focal lengths for the fisheye, the held parameters fixed by its flags) or, for a model
OpenCV does not calibrate (the double sphere), each of the model's guesses through its rays
refined by the bundle adjustment (:func:`ray_start`). Both give an :class:`OpenCVCalibration`:
the camera, the board pose of every view (``T_cam_board``: board coordinates, m, to the OpenCV
camera frame) and the reprojection RMS (px).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

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
from selfcal.errors import EstimationError, InputError
from selfcal.estimation.bundle_adjust import bundle_adjust
from selfcal.estimation.pose_models import ViewPoses
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.transforms import make_pose

__all__ = ["OpenCVCalibration", "opencv_calibration", "ray_start"]


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
