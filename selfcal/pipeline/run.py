"""The commands behind ``selfcal acquire | calibrate | report | run``.

Data flows one way: robot -> dataset on disk -> calibration.json -> report.json. ``calibrate``
never opens ``truth.json``; ``report`` does when there is one (simulation: tool-tip errors on the
validation postures, ``validation.csv``, parameters against truth), and without it reports what
the data says (:mod:`selfcal.pipeline.report_fit`). With ``figures=True`` (the commands) they also draw
``DIR/figures/*.png`` (:mod:`selfcal.plots.job_figures`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import shlex
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from selfcal.acquisition.acquire import acquire
from selfcal.acquisition.backends import open_robot, plan_dataset
from selfcal.acquisition.held_frames import HeldFrames
from selfcal.acquisition.simulator_setup import SimSetup, sim_setup
from selfcal.calibration.board.evaluate import Evaluation, evaluate_board, no_gain, worse
from selfcal.calibration.field.calibrate import CalibrationFailedError, calibrate
from selfcal.calibration.field.detections import detect_ahead
from selfcal.calibration.field.evaluate import evaluate_field
from selfcal.config.paper_data import TABLE_II_MM, table_ii_postures
from selfcal.config.scenario import Scenario
from selfcal.config.shipped import SHIPPED_DIR
from selfcal.console.log import get_logger
from selfcal.console.progress import Progress
from selfcal.io.atomic import write_text_atomic
from selfcal.io.board_calibration import (
    BoardCalibrationResult,
    calibration_kind,
    read_board_calibration,
)
from selfcal.io.calibration import CalibrationResult, read_calibration, write_calibration
from selfcal.io.dataset import Dataset, DatasetError, DatasetWriter
from selfcal.io.frame_cache import FrameCache
from selfcal.io.jsonfile import write_report
from selfcal.io.truth import read_truth
from selfcal.kinematics.accuracy import aligned_errors, format_table_iv, parameter_table, tool_tips
from selfcal.kinematics.alignment import express_in_frame
from selfcal.pipeline.report_cameras import camera_rows, rig_camera_rows
from selfcal.pipeline.report_fit import board_fit_report, fit_report, write_fit_report
from selfcal.pipeline.report_text import _markdown, _validation_csv, report_summary
from selfcal.plots.figure_pool import FigurePool, run_figure_pool
from selfcal.plots.job_figures import (
    ReprojectionData,
    parameter_figure,
    reprojection_figure,
    tool_tip_figure,
    write_figure,
)
from selfcal.robot.definition import load_robot
from selfcal.terms.base import Term
from selfcal.transforms import inv_pose

if TYPE_CHECKING:
    from selfcal.calibration.board.deviation import Deviation

_log = get_logger(__name__)

__all__ = [
    "run_acquire",
    "run_calibrate",
    "run_report",
    "report_summary",
    "run_all",
    "dithered",
]


def _say(quiet: bool, text: str) -> None:
    if not quiet:
        print(text, file=sys.stderr)


def scenario_arg(s: Scenario) -> str:
    """The scenario as a ``selfcal`` argument: a shipped one by name, else its file (quoted)."""
    p = Path(s.source)
    return p.stem if p.resolve().parent == SHIPPED_DIR else shlex.quote(s.source)


def dithered(planned_deg: np.ndarray, robot, seed: int) -> np.ndarray:
    """The postures ``planned_deg`` (m, n) deg moved by a uniform random fraction of one
    motor count of ``robot`` (:attr:`selfcal.robot.encoder.EncoderSpec.count_step`; draw
    ``seed``), within the joint limits: in a Monte Carlo the read-back rounding errors become a
    fresh uniform draw instead of the same in every draw. Unmoved without an encoder table."""
    rng = np.random.default_rng(int(seed) + 104_729)
    q = np.asarray(planned_deg, dtype=float)
    if robot.encoder is None:
        return q.copy()
    step_deg = robot.encoder.count_step / robot.edge_unit
    lo, hi = np.degrees(robot.limits).T
    return np.clip(q + rng.uniform(-0.5, 0.5, q.shape) * step_deg, lo, hi)


def run_acquire(
    s: Scenario,
    out: Path,
    *,
    resume: bool = False,
    quiet: bool = False,
    dither_seed: int | None = None,
    keep: FrameCache | None = None,
    resume_command: str | None = None,
    setup: SimSetup | None = None,
    held: HeldFrames | None = None,
) -> Path:
    """Acquire the scenario's dataset into ``out`` (resumable). ``dither_seed`` (simulation):
    move the planned postures by a random fraction of an encoder count (:func:`dithered`).
    ``keep``: also keep the images in memory for :func:`run_calibrate` (:class:`FrameCache`)
    and, for the field route, detect their markers as they are taken (:func:`detect_ahead`).
    ``resume_command``: what continues it when it stops (default ``selfcal acquire ... --resume``
    with this scenario and ``out``). ``setup``: the simulator's (default
    :func:`selfcal.acquisition.simulator_setup.sim_setup` of ``s``; a benchmark's changed one).
    ``held``: the frames' files are written by it, on a thread of its own, into what runs
    after the acquisition (:class:`HeldFrames`; the caller's ``with held:`` waits for them)."""
    if setup is None and s.robot.backend == "sim":
        setup = sim_setup(s)
    info = plan_dataset(s, setup)
    if dither_seed is not None and setup is not None:
        q = dithered(np.asarray(info.planned_joints_deg), setup.robot, dither_seed)
        info = dataclasses.replace(info, planned_joints_deg=q)
    writer = DatasetWriter(out, info, resume=resume)
    before = writer.n_done
    if keep is not None and _route(s) == "field":
        detect_ahead(info, keep)
    robot, hooks = open_robot(s, out, setup)
    try:
        n = acquire(
            robot,
            writer,
            hooks=hooks,
            progress=Progress("acquire", enabled=not quiet),
            keep=keep,
            resume_command=resume_command
            or f"selfcal acquire {scenario_arg(s)} --out {shlex.quote(str(out))} --resume",
            held=held,
        )
    finally:
        robot.close()
    _say(quiet, f"acquired {n} new frame(s); {before + n} in {out}")  # held ones included
    return out


def _route(s: Scenario) -> str:
    """How :func:`run_all` calibrates ``s``: ``"static"`` (a simulated fixed camera, the board on
    the flange), ``"board"`` (a board of known geometry) or ``"field"`` (:func:`run_calibrate`)."""
    if s.camera.setup == "eye-to-hand" and s.robot.backend == "sim":
        return "static"
    return "board" if s.target.board else "field"


def run_calibrate(
    root: Path,
    *,
    quiet: bool = False,
    method: str = "joint",
    allow_missing_frames: bool = False,
    raise_failed: bool = True,
    figures: bool = False,
    terms: Sequence[Term] = (),
    cache: FrameCache | None = None,
    joint_sigma: np.ndarray | None = None,
    before_write: Callable[[], None] | None = None,
) -> CalibrationResult:
    """Calibrate the dataset in ``root`` and write ``root/calibration.json``; returns the
    result. Its warnings are printed (unless ``quiet``). ``raise_failed=False``: return a
    calibration marked failed as well (studies, which measure it against the truth).
    ``figures``: also ``root/figures/reprojection.png`` (:func:`reprojection_figures`).
    ``terms``: measurement terms estimated with the images (:mod:`selfcal.terms`, e.g. a
    :class:`selfcal.terms.tracker.TrackerTerm`).
    ``cache``: the images the acquisition of this run kept in memory (the rest is read); the
    detections are added to it. ``joint_sigma``: the joint read-back noise (rad / m) to model
    instead of the robot file's encoder resolution. ``before_write``: called when the
    calibration is done, before ``calibration.json`` is written (``selfcal run``: waits for
    the dataset's frames still being written, :meth:`HeldFrames.drain`, so that no calibration
    file stands beside a dataset missing its frames).

    Raises:
        CalibrationFailedError: the calibration failed a check of :mod:`selfcal.calibration.field.quality`; it is
            written all the same, marked failed (unless ``raise_failed`` is False).
    """
    res = calibrate(root, progress=Progress("detect", enabled=not quiet), method=method,
                    allow_missing_frames=allow_missing_frames, terms=terms,
                    cache=cache, joint_sigma=joint_sigma)  # fmt: skip
    if before_write is not None:
        before_write()
    path = write_calibration(Path(root) / "calibration.json", res)
    if figures:
        _say(quiet, f"figure: {reprojection_figures(root, evaluate_field(res, root, root, cache))}")
    i = res.intrinsics
    for text in res.warnings:
        _log.warning("%s", text)
    ident, joint = res.identification, res.joint
    if joint is None:  # the two-stage method: its identification is the result
        fitted = f"identification rank {ident.rank}/{ident.n_params}"
    else:  # the one-step refinement fits the chain less the world frame's gauge
        gauge = len(joint.gauge_held)
        fitted = (
            f"{ident.n_params - gauge} kinematic parameters fitted ({gauge} fixed by the world "
            f"frame's gauge), rank {joint.rank}/{joint.n_unknowns} of the one-step refinement"
        )
    _say(
        quiet,
        f"calibrated {res.dataset.frames_used}/{res.dataset.frames} frames in "
        f"{res.seconds:.1f} s: fx = {i.fx:.2f} px, mu = {i.mu:.5f}, "
        f"reprojection RMS {res.reprojection_rms_px:.3f} px{_fair_nominal_text(res)}, {fitted}",
    )
    if res.failed and raise_failed:
        raise CalibrationFailedError.of(res.failures, path)
    return res


def _fair_nominal_text(res: CalibrationResult) -> str:
    """The calibration images predicted from their joint readings by the calibrated model and
    by the fair nominal (over the same corners; the fits' own RMS let the joint read-back
    corrections absorb part of a misfit) and, when the calibrated model is no better
    (:func:`selfcal.calibration.board.evaluate.no_gain`; worse is a failure, said apart), that
    it is no gain."""
    nom = res.nominal
    if nom is None:
        return ""
    rms = nom.calibration_images_rms_px
    out = (f" (from the joint readings {rms['calibrated']:.3f} px, the fair nominal "
           f"{rms['nominal']:.3f} px)")  # fmt: skip
    if no_gain(rms["calibrated"], rms["nominal"]) and not worse(rms["calibrated"], rms["nominal"]):
        out += "; NO GAIN: predicts the calibration images no better than the fair nominal"
    return out


def reprojection_figures(root: Path, ev: Evaluation) -> Path:
    """``root/figures/reprojection.png`` from the dataset's own images predicted from their
    joint readings (``ev``: :func:`selfcal.calibration.field.evaluate.evaluate_field` of the dataset with
    its calibration)."""
    return write_figure(reprojection_figure(ev, "calibration images"), root, "reprojection.png")


def run_report(
    root: Path,
    *,
    quiet: bool = False,
    figures: bool = False,
    cache: FrameCache | None = None,
    pool: FigurePool | None = None,
) -> dict:
    """``root/report.json`` and ``report.md``: with ``truth.json`` (simulation) the calibration
    against the truth and ``root/validation.csv`` (per validation posture); without it the fit,
    a held-out check, the sigmas and the identifiability (:mod:`selfcal.pipeline.report_fit`).
    ``figures``: also the figures (:mod:`selfcal.plots.job_figures`), linked from ``report.md``.
    ``cache``: the dataset's images and detections already in memory (:class:`FrameCache`).
    ``pool``: where the figures are drawn (:class:`FigurePool`; default: here, one by one)."""
    root = Path(root)
    ds = Dataset.open(root)
    cal_path = root / "calibration.json"
    if not cal_path.is_file():
        raise DatasetError(f"{cal_path} is missing: run `selfcal calibrate {root}` first")
    if calibration_kind(cal_path) == "board":
        return _board_report(root, read_board_calibration(cal_path), quiet=quiet, figures=figures)
    cal = read_calibration(cal_path)
    truth_path = root / "truth.json"
    if not truth_path.is_file():
        return _report_without_truth(root, cal, quiet=quiet, figures=figures, cache=cache)
    truth = read_truth(truth_path)
    robot = load_robot(ds.info.robot_model)
    est = cal.model
    T_cam_tip = truth.T_cam_tip
    qv = np.radians(ds.info.validation_joints_deg)

    p_true = tool_tips(truth.true_model, qv, T_cam_tip)
    err_nom = aligned_errors(tool_tips(truth.nominal_model, qv, T_cam_tip), p_true)
    err_cal = aligned_errors(tool_tips(est, qv, T_cam_tip), p_true)

    # Truth in the estimate's world frame: the reconstruction frame is the true left camera of
    # the reference frame, so the transform is known exactly in simulation.
    ref = cal.camera_poses.reference_frame_index
    ref_truth = truth.frame(ref)
    if ref_truth is None:
        raise DatasetError(f"{truth_path} lacks frame {ref}; the dataset and truth disagree")
    T_recon_world = inv_pose(ref_truth.T_world_cam_left)
    truth_est = express_in_frame(truth.true_model, T_recon_world, like=est)
    nominal_est = express_in_frame(truth.nominal_model, T_recon_world, like=est)
    std_si = {p.name: np.nan if p.std is None else p.std * p.to_si for p in cal.parameters}
    params = parameter_table(est, std_si, truth_est, nominal_est)

    table_iv = []
    q2 = table_ii_postures(robot)[0] if robot.name == "er4u-paper" else None
    if q2 is not None:
        T_nom = err_nom["T_true_pred"]  # nominal frame -> true world
        p_des = tool_tips(truth.nominal_model, q2, T_cam_tip)
        to_nom = inv_pose(T_nom)
        p_true2 = tool_tips(truth.true_model, q2, T_cam_tip) @ to_nom[:3, :3].T + to_nom[:3, 3]
        Tc = to_nom @ err_cal["T_true_pred"]
        p_cal2 = tool_tips(est, q2, T_cam_tip) @ Tc[:3, :3].T + Tc[:3, 3]
        for k in range(len(q2)):
            table_iv.append(
                {
                    "position": k + 1,
                    "joints_deg": np.degrees(q2[k]).round(4).tolist(),
                    "paper_table_ii_mm": TABLE_II_MM[k].tolist(),
                    "desired_mm": (p_des[k] * 1000).tolist(),
                    "true_mm": (p_true2[k] * 1000).tolist(),
                    "calibrated_mm": (p_cal2[k] * 1000).tolist(),
                }
            )
    ti = truth.intrinsics_left
    bounds = cal.bounds
    if bounds is not None:
        bound_by_name = {b.name: b.bound for b in bounds.parameters}
        for row in params:
            row["bound"] = bound_by_name.get(row["name"])
    failures = list(cal.failures)
    if err_cal["rms"] > err_nom["rms"]:
        failures.append(
            f"the calibrated model predicts the validation tool tips worse than the nominal model "
            f"({err_cal['rms']:.3f} mm RMS against {err_nom['rms']:.3f} mm over "
            f"{len(qv)} held-out postures): the calibration is wrong (see calibration.json "
            "failures and warnings for the likely causes)"
        )
    report = {
        "status": "failed" if failures else "ok",
        "failures": failures,
        "validation": {
            "poses": int(len(qv)),
            "tool_tip_error_mm": {
                "nominal": {"rms": err_nom["rms"], "max": err_nom["max"]},
                "calibrated": {"rms": err_cal["rms"], "max": err_cal["max"]},
            },
            "tool_tip_bound_mm": None if bounds is None else bounds.tool_tip_rms_mm.bound,
            "note": (
                "tool-tip errors after the best rigid alignment (rotation and translation, no "
                "scale) of the predicted positions to the true ones over the validation postures: "
                "the robot's placement relative to the unknown scene is not observable and does "
                "not count"
            ),
        },
        "intrinsics": {
            "fx": {"estimate": cal.intrinsics.fx, "truth": ti.fx},
            "mu": {"estimate": cal.intrinsics.mu, "truth": ti.mu},
            **camera_rows(cal.intrinsics.camera(), cal.intrinsics.std, ti),
        },
        **({"cameras": cams} if (cams := rig_camera_rows(cal, truth)) else {}),
        "scale_factor": cal.scale.k,
        "reprojection_rms_px": cal.reprojection_rms_px,
        "effective_corner_noise_px": float(
            cal.reprojection_rms_px / np.sqrt(2) if cal.joint is None else cal.joint.sigma_px
        ),
        "effective_corner_noise_note": (
            "per-coordinate corner noise estimated from the final residuals, corrected for the "
            "fitted degrees of freedom"
        ),
        "observation": ds.info.observation,
        "parameters": params,
        "parameters_note": (
            "truth expressed in the estimate's world frame (the reconstruction frame, known "
            "exactly in simulation) and joint-offset convention; base parameters describe the "
            "robot relative to that arbitrary frame"
        ),
        "table_iv": table_iv,
    }
    write_text_atomic(root / "validation.csv", _validation_csv(qv, err_nom, err_cal))
    section, workspace_map = _field_accuracy(root, cal)
    if section is not None:
        report["accuracy"] = section
    pending = []
    if figures:
        pool = pool or FigurePool(enabled=False)
        ev = evaluate_field(cal, root, root, cache)
        report["reprojection_predicted_px"] = ev.rms["calibrated"]
        pending = pool.draw_all([
            (tool_tip_figure, (err_nom["errors_mm"], err_cal["errors_mm"]), root,
             "tool_tip_errors.png"),
            (reprojection_figure, (ReprojectionData.of(ev), "calibration images"), root,
             "reprojection.png"),
            (parameter_figure, (params,), root, "parameters.png"),
            *([] if workspace_map is None else [workspace_map]),
        ])  # fmt: skip
    report["figures"] = [str(f.wait().relative_to(root)) for f in pending]
    write_report(root / "report.json", report)
    md = _markdown(report)
    write_text_atomic(root / "report.md", md)
    if table_iv:
        md_iv = format_table_iv(table_iv)
        write_text_atomic(root / "table_iv.md", md_iv)
    return report


def _report_without_truth(
    root: Path, cal: CalibrationResult, *, quiet: bool, figures: bool, cache: FrameCache | None
) -> dict:
    drawn = [reprojection_figures(root, evaluate_field(cal, root, root, cache))] if figures else []
    report = fit_report(root, cal)
    section, workspace_map = _field_accuracy(root, cal)
    if section is not None:
        report["accuracy"] = section
        if figures and workspace_map is not None:
            builder, args, _, name = workspace_map
            drawn.append(write_figure(builder(*args), root, name))
    return write_fit_report(root, report, drawn, quiet=quiet)


def _field_accuracy(root: Path, cal: CalibrationResult) -> tuple[dict | None, Any]:
    """:func:`selfcal.pipeline.field_accuracy.field_accuracy_section`, the predicted tool-point
    accuracy (issue #29): imported here, as it loads scipy.special, off `selfcal run`'s serial
    start (tests/unit/test_cli_imports.py)."""
    from selfcal.pipeline.field_accuracy import field_accuracy_section

    return field_accuracy_section(root, cal)


def _board_report(root: Path, cal: BoardCalibrationResult, *, quiet: bool, figures: bool) -> dict:
    if (root / "truth.json").is_file():  # a simulated board: against the truth
        from selfcal.pipeline.board_run import write_board_truth_report
        from selfcal.pipeline.static_report import write_static_truth_report

        truth = read_truth(root / "truth.json")
        if cal.eye_to_hand:
            return write_static_truth_report(root, cal, truth, figures=figures)
        return write_board_truth_report(root, cal, truth, quiet=quiet, figures=figures)
    from selfcal.pipeline.board_accuracy import board_accuracy_section

    ev = evaluate_board(cal, str(root / "calibration.json"), root) if figures else None
    drawn = [] if ev is None else [reprojection_figures(root, ev)]
    report = board_fit_report(root, cal)
    section, maps = board_accuracy_section(root, cal, figures=figures)
    if section is not None:
        report["accuracy"] = section
    return write_fit_report(root, report, drawn + maps, quiet=quiet)


def run_all(
    s: Scenario,
    out: Path,
    *,
    resume: bool = False,
    quiet: bool = False,
    method: str = "joint",
    figures: bool = True,
    pool: FigurePool | None = None,
    deviation: Deviation | None = None,
) -> dict:
    """Acquire, calibrate and (in simulation) report; prints a summary. ``figures``: the
    report's figures in ``out/figures/``. ``deviation``: a board calibration's prior on the
    arm's deviation from its drawing (:func:`selfcal.pipeline.board_run.calibrate_board_run`;
    the simulator's perturbation is never read for it). ``pool``: the caller's
    :func:`selfcal.plots.figure_pool.run_figure_pool` of ``s``, forked before its imports (the
    caller closes it); default: forked here and closed at the end."""
    t0 = time.perf_counter()
    kept = FrameCache()  # calibration and report: the images taken now from memory, detected once
    # the report's figures: a worker forked now (before any thread or GL context) loads
    # matplotlib while this process acquires and calibrates (selfcal/plots/figure_pool.py)
    own = run_figure_pool(s, figures) if pool is None else contextlib.nullcontext(pool)
    route = _route(s)
    # a simulation's field dataset: the PNGs are written beside the calibration (one core),
    # not during the acquisition (two); leaving the block waits for them, also on an error
    held = HeldFrames() if route == "field" and s.robot.backend == "sim" else None
    with own as pool, held or contextlib.nullcontext():
        again = f"selfcal run {scenario_arg(s)} --out {shlex.quote(str(out))}"
        again += "" if method == "joint" else f" --method {method}"
        run_acquire(s, out, resume=resume, quiet=quiet, keep=kept, resume_command=again,
                    held=held)  # fmt: skip
        if route == "static":  # the board on the flange
            from selfcal.pipeline.static_report import calibrate_and_report_static

            return calibrate_and_report_static(out, quiet=quiet, figures=figures, t0=t0,
                                               deviation=deviation)  # fmt: skip
        if route == "board":  # the board route (selfcal/pipeline/board_run.py)
            from selfcal.pipeline.board_run import calibrate_and_report_board

            return calibrate_and_report_board(s, out, quiet=quiet, figures=figures, t0=t0,
                                              deviation=deviation)  # fmt: skip
        if held is not None and held.pending and not kept.left_out:
            kept.dataset = held.dataset()  # calibrated from memory while the files are written
        elif held is not None:
            held.drain()
        # without truth (hardware) there is no report: the calibration draws what it can
        try:
            cal = run_calibrate(
                out,
                quiet=quiet,
                method=method,
                figures=figures and s.robot.backend != "sim",
                cache=kept,
                before_write=None if held is None else held.drain,
            )
        except CalibrationFailedError:
            if s.robot.backend == "sim":
                run_report(out, quiet=True)  # report.json marked failed as well
            raise
        result: dict[str, Any] = {"calibration": cal}
        if s.robot.backend == "sim":
            rep = run_report(out, quiet=True, figures=figures, cache=kept, pool=pool)
            result["report"] = rep
            v = rep["validation"]["tool_tip_error_mm"]
            print(
                f"tool-tip error on {rep['validation']['poses']} validation postures: nominal "
                f"{v['nominal']['rms']:.3f} mm RMS (max {v['nominal']['max']:.3f}), calibrated "
                f"{v['calibrated']['rms']:.3f} mm RMS (max {v['calibrated']['max']:.3f}); "
                f"fx {cal.intrinsics.fx:.2f} px; total {time.perf_counter() - t0:.1f} s; "
                f"details in {out}/report.md"
            )
            for f in rep["figures"]:
                _say(quiet, f"figure: {out / f}")
            if rep["failures"]:
                raise CalibrationFailedError.of(tuple(rep["failures"]), out / "report.json")
    return result
