"""``selfcal report DIR`` of a pose dataset's calibration (flange poses, no joints).

A short report: the setup and that no kinematics were identified, how the flange poses were
weighed (``calibration.json`` ``flange_poses``) and whether the camera was refined or held
(``camera_choice``); the hand-eye and the board mount, calibrated
(with sigmas) beside the nominal (the camera stage's camera held, both fitted
by the same objective) and their difference; the camera's parameters, calibrated beside
nominal; the fit (RMS of both); the held-out reprojection when ``DIR/evaluation.json`` holds a
``selfcal evaluate`` of this calibration, with whether the calibration beat the nominal.
Output: ``DIR/report.json`` (``"kind": "handeye"``) and ``DIR/report.md``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.evaluate import changed_since, names_calibration
from selfcal.calibration.handeye.calibration_file import (
    camera_text,
    flange_poses_text,
    held_out_verdict,
    read_handeye,
)
from selfcal.io.atomic import write_text_atomic
from selfcal.io.jsonfile import write_report

__all__ = ["handeye_report", "handeye_summary", "handeye_markdown"]

NO_KINEMATICS = (
    "No kinematics were identified: the flange poses are the robot's reports, so whatever error "
    "they carry (the controller's own model, backlash, the tool frame) stays in the residuals "
    "or, where the poses were corrected, in the corrections"
)


def _transform(cal: dict, nom: dict) -> dict:
    Rc = Rotation.from_quat(cal["quat_xyzw"])
    Rn = Rotation.from_quat(nom["quat_xyzw"])
    return {
        "what": cal["transform"],
        "calibrated": {
            k: cal[k] for k in ("xyz_mm", "quat_xyzw", "sigma_xyz_mm", "sigma_rotation_deg")
        },  # fmt: skip
        "nominal": {k: nom[k] for k in ("xyz_mm", "quat_xyzw")},
        "difference_mm": float(np.linalg.norm(np.subtract(cal["xyz_mm"], nom["xyz_mm"]))),
        "difference_deg": float(np.degrees((Rc * Rn.inv()).magnitude())),
    }


def _held_out(root: Path, cal_path: Path) -> dict:
    ev_path = root / "evaluation.json"
    fix = (f"run `selfcal evaluate {root} HELD_OUT_DATASET --out {ev_path}` with a second pose "
           "dataset of the same setup")  # fmt: skip
    if not ev_path.is_file():
        return {"error": f"no held-out check: {ev_path} is missing; {fix}"}
    ev = json.loads(ev_path.read_text())
    if "held_out_rms_px" not in ev or not names_calibration(
        ev.get("calibration", ""), ev.get("calibration_file"), cal_path):  # fmt: skip
        return {"error": f"no held-out check: {ev_path} is not an evaluation of {cal_path}; {fix}"}
    if changed_since(ev.get("calibration_sha256"), cal_path):
        return {"error": f"no held-out check: {ev_path} evaluates an earlier {cal_path} (the "
                         f"file changed since); {fix}"}  # fmt: skip
    return {"source": "selfcal evaluate", "file": str(ev_path), "dataset": ev["dataset"],
            "frames": ev["frames"], "corners": ev["corners"],
            "reprojection_rms_px": ev["held_out_rms_px"],
            "behind_camera": ev.get("behind_camera", {}),  # files before it: none counted
            "calibration_better_than_nominal": ev["calibration_better_than_nominal"]}  # fmt: skip


def handeye_report(root: str | Path) -> dict:
    """Write ``root/report.json`` and ``report.md`` for the hand-eye calibration in ``root``
    (module docstring) and return the report; lengths mm, angles deg, image quantities px."""
    root = Path(root)
    cal_path = root / "calibration.json"
    setup, _, _, doc = read_handeye(cal_path)
    nom = doc["nominal"]
    cam, ncam = doc["camera"], nom["camera"]
    report = {
        "kind": "handeye",
        "setup": setup,
        "calibration": str(cal_path),
        "kinematics": NO_KINEMATICS,
        "flange_poses": flange_poses_text(doc["flange_poses"])
        if "flange_poses" in doc
        else "flange poses: taken as reported",
        "camera_choice": camera_text(doc["camera_choice"])
        if "camera_choice" in doc
        else "camera: refined with the hand-eye",
        "frames_used": doc["frames_used"],
        "transforms": [_transform(doc[k], nom[k]) for k in ("hand_eye", "board_mount")],
        "camera": {
            "model": cam["model"],
            "free": cam["free"],
            "parameters": {
                k: {"calibrated": v, "std": cam["std"].get(k), "nominal": ncam["values"][k]}
                for k, v in cam["values"].items()
            },
        },  # fmt: skip
        "fit": {
            "reprojection_rms_px": {
                "calibrated": doc["reprojection_rms_px"],
                "nominal": nom["reprojection_rms_px"],
            },
            "camera_stage_rms_px": doc["camera_stage_rms_px"],
            "inliers": doc["inliers"],
            "rows": doc["rows"],
        },  # fmt: skip
        "nominal_is": nom["what"],
        "held_out": _held_out(root, cal_path),
        "camera_held": doc.get("camera_choice", {}).get("treatment") == "held",
        "failures": [],
    }
    write_report(root / "report.json", report)
    write_text_atomic(root / "report.md", handeye_markdown(report))
    return report


def _held_out_line(h: dict, held: bool = False) -> str:
    if "error" in h:
        return h["error"]
    r, behind = h["reprojection_rms_px"], h.get("behind_camera", {})

    def px(k: str, rms: str) -> str:
        out = "no corner in front of the camera" if r[k] is None else f"{r[k]:.3f} px{rms}"
        return out + (f" ({behind[k]} corners behind the camera)" if behind.get(k) else "")

    verdict = held_out_verdict(h["calibration_better_than_nominal"],
                               {"treatment": "held"} if held else None)  # fmt: skip
    return (f"held-out reprojection {px('calibrated', ' RMS')} calibrated, {px('nominal', '')} nominal over "
            f"{h['frames']} frames of {h['dataset']}: {verdict}")  # fmt: skip


def handeye_summary(report: dict, root: Path) -> str:
    """The one line ``selfcal report`` prints for a hand-eye calibration."""
    f = report["fit"]["reprojection_rms_px"]
    return (f"report ({report['setup']}, flange poses: no kinematics identified): fit "
            f"{f['calibrated']:.3f} px RMS calibrated, {f['nominal']:.3f} px nominal; "
            f"{_held_out_line(report['held_out'], report['camera_held'])}; {Path(root) / 'report.json'}")  # fmt: skip


def _v(xs) -> str:
    return ", ".join(f"{x:.2f}" for x in xs)


def handeye_markdown(r: dict) -> str:
    """``report.md`` of a hand-eye report."""
    f = r["fit"]
    lines = [f"# Hand-eye calibration report ({r['setup']})", "", NO_KINEMATICS + ".", "",
             r["flange_poses"][0].upper() + r["flange_poses"][1:] + ".", "",
             r["camera_choice"][0].upper() + r["camera_choice"][1:] + ".", "",
             "| transform | calibrated xyz (mm) | sigma xyz (mm) | sigma rotation (deg) | "
             "nominal xyz (mm) | calibrated - nominal |", "|---|---|---|---|---|---|"]  # fmt: skip
    for t in r["transforms"]:
        c = t["calibrated"]
        lines.append(f"| {t['what']} | {_v(c['xyz_mm'])} | {_v(c['sigma_xyz_mm'])} | "
                     f"{max(c['sigma_rotation_deg']):.3f} | {_v(t['nominal']['xyz_mm'])} | "
                     f"{t['difference_mm']:.2f} mm, {t['difference_deg']:.3f} deg |")  # fmt: skip
    lines += ["", f"Nominal: {r['nominal_is']}. Quaternions (xyzw) and matrices: "
              "calibration.json; for ROS: `selfcal export DIR --format tf`.", "",
              f"Fit over {r['frames_used']} frames ({f['inliers']} of {f['rows']} corners "
              f"inliers): calibrated {f['reprojection_rms_px']['calibrated']:.3f} px RMS, nominal "
              f"{f['reprojection_rms_px']['nominal']:.3f} px, camera stage (a free board pose "
              f"per image) {f['camera_stage_rms_px']:.3f} px.", "",
              "## Held-out reprojection", "", _held_out_line(r["held_out"], r["camera_held"]) + ".", "",
              f"## Camera ({r['camera']['model']})", "",
              "| parameter | calibrated | std | nominal |", "|---|---|---|---|"]  # fmt: skip
    for k, p in r["camera"]["parameters"].items():
        std = "held" if p["std"] is None else f"{p['std']:.4g}"
        lines.append(f"| {k} | {p['calibrated']:.6g} | {std} | {p['nominal']:.6g} |")
    return "\n".join(lines) + "\n"
