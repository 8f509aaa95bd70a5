"""``selfcal calibrate`` of a board dataset, and ``selfcal run`` / ``report`` of a simulated
board (``[target] board``): the board calibration against ``truth.json``.

The scenario's dataset holds rendered images of a board of known geometry (:mod:`selfcal.sim.board_scene`);
``calibrate`` is the board route (:mod:`selfcal.calibration.board.dataset`: camera, hand-eye, board pose and
kinematics, the board frame the world), and the report compares it with the truth:

- tool tip at the validation postures after the best rigid alignment, calibrated and nominal
  (as the field's report, :func:`selfcal.kinematics.accuracy.aligned_errors`);
- the camera's pose in the board frame at the validation postures (no alignment: the board is
  the frame): the calibrated chain, and the reference with only hand-eye and board pose fitted
  to the nominal chain (``calibration.json`` ``nominal_mcpc``);
- every free camera parameter: estimate, truth, standard deviation and ``z = (estimate - truth)
  / std``; of a stereo rig also the second camera's and its pose in the first camera's frame;
- the hand-eye (the chain's last shape matrix, last link -> camera) and every minimal
  kinematic parameter, the truth expressed in the board frame and the estimate's joint-offset
  convention (:func:`selfcal.kinematics.alignment.express_in_frame`).

Units: mm and deg in the report, px for the camera.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.bounds import estimated_parameters
from selfcal.calibration.board.evaluate import evaluate_board
from selfcal.calibration.board.nominal_fit import beyond_placement, placement_indices
from selfcal.calibration.board.parameter_pool import identified_words
from selfcal.calibration.spread import spread_line
from selfcal.camera import CameraModel, opencv_values
from selfcal.config.scenario import Scenario
from selfcal.console.log import get_logger
from selfcal.console.progress import Progress
from selfcal.errors import InputError
from selfcal.io.atomic import write_text_atomic
from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
from selfcal.io.dataset import Dataset, DatasetError
from selfcal.io.jsonfile import write_report
from selfcal.io.truth import Truth, read_truth
from selfcal.kinematics.accuracy import aligned_errors, parameter_table, tool_tips
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, param_names, shape_matrices
from selfcal.pipeline.board_accuracy import (
    accuracy_markdown,
    board_accuracy_section,
    spread_against_prediction,
)
from selfcal.pipeline.board_report_text import board_report_markdown
from selfcal.pipeline.board_truth_accuracy import (
    predicted_against_truth,
    predicted_against_truth_words,
)
from selfcal.plots.job_figures import (
    parameter_figure,
    reprojection_figure,
    tool_tip_figure,
    write_figure,
)
from selfcal.terms.base import Term
from selfcal.transforms import inv_pose

if TYPE_CHECKING:  # imported by the calibration itself (start-up time)
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.pipeline.board_spread import BootstrapRun

__all__ = [
    "board_truth_report",
    "camera_bounds",
    "camera_rows",
    "calibrate_and_report_board",
    "calibrate_board_run",
    "pose_errors",
    "summary",
    "write_board_truth_report",
]

_log = get_logger(__name__)
SPREAD_FIGURE = "spread.png"
"""``selfcal calibrate --spread N``'s figure of the run-to-run spreads (in ``DIR/figures``)."""


def pose_errors(T_pred: np.ndarray, T_true: np.ndarray) -> dict:
    """Position (mm) and rotation (deg) errors of the poses ``T_pred`` (m, 4, 4) against
    ``T_true``: RMS and max of each."""
    dp = np.linalg.norm(T_pred[:, :3, 3] - T_true[:, :3, 3], axis=1) * 1000.0
    dR = np.einsum("kji,kjl->kil", T_true[:, :3, :3], T_pred[:, :3, :3])
    da = np.degrees(Rotation.from_matrix(dR).magnitude())
    return {
        "position_mm": {"rms": float(np.sqrt(np.mean(dp**2))), "max": float(dp.max())},
        "rotation_deg": {"rms": float(np.sqrt(np.mean(da**2))), "max": float(da.max())},
    }


def camera_rows(
    est: CameraModel, std: dict[str, float], true: CameraModel, bound: dict[str, float]
) -> dict:
    """Per free parameter of ``est``: estimate, truth, std, z (a parameter the true model
    lacks: truth 0, no lens term) and the Cramer-Rao bound (None when not computed)."""
    t_vals = dict(zip(true.names, true.values().tolist()))
    vals = dict(zip(est.names, est.values().tolist()))
    rows = {}
    for n in est.free:
        t, s = t_vals.get(n, 0.0), std.get(n)
        z = None if not s else (vals[n] - t) / s
        rows[n] = {"estimate": vals[n], "truth": t, "std": s, "z": z, "bound": bound.get(n)}
    return rows


def camera_bounds(cal: BoardCalibrationResult, k: int) -> dict[str, float]:
    """Camera ``k``'s bounds of ``calibration.json`` (empty without bounds)."""
    return {} if cal.bounds is None else dict(cal.bounds.cameras[k].bounds)


def _rig_rows(cal: BoardCalibrationResult, truth: Truth) -> dict:
    """The further camera of a simulated stereo rig (truth: the right camera): its parameters
    as :func:`_camera_rows` and its pose in the first camera's frame against the truth."""
    if cal.T_first_cam is None or len(cal.cameras) < 2:
        return {}
    name = cal.camera_names[1]
    return {
        name: {
            "camera": camera_rows(
                cal.cameras[1], cal.camera_std[1], truth.intrinsics_right, camera_bounds(cal, 1)
            ),
            "extrinsics": pose_errors(cal.T_first_cam[1][None], truth.T_left_right[None]),
        }
    }


def _hand_eye(est: MCPCModel, true: MCPCModel, nominal: MCPCModel) -> dict:
    """The last link -> camera transform (the chain's last shape matrix) of the estimate and of
    the nominal chain against the truth (all in the estimate's convention): mm and deg."""
    V = [shape_matrices(m.params)[-1][None] for m in (est, nominal, true)]
    return {
        "calibrated": pose_errors(V[0], V[2]),
        "nominal": pose_errors(V[1], V[2]),
    }


def _same_branch(m: MCPCModel, like: MCPCModel) -> MCPCModel:
    """``m`` with each angle (alpha, beta, gamma) within 180 deg of ``like``'s (the same rotation
    written on the same branch, so that differences read small)."""
    p = m.params.copy()
    d = p[:, :3] - like.params[:, :3]
    p[:, :3] = like.params[:, :3] + (d + np.pi) % (2 * np.pi) - np.pi
    return m.with_params(p)


def board_truth_report(root: Path, cal: BoardCalibrationResult, truth: Truth) -> dict:
    """The report (module docstring) of the board calibration ``cal`` of the simulated dataset
    in ``root`` against ``truth``; ``status`` "failed" when the calibrated tool tip is worse
    than the nominal one at the validation postures."""
    T_world_board = truth.T_world_board
    if T_world_board is None:
        raise DatasetError(
            f"{root / 'truth.json'} holds no board but calibration.json is a board calibration",
            fix="acquire the dataset again with the scenario's [target] board",
        )
    ds = Dataset.open(root)
    qv = np.radians(ds.info.validation_joints_deg)
    T_cam_tip = truth.T_cam_tip
    p_true = tool_tips(truth.true_model, qv, T_cam_tip)
    err_nom = aligned_errors(tool_tips(truth.nominal_model, qv, T_cam_tip), p_true)
    err_cal = aligned_errors(tool_tips(cal.model, qv, T_cam_tip), p_true)
    T_board_world = inv_pose(T_world_board)
    T_true = T_board_world @ fk_tool(truth.true_model, qv)
    true_est = _same_branch(
        express_in_frame(truth.true_model, T_board_world, like=cal.model), cal.model
    )
    nominal_est = _same_branch(
        express_in_frame(truth.nominal_model, T_board_world, like=cal.model), cal.model
    )
    params = parameter_table(cal.model, {}, true_est, nominal_est)
    if cal.bounds is not None:  # each minimal parameter's Cramer-Rao bound (mm or deg)
        bound_by_name = {b.name: b.bound for b in cal.bounds.parameters}
        for row in params:
            row["bound"] = bound_by_name.get(row["name"])
    failures: list[str] = []
    if err_cal["rms"] > err_nom["rms"]:
        failures.append(
            f"the calibrated model predicts the validation tool tips worse than the nominal model "
            f"({err_cal['rms']:.3f} mm RMS against {err_nom['rms']:.3f} mm over {len(qv)} "
            "held-out postures): the calibration is wrong"
        )
    return {
        "kind": "board-truth",
        "status": "failed" if failures else "ok",
        "failures": failures,
        "target": cal.target,
        "validation": {
            "poses": int(len(qv)),
            "tool_tip_error_mm": {
                "nominal": {"rms": err_nom["rms"], "max": err_nom["max"]},
                "calibrated": {"rms": err_cal["rms"], "max": err_cal["max"]},
            },
            "tool_tip_bound_mm": (None if cal.bounds is None else cal.bounds.tool_tip_rms_mm.bound),
            "note": (
                "tool-tip errors after the best rigid alignment (rotation and translation, no "
                "scale) of the predicted positions to the true ones over the validation postures"
            ),
            "predicted_point": predicted_against_truth(cal, truth, qv),
            "camera_pose_in_board": {
                "calibrated": pose_errors(fk_tool(cal.model, qv), T_true),
                "nominal": pose_errors(fk_tool(cal.nominal_model, qv), T_true),
                "note": (
                    "the camera's pose in the board frame predicted from the joint readings "
                    "(no alignment); nominal: the fair nominal, the nominal chain with hand-eye, "
                    "board pose and camera fitted to the pixels (calibration.json nominal_mcpc)"
                ),
            },
        },
        "camera": camera_rows(
            cal.cameras[0], cal.camera_std[0], truth.intrinsics_left, camera_bounds(cal, 0)
        ),
        "rig": _rig_rows(cal, truth),
        "hand_eye": _hand_eye(cal.model, true_est, nominal_est),
        "reprojection_rms_px": cal.reprojection_rms_px,
        "frames": {"planned": cal.frames, "used": cal.frames_used},
        "parameters": params,
        "parameters_note": (
            "truth expressed in the board frame and the estimate's joint-offset convention; the "
            "board calibration gives no kinematic sigma; 'bound' in report.json is each "
            "parameter's Cramer-Rao bound (calibration.json bounds)"
        ),
    }


def write_board_truth_report(
    root: Path, cal: BoardCalibrationResult, truth: Truth, *, quiet: bool, figures: bool
) -> dict:
    """:func:`board_truth_report` written as ``root/report.json`` and ``report.md`` (and with
    ``figures`` the tool-tip, reprojection and parameter figures in ``root/figures``)."""
    report = board_truth_report(root, cal, truth)
    drawn: list[Path] = []
    if figures:
        ds = Dataset.open(root)
        qv = np.radians(ds.info.validation_joints_deg)
        p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
        e = [
            aligned_errors(tool_tips(m, qv, truth.T_cam_tip), p_true)["errors_mm"]
            for m in (truth.nominal_model, cal.model)
        ]
        ev = evaluate_board(cal, str(root / "calibration.json"), root)
        drawn = [
            write_figure(tool_tip_figure(e[0], e[1]), root, "tool_tip_errors.png"),
            write_figure(reprojection_figure(ev, "calibration images"), root, "reprojection.png"),
            write_figure(parameter_figure(report["parameters"]), root, "parameters.png"),
        ]
    section, maps = board_accuracy_section(root, cal, figures=figures)
    if section is not None:  # the predicted tool-point accuracy (issue #29)
        report["accuracy"] = section
    report["figures"] = [str(p.relative_to(root)) for p in drawn + maps]
    write_report(root / "report.json", report)
    md = board_report_markdown(report)
    if section is not None:
        md += "\n".join(accuracy_markdown(section)) + "\n"
    write_text_atomic(root / "report.md", md)
    return report


def calibrate_board_run(
    root: Path,
    *,
    quiet: bool = False,
    allow_missing_frames: bool = False,
    figures: bool = False,
    joint_sigma: np.ndarray | None = None,
    terms: Sequence[Term] = (),
    deviation: Deviation | None = None,
    bootstrap: BootstrapRun | None = None,
) -> BoardCalibrationResult:
    """``selfcal calibrate`` of a board dataset: :func:`selfcal.calibration.board.dataset.calibrate_board_dataset`
    written as ``root/calibration.json``, its warnings logged and a one-line summary printed
    (unless ``quiet``); ``figures``: also ``root/figures/reprojection.png``; ``joint_sigma``:
    the joint read-back noise (rad / m) instead of the robot file's encoder resolution;
    ``terms``: further measurements estimated with the images (:mod:`selfcal.terms`);
    ``deviation``: the arm's deviation from its drawing for the predicted accuracy (default
    :class:`selfcal.calibration.board.deviation.Deviation`'s); ``bootstrap``: also the
    run-to-run spread over refits of resampled configurations (``--spread N``,
    :mod:`selfcal.pipeline.board_spread`), written as ``accuracy.bootstrap_spread`` and drawn in
    ``root/figures/spread.png`` (with ``figures``)."""
    from selfcal.calibration.board.bootstrap import KEY
    from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed

    label = "board calibration (detection, camera, hand-eye, kinematics, bounds)"
    with Progress("calibrate", enabled=not quiet).step(label) as st:
        detailed = calibrate_board_dataset_detailed(
            root,
            allow_missing_frames=allow_missing_frames,
            joint_sigma=joint_sigma,
            terms=terms,
            deviation=deviation,
        )
        res = detailed.result
        st.result(f"reprojection RMS {res.reprojection_rms_px:.3f} px")
    if bootstrap is not None:  # refits of resampled configurations (issue #29)
        from selfcal.pipeline.board_spread import run_bootstrap, with_bootstrap

        try:
            spread = run_bootstrap(detailed, bootstrap, quiet=quiet)
        except InputError as exc:  # no workspace to spread over: the calibration still stands
            text = f"no bootstrap spread (--spread {bootstrap.count}): {exc.message}"
            res = dataclasses.replace(res, warnings=(*res.warnings, text))
        else:
            res = dataclasses.replace(res, accuracy=with_bootstrap(res.accuracy or {}, spread))
    # is the calibration predicted to beat the drawing?
    from selfcal.calibration.board.plan.drawn_check import with_drawn_reference

    res = with_drawn_reference(root, res, detailed, deviation)
    write_board_calibration(Path(root) / "calibration.json", res)
    if figures:
        ev = evaluate_board(res, str(Path(root) / "calibration.json"), root)
        path = write_figure(reprojection_figure(ev, "calibration images"), root, "reprojection.png")
        _say(quiet, f"figure: {path}")
    for text in res.warnings:
        _log.warning("%s", text)
    _say(quiet, summary(res))
    accuracy = res.accuracy or {}
    folds = accuracy.get("spread")
    if folds:  # the run-to-run spread over the folds (issue #29)
        more = spread_against_prediction(folds, accuracy.get("regions") or {},
                                         accuracy.get("cross_validation"))  # fmt: skip
        _say(quiet, spread_line(folds) + (f".{more}" if more else ""))
    boot = accuracy.get(KEY)
    if boot:
        _say(quiet, spread_line(boot))
        if figures:
            from selfcal.plots.spread_figure import spread_figure

            _say(quiet, f"figure: {write_figure(spread_figure(accuracy), root, SPREAD_FIGURE)}")
    return res


def _nominal_text(res: BoardCalibrationResult) -> str:
    """The fair nominal's fit, what was identified and, when it is no gain, that it is none."""
    out = ""
    if res.nominal_rms_px is not None:
        out += f" (fair nominal {res.nominal_rms_px:.3f} px)"
    sel = res.selection
    if sel:
        cands = {c["label"]: c for c in sel["candidates"]}
        ch, nom = cands[sel["chosen"]], sel["candidates"][0]
        counted = sel.get("folds_counted") or []  # the folds the selection compares over
        folds = (f"the {sum(map(bool, counted))} of {len(counted)} folds that count"
                 if counted and not all(counted) else "the folds")  # fmt: skip
        cv = (
            ""
            if ch.get("cv_px") is None or nom.get("cv_px") is None
            else (
                f", cross-validated {ch['cv_px']:.3f} px against the nominal's {nom['cv_px']:.3f} px "
                f"(geometric mean over {folds})"
            )
        )
        # what it estimated beyond the placement (plan and plan --add count the same)
        count = beyond_placement(*estimated_parameters(res), res.model.n)
        placed = set(param_names(placement_indices(res.model.n)))
        extra = [str(p) for p in sel.get("identified", ch["parameters"]) if p not in placed]
        out += (f"; {count} kinematic parameter(s) beyond the placement identified"
                f"{identified_words(extra, sel.get('held') or {})}{cv}")  # fmt: skip
    verdict = res.cv_verdict()
    if verdict:
        out += f"; NO GAIN: {verdict}"
    return out


def summary(res: BoardCalibrationResult) -> str:
    """One line on a board calibration, and one more per further camera of a rig."""
    c = res.cameras[0]
    lines = [
        f"calibrated {res.frames_used}/{res.frames} frames with the {res.target['type']} "
        f"({c.model_name} camera): {_camera_text(c)}, "
        f"reprojection RMS {res.reprojection_rms_px:.3f} px" + _nominal_text(res)
    ]
    from selfcal.calibration.board.plan.drawn_check import KEY, drawn_words

    drawn = drawn_words((res.accuracy or {}).get(KEY))
    if drawn:
        lines.append(drawn)
    for name, cam in zip(res.camera_names[1:], res.cameras[1:], strict=True):
        lines.append(f"camera {name} ({cam.model_name}): {_camera_text(cam)}")
    return "\n".join(lines)


def _camera_text(c: CameraModel) -> str:
    """A camera's pixel map and free lens coefficients by OpenCV name."""
    v = opencv_values(c)
    lens = "".join(f", {n} = {v[n]:.4g}" for n in c.free if n in v and n[0] in "kp")
    return (
        f"fx = {v['fx']:.2f} px, fy = {v['fy']:.2f} px, "
        f"cx = {v['cx']:.2f} px, cy = {v['cy']:.2f} px{lens}"
    )


def calibrate_and_report_board(
    s: Scenario,
    out: Path,
    *,
    quiet: bool = False,
    figures: bool = True,
    t0: float | None = None,
    deviation: Deviation | None = None,
) -> dict:
    """The rest of ``selfcal run`` for a board scenario once acquired in ``out``: the board
    calibration and in simulation the report against the truth; prints a summary line (total
    time since ``t0``, :func:`time.perf_counter`); ``deviation``: as :func:`calibrate_board_run`.

    Raises:
        CalibrationFailedError: the report found the calibration worse than nominal.
    """
    from selfcal.calibration.field.calibrate import CalibrationFailedError

    t0 = time.perf_counter() if t0 is None else t0
    cal = calibrate_board_run(out, quiet=quiet, figures=figures and s.robot.backend != "sim",
                              deviation=deviation)  # fmt: skip
    result: dict = {"calibration": cal}
    if s.robot.backend != "sim":
        return result
    truth = read_truth(out / "truth.json")
    rep = write_board_truth_report(out, cal, truth, quiet=True, figures=figures)
    result["report"] = rep
    v = rep["validation"]["tool_tip_error_mm"]
    rows = [rep["camera"], *(k["camera"] for k in rep["rig"].values())]
    zs = [abs(c["z"]) for r in rows for c in r.values() if c["z"] is not None]
    bound = rep["validation"]["tool_tip_bound_mm"]
    point = predicted_against_truth_words(rep["validation"].get("predicted_point"))
    print(
        f"tool-tip error on {rep['validation']['poses']} validation postures (after the best "
        f"rigid alignment): nominal {v['nominal']['rms']:.3f} mm RMS (max "
        f"{v['nominal']['max']:.3f}), calibrated {v['calibrated']['rms']:.3f} mm RMS (max "
        f"{v['calibrated']['max']:.3f}){'' if bound is None else f', bound {bound:.3f} mm'}; "
        f"{'' if point is None else f'{point}; '}camera parameters within "
        f"{max(zs, default=float('nan')):.2f} sigma of the truth; total "
        f"{time.perf_counter() - t0:.1f} s; details in {out}/report.md"
    )
    if rep["failures"]:
        raise CalibrationFailedError.of(tuple(rep["failures"]), out / "report.json")
    return result


def _say(quiet: bool, text: str) -> None:
    if not quiet:
        print(text, file=sys.stderr)
