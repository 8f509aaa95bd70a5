"""The held-out check of a field self-calibration (``selfcal evaluate`` for the ArUco field).

As :mod:`selfcal.calibration.board.evaluate` for a board, with the calibrated marker corners (``calibration.json``
``scene``, world = the reconstruction frame of the calibration) as the target and the rig of the
calibration (one camera, or the stereo pair): every marker corner detected in every camera of
DATASET2 is predicted from the frame's joint readings with the calibrated chain (tool = left
camera), the calibrated camera model (its lens included; the field's cameras share one) and the
right camera's pose in the left one's frame -- nothing re-fitted.
The nominal reference is the calibration's fair nominal (``calibration.json`` ``nominal``,
:mod:`selfcal.calibration.field.nominal_fit`): the nominal chain with the hand-eye, camera, rig
and marker corners fitted to the calibration images by the calibration's own objective, which
predicts with its own camera, rig and corners. Both models predict the same corners (those both
scenes hold).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.calibration.board.evaluate import Evaluation, rms_px
from selfcal.calibration.field.calibrate import detect_dataset
from selfcal.errors import InputError
from selfcal.io.calibration import CalibrationResult
from selfcal.io.calibration_blocks import CameraIntrinsics
from selfcal.io.dataset import Dataset
from selfcal.io.dataset_info import CAMERAS
from selfcal.io.frame_cache import FrameCache
from selfcal.kinematics.forward import fk_tool
from selfcal.target.aruco import markers_to_features
from selfcal.transforms import inv_pose

__all__ = ["evaluate_field"]


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
        InputError: the calibration holds no scene points or no fair nominal (written before
            they were stored, or the fair nominal's fit failed: its warnings say why),
            DATASET2 is not a one-camera or stereo field dataset, or no image shows a
            calibrated marker.
    """
    if cal.scene is None:
        raise InputError(f"{cal_root}: calibration.json holds no scene points",
                         fix=f"re-run `selfcal calibrate {cal_root}` with this version")  # fmt: skip
    nominal = cal.nominal_model
    if cal.nominal is None or nominal is None:
        raise InputError(
            f"{cal_root}: calibration.json holds no fair nominal (the nominal chain fitted to the "
            "same pixels), the reference a calibration is judged against",
            fix=f"re-run `selfcal calibrate {cal_root}` with this version (if it warns that the "
            "fair nominal could not be fitted, the warning says why)",
        )
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
    scene = {"calibrated": dict(zip(cal.scene.point_ids, cal.scene.X_world_m, strict=True)),
             "nominal": dict(zip(cal.nominal.scene.point_ids, cal.nominal.scene.X_world_m,
                                 strict=True))}  # fmt: skip
    models = {"nominal": nominal, "calibrated": cal.model}
    row = {int(i): k for k, i in enumerate(ds.indices)}
    q = np.radians(ds.joints_deg)
    T = {k: fk_tool(m, q) for k, m in models.items()}
    # each camera of each model predicts with its own intrinsics (the shared one for a shared
    # camera) and its own pose in the left camera's frame
    T_cam: dict[str, dict[str, np.ndarray]] = {}
    camera: dict[str, dict] = {}
    rigs = (
        ("calibrated", T_lr, cal.intrinsics_of),
        ("nominal", cal.nominal.rig.T_left_right_m, _nominal_intrinsics(cal)),
    )
    for k, rig, of in rigs:
        T_cam[k] = {ds.info.cameras[0]: np.eye(4)}  # one camera (any name), or the pair
        if len(ds.info.cameras) == 2:
            T_cam[k]["right"] = np.asarray(rig, dtype=float)
        camera[k] = {c: of(i).camera() for i, c in enumerate(ds.info.cameras)}
    errs: list[dict[str, np.ndarray]] = []
    per = []
    for (index, cam), markers in sorted(dets.items()):
        ft = markers_to_features(markers, where=f"frame {index} {cam}")
        keep = np.array([int(i) in scene["calibrated"] and int(i) in scene["nominal"]
                         for i in ft.ids], bool)  # fmt: skip
        if not keep.any():
            continue
        out = {"image": f"{index:04d}_{cam}", "index": index, "camera": cam,
               "features": int(keep.sum())}  # fmt: skip
        e: dict[str, np.ndarray] = {}
        for k in models:
            X = np.array([scene[k][int(i)] for i in ft.ids[keep]])
            Tc = inv_pose(T[k][row[index]] @ T_cam[k][cam])
            e[k] = camera[k][cam].project(X @ Tc[:3, :3].T + Tc[:3, 3]) - ft.uv[keep]
            out[f"{k}_px"] = rms_px(e[k])
        per.append(out)
        errs.append(e)
    if not per:
        raise InputError(f"{ds.root}: no image shows a calibrated marker",
                         fix="give held-out images of the same marker field")  # fmt: skip
    return Evaluation.of(per, errs, (), str(ds.root), str(cal_root))


def _nominal_intrinsics(cal: CalibrationResult):
    """The fair nominal's camera of the rig's camera ``index``: its own, or the shared."""
    nom = cal.nominal
    assert nom is not None

    def of(index: int) -> CameraIntrinsics:
        return nom.cameras[index].intrinsics if nom.cameras else nom.intrinsics

    return of
