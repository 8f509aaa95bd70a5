"""The held-out check of a board calibration: ``selfcal evaluate CALIBRATION_DIR DATASET2``.

Every feature the target's detector finds in DATASET2's images is predicted from the frame's
joint readings alone: ``uv = camera(inv(fk(model, q)) X)`` with ``X`` the board point (board
frame = the calibration's world) and ``model`` the calibrated kinematics (hand-eye and board
pose included) -- nothing is re-fitted. The same with the calibration's nominal reference (the
nominal kinematics with only hand-eye and board pose fitted on the calibration data, same camera).
Result: the 2-D reprojection RMS (px) of both, overall and per image (``evaluation.json``).
The board must not have moved between the two datasets (its pose is part of the model).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib.board_dataset import dataset_board, detect_board
from calib.errors import InputError, SelfCalWarning
from calib.io.board_calibration import BoardCalibrationResult
from calib.io.dataset import Dataset
from calib.io.jsonfile import SCHEMA_KEY, Fields, check_header, load_json, write_json_atomic
from calib.kinematics import fk_tool
from calib.mcpc import MCPCModel
from calib.transforms import inv_pose

__all__ = [
    "EVAL_FORMAT",
    "Evaluation",
    "evaluate_board",
    "rms_px",
    "read_evaluation",
    "write_evaluation",
]

EVAL_FORMAT = "scorbot-selfcal-evaluation"


class EvaluationWarning(SelfCalWarning):
    """Held-out images without the board (named and counted; they are left out)."""


@dataclass(frozen=True)
class Evaluation:
    """``rms`` by model (``nominal``, ``calibrated``) over every feature (px, 2-D); ``images``:
    per image its file, feature count and RMS by model; ``skipped``: images without the board;
    ``residuals``: by model, every feature's predicted - detected (k, 2) px in the order of
    ``images`` (not written to ``evaluation.json``; figures draw them)."""

    rms: dict[str, float]
    images: tuple[dict, ...]
    skipped: tuple[str, ...]
    dataset: str
    calibration: str
    residuals: dict[str, np.ndarray] = field(default_factory=dict, compare=False, repr=False)

    @property
    def failures(self) -> tuple[str, ...]:
        """The held-out check failed: the calibrated model predicts worse than the nominal one
        (one sentence), else empty (#15)."""
        cal, nom = self.rms.get("calibrated", np.nan), self.rms.get("nominal", np.nan)
        if not cal > nom:
            return ()
        return (
            f"the calibrated model predicts the held-out images of {self.dataset} worse than the "
            f"nominal model ({cal:.3f} px RMS against {nom:.3f} px): the calibration is wrong "
            "for this robot and camera (see its failures and warnings), or the two datasets do "
            "not show the same robot, camera and target",
        )

    def to_json(self) -> dict:
        return {
            "format": EVAL_FORMAT,
            SCHEMA_KEY: 1,
            "calibration": self.calibration,
            "dataset": self.dataset,
            "status": "failed" if self.failures else "ok",
            "failures": list(self.failures),
            "reprojection_rms_px": dict(self.rms),
            "images": list(self.images),
            "skipped_images": list(self.skipped),
        }

    def line(self) -> str:
        """The one line ``selfcal evaluate`` prints."""
        n = sum(i["features"] for i in self.images)
        return (
            f"held-out reprojection RMS over {n} features in {len(self.images)} images: nominal "
            f"{self.rms['nominal']:.3f} px, calibrated {self.rms['calibrated']:.3f} px"
        )


def rms_px(e: np.ndarray) -> float:
    """2-D RMS (px) of residuals (k, 2)."""
    return float(np.sqrt(np.mean(np.sum(e**2, axis=-1))))


def evaluate_board(cal: BoardCalibrationResult, cal_where: str, root: str | Path) -> Evaluation:
    """Predict DATASET2 (``root``) with ``cal`` (module docstring).

    Raises:
        InputError: the datasets' robot, target or camera do not match the calibration's, or no
            image of DATASET2 shows the board.
    """
    ds = Dataset.open(root)
    board = dataset_board(ds)
    if ds.info.board != cal.target:
        raise InputError(
            f"{ds.root}: target {ds.info.board} differs from the calibration's {cal.target}",
            fix="evaluate on a dataset of the same board (import it with the same --target)",
        )
    cam_name = cal.camera_names[0]
    if cam_name not in ds.info.cameras:
        raise InputError(f"{ds.root}: no camera {cam_name!r} (the calibrated one)",
                         fix=f"import the held-out images as --images '{cam_name}=...'")  # fmt: skip
    camera = cal.cameras[0]
    if ds.info.resolution_of(cam_name) != (camera.width, camera.height):
        raise InputError(
            f"{ds.root}: camera {cam_name} is {ds.info.resolution_of(cam_name)} px, the "
            f"calibration's {(camera.width, camera.height)}",
            fix="evaluate on images of the calibrated camera at its size",
        )
    n = len(cal.model.joint_types)
    if ds.joints_deg.shape[1] != n:
        raise InputError(f"{ds.root}: {ds.joints_deg.shape[1]} joints, the calibration's robot "
                         f"{n}", fix="evaluate on a dataset of the calibrated robot")  # fmt: skip
    feats, names = detect_board(ds, board, cam_name)
    q = np.radians(ds.joints_deg)
    models: dict[str, MCPCModel] = {"nominal": cal.nominal_model, "calibrated": cal.model}
    T = {k: inv_pose(fk_tool(m, q)) for k, m in models.items()}  # camera <- board, per frame
    errs: dict[str, list[np.ndarray]] = {k: [] for k in models}
    per, skipped = [], []
    for f, (ft, name) in enumerate(zip(feats, names, strict=True)):
        if len(ft) < board.min_features:
            skipped.append(name)
            continue
        X = board.points(ft.ids)
        row = {"image": name, "index": int(ds.indices[f]), "features": len(ft)}
        for k in models:
            Xc = X @ T[k][f, :3, :3].T + T[k][f, :3, 3]
            e = camera.project(Xc) - ft.uv
            errs[k].append(e)
            row[f"{k}_px"] = rms_px(e)
        per.append(row)
    if skipped:
        warnings.warn(f"the {board.describe()} is not found in {len(skipped)} of {len(names)} "
                      f"held-out image(s), left out: {', '.join(skipped[:8])}",
                      EvaluationWarning, stacklevel=2)  # fmt: skip
    if not per:
        raise InputError(f"{ds.root}: no image shows the {board.describe()}",
                         fix="give held-out images that show the board")  # fmt: skip
    res = {k: np.concatenate(v) for k, v in errs.items()}
    rms = {k: rms_px(v) for k, v in res.items()}
    return Evaluation(rms, tuple(per), tuple(skipped), str(ds.root), cal_where, res)


def write_evaluation(path: str | Path, ev: Evaluation) -> Path:
    """Write ``evaluation.json`` (atomically; the one writer)."""
    return write_json_atomic(path, ev.to_json())


def read_evaluation(path: str | Path) -> Evaluation:
    """Read the ``evaluation.json`` at ``path`` (the one reader; no residuals).

    Raises:
        InputError: missing or unreadable, another format, a newer schema, a missing key (named).
    """
    fix = "re-run `selfcal evaluate CALIBRATION_DIR DATASET2`"
    doc = load_json(path, fix=fix)
    check_header(doc, str(path), fmt=EVAL_FORMAT, version=1, fix=fix)
    f = Fields(doc, str(path), fix)
    images = tuple(dict(i.doc) for i in f.items("images"))
    return Evaluation(dict(f.float_map("reprojection_rms_px")), images,
                      f.strs("skipped_images"), f.str("dataset"), f.str("calibration"))  # fmt: skip
