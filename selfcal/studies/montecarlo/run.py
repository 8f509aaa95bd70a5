"""The Monte Carlo of ``selfcal montecarlo``: achieved error against the Cramer-Rao bound.

ONE truth -- the default scenario (``scenarios/paper.toml``, or ``config``: any robot's scenario)
on the analytic path: perturbation
seed 1, trajectory seed 1 (the same calibration and validation postures), the same marker field --
and many noise draws (``[noise] seed`` = draw index): Gaussian corner noise, and, with ``dither``
(default), the encoder quantisation residue too: each draw moves the robot to the planned postures
plus a uniform random fraction of one encoder count (< 0.01 deg), so the read-back errors are a
fresh uniform draw with the variance the joint method's prior assumes, instead of the same
deterministic rounding errors in every draw (which would be a fixed, truth-like bias).

Every draw runs the two-stage calibration and the one-step refinement (``selfcal.calibration.field.calibrate``,
method "joint"; the two-stage result is the start) and records, for both methods, the validation
tool-tip RMS after rigid alignment (as ``selfcal report``) and every minimal MCPC parameter's error
in the reference-camera frame, together with the bounds of :mod:`selfcal.calibration.field.bounds` at the draw's
joint estimate with the *true* noise levels (``pixel_sigma``, encoder resolution).

Summary (``DIR/summary.md``, ``DIR/summary.json``, ``DIR/montecarlo.png``): the statistics are
:mod:`selfcal.studies.montecarlo.stats`'s, the markdown and the figure :mod:`selfcal.studies.montecarlo.report`'s;
the plan comparison (``--plans``) is :mod:`selfcal.studies.montecarlo.plan_comparison`, the command
:mod:`selfcal.cli.montecarlo`.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from selfcal.acquisition.acquire import acquire
from selfcal.acquisition.backends import open_robot, plan_dataset
from selfcal.acquisition.simulator_setup import sim_setup
from selfcal.calibration.field.bounds import aligned_error_dof, cramer_rao
from selfcal.calibration.field.bounds_setup import setup_from_output
from selfcal.calibration.field.calibrate import calibrate_detailed, detect_dataset, observations_of
from selfcal.camera import values_by_name
from selfcal.config.scenario import load_scenario
from selfcal.console.log import get_logger
from selfcal.console.progress import Progress, TaskCounts
from selfcal.errors import InternalError
from selfcal.io.dataset import Dataset, DatasetWriter
from selfcal.io.truth import read_truth
from selfcal.kinematics.accuracy import aligned_errors, tool_tips
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.mcpc import minimal_indices, param_is_angle
from selfcal.pipeline.run import dithered
from selfcal.robot.definition import load_robot
from selfcal.studies.montecarlo.board import evaluate_board_draw
from selfcal.studies.montecarlo.journal import JOURNAL, DrawJournal, draw_key
from selfcal.studies.montecarlo.report import plot, summary_markdown
from selfcal.studies.montecarlo.stats import summarize
from selfcal.studies.parallel import run_tasks
from selfcal.studies.row_checks import check_fields
from selfcal.transforms import inv_pose

__all__ = ["acquire_draw", "draw_one", "run_montecarlo", "write_csv"]


# ------------------------------------------------------------------------------ one draw
def _scenario(settings: dict):
    return load_scenario(
        settings.get("config"),
        {
            "noise": {
                "render": bool(settings.get("render", False)),
                "pixel_sigma": float(settings["pixel_sigma"]),
                "seed": int(settings["seed"]),
                "quantize_joints": bool(settings.get("quantize", True)),
            },
            "trajectory": {"poses": int(settings["poses"]), "seed": int(settings["traj_seed"])},
            "perturbation": {"seed": int(settings["perturb_seed"])},
        },
    )


def acquire_draw(settings: dict, root: Path):
    """The draw's dataset in ``root`` (``settings`` as :func:`draw_one`'s): planned (or given)
    postures, dithered, analytic corners (rendered images with ``settings["render"]``); returns
    the draw's scenario."""
    s = _scenario(settings)
    setup = sim_setup(s)
    info = plan_dataset(s, setup)
    planned = info.planned_joints_deg
    if settings.get("joints_deg") is not None:
        planned = np.asarray(settings["joints_deg"], dtype=float)
    if settings.get("dither", True):
        planned = dithered(planned, setup.robot, int(settings["seed"]))
    info = dataclasses.replace(info, planned_joints_deg=planned)
    writer = DatasetWriter(root, info)
    robot, hooks = open_robot(s, root, setup)
    try:
        acquire(robot, writer, hooks=hooks)
    finally:
        robot.close()
    return s


def draw_one(settings: dict) -> dict:
    """One noise draw: acquire, calibrate (two-stage + joint), compare with truth and the bound
    (a board scenario's: :func:`selfcal.studies.montecarlo.board.evaluate_board_draw`).

    ``settings``: ``poses``, ``pixel_sigma``, ``seed`` (noise), ``traj_seed``, ``perturb_seed``,
    ``dither`` (bool), optionally ``joints_deg`` (planned postures to use instead of the
    scenario's plan), ``quantize``, ``config``, ``render`` (MuJoCo images detected as ``selfcal
    run`` with ``[noise] render = true`` does; default the analytic path), ``fair_nominal``
    (default True; False: the field calibration skips its fair nominal, the row's
    ``fair_nominal_tip_rms_mm`` is NaN and its ``fair_nominal`` False, which tells the skip from
    a failed fit). Returns a flat row (mm / deg); never raises: a
    failed draw has ``status = "failed: ..."``.
    """
    t0 = time.perf_counter()
    row: dict = {k: settings.get(k) for k in ("poses", "pixel_sigma", "seed", "dither")}
    row["plan"] = settings.get("plan", "random")
    try:
        with tempfile.TemporaryDirectory(prefix="selfcal-mc-") as d, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            root = Path(d) / "run"
            s = acquire_draw(settings, root)
            sigma = float(settings["pixel_sigma"])
            fair = bool(settings.get("fair_nominal", True))
            row["fair_nominal"] = fair  # NaN below: skipped, not failed
            row.update(evaluate_board_draw(root, sigma) if s.target.board
                       else _evaluate(root, sigma, fair_nominal=fair))  # fmt: skip
        row["status"] = "ok"
    except Exception as exc:  # noqa: BLE001 - a study records failures instead of stopping
        row["status"] = f"failed: {type(exc).__name__}: {str(exc)[:200]}"
    row["seconds"] = round(time.perf_counter() - t0, 3)
    return row


def _evaluate(root: Path, pixel_sigma: float, *, fair_nominal: bool = True) -> dict:
    out = calibrate_detailed(root, method="joint", fair_nominal=fair_nominal)
    joint = out.joint
    if joint is None:  # pragma: no cover - method="joint" sets it
        raise InternalError(f"{root}: the joint calibration gave no joint refinement")
    ds = Dataset.open(root)
    robot = load_robot(ds.info.robot_model)
    truth = read_truth(root / "truth.json")
    qv = np.radians(ds.info.validation_joints_deg)
    p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    models = {"joint": out.model, "two_stage": out.identification.model}
    row: dict = check_fields(out.result.failures)  # the checks `selfcal calibrate` reports
    row["frames_used"] = int(len(out.frames_used))
    row["frames"] = int(len(ds.indices))
    for k, mdl in models.items():
        row[f"{k}_tip_rms_mm"] = aligned_errors(tool_tips(mdl, qv, truth.T_cam_tip), p_true)["rms"]
    row["nominal_tip_rms_mm"] = aligned_errors(
        tool_tips(truth.nominal_model, qv, truth.T_cam_tip), p_true
    )["rms"]
    fair = out.result.nominal_model  # the fair nominal's chain (None: its fit failed)
    row["fair_nominal_tip_rms_mm"] = (
        float("nan") if fair is None
        else aligned_errors(tool_tips(fair, qv, truth.T_cam_tip), p_true)["rms"]
    )  # fmt: skip
    row["joint_fx_err_px"] = joint.fx - truth.intrinsics_left.fx
    row["two_stage_fx_err_px"] = out.selfcal.fx - truth.intrinsics_left.fx
    # parameters in the reference-camera frame (the true one for the truth, like selfcal report)
    frames = {f.frame_index: f for f in truth.frames}
    idx = minimal_indices(out.model.joint_types)
    scale = np.where(param_is_angle(idx), 180.0 / np.pi, 1000.0)
    for k, mdl in models.items():
        ref = joint.ref_config if k == "joint" else out.selfcal.ref_config
        T = inv_pose(frames[int(ds.indices[ref])].T_world_cam_left)
        err = minimal_difference(mdl, express_in_frame(truth.true_model, T, like=mdl)) * scale
        for name, e in zip(joint.names, err):
            row[f"{k}_err_{name}"] = float(e)
    # the bound at this draw's joint estimate, with the true noise levels
    # the calibration's own detections: with a lens estimated it detected again through it
    obs = out.observations
    if obs is None:
        obs = observations_of(ds, detect_dataset(ds).detections)
    q = np.radians(ds.joints_deg)
    s = setup_from_output(out, obs, q, robot, ds.info, pixel_sigma_px=pixel_sigma)
    cr = cramer_rao(s)
    row["bound_tip_rms_mm"] = 1000.0 * cr.aligned_tool_rms(qv, truth.T_cam_tip)
    row["dof_tip"] = aligned_error_dof(*cr.tool_points(qv, truth.T_cam_tip))
    two = dataclasses.replace(out, joint=None, model=out.identification.model)
    s2 = setup_from_output(two, obs, q, robot, ds.info, pixel_sigma_px=pixel_sigma)
    row["bound_tip_two_stage_mm"] = 1000.0 * cramer_rao(s2).aligned_tool_rms(qv, truth.T_cam_tip)
    row["bound_fx_px"] = cr.fx_std
    # every free camera parameter (px or unitless); a rig whose cameras have their own
    # intrinsics adds the others' as "right.k1" ..., each against its own truth
    trues = {"left": truth.intrinsics_left, "right": truth.intrinsics_right}
    est = dict(zip(joint.cameras.names, joint.cameras.cameras)) if joint.cameras \
        else {"left": joint.camera}  # fmt: skip
    bounds = cr.cameras_std or {"left": cr.camera_std}
    for cam, stds in bounds.items():
        # by the model's names and OpenCV's (fy = mu fx has a bound of its own)
        true_cam, est_cam = values_by_name(trues[cam]), values_by_name(est[cam])
        pre = "" if cam == "left" else f"{cam}."
        for name, b in stds.items():
            row[f"joint_cam_err_{pre}{name}"] = est_cam[name] - true_cam.get(name, 0.0)
            row[f"bound_cam_{pre}{name}"] = float(b)
    row["sigma_hat_px"] = joint.sigma_px
    row["outliers"] = joint.n_outliers
    for name, b in zip(cr.names, cr.std_ref * scale):
        row[f"bound_{name}"] = float(b) if np.isfinite(b) else None
        row[f"held_{name}"] = name in cr.held and not cr.held[name].startswith("gauge")
    return row


# ------------------------------------------------------------------------------ driver
def _failed_draw(settings: dict, exc: BaseException) -> dict:
    row: dict = {k: settings.get(k) for k in ("poses", "pixel_sigma", "seed", "dither")}
    row["plan"] = settings.get("plan", "random")
    row["status"] = f"failed: {type(exc).__name__}: {str(exc)[:200]}"
    row["seconds"] = None
    return row


def run_montecarlo(
    draws: int,
    out: str | Path | None = None,
    *,
    poses: int = 30,
    pixel_sigma: float = 0.5,
    traj_seed: int = 1,
    perturb_seed: int = 1,
    dither: bool = True,
    plan: str = "random",
    joints_deg: np.ndarray | None = None,
    jobs: int = 2,
    first_seed: int = 1,
    quiet: bool = False,
    config: str | Path | None = None,
    cluster: str | None = None,
    retries: int = 2,
    task: Callable[[dict], dict] | None = None,
) -> tuple[list[dict], dict]:
    """Run ``draws`` noise draws (seeds ``first_seed ..``); returns ``(rows, summary)``.

    ``config``: the scenario TOML of the truth (default ``scenarios/paper.toml``), e.g.
    ``scenarios/ur5e.toml`` for another robot; always on the analytic path.

    With ``out``: each draw's row goes to the journal ``draws.jsonl`` as it arrives
    (:mod:`selfcal.studies.montecarlo.journal`), and draws already there are not run again: an
    interrupted run resumes, locally or on a cluster whichever ran the first part; at the end
    ``runs.csv``, ``summary.json``, ``summary.md`` and ``montecarlo.png``. ``joints_deg``:
    planned postures to use instead of the scenario's random plan (e.g. from
    :func:`plan_optimal`; ``plan`` names them in the output). ``cluster``: a Dask scheduler
    address to run the draws on instead of ``jobs`` local processes (docs/cluster.md; ``retries``
    extra tries of a task that raised). ``task``: computes one row from a draw's settings
    (default :func:`draw_one`); a task that fails on every try gives a ``failed: ...`` row.
    """
    base = {
        "poses": poses if joints_deg is None else len(joints_deg),
        "pixel_sigma": pixel_sigma,
        "traj_seed": traj_seed,
        "perturb_seed": perturb_seed,
        "dither": dither,
        "plan": plan,
        "joints_deg": None if joints_deg is None else np.asarray(joints_deg).tolist(),
        "config": None if config is None else str(config),
    }
    items = [{**base, "seed": first_seed + i} for i in range(draws)]
    keys = [draw_key(x) for x in items]
    journal = None if out is None else DrawJournal(Path(out) / JOURNAL)
    done = {} if journal is None else journal.load()
    todo = [i for i, k in enumerate(keys) if k not in done]
    t0 = time.perf_counter()
    counts = TaskCounts(len(todo))
    if not quiet and journal is not None and len(todo) < draws:
        print(
            f"montecarlo: {draws - len(todo)} of {draws} draws done before ({journal.path}); "
            f"{len(todo)} to do",
            file=sys.stderr,
        )
    bar = Progress("Monte Carlo", enabled=not quiet, counts=counts)
    bar.start(len(todo))

    def say(row):
        counts.finish(failed=row["status"] != "ok")
        took = "" if row["seconds"] is None else f" ({row['seconds']:.1f} s)"
        msg = (
            f"joint {row['joint_tip_rms_mm']:.3f} mm, two-stage {row['two_stage_tip_rms_mm']:.3f}"
            f" mm, bound {row['bound_tip_rms_mm']:.3f} mm"
            if row["status"] == "ok"
            else row["status"]
        )
        if row.get("checks") == "failed":
            msg += ", checks FAILED"
        bar.advance(note=f"seed {row['seed']}: {msg}{took}")

    try:
        for i, row in run_tasks(
            task or draw_one,
            [items[i] for i in todo],
            jobs=max(1, int(jobs)),
            error_row=_failed_draw,
            cluster=cluster if todo else None,
            retries=retries,
            counts=counts,
        ):
            done[keys[todo[i]]] = row
            if journal is not None:
                journal.append(keys[todo[i]], row)
            say(row)
    except KeyboardInterrupt:
        if journal is not None:
            print(
                f"montecarlo: interrupted; finished draws are kept in {journal.path}; run the "
                "same command again (with or without --cluster) to resume",
                file=sys.stderr,
            )
        raise
    bar.finish()
    rows = [done[k] for k in keys]
    summary = summarize(rows)
    summary["settings"] = {k: v for k, v in base.items() if k != "joints_deg"}
    summary["seconds"] = round(time.perf_counter() - t0, 1)
    if summary["checks_failed"]:
        get_logger(__name__).warning(
            "montecarlo: %d of %d draws' calibrations FAILED their reliability checks (runs.csv "
            "columns checks, failed_checks)",
            summary["checks_failed"],
            len(rows),
        )
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        write_csv(rows, out / "runs.csv")
        (out / "summary.json").write_text(json.dumps(summary, indent=2))
        (out / "summary.md").write_text(summary_markdown(summary))
        plot(rows, summary, out / "montecarlo.png")
    return rows, summary


def write_csv(rows: list[dict], path: Path) -> None:
    cols: list[str] = []
    for r in rows:
        cols += [c for c in r if c not in cols]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow(["" if r.get(c) is None else r.get(c) for c in cols])
