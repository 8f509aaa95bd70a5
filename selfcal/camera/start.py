"""A camera's start from images of a known target, through its rays.

OpenCV calibrates the perspective models (``cv2.calibrateCamera``, ``cv2.fisheye.calibrate``); a
model it does not know (the double sphere) starts here: a guess of the model
(:meth:`selfcal.camera.model.CameraModel.starts`, or the caller's) unprojects the detected pixels
to rays, and ``cv2.solvePnP`` (SQPnP) finds every view's target pose from its rays' normalised
coordinates (the rays turned so that their mean is the optical axis: a target beside or behind a
camera past 180 deg). :func:`ray_poses` returns the poses and their reprojection RMS (px; a
detection the model does not project counts as the image's diagonal); the board calibration
refines each of the model's guesses on the one solver and keeps the lowest cost
(:func:`selfcal.calibration.board.camera_start.ray_start`): the double sphere's ``fx``, ``xi`` and
``alpha`` trade off, and a guess too long in focal length ends in a local minimum.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from selfcal.camera.model import CameraModel
from selfcal.errors import EstimationError
from selfcal.transforms import make_pose

__all__ = ["RayStart", "ray_poses"]

_MIN_FORWARD = 0.1
"""The smallest z of a view's unit ray, turned so that the view's mean ray is the axis, that the
pose step uses (rays ~84 deg or more from the view's mean have ill-conditioned normalised
coordinates)."""


@dataclass(frozen=True)
class RayStart:
    """A guess ``camera``, the target poses ``T_cam_target`` (V, 4, 4; camera <- target, m)
    through its rays and their reprojection ``rms_px`` (px; RMS of the 2-D errors)."""

    camera: CameraModel
    T_cam_target: np.ndarray
    rms_px: float


def _toward_z(d: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) that takes the unit vector ``d`` (3,) to the optical axis (0, 0, 1)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(d, z)
    s, c = np.linalg.norm(axis), float(d @ z)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return cv2.Rodrigues(axis / s * np.arctan2(s, c))[0]


def _poses(camera: CameraModel, points: Sequence[np.ndarray], uv: Sequence[np.ndarray]):
    """Every view's pose (V, 4, 4) from ``camera``'s rays, or None when a view has fewer than
    four usable rays. A view's rays are turned so that their mean is the optical axis before
    SQPnP (a target beside or behind a camera past 180 deg has rays with z <= 0), and the pose
    turned back."""
    T = []
    for p, u in zip(points, uv, strict=True):
        ray = camera.unproject(np.asarray(u, dtype=float))
        ok = np.all(np.isfinite(ray), axis=-1)
        if ok.sum() < 4:
            return None
        R0 = _toward_z(ray[ok].mean(axis=0) / np.linalg.norm(ray[ok].mean(axis=0)))
        turned = ray @ R0.T
        ok &= turned[:, 2] > _MIN_FORWARD
        if ok.sum() < 4:
            return None
        xn = turned[ok, :2] / turned[ok, 2:3]
        found, rvec, tvec = cv2.solvePnP(
            np.asarray(p, dtype=np.float64)[ok], xn, np.eye(3), None, flags=cv2.SOLVEPNP_SQPNP
        )
        if not found:
            return None
        T.append(make_pose(R0.T @ cv2.Rodrigues(rvec)[0], R0.T @ np.ravel(tvec)))
    return np.stack(T)


def _rms(camera: CameraModel, T: np.ndarray, points, uv) -> float:
    miss = float(np.hypot(camera.width, camera.height))
    e = []
    for Ti, p, u in zip(T, points, uv, strict=True):
        Xc = np.asarray(p, dtype=float) @ Ti[:3, :3].T + Ti[:3, 3]
        pix, ok = camera.project_valid(Xc)
        d = np.linalg.norm(pix - u, axis=-1)
        e.append(np.where(ok & np.isfinite(d), np.minimum(d, miss), miss))
    return float(np.sqrt(np.mean(np.concatenate(e) ** 2)))


def ray_poses(
    camera: CameraModel, points: Sequence[np.ndarray], uv: Sequence[np.ndarray]
) -> RayStart:
    """Every view's target pose through ``camera``'s rays and their reprojection (module
    docstring): the views' target points ``points`` (V arrays (n_i, 3), target frame, m) are
    detected at pixels ``uv`` (V arrays (n_i, 2), px).

    Raises:
        EstimationError: a view has fewer than four detections the model unprojects, or SQPnP
            found no pose for it.
    """
    T = _poses(camera, points, uv)
    if T is None:
        raise EstimationError(
            f"no start of the {camera.model_name} camera ({camera.values()[0]:.1f} px focal) from its "
            "rays: a view has fewer than four detections the model unprojects, or no pose",
            fix="check the camera model and the image size",
        )
    return RayStart(camera, T, _rms(camera, T, points, uv))
