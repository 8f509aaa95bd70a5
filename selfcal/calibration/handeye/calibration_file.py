"""``calibration.json`` of a hand-eye calibration from flange poses (:mod:`selfcal.calibration.handeye.calibrate`).

Holds the setup, the camera (model, values by OpenCV name, standard deviations), the hand-eye
``X`` and the board mount ``B`` (what each is: :data:`selfcal.calibration.handeye.calibrate.FRAMES`) as 4x4 matrices,
mm and quaternions with their standard deviations (mm, deg), for the calibrated fit and for the
nominal (the camera of the camera stage held, ``X`` and ``B`` fitted by the same objective), and
the fit RMS. :func:`read_handeye` reads back what :func:`handeye_document` writes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.handeye.calibrate import FRAMES, HandEyeCalibration, HandEyeFit
from selfcal.calibration.handeye.fit import CV_MARGIN
from selfcal.camera import CameraModel, camera_model, lens_names
from selfcal.errors import InputError
from selfcal.io.jsonfile import SCHEMA_KEY, Fields, check_header, load_json

__all__ = [
    "HANDEYE_FORMAT",
    "HandEyeFile",
    "HandEyeModel",
    "camera_section",
    "camera_text",
    "flange_poses_section",
    "flange_poses_text",
    "handeye_document",
    "held_out_verdict",
    "is_handeye",
    "read_handeye",
]

HANDEYE_FORMAT = "scorbot-selfcal-handeye-calibration"
_FIX = "calibrate the pose dataset again with `selfcal calibrate DIR`"


def _transform(T: np.ndarray, std: np.ndarray, what: str) -> dict:
    return {
        "transform": what,
        "matrix": np.round(T, 12).tolist(),
        "xyz_mm": (T[:3, 3] * 1000.0).tolist(),
        "quat_xyzw": Rotation.from_matrix(T[:3, :3]).as_quat().tolist(),
        "sigma_xyz_mm": (std[3:] * 1000.0).tolist(),
        "sigma_rotation_deg": np.degrees(std[:3]).tolist(),
    }


def _camera(cam: CameraModel, std: dict[str, float]) -> dict:
    return {"model": cam.model_name, "width": cam.width, "height": cam.height,
            "free": list(cam.free),
            "values": dict(zip(cam.names, (float(v) for v in cam.values()), strict=True)),
            "std": std}  # fmt: skip


def _fit(fit: HandEyeFit, setup: str) -> dict:
    x_what, b_what = FRAMES[setup]
    return {"camera": _camera(fit.camera, fit.camera_std),
            "hand_eye": _transform(fit.X, fit.X_std, x_what),
            "board_mount": _transform(fit.B, fit.B_std, b_what),
            "reprojection_rms_px": fit.rms_px, "sigma_px": fit.sigma_px,
            "inliers": int(fit.inlier.sum()), "rows": int(fit.inlier.size)}  # fmt: skip


def flange_poses_section(cal: HandEyeCalibration) -> dict:
    """``calibration.json``'s ``flange_poses``: how the answer treated the reported flange
    poses (``exact`` or ``corrected``, :mod:`selfcal.calibration.handeye.eiv`), the noise it
    weighed them with (mm, deg per axis) and whether estimated, the corrections' RMS, and the
    cross-validation that chose (None: the caller gave the noise)."""
    f, ch = cal.calibrated, cal.pose_choice
    c = f.corrections if len(f.corrections) else np.zeros((1, 6))
    return {
        "treatment": "exact" if f.pose_noise.exact else "corrected",
        "sigma_mm": f.pose_noise.mm, "sigma_deg": f.pose_noise.deg,
        "estimated": f.pose_noise_estimated,
        "corrections_rms_mm": float(1e3 * np.sqrt(np.mean(c[:, 3:] ** 2))),
        "corrections_rms_deg": float(np.degrees(np.sqrt(np.mean(c[:, :3] ** 2)))),
        "cross_validation": None if ch is None else {
            "folds": ch.folds, "exact_px": ch.exact_px, "corrected_px": ch.eiv_px,
            "chosen": "corrected" if ch.eiv else "exact"},
    }  # fmt: skip


def flange_poses_text(section: dict) -> str:
    """One line for people of :func:`flange_poses_section`'s ``section``."""
    cv = section.get("cross_validation")
    why = "" if cv is None else (
        f"; left-out images predicted from their poses ({cv['folds']} folds): exact "
        f"{cv['exact_px']:.3f} px, corrected {cv['corrected_px']:.3f} px")  # fmt: skip
    if section["treatment"] == "exact":
        return "flange poses: taken as reported" + why
    how = "estimated" if section["estimated"] else "given"
    return (f"flange poses: each corrected with a prior of {section['sigma_mm']:.3f} mm, "
            f"{section['sigma_deg']:.4f} deg per axis ({how}; corrections RMS "
            f"{section['corrections_rms_mm']:.3f} mm, {section['corrections_rms_deg']:.4f} deg)"
            + why)  # fmt: skip


def camera_section(cal: HandEyeCalibration) -> dict:
    """``calibration.json``'s ``camera_choice``: whether the answer ``refined`` the camera or
    ``held`` the camera stage's, who chose (``chosen_by``: ``"cross-validation"``, or
    ``"caller"`` when forced by ``selfcal calibrate --camera held|refined``) and the
    cross-validation that chose (None when the caller did; ``margin``: how much better,
    relative, refining had to predict to be chosen)."""
    ch = cal.camera_choice
    return {
        "treatment": "refined" if cal.camera_refined else "held",
        "chosen_by": "caller" if ch is None else "cross-validation",
        "cross_validation": None if ch is None else {
            "folds": ch.folds, "held_px": ch.held_px, "refined_px": ch.refined_px,
            "margin": CV_MARGIN, "chosen": "refined" if ch.refined else "held",
            "held_failed_folds": ch.held_failed},
    }  # fmt: skip


def camera_text(section: dict) -> str:
    """One line for people of :func:`camera_section`'s ``section``."""
    cv = section.get("cross_validation")
    head = ("camera: refined with the hand-eye" if section["treatment"] == "refined"
            else "camera: held at the board calibration's")  # fmt: skip
    if cv is None:
        return head + " (as asked)"
    failed = cv.get("held_failed_folds", 0)
    note = (f"; the held camera could not be calibrated in {failed} of {cv['folds']} folds: "
            "compared over the others" if failed else "")  # fmt: skip
    return (f"{head}; left-out images predicted from their poses ({cv['folds']} folds): held "
            f"{cv['held_px']:.3f} px, refined {cv['refined_px']:.3f} px (refined only when "
            f"better by more than {100 * cv['margin']:g} %){note}")  # fmt: skip


def held_out_verdict(better: bool, section: dict | None) -> str:
    """The held-out check's verdict for people: whether the calibration predicted better than
    the nominal (``better``), or, when its ``camera_choice`` ``section`` held the camera, that
    it is the nominal."""
    if section is not None and section.get("treatment") == "held":
        return "the calibration is the nominal: the camera held at the board calibration's"
    return f"the calibration is {'better than' if better else 'NOT better than'} the nominal"


def handeye_document(cal: HandEyeCalibration, dataset: str) -> dict:
    """The ``calibration.json`` document of ``cal`` calibrated from the pose dataset ``dataset``."""
    return {
        "format": HANDEYE_FORMAT,
        SCHEMA_KEY: 1,
        "dataset": dataset,
        "setup": cal.setup,
        "method": "hand-eye on corner reprojection (linear Park start, the one solver)",
        "kinematics": "none identified: the flange poses are the robot's reports",
        "flange_poses": flange_poses_section(cal),
        "camera_choice": camera_section(cal),
        "frames_used": int(cal.used.sum()),
        "camera_stage_rms_px": cal.camera_stage.rms_px,
        **_fit(cal.calibrated, cal.setup),
        "nominal": {
            "what": "the camera stage's camera held, hand-eye and board mount fitted by "
            "the same objective",
            **_fit(cal.nominal, cal.setup),
        },  # fmt: skip
    }


def is_handeye(path: str | Path) -> bool:
    """Whether ``path`` (a calibration.json or its folder) is a hand-eye calibration."""
    p = Path(path)
    p = p / "calibration.json" if p.is_dir() else p
    try:
        return p.is_file() and load_json(p, fix=_FIX).get("format") == HANDEYE_FORMAT
    except ValueError:
        return False


@dataclass(frozen=True)
class HandEyeModel:
    """One fit read back: ``camera``, ``X`` and ``B`` (4, 4) m."""

    camera: CameraModel
    X: np.ndarray
    B: np.ndarray


def _model(f: Fields) -> HandEyeModel:
    """One fit, checked (finite values, positive focal length, rigid X and B)."""
    c = f.sub("camera")
    v, model = c.sub("values"), c.str("model")
    cam = camera_model(model, fx=v.positive("fx"), mu=v.positive("mu"), cx=v.finite("cx"),
                       cy=v.finite("cy"), width=c.int("width"), height=c.int("height"),
                       coeffs={k: v.finite(k) for k in lens_names(model) if v.has(k)},
                       free=c.strs("free"), skew=v.finite("skew") if v.has("skew") else 0.0)  # fmt: skip
    return HandEyeModel(cam, f.sub("hand_eye").poses("matrix", (4, 4)),
                        f.sub("board_mount").poses("matrix", (4, 4)))  # fmt: skip


class HandEyeFile(NamedTuple):
    """A hand-eye ``calibration.json`` read back: the ``setup`` (``eye-in-hand`` or
    ``eye-to-hand``), the ``calibrated`` and the ``nominal`` model and the whole ``document``."""

    setup: str
    calibrated: HandEyeModel
    nominal: HandEyeModel
    document: dict


def read_handeye(path: str | Path) -> HandEyeFile:
    """The setup, the calibrated and the nominal model and the whole document of the hand-eye
    ``calibration.json`` ``path`` (or its folder). Raises :class:`selfcal.errors.InputError`
    naming the file."""
    p = Path(path)
    p = p / "calibration.json" if p.is_dir() else p
    doc = load_json(p, fix=_FIX)
    check_header(doc, str(p), fmt=HANDEYE_FORMAT, version=1, fix=_FIX)
    f = Fields(doc, str(p), _FIX)
    try:
        return HandEyeFile(f.str("setup"), _model(f), _model(f.sub("nominal")), doc)
    except InputError:
        raise
    except (KeyError, TypeError, ValueError) as exc:  # a camera model refusing its values
        raise InputError(f"{p}: malformed camera ({exc})", fix=_FIX) from None
