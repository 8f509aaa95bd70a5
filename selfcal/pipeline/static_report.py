"""``selfcal run`` / ``report`` of a simulated eye-to-hand cell: the calibration against ``truth.json``.

The dataset of ``[camera] setup = "eye-to-hand"`` (:mod:`selfcal.acquisition.eye_to_hand`: one
camera static in the cell, the board on the flange) is calibrated by the board route on the
inverted chain (:mod:`selfcal.calibration.board.dataset`); the report compares, with the truth
the calibration never saw:

- every free camera parameter: estimate, truth, standard deviation, ``z``;
- base -> camera and flange -> board (``calibration.json`` ``mounts``, read out of the chain as
  :mod:`selfcal.calibration.board.mounts` reads the truth's): the error's rotation (deg, about
  the parent's axes) and translation (mm, along them), their sigmas and ``z`` per component;
- the board's pose in the camera frame at the validation postures, predicted from the joints by
  the calibrated chain and by the fair nominal (``nominal_mcpc``), against the true one (no
  alignment: base -> camera's error is in it);
- the flange centre at the same postures after the best rigid alignment of the predicted
  positions to the true ones (:func:`flange_centre_errors`): the kinematic part alone, the
  quantity ``selfcal plan --mount eye-to-hand`` predicts (base -> camera's error left out);
- the predicted tool-point accuracy and the cross-validated reprojection of ``calibration.json``'s
  ``accuracy`` block, as the board route's report gives them
  (:mod:`selfcal.pipeline.board_accuracy`, issue #29).

``status`` is "failed" when the calibrated chain predicts the validation postures worse than the
fair nominal in both figures (:func:`selfcal.calibration.board.evaluate.worse`: by more than a
rounding): the board pose in the camera frame and the flange centre after the rigid alignment
(the kinematic part, which the eye-in-hand board report judges alone). Worse in one of them and
not the other is a calibration whose estimation noise outweighs what it fixes in that figure, not
a wrong one: it is said as NO GAIN in ``notes``, as is a figure merely no better. Measured on the
UR5e's cell at 0.2 px (the drift benchmark's draws): seed 25 unaligned 1.128 mm against 1.097 mm
(1.06 mm of it along the camera's axis, the depth a 0.18 % focal-length error gives at 0.6 m,
within the calibration's own predicted 1.85 mm) with the flange centre 0.103 mm against 0.153
mm; seed 2 the flange centre 0.230 mm against 0.206 mm (every identifiable parameter kept where
the drawn chain erred by little there) with the board pose 1.096 mm against 2.467 mm. Units: mm
and deg, px for the camera.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.evaluate import evaluate_board, no_gain, worse
from selfcal.calibration.board.mounts import flange_to_tool, mounts
from selfcal.io.atomic import write_text_atomic
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.io.dataset import Dataset, DatasetError
from selfcal.io.jsonfile import write_report
from selfcal.io.truth import Truth, read_truth
from selfcal.kinematics.accuracy import aligned_errors
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.pipeline.board_accuracy import (
    accuracy_markdown,
    accuracy_summary,
    board_accuracy_section,
)
from selfcal.pipeline.board_run import (
    calibrate_board_run,
    camera_bounds,
    camera_rows,
    pose_errors,
)
from selfcal.plots.job_figures import reprojection_figure, write_figure
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.transforms import inv_pose

if TYPE_CHECKING:
    from selfcal.calibration.board.deviation import Deviation

PREDICTED_WHERE = "in the camera frame, base -> camera's uncertainty in it"
"""What the eye-to-hand report's predicted tool-point accuracy is, said beside it: the flange in
the camera frame (the world of the inverted chain), unlike the plan's and the aligned figure."""

__all__ = [
    "PREDICTED_WHERE",
    "calibrate_and_report_static",
    "flange_centre_errors",
    "static_truth_report",
    "write_static_truth_report",
    "static_summary",
]


def _mount_rows(cal: BoardCalibrationResult, truth_chain, robot) -> list[dict]:
    """Per mount of ``cal``: estimate and truth (mm, deg), the error, its sigmas and z."""
    rows = []
    for est, true in zip(cal.mounts, mounts(truth_chain, robot, eye_to_hand=True), strict=True):
        w = Rotation.from_matrix(est.T[:3, :3] @ true.T[:3, :3].T).as_rotvec()
        d = est.T[:3, 3] - true.T[:3, 3]
        s_r, s_t = est.sigma_rotation_rad, est.sigma_xyz_m
        z, sigma = None, None
        if s_r is not None and s_t is not None:
            z = np.r_[w / s_r, d / s_t]
            sigma = {"rotation_deg": np.degrees(s_r).tolist(), "xyz_mm": (1000 * s_t).tolist()}
        rows.append({
            "transform": est.what,
            "estimate": {"xyz_mm": (1000 * est.T[:3, 3]).tolist(),
                         "rotvec_deg": np.degrees(Rotation.from_matrix(est.T[:3, :3])
                                                  .as_rotvec()).tolist()},
            "truth": {"xyz_mm": (1000 * true.T[:3, 3]).tolist(),
                      "rotvec_deg": np.degrees(Rotation.from_matrix(true.T[:3, :3])
                                               .as_rotvec()).tolist()},
            "error": {"rotation_deg": np.degrees(w).tolist(), "xyz_mm": (1000 * d).tolist()},
            "sigma": sigma,
            "z": None if z is None else z.tolist(),
            "max_abs_z": None if z is None else float(np.abs(z).max()),
        })  # fmt: skip
    return rows


def flange_centre_errors(model: MCPCModel, true_chain: MCPCModel, T_flange_board: np.ndarray,
                         robot: RobotDef, q: np.ndarray) -> dict[str, float]:  # fmt: skip
    """RMS and max (mm) of the flange centre predicted by the eye-to-hand chain ``model`` (camera
    -> base -> ... -> board, m; its flange from its own flange -> board,
    :func:`selfcal.calibration.board.mounts.flange_to_tool`) at the joint vectors ``q`` (m, n)
    rad against ``true_chain``'s (whose board sits at ``T_flange_board`` in the flange), after
    the best rigid alignment of the predicted positions to the true ones: a rigid motion of the
    whole workspace, such as base -> camera's error, is left out."""
    p_true = (fk_tool(true_chain, q) @ inv_pose(np.asarray(T_flange_board, float)))[:, :3, 3]
    p_est = (fk_tool(model, q) @ inv_pose(flange_to_tool(model, robot)))[:, :3, 3]
    e = aligned_errors(p_est, p_true)
    return {"rms": e["rms"], "max": e["max"]}


def static_truth_report(root: Path, cal: BoardCalibrationResult, truth: Truth) -> dict:
    """The report (module docstring) of the eye-to-hand calibration ``cal`` of the simulated
    dataset in ``root`` against ``truth``.

    Raises:
        DatasetError: ``truth.json`` is not an eye-to-hand cell's.
    """
    if truth.board is None or truth.board.get("setup") != "eye-to-hand":
        raise DatasetError(f"{root / 'truth.json'} is not the truth of an eye-to-hand cell but "
                           "calibration.json is an eye-to-hand calibration",
                           fix="acquire the dataset again from its scenario")  # fmt: skip
    ds = Dataset.open(root)
    robot = load_robot(ds.robot_source)
    qv = np.radians(ds.info.validation_joints_deg)
    true_chain = truth.true_model.with_base(inv_pose(np.asarray(truth.board["T_world_cam"])))
    T_true = fk_tool(true_chain, qv)
    cal_err = pose_errors(fk_tool(cal.model, qv), T_true)
    nom_err = pose_errors(fk_tool(cal.nominal_model, qv), T_true)
    T_fb = np.asarray(truth.board["T_flange_board"], float)
    aligned = {k: flange_centre_errors(m, true_chain, T_fb, robot, qv)
               for k, m in (("calibrated", cal.model), ("nominal", cal.nominal_model))}  # fmt: skip
    failures, notes = [], []
    a_cal, a_nom = aligned["calibrated"]["rms"], aligned["nominal"]["rms"]
    p_cal, p_nom = cal_err["position_mm"]["rms"], nom_err["position_mm"]["rms"]
    figures = (f"the board pose in the camera frame {p_cal:.3f} mm RMS against {p_nom:.3f} mm "
               f"(unaligned: base -> camera and the camera, fitted by both, are in it), the "
               f"flange centre after the best rigid alignment {a_cal:.3f} mm against "
               f"{a_nom:.3f} mm, over {len(qv)} held-out postures")  # fmt: skip
    if worse(a_cal, a_nom) and worse(p_cal, p_nom):
        failures.append(f"the calibrated chain predicts the validation postures worse than the "
                        f"fair nominal in both figures ({figures}): the calibration is wrong")  # fmt: skip
    else:
        verdict = cal.cv_verdict()
        for what, no in (("in the camera frame", no_gain(p_cal, p_nom)),
                         ("in the kinematic part", no_gain(a_cal, a_nom))):  # fmt: skip
            if no:
                notes.append(f"NO GAIN {what}: the calibrated chain predicts the validation "
                             f"postures no better there than the fair nominal ({figures})"
                             + ("" if verdict is None else f"; {verdict}"))  # fmt: skip
    return {
        "kind": "eye-to-hand-truth",
        "status": "failed" if failures else "ok",
        "failures": failures,
        "notes": notes,
        "setup": "eye-to-hand",
        "target": cal.target,
        "camera": camera_rows(
            cal.cameras[0], cal.camera_std[0], truth.intrinsics_left, camera_bounds(cal, 0)
        ),  # fmt: skip
        "mounts": _mount_rows(cal, true_chain, robot),
        "mounts_note": (
            "errors about / along the parent's axes; sigmas from the Cramer-Rao "
            "covariance at the estimate (calibration.json mounts)"
        ),  # fmt: skip
        "validation": {
            "poses": int(len(qv)),
            "board_pose_in_camera": {"calibrated": cal_err, "nominal": nom_err},
            "flange_centre_aligned_mm": aligned,
            "note": (
                "board_pose_in_camera: the board's pose in the camera frame predicted from the "
                "joint readings (no alignment: the camera is the world, base -> camera's error "
                "is in it); flange_centre_aligned_mm: the flange centre after the best rigid "
                "alignment (rotation and translation) of the predicted positions to the true "
                "ones, the kinematic part alone, what `selfcal plan` predicts; nominal: the "
                "fair nominal, the nominal chain with base -> camera, flange -> board and "
                "camera fitted to the pixels"
            ),
        },  # fmt: skip
        "reprojection_rms_px": cal.reprojection_rms_px,
        "frames": {"planned": cal.frames, "used": cal.frames_used},
        "identified": list((cal.selection or {}).get("identified", [])),
    }


def _markdown(r: dict) -> str:
    v = r["validation"]["board_pose_in_camera"]
    lines = ["# Eye-to-hand calibration against the truth", "",
             f"Status: **{r['status']}**"
             + "".join(f"\n- {f}" for f in r["failures"] + r["notes"]), "",
             f"Reprojection RMS {r['reprojection_rms_px']:.3f} px over {r['frames']['used']} of "
             f"{r['frames']['planned']} frames.", "", "## Camera", "",
             "| parameter | estimate | truth | std | z |", "|---|---|---|---|---|"]  # fmt: skip
    for n, c in r["camera"].items():
        z = "" if c["z"] is None else f"{c['z']:+.2f}"
        std = "" if c["std"] is None else f"{c['std']:.4g}"
        lines.append(f"| {n} | {c['estimate']:.6g} | {c['truth']:.6g} | {std} | {z} |")
    lines += ["", "## Mounts", "", "| transform | rotation error (deg) | translation error (mm) "
              "| max abs z |", "|---|---|---|---|"]  # fmt: skip
    for m in r["mounts"]:
        z = "" if m["max_abs_z"] is None else f"{m['max_abs_z']:.2f}"
        rot = ", ".join(f"{x:+.4f}" for x in m["error"]["rotation_deg"])
        xyz = ", ".join(f"{x:+.3f}" for x in m["error"]["xyz_mm"])
        lines.append(f"| {m['transform']} | {rot} | {xyz} | {z} |")
    a = r["validation"].get("flange_centre_aligned_mm")  # a report written before it: none
    lines += ["", f"## Board pose at {r['validation']['poses']} validation postures", "",
              "| model | board pose, unaligned: position RMS (mm) | rotation RMS (deg) |"
              + ("" if a is None else " flange centre after rigid alignment, RMS (mm) |"),
              "|---|---|---|" + ("" if a is None else "---|")]  # fmt: skip
    for k in ("nominal", "calibrated"):
        lines.append(f"| {k} | {v[k]['position_mm']['rms']:.4f} | "
                     f"{v[k]['rotation_deg']['rms']:.5f} |"
                     + ("" if a is None else f" {a[k]['rms']:.4f} |"))  # fmt: skip
    lines += ["", r["mounts_note"] + "; " + r["validation"]["note"] + "."]
    return "\n".join(lines) + "\n"


def write_static_truth_report(root: Path, cal: BoardCalibrationResult, truth: Truth, *,
                              figures: bool) -> dict:  # fmt: skip
    """:func:`static_truth_report` written as ``root/report.json`` and ``report.md`` (with
    ``figures`` the reprojection figure and the workspace map in ``root/figures``)."""
    report = static_truth_report(root, cal, truth)
    drawn = []
    if figures:
        ev = evaluate_board(cal, str(root / "calibration.json"), root)
        drawn.append(write_figure(reprojection_figure(ev, "calibration images"), root,
                                  "reprojection.png"))  # fmt: skip
    section, maps = board_accuracy_section(root, cal, figures=figures)
    md = _markdown(report)
    if section is not None:  # the predicted tool-point accuracy (issue #29)
        report["accuracy"] = section
        acc = accuracy_markdown(section)  # its heading, the line, then the table
        acc[4:4] = ["", f"The prediction is {PREDICTED_WHERE}: compare it with the unaligned "
                    "board pose above, not with the flange centre after alignment nor with "
                    "`selfcal plan`'s figure, which leave base -> camera out."]  # fmt: skip
        md += "\n".join(acc) + "\n"
    report["figures"] = [str(p.relative_to(root)) for p in drawn + maps]
    write_report(root / "report.json", report)
    write_text_atomic(root / "report.md", md)
    return report


def static_summary(rep: dict, root: Path) -> str:
    """One line on the report: camera and mount z, the validation board poses, and the predicted
    tool-point accuracy with the cross-validated reprojection when the report has them."""
    acc = rep.get("accuracy")
    tool = "" if not acc else f"; predicted {PREDICTED_WHERE}: {accuracy_summary(acc)}"
    zc = [abs(c["z"]) for c in rep["camera"].values() if c["z"] is not None]
    zm = [m["max_abs_z"] for m in rep["mounts"] if m["max_abs_z"] is not None]
    v = rep["validation"]["board_pose_in_camera"]
    a = rep["validation"].get("flange_centre_aligned_mm")  # a report written before it: none
    kin = (
        ""
        if a is None
        else (
            f" (flange centre after the best rigid alignment, base -> camera left out: nominal "
            f"{a['nominal']['rms']:.3f} mm RMS, calibrated {a['calibrated']['rms']:.3f} mm RMS)"
        )
    )
    return (f"eye-to-hand: camera parameters within {max(zc, default=float('nan')):.2f} sigma "
            f"and base -> camera, flange -> board within {max(zm, default=float('nan')):.2f} "
            f"sigma of the truth; board pose on {rep['validation']['poses']} validation "
            f"postures, unaligned: nominal {v['nominal']['position_mm']['rms']:.3f} mm RMS, "
            f"calibrated {v['calibrated']['position_mm']['rms']:.3f} mm RMS{kin}{tool}; details "
            f"in {root}/report.md")  # fmt: skip


def calibrate_and_report_static(out: Path, *, quiet: bool = False, figures: bool = True,
                                t0: float | None = None,
                                deviation: Deviation | None = None) -> dict:  # fmt: skip
    """The rest of ``selfcal run`` for an eye-to-hand scenario once acquired in ``out``: the
    calibration and the report against the truth; prints a summary line (total time since
    ``t0``, :func:`time.perf_counter`); ``deviation``: as
    :func:`selfcal.pipeline.board_run.calibrate_board_run`.

    Raises:
        CalibrationFailedError: the report found the calibration worse than the fair nominal.
    """
    from selfcal.calibration.field.calibrate import CalibrationFailedError

    t0 = time.perf_counter() if t0 is None else t0
    cal = calibrate_board_run(out, quiet=quiet, figures=False, deviation=deviation)
    rep = write_static_truth_report(out, cal, read_truth(out / "truth.json"), figures=figures)
    print(f"{static_summary(rep, out)}; total {time.perf_counter() - t0:.1f} s")
    for note in rep["notes"]:
        print(f"note: {note}")
    if rep["failures"]:
        raise CalibrationFailedError.of(tuple(rep["failures"]), out / "report.json")
    return {"calibration": cal, "report": rep}
