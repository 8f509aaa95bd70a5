"""One Monte Carlo draw of a board scenario (``[target] board``) against the board route's bound.

:func:`selfcal.studies.montecarlo.run.draw_one` acquires the draw on the analytic path (the board's features
projected with the true camera at the true poses, Gaussian noise of ``pixel_sigma``,
:func:`selfcal.sim.analytic.project_board`), or rendered, and hands the dataset here (the row
counts the ``frames`` and those in which every feature of the board was found, ``frames_whole``): the board route calibrates it as
``selfcal calibrate`` does, less the predicted accuracy block, which the row does not read
(:func:`selfcal.calibration.board.dataset.calibrate_board_dataset_detailed`:
OpenCV's calibration as the start, the two-stage fit -- camera stage, then the identification on
its camera poses -- and the one-step refinement with joint corrections), and the row holds, for
both methods as the field's (:mod:`selfcal.studies.montecarlo.run`), the validation tool tip's RMS after
the best rigid alignment, every minimal parameter's error in the board frame (the board is the
world: no reference camera) and every camera's free parameters' errors (a further camera's
named ``right_fx`` ...), with the bounds of
:mod:`selfcal.calibration.board.bounds` at the draw's one-step estimate with the *true* noise levels
(``pixel_sigma``, encoder resolution). The two-stage method's camera is the camera stage's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.calibration.board.bounds import board_bounds
from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed, dataset_board
from selfcal.camera import values_by_name
from selfcal.estimation.joint_report import encoder_sigma
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.accuracy import aligned_errors, tool_tips
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.mcpc import minimal_indices, param_is_angle, param_names
from selfcal.robot.definition import load_robot
from selfcal.transforms import inv_pose

__all__ = ["evaluate_board_draw"]


def evaluate_board_draw(root: Path, pixel_sigma: float) -> dict:
    """The row (mm / deg / px; module docstring) of the board dataset acquired in ``root``."""
    ds = Dataset.open(root)
    out = calibrate_board_dataset_detailed(root, accuracy=False)  # the row reads no accuracy
    cal, fit = out.result, out.fit
    truth = read_truth(root / "truth.json")
    assert truth.T_world_board is not None  # a board scenario's truth
    robot = load_robot(ds.info.robot_model)
    qv = np.radians(ds.info.validation_joints_deg)
    T_cam_tip = truth.T_cam_tip
    p_true = tool_tips(truth.true_model, qv, T_cam_tip)
    # the two-stage identification can fail on a draw (the fits then start from the nominal)
    two = None if fit.identification is None else fit.identification.model
    models = {"joint": cal.model, **({} if two is None else {"two_stage": two})}
    n_features = len(dataset_board(ds).layout()[0])
    row: dict = {  # frames whose every board feature was found (rendered: detected)
        "frames": len(out.features[0]),
        "frames_whole": sum(len(f.ids) == n_features for f in out.features[0]),
    }
    for k, mdl in models.items():
        row[f"{k}_tip_rms_mm"] = aligned_errors(tool_tips(mdl, qv, T_cam_tip), p_true)["rms"]
    row["nominal_tip_rms_mm"] = aligned_errors(
        tool_tips(truth.nominal_model, qv, T_cam_tip), p_true
    )["rms"]
    true_cam = truth.intrinsics_left
    t_vals = dict(zip(true_cam.names, true_cam.values().tolist()))
    cams = {"joint": cal.cameras[0], "two_stage": fit.board.camera}
    for k, cam in cams.items():
        row[f"{k}_fx_err_px"] = float(cam.values()[0] - t_vals["fx"])
    # kinematic parameters in the board frame (the world of the board route)
    idx = minimal_indices(cal.model.joint_types)
    names = param_names(idx)
    scale = np.where(param_is_angle(idx), 180.0 / np.pi, 1000.0)
    T_board_world = inv_pose(truth.T_world_board)
    for k, mdl in models.items():
        true_b = express_in_frame(truth.true_model, T_board_world, like=mdl)
        for name, e in zip(names, minimal_difference(mdl, true_b) * scale, strict=True):
            row[f"{k}_err_{name}"] = float(e)
    if two is None:
        row["two_stage_tip_rms_mm"] = float("nan")
        row.update({f"two_stage_err_{name}": float("nan") for name in names})
    # the bound at this draw's one-step estimate, with the true noise levels
    used = np.flatnonzero(fit.used).tolist()
    b, _ = board_bounds(
        dataset_board(ds), cal, [[fc[i] for i in used] for fc in out.features], out.q[used], qv,
        T_cam_tip, joint_sigma=encoder_sigma(robot), pixel_sigma_px=pixel_sigma,
    )  # fmt: skip
    row["bound_tip_rms_mm"] = b.tool_tip_rms_mm.bound
    row["dof_tip"] = None
    row["bound_fx_px"] = b.cameras[0].bounds["fx"]
    trues = (true_cam, truth.intrinsics_right)
    for c, (cam, cb) in enumerate(zip(cal.cameras, b.cameras, strict=True)):
        est, tv = values_by_name(cam), values_by_name(trues[c])  # fy's bound too
        pre = "" if c == 0 else f"{cb.name}_"  # a further camera's: e.g. right_fx
        for name, bound in cb.bounds.items():  # every free camera parameter (px or unitless)
            row[f"joint_cam_err_{pre}{name}"] = est[name] - tv.get(name, 0.0)
            row[f"bound_cam_{pre}{name}"] = float(bound)
    row["sigma_hat_px"] = cal.reprojection_rms_px / np.sqrt(2.0)
    row["outliers"] = int((~fit.board.inlier).sum())
    for p in b.parameters:
        row[f"bound_{p.name}"] = p.bound
        row[f"held_{p.name}"] = p.held
    return row
