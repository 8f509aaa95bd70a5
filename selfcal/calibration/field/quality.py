"""Is a finished calibration believable? The checks that mark it failed (issue #15).

A calibration can converge, fit its own data and still be wrong; these checks compare it with
what is declared and with the nominal model, and return one sentence per failure with the likely
causes (empty: no failure). :func:`selfcal.calibration.field.calibrate.calibrate_detailed` stores them in the result
(``calibration.json`` ``status`` and ``failures``); the CLI then exits with status 3.

- **Rig direction.** The dataset's cameras are named ``left`` and ``right``: the right camera
  lies along +x (image right, OpenCV frame) of the left one. An estimated baseline more than 90
  degrees from that direction means the images of the two cameras are swapped (or the cameras
  were listed in the wrong order). The swap is invisible to every fit (the reprojection error is
  the same to 1e-12 px: the identified hand-eye simply moves by one baseline), so it is checked
  against the declaration.
- **Calibrated against nominal.** The calibration images predicted from their joint readings by
  the calibrated model against the fair nominal (:mod:`selfcal.calibration.field.nominal_fit`:
  the nominal chain with the hand-eye, camera, rig and marker corners fitted to the same pixels
  by the calibration's objective), each with its own camera, rig and corners, over the same
  corners (``calibration.json`` ``nominal.calibration_images_rms_px``). A calibration that
  predicts them no better than the fair nominal has failed (a diverged or mis-gauged estimation,
  wrong joint readings): it fits more parameters to the same pixels.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from selfcal.calibration.board.evaluate import worse
from selfcal.calibration.field.results import CalibrationOutput
from selfcal.camera import CameraModel
from selfcal.estimation.observations import Observations
from selfcal.io.calibration_blocks import FairNominal
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.transforms import inv_pose

__all__ = [
    "MAX_BASELINE_ANGLE_DEG",
    "baseline_angle_deg",
    "rig_direction_failure",
    "model_reprojection_rms_px",
    "nominal_fit_failure",
    "assess_calibration",
]

MAX_BASELINE_ANGLE_DEG = 90.0
"""Largest angle (deg) between the estimated baseline and the declared one (+x of the left
camera) that is accepted: a swap gives 180, a real rig a few degrees."""


def baseline_angle_deg(T_left_right: np.ndarray) -> float:
    """Angle (deg) between the right camera's position in the left camera frame (the translation
    of ``T_left_right``, (4, 4) m) and the left camera's +x axis."""
    t = np.asarray(T_left_right, dtype=float)[:3, 3]
    n = float(np.linalg.norm(t))
    if not np.isfinite(n) or n == 0.0:
        return float("nan")
    return float(np.degrees(np.arccos(np.clip(t[0] / n, -1.0, 1.0))))


def rig_direction_failure(T_left_right: np.ndarray) -> str | None:
    """The failure sentence when the estimated baseline points away from the declared +x, else
    None (see the module docstring)."""
    angle = baseline_angle_deg(T_left_right)
    if not angle > MAX_BASELINE_ANGLE_DEG:
        return None
    t_mm = np.asarray(T_left_right, dtype=float)[:3, 3] * 1000.0
    return (
        f"the right camera is estimated at ({t_mm[0]:.1f}, {t_mm[1]:.1f}, {t_mm[2]:.1f}) mm in "
        f"the left camera frame, {angle:.0f} deg from the declared direction (+x, image right; "
        f"at most {MAX_BASELINE_ANGLE_DEG:.0f} accepted): the left and right images are likely "
        "swapped, or the cameras listed in the wrong order (robot.hardware.cameras, dataset.json "
        "cameras); the identified camera mount is then off by one baseline"
    )


def model_reprojection_rms_px(
    model: MCPCModel,
    q: np.ndarray,
    obs: Observations,
    camera: CameraModel | Sequence[CameraModel],
    T_first_cam: np.ndarray,
    point_ids: np.ndarray,
    X_world: np.ndarray,
) -> float:
    """2-D reprojection RMS (px) of the observations ``obs`` (configurations index ``q`` (m, n)
    rad) predicted with the camera poses of ``model`` (tool = the first camera), the rig
    ``T_first_cam`` (N, 4, 4) m, the points ``X_world`` (P, 3) m of ``point_ids`` and
    ``camera``: one model for every camera of the rig, or camera ``c``'s model ``camera[c]``
    (a rig of different lenses: one model for all predicted the right images with the left
    lens, tens of pixels off). Observations of points without a finite position are left
    out; NaN when none remains."""
    T_world_first = fk_tool(model, q)
    ids = np.asarray(point_ids)
    k = -np.ones(len(obs.point), np.int64)  # index of each observation's point in point_ids
    if len(ids):
        order = np.argsort(ids, kind="stable")
        pos = np.minimum(np.searchsorted(ids[order], obs.point), len(ids) - 1)
        k = np.where(ids[order][pos] == obs.point, order[pos], -1)
    keep = k >= 0
    keep[keep] = np.isfinite(X_world[k[keep]]).all(axis=1)
    if not keep.any():
        return float("nan")
    T_cam_world = inv_pose(T_world_first[:, None] @ np.asarray(T_first_cam)[None])  # (m, N)
    T = T_cam_world[obs.config[keep], obs.camera[keep]]  # per observation
    X = np.einsum("kij,kj->ki", T[:, :3, :3], X_world[k[keep]]) + T[:, :3, 3]
    cams = [camera] if isinstance(camera, CameraModel) else list(camera)
    which = np.minimum(obs.camera[keep], len(cams) - 1) if len(cams) > 1 else None
    uv = np.empty((len(X), 2))
    for c, cam in enumerate(cams):
        rows = slice(None) if which is None else which == c
        uv[rows] = cam.project(X[rows])
    return float(np.sqrt(np.mean(np.sum((uv - obs.uv[keep]) ** 2, axis=1))))


def nominal_fit_failure(calibrated_px: float, nominal_px: float) -> str | None:
    """The failure sentence when the calibrated model predicts the calibration images no better
    than the fair nominal (both RMS px over the same corners, see the module docstring), else
    None."""
    if not worse(calibrated_px, nominal_px):  # NaN on either side: no verdict
        return None
    return (
        f"the calibrated model predicts the calibration images from their joint readings WORSE "
        f"than the fair nominal ({calibrated_px:.3f} px RMS against {nominal_px:.3f} px with the "
        "nominal chain, its hand-eye, camera and marker corners fitted to the same pixels): the "
        "estimation went wrong; likely causes: joint readings in another unit or order than "
        "joints.csv declares, frames whose images and joints do not belong together, a robot "
        "file that is not this robot, too few and too similar postures, or the two-stage method "
        "where it misses (use the default --method joint)"
    )


def assess_calibration(out: CalibrationOutput, nominal: FairNominal | None) -> tuple[str, ...]:
    """The failures of the calibration ``out`` (:func:`selfcal.calibration.field.calibrate.calibrate_detailed`)
    judged against its fair nominal ``nominal`` (:func:`selfcal.calibration.field.nominal_fit.fair_nominal`;
    None: its fit failed, no verdict from that check): one sentence each, empty when none."""
    final = out.joint if out.joint is not None else out.selfcal
    failures = [rig_direction_failure(final.T_first_cam[1])] if len(final.T_first_cam) > 1 else []
    if nominal is not None:
        rms = nominal.calibration_images_rms_px
        failures.append(nominal_fit_failure(rms["calibrated"], rms["nominal"]))
    return tuple(f for f in failures if f is not None)
