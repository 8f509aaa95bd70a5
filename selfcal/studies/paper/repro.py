"""``selfcal paper --out DIR``: the seed paper's Tables II-IV and Fig. 3, reproduced in simulation.

What is computed (all positions in mm, of the tool tip = origin of the last DH frame):

- Table II: the nominal er4u-paper model's tool tip at the five Table II postures. The postures
  are solved by IK holding the CARTESIAN tool pitch/roll of Table II row 1 (-138.54 deg, 0 deg,
  what FK gives at Table I's joint angles). Table II's "Pitch (theta4) = -63.54 deg" read as the
  joint angle makes row 2 unreachable by 7.324 mm (see ``tests/unit/test_paper_tables.py``); the table
  lists that distance per row.
- Tables III/IV: the simulated actual robot (nominal + injected errors) is driven along a
  trajectory whose first five frames ARE the Table II postures, then self-calibrated. "Measured by
  the camera" is the tool tip computed from the camera pose the self-calibration recovered at that
  frame (``T_world_cam @ T_cam_tip``). Errors follow the paper: measured - desired, desired = the
  nominal model.
- What the paper could not show: the simulator's truth at the same postures, hence the camera's own
  measurement error (measured - true), the nominal model's error (desired - true) and the
  calibrated model's error (calibrated - true), plus the held-out validation RMS.

Frames: the camera measures in its reconstruction frame (the left camera of the reference frame);
it is registered to the simulator's world by the best rigid alignment (no scale) of all recovered
camera centres onto the true ones (``truth.json``); the results are expressed, like
``report.json``'s ``table_iv``, in the nominal base frame through the best rigid alignment of the
nominal model onto the truth over the validation postures (the robot's placement relative to the
unknown scene is not observable and does not count).

The paper's values are given beside ours; its internal inconsistencies are detected by
:func:`selfcal.studies.paper.checks.paper_inconsistencies` and listed, never used as truth. The files
are written by ``selfcal.studies.paper.report``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from selfcal.console.common import add_json, note_written
from selfcal.console.progress import Progress

if TYPE_CHECKING:
    from selfcal.io.calibration import CalibrationResult
    from selfcal.io.truth import Truth


# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = ["reproduce", "register"]


def _theta4_held_distances(robot) -> np.ndarray:
    """Distance (mm) from each Table II row to the reachable set with theta4, theta5 as printed."""
    from selfcal.config.paper_data import TABLE_II_MM, TABLE_II_THETA4_DEG
    from selfcal.kinematics.ik import nearest_reachable

    fixed: dict[int | str, float] = {3: float(np.radians(TABLE_II_THETA4_DEG)), 4: 0.0}
    return np.array([nearest_reachable(robot, p / 1000, fixed)[1] * 1000 for p in TABLE_II_MM])


# ------------------------------------------------------------------------------------- run
def _acquire_with_postures(s, root: Path, q_deg: np.ndarray, quiet: bool) -> None:
    """Acquire the scenario's dataset with ``q_deg`` (k, n) prepended to its trajectory."""
    from selfcal.acquisition.acquire import acquire
    from selfcal.acquisition.backends import open_robot, plan_dataset
    from selfcal.acquisition.simulator_setup import sim_setup
    from selfcal.io.dataset import DatasetWriter

    setup = sim_setup(s)
    info = plan_dataset(s, setup)
    planned = np.vstack([np.round(q_deg, 6), info.planned_joints_deg])
    info = dataclasses.replace(info, planned_joints_deg=planned)
    writer = DatasetWriter(root, info, resume=(root / "dataset.json").is_file())
    robot, hooks = open_robot(s, root, setup)
    try:
        acquire(robot, writer, hooks=hooks, progress=Progress("acquire", enabled=not quiet))
    finally:
        robot.close()


def _camera_measured_tips(
    cal: CalibrationResult, truth: Truth, frames: list[int]
) -> tuple[np.ndarray, float]:
    """Tool tips (m, simulator world) from the self-calibrated camera poses of ``frames``.

    The reconstruction frame is registered to the simulator's world by the best rigid alignment
    (no scale) of all recovered left-camera centres onto the true ones, so no single frame (such
    as the reference frame, whose recovered pose is the identity) is favoured. Returns the tips
    (NaN for unregistered frames) and the RMS of that registration (mm).
    """
    from selfcal.transforms import kabsch

    cp = cal.camera_poses
    pose_of = dict(zip(cp.frame_index, cp.T_world_cam_left_m))
    true_of = {f.frame_index: f.T_world_cam_left for f in truth.frames}
    common = sorted(set(pose_of) & set(true_of))
    A = np.array([pose_of[i][:3, 3] for i in common])
    B = np.array([true_of[i][:3, 3] for i in common])
    T_world_recon = kabsch(A, B)
    reg_rms = float(
        np.sqrt(
            np.mean(np.sum((A @ T_world_recon[:3, :3].T + T_world_recon[:3, 3] - B) ** 2, axis=1))
        )
        * 1000
    )
    out = np.full((len(frames), 3), np.nan)
    for k, i in enumerate(frames):
        if i in pose_of:
            out[k] = (T_world_recon @ pose_of[i] @ truth.T_cam_tip)[:3, 3]
    return out, reg_rms


def reproduce(out: str | Path, config: str | Path | None = None, *, quiet: bool = False) -> dict:
    """Run the paper reproduction into ``out`` (see the module docstring); returns the summary.

    Writes ``out/run/`` (the dataset, calibration.json, report.json), ``table_ii.{md,csv}``,
    ``table_iv.{md,csv}``, ``paper_typos.md``, ``fig3.png``, ``paper.md`` (all of it) and
    ``paper.json``. Re-running resumes the acquisition and recomputes the rest.

    Raises:
        ConfigError: the scenario is not a simulated er4u-paper robot.
    """
    from selfcal.config.paper_data import (
        AXES,
        PAPER_TABLE_III_MM,
        PAPER_TABLE_IV,
        TABLE_II_MM,
        table_ii_postures,
    )
    from selfcal.config.scenario import ConfigError, load_scenario
    from selfcal.io.dataset_info import read_dataset_info
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.accuracy import aligned_errors, tool_tips
    from selfcal.kinematics.forward import fk_nominal
    from selfcal.pipeline.run import run_calibrate, run_report
    from selfcal.robot.definition import load_robot
    from selfcal.studies.paper.checks import paper_inconsistencies
    from selfcal.studies.paper.report import write_outputs
    from selfcal.transforms import inv_pose

    t0 = time.perf_counter()
    out = Path(out)
    s = load_scenario(config)
    if s.robot.model != "er4u-paper" or s.robot.backend != "sim":
        raise ConfigError(
            f"{s.source}: the paper reproduction needs robot.model = 'er4u-paper' and "
            f"robot.backend = 'sim' (got {s.robot.model!r}, {s.robot.backend!r})"
        )
    robot = load_robot(s.robot.model)
    q5, pitch, roll = table_ii_postures(robot)
    nominal_mm = fk_nominal(robot, q5)[:, -1, :3, 3] * 1000
    theta4_dist = _theta4_held_distances(robot)

    root = out / "run"
    out.mkdir(parents=True, exist_ok=True)
    _acquire_with_postures(s, root, np.degrees(q5), quiet)
    cal = run_calibrate(root, quiet=quiet)
    rep = run_report(root, quiet=True)

    truth = read_truth(root / "truth.json")
    qv = np.radians(read_dataset_info(root / "dataset.json").validation_joints_deg)
    T_cam_tip = truth.T_cam_tip
    p_true_v = tool_tips(truth.true_model, qv, T_cam_tip)
    to_nom = inv_pose(
        aligned_errors(tool_tips(truth.nominal_model, qv, T_cam_tip), p_true_v)["T_true_pred"]
    )

    def nom(p_world: np.ndarray) -> np.ndarray:
        return (p_world @ to_nom[:3, :3].T + to_nom[:3, 3]) * 1000

    desired = tool_tips(truth.nominal_model, q5, T_cam_tip) * 1000
    true_mm = nom(tool_tips(truth.true_model, q5, T_cam_tip))
    meas_world, reg_rms = _camera_measured_tips(cal, truth, list(range(5)))
    measured = nom(meas_world)
    calibrated = np.array([r["calibrated_mm"] for r in rep["table_iv"]])
    # Cross-checks against report.json (same alignment) and the simulator's own tool-tip site.
    np.testing.assert_allclose(desired, [r["desired_mm"] for r in rep["table_iv"]], atol=1e-6)
    np.testing.assert_allclose(true_mm, [r["true_mm"] for r in rep["table_iv"]], atol=1e-6)
    site = np.array(
        [
            f.tool_tip_m
            for f in sorted(truth.frames, key=lambda f: f.frame_index or 0)
            if f.frame_index is not None and f.frame_index < 5
        ]
    )
    np.testing.assert_allclose(nom(site), true_mm, atol=1e-6)

    rows_ii = []
    for i in range(5):
        rows_ii.append(
            {
                "position": i + 1,
                "paper_mm": TABLE_II_MM[i].tolist(),
                "nominal_mm": nominal_mm[i].tolist(),
                "diff_mm": (nominal_mm[i] - TABLE_II_MM[i]).tolist(),
                "joints_deg": np.degrees(q5[i]).tolist(),
                "theta4_held_distance_mm": float(theta4_dist[i]),
            }
        )
    rows_iv = []
    for i in range(5):
        for k, ax in enumerate(AXES):
            rows_iv.append(
                {
                    "position": i + 1,
                    "axis": f"p_{ax}",
                    "paper_desired": float(PAPER_TABLE_IV["desired_mm"][i, k]),
                    "paper_measured_iv": float(PAPER_TABLE_IV["measured_mm"][i, k]),
                    "paper_measured_iii": float(PAPER_TABLE_III_MM[i, k]),
                    "paper_error_printed": float(PAPER_TABLE_IV["error_mm"][i, k]),
                    "paper_error_recomputed": round(
                        float(PAPER_TABLE_IV["measured_mm"][i, k] - TABLE_II_MM[i, k]), 2
                    ),
                    "desired": float(desired[i, k]),
                    "measured": float(measured[i, k]),
                    "error_measured_minus_desired": float(measured[i, k] - desired[i, k]),
                    "true": float(true_mm[i, k]),
                    "camera_error_measured_minus_true": float(measured[i, k] - true_mm[i, k]),
                    "nominal_error_desired_minus_true": float(desired[i, k] - true_mm[i, k]),
                    "calibrated": float(calibrated[i, k]),
                    "calibrated_error_minus_true": float(calibrated[i, k] - true_mm[i, k]),
                }
            )
    typos = paper_inconsistencies()
    v = rep["validation"]["tool_tip_error_mm"]
    summary = {
        "scenario": s.source,
        "run_dir": str(root),
        "cartesian_pitch_deg": float(np.degrees(pitch)),
        "cartesian_roll_deg": float(np.degrees(roll)),
        "table_ii": rows_ii,
        "table_iv": rows_iv,
        "paper_typos": typos,
        "validation": {
            "poses": rep["validation"]["poses"],
            "nominal_rms_mm": v["nominal"]["rms"],
            "nominal_max_mm": v["nominal"]["max"],
            "calibrated_rms_mm": v["calibrated"]["rms"],
            "calibrated_max_mm": v["calibrated"]["max"],
        },
        "camera_error_rms_mm": float(np.sqrt(np.mean(np.sum((measured - true_mm) ** 2, axis=1)))),
        "camera_registration_rms_mm": reg_rms,
        "table_i_posture_fk_mm": (fk_nominal(robot, robot.home)[0, -1, :3, 3] * 1000).tolist(),
        "fx_px": {"estimate": cal.intrinsics.fx, "truth": rep["intrinsics"]["fx"]["truth"]},
        "reprojection_rms_px": cal.reprojection_rms_px,
        "observation": rep["observation"],
        "seconds": round(time.perf_counter() - t0, 2),
    }
    write_outputs(out, summary)
    if not quiet:
        print((out / "paper.md").read_text())
    print(
        f"paper reproduction in {summary['seconds']:.1f} s: Table II max |ours - paper| "
        f"{max(abs(d) for r in rows_ii for d in r['diff_mm']):.3f} mm; camera-measured tool tips "
        f"{summary['camera_error_rms_mm']:.3f} mm RMS from truth; validation nominal "
        f"{v['nominal']['rms']:.3f} -> calibrated {v['calibrated']['rms']:.3f} mm RMS; "
        f"files in {out}",
        file=sys.stderr,
    )
    return summary


# ------------------------------------------------------------------------------------- CLI
def _cmd(args: argparse.Namespace) -> int:
    summary = reproduce(Path(args.out), args.config, quiet=args.quiet)
    if args.json:
        print(json.dumps(summary, default=str))
    note_written(args, args.out)
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal paper [CONFIG] [--out DIR]`` to an argparse subparsers object."""
    sp = subparsers.add_parser(
        "paper",
        help="reproduce the paper's Tables II-IV and Fig. 3 in simulation",
        description="Reproduce the paper's Tables II-IV and Fig. 3 from the simulation: "
        "DIR/paper.md, table_ii/table_iv (.md, .csv), paper_typos.md, fig3.png, paper.json; "
        "the run itself in DIR/run.",
    )
    sp.add_argument(
        "config",
        nargs="?",
        default=None,
        metavar="SCENARIO",
        help="scenario TOML (default scenarios/paper.toml)",
    )
    sp.add_argument("--out", default="runs/paper", help="output folder (default runs/paper)")
    add_json(sp)
    sp.set_defaults(func=_cmd)
    return sp
