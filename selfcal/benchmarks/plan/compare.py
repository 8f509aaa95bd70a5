"""``python -m selfcal.benchmarks.plan.compare [--draws 30] [--jobs 2] [--out DIR]``: the postures
of ``selfcal plan`` against random ones, achieved in simulation (docs/plan.md, issue #30).

The cell of docs/plan.md's example (UR5e, 60 deg 640 x 480 wrist camera, ChArUco at
-472, -133, 3 mm, one keep-out box): the plan of 12, the first 12 and the first 30 of its
candidate pool (random postures under the same filters). Every draw is one simulated truth
(``[perturbation] seed`` = the draw) and one noise draw, on the analytic path with dithered
read-back, calibrated by the board route as ``selfcal calibrate`` does
(:func:`selfcal.studies.montecarlo.run.draw_one`); the achieved error is the validation tool
tip's RMS after the best rigid alignment against the truth. Prints, per posture set, the
prediction (:func:`selfcal.calibration.board.plan.planner.predict_kept`) and the achieved median and
90th percentile, and their ratio (each draw also in ``DIR/draws.jsonl`` as it ends).
"""

from __future__ import annotations

import argparse
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.io.atomic import write_text_atomic

__all__ = ["BOARD_POSE", "KEEP_OUT", "arguments", "draw_all", "main", "posture_sets", "sets_of"]

BOARD_POSE = np.array([-472.0, -133.0, 3.0, 0.0, 0.0, 0.0])
"""mm, deg: docs/plan.md's board."""
KEEP_OUT = np.array([[-300.0, 50.0, 0.0, -100.0, 400.0, 600.0]])
"""mm: docs/plan.md's keep-out box."""


def posture_sets(count: int = 12, random_counts: tuple[int, ...] = (12, 30)) -> dict:
    """``{name: (q (m, n) rad, predicted tool-point RMS m)}``: the plan of ``count`` and the
    pool's first ``random_counts`` postures, and the setup's robot and camera."""
    from selfcal.calibration.board.plan.views import PlanSetup
    from selfcal.io.camera_file import camera_from_fov
    from selfcal.io.target_toml import load_board
    from selfcal.robot.definition import load_robot, models_dir
    from selfcal.target.placement import board_pose

    robot = load_robot("ur5e")
    board = load_board(models_dir() / "targets/charuco.toml")
    setup = PlanSetup(robot, camera_from_fov(60.0, 640, 480), board,
                      board_pose(board, BOARD_POSE[:3] / 1000.0), KEEP_OUT / 1000.0)  # fmt: skip
    return sets_of(setup, count, random_counts)


def sets_of(setup, count: int, random_counts: tuple[int, ...], pixel_sigma_px: float = 0.5) -> dict:
    """:func:`posture_sets` of any plan ``setup``
    (:class:`selfcal.calibration.board.plan.views.PlanSetup`, either mount): ``{"sets", "setup",
    "workspace"}``, planned and predicted for corners of ``pixel_sigma_px`` px noise and the
    robot file's joint read-back noise."""
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.plan.candidates import candidate_pool
    from selfcal.calibration.board.plan.information import board_model, frame_information
    from selfcal.calibration.board.plan.planner import plan_recording, predict_kept
    from selfcal.estimation.joint_report import aligned_tool_weight, encoder_sigma

    robot = setup.robot
    js = encoder_sigma(robot)
    plan = plan_recording(setup, count, seed=1, joint_sigma=js, pixel_sigma_px=pixel_sigma_px)
    pool, _ = candidate_pool(setup, 400, seed=1)
    G = aligned_tool_weight(board_model(setup), plan.workspace, setup.T_tool_tip)
    var = Deviation().variance(robot.joint_types)
    out = {f"plan {count}": (plan.q, plan.predicted_m)}
    for n in random_counts:
        q = pool[:n]
        F = frame_information(setup, q, plan.pixel_sigma_px, js).sum(axis=0)
        out[f"random {n}"] = (q, predict_kept(setup, q, F, G, var))
    return {"sets": out, "setup": setup, "workspace": plan.workspace}


def _draw(item: tuple[str, str, list, int]) -> tuple[str, int, float, str]:
    from selfcal.studies.montecarlo.run import draw_one

    name, config, joints_deg, seed = item
    row = draw_one({"config": config, "poses": len(joints_deg), "pixel_sigma": 0.5,
                    "seed": seed, "traj_seed": 1, "perturb_seed": seed, "dither": True,
                    "joints_deg": joints_deg})  # fmt: skip
    return name, seed, float(row.get("joint_tip_rms_mm") or np.nan), str(row["status"])


def arguments(
    argv: list[str] | None,
    doc: str,
    out: str,
    jobs: int,
    write_docs: bool = False,
    parents: tuple[argparse.ArgumentParser, ...] = (),
    *,
    module_file: str,
) -> argparse.Namespace:
    """A plan benchmark's ``--draws`` (30), ``--jobs`` (``jobs``) and ``--out`` (``out``),
    ``--write-docs`` where ``write_docs``, and the options of ``parents`` (parsers made with
    ``add_help=False``: the script's own); its usage names the module of ``module_file`` (the
    script's ``__file__``: :func:`selfcal.benchmarks.usage.benchmark_parser`)."""
    ap = benchmark_parser(module_file, description=doc.split("\n\n")[0], parents=list(parents))
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument("--jobs", type=int, default=jobs)
    ap.add_argument("--out", default=out)
    if write_docs:
        ap.add_argument("--write-docs", action="store_true", help="write the table into the docs")
    return ap.parse_args(argv)


def draw_all(
    draw: Callable[[Any], Any], items: list, jobs: int, root: Path, done: list | None = None
) -> list:
    """``draw`` of every item in ``jobs`` spawned processes, each row written to
    ``root/draws.jsonl`` as it ends (in the order they end) after the rows ``done`` before."""
    from multiprocessing import get_context

    rows: list = list(done or [])
    with get_context("spawn").Pool(jobs) as pool:
        for row in pool.imap_unordered(draw, items):
            rows.append(row)
            write_text_atomic(root / "draws.jsonl", "".join(json.dumps(r) + "\n" for r in rows))
    return rows


def main(argv: list[str] | None = None) -> int:
    """Draw and print the table."""
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.io.plan_files import joints_csv
    from selfcal.robot.definition import models_dir

    a = arguments(argv, __doc__ or "", "runs/plan-compare", 2, module_file=__file__)
    got = posture_sets()
    setup, sets = got["setup"], got["sets"]
    root = Path(a.out)
    items = []
    for name, (q, _) in sets.items():
        folder = root / name.replace(" ", "-")
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(models_dir() / "targets/charuco.toml", folder / "target.toml")
        write_text_atomic(folder / "joints.csv", joints_csv(q, setup.robot.edge_unit))
        write_text_atomic(
            folder / "scenario.toml", scenario_text("ur5e", setup.camera, BOARD_POSE, len(q))
        )
        deg = (q / setup.robot.edge_unit).tolist()
        items += [(name, str(folder / "scenario.toml"), deg, s) for s in range(1, a.draws + 1)]
    rows = draw_all(_draw, items, a.jobs, root)
    print("| postures | predicted (mm) | achieved median (mm) | 90th percentile | median / "
          "predicted | failed |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for name, (_, pred) in sets.items():
        e = np.array([r[2] for r in rows if r[0] == name and r[3] == "ok"])
        bad = sum(1 for r in rows if r[0] == name and r[3] != "ok")
        med, p90 = np.median(e), np.percentile(e, 90)
        print(f"| {name} | {pred * 1000:.3f} | {med:.3f} | {p90:.3f} | {med / (pred * 1000):.2f} "
              f"| {bad} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
