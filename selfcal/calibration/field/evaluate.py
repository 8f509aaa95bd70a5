"""The held-out check of a field self-calibration (``selfcal evaluate`` for the ArUco field).

As :mod:`selfcal.calibration.board.evaluate` for a board, with the calibrated marker corners (``calibration.json``
``scene``, world = the reconstruction frame of the calibration) as the target and the rig of the
calibration (one camera, or the stereo pair): every marker corner detected in every camera of
DATASET2 is predicted from the frame's joint readings with the calibrated chain (tool = left
camera), the calibrated camera model (its lens included; the field's cameras share one) and the
right camera's pose in the left one's frame -- nothing re-fitted.
The nominal reference is the nominal chain with only its base (the world placement) and tool
(the hand-eye) fitted to the calibration's camera poses of the calibration dataset.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.calibration.board.evaluate import Evaluation, rms_px
from selfcal.calibration.field.calibrate import detect_dataset
from selfcal.calibration.field.quality import nominal_with_fitted_base_and_tool
from selfcal.errors import InputError
from selfcal.io.calibration import CalibrationResult
from selfcal.io.dataset import Dataset
from selfcal.io.dataset_info import CAMERAS
from selfcal.io.frame_cache import FrameCache
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.target.aruco import markers_to_features
from selfcal.transforms import inv_pose

__all__ = ["nominal_reference", "evaluate_field"]


def nominal_reference(cal: CalibrationResult, cal_root: Path) -> MCPCModel:
    """The nominal chain with base and tool fitted to ``cal``'s camera poses of the frames of
    the calibration dataset in ``cal_root`` (world = the calibration's)."""
    ds = Dataset.open(cal_root)
    robot = load_robot(ds.robot_source)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    row = {int(i): k for k, i in enumerate(ds.indices)}
    poses = cal.camera_poses
    q = np.radians(ds.joints_deg[[row[i] for i in poses.frame_index]])
    return nominal_with_fitted_base_and_tool(nominal, q, poses.T_world_cam_left_m)


def evaluate_field(
    cal: CalibrationResult,
    cal_root: str | Path,
    root: str | Path,
    cache: FrameCache | None = None,
) -> Evaluation:
    """Predict the field dataset ``root`` with the field calibration ``cal`` of the dataset in
    ``cal_root`` (module docstring). ``cache``: ``root``'s images and detections already in
    memory (:func:`selfcal.calibration.field.calibrate.detect_dataset`).

    Raises:
        InputError: the calibration holds no scene points (written before they were stored),
            DATASET2 is not a one-camera or stereo field dataset, or no image shows a
            calibrated marker.
    """
    if cal.scene is None:
        raise InputError(f"{cal_root}: calibration.json holds no scene points",
                         fix=f"re-run `selfcal calibrate {cal_root}` with this version")  # fmt: skip
    ds = Dataset.open(root)
    if ds.info.board is not None or (ds.info.cameras != CAMERAS and len(ds.info.cameras) != 1):
        raise InputError(f"{ds.root}: not a one-camera or stereo dataset of the ArUco field",
                         fix="evaluate on a dataset acquired like the calibration's")  # fmt: skip
    T_lr = np.asarray(cal.rig.T_left_right_m, dtype=float)
    if len(ds.info.cameras) > 1 and not np.isfinite(T_lr).all():
        raise InputError(
            f"{ds.root}: a stereo dataset, but the calibration in {cal_root} is of one camera "
            "(it has no right camera to predict)",
            fix="evaluate on a one-camera dataset, or calibrate a stereo dataset",
        )
    dets = detect_dataset(ds, cache=cache).detections
    scene = dict(zip(cal.scene.point_ids, cal.scene.X_world_m, strict=True))
    models = {"nominal": nominal_reference(cal, Path(cal_root)), "calibrated": cal.model}
    row = {int(i): k for k, i in enumerate(ds.indices)}
    q = np.radians(ds.joints_deg)
    T_cam = {ds.info.cameras[0]: np.eye(4)}  # one camera (any name), or the pair
    if len(ds.info.cameras) == 2:
        T_cam["right"] = T_lr
    T = {k: fk_tool(m, q) for k, m in models.items()}
    # each camera predicts with its own intrinsics (the shared one for a shared camera)
    camera = {c: cal.intrinsics_of(i).camera() for i, c in enumerate(ds.info.cameras)}
    errs: list[dict[str, np.ndarray]] = []
    per = []
    for (index, cam), markers in sorted(dets.items()):
        ft = markers_to_features(markers, where=f"frame {index} {cam}")
        keep = np.array([int(i) in scene for i in ft.ids], bool)
        if not keep.any():
            continue
        X = np.array([scene[int(i)] for i in ft.ids[keep]])
        out = {"image": f"{index:04d}_{cam}", "index": index, "camera": cam,
               "features": int(keep.sum())}  # fmt: skip
        e: dict[str, np.ndarray] = {}
        for k in models:
            Tc = inv_pose(T[k][row[index]] @ T_cam[cam])
            e[k] = camera[cam].project(X @ Tc[:3, :3].T + Tc[:3, 3]) - ft.uv[keep]
            out[f"{k}_px"] = rms_px(e[k])
        per.append(out)
        errs.append(e)
    if not per:
        raise InputError(f"{ds.root}: no image shows a calibrated marker",
                         fix="give held-out images of the same marker field")  # fmt: skip
    return Evaluation.of(per, errs, (), str(ds.root), str(cal_root))
