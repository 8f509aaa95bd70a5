"""The held-out check of a field self-calibration (``selfcal evaluate`` for the ArUco field).

As :mod:`calib.evaluate` for a board, with the calibrated marker corners (``calibration.json``
``scene``, world = the reconstruction frame of the calibration) as the target and the stereo
rig of the calibration: every marker corner detected in DATASET2 is predicted from the frame's
joint readings with the calibrated chain (tool = left camera) and the rig -- nothing re-fitted.
The nominal reference is the nominal chain with only its base (the world placement) and tool
(the hand-eye) fitted to the calibration's camera poses of the calibration dataset.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.calibrate import detect_dataset
from calib.errors import InputError
from calib.evaluate import Evaluation, rms_px
from calib.io.calibration import CalibrationResult
from calib.io.dataset import Dataset
from calib.io.dataset_info import CAMERAS
from calib.io.frame_cache import FrameCache
from calib.kinematics import fk_tool
from calib.mcpc import MCPCModel, nominal_mcpc
from calib.quality import nominal_with_fitted_base_and_tool
from calib.robot_def import load_robot
from calib.target.aruco import markers_to_features
from calib.transforms import inv_pose

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
    memory (:func:`calib.calibrate.detect_dataset`).

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
    dets = detect_dataset(ds, cache=cache).detections
    scene = dict(zip(cal.scene.point_ids, cal.scene.X_world_m, strict=True))
    models = {"nominal": nominal_reference(cal, Path(cal_root)), "calibrated": cal.model}
    row = {int(i): k for k, i in enumerate(ds.indices)}
    q = np.radians(ds.joints_deg)
    T_cam = {ds.info.cameras[0]: np.eye(4)}  # one camera (any name), or the pair
    if len(ds.info.cameras) == 2:
        T_cam["right"] = cal.rig.T_left_right_m
    T = {k: fk_tool(m, q) for k, m in models.items()}
    camera = cal.pinhole
    errs: dict[str, list[np.ndarray]] = {k: [] for k in models}
    per = []
    for (index, cam), markers in sorted(dets.items()):
        ft = markers_to_features(markers, where=f"frame {index} {cam}")
        keep = np.array([int(i) in scene for i in ft.ids], bool)
        if not keep.any():
            continue
        X = np.array([scene[int(i)] for i in ft.ids[keep]])
        out = {"image": f"{index:04d}_{cam}", "index": index, "features": int(keep.sum())}
        for k in models:
            Tc = inv_pose(T[k][row[index]] @ T_cam[cam])
            e = camera.project(X @ Tc[:3, :3].T + Tc[:3, 3]) - ft.uv[keep]
            errs[k].append(e)
            out[f"{k}_px"] = rms_px(e)
        per.append(out)
    if not per:
        raise InputError(f"{ds.root}: no image shows a calibrated marker",
                         fix="give held-out images of the same marker field")  # fmt: skip
    res = {k: np.concatenate(v) for k, v in errs.items()}
    rms = {k: rms_px(v) for k, v in res.items()}
    return Evaluation(rms, tuple(per), (), str(ds.root), str(cal_root), res)
