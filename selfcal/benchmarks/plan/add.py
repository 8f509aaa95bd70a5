"""``python -m selfcal.benchmarks.plan.add [--truths 6] [--add 5] [--jobs 2] [--out DIR]
[--write-docs]``:
``selfcal plan --add`` on a poorly identified dataset, simulated (docs/plan.md, issue #30).

For every truth (the scenario's ``[perturbation] seed``): a UR5e with a 60 deg wrist camera
records 12 postures that move only the wrist (the arm's first three joints at home, the board
on the table where home looks: as the Nachi groups of real data), ``selfcal run`` acquires and
calibrates them; ``selfcal plan --add K`` plans K postures for that dataset; the dataset's
postures and the added ones are acquired again in simulation with the same truth and
calibrated. A row: the predicted tool-point RMS before and after (``plan.json``) and the
achieved one (``report.json``'s validation tool tip against the simulated truth). Prints the
table and the medians of the before/after ratios; ``--write-docs`` puts them between
docs/plan.md's ``benchmark_plan_add_K`` markers (K the ``--add``).
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, print_table
from selfcal.io.atomic import write_text_atomic

__all__ = ["wrist_cell", "wrist_only_row", "main"]

WRIST_SPAN_DEG = (40.0, 40.0, 90.0)
"""How far the wrist's three joints move from home in the wrist-only dataset (deg)."""


def wrist_cell():
    """The benchmark's cell: a :class:`selfcal.calibration.board.plan.views.PlanSetup` (UR5e,
    60 deg 640 x 480 camera, the ChArUco board on the table where home looks), the target
    file and the board pose (mm, deg)."""
    from selfcal.calibration.board.plan.views import PlanSetup
    from selfcal.io.camera_file import camera_from_fov
    from selfcal.io.target_toml import load_target
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.kinematics.trajectory import home_target_center
    from selfcal.robot.definition import load_robot, models_dir
    from selfcal.target.placement import board_pose

    robot = load_robot("ur5e")
    cx, cy = home_target_center(robot, nominal_mcpc(robot).with_tool(robot.T_flange_cam))
    target = models_dir() / "targets/charuco.toml"
    board = load_target(target)
    bp = np.array([cx * 1000.0, cy * 1000.0, 3.0, 0.0, 0.0, 0.0])
    camera = camera_from_fov(60.0, 640, 480)
    return PlanSetup(robot, camera, board, board_pose(board, bp[:3] / 1000.0)), target, bp


def _write(folder: Path, setup, target: Path, bp: np.ndarray, joints: str, seed: int) -> Path:
    from selfcal.cli.plan_scenario import scenario_text

    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(target, folder / "target.toml")
    n = len((folder / joints).read_text().splitlines()) - 1
    write_text_atomic(folder / "scenario.toml",
                      scenario_text("ur5e", setup.camera, bp, n, joints=joints, seed=seed))  # fmt: skip
    return folder / "scenario.toml"


def _achieved(scenario: Path, out: Path) -> float:
    """``selfcal run``'s validation tool-tip RMS (mm); a run marked failed (worse than the
    nominal) still reports it."""
    from selfcal.cli.main import main as selfcal

    if not (out / "report.json").is_file():
        selfcal(["run", str(scenario), "--out", str(out), "--quiet"])
    rep = json.loads((out / "report.json").read_text())
    return float(rep["validation"]["tool_tip_error_mm"]["calibrated"]["rms"])


def wrist_only_row(root: Path, seed: int, add: int = 5) -> dict:
    """One truth (module docstring) in ``root``: predicted and achieved tool-point RMS (mm)
    before and after adding ``add`` postures, and the parameters each calibration kept."""
    from selfcal.calibration.board.plan.views import feasible
    from selfcal.cli.main import main as selfcal
    from selfcal.io.plan_files import joints_csv

    setup, target, bp = wrist_cell()
    robot = setup.robot
    rng = np.random.default_rng(seed)
    q = np.tile(robot.home, (4000, 1))
    q[:, 3:] += rng.uniform(-1, 1, size=(4000, 3)) * np.radians(WRIST_SPAN_DEG)
    q = q[feasible(setup, q)][:12]
    first = root / "wrist"
    first.mkdir(parents=True, exist_ok=True)
    write_text_atomic(first / "joints.csv", joints_csv(q, robot.edge_unit))
    before = _achieved(_write(first, setup, target, bp, "joints.csv", seed), root / "dataset")
    plan = root / "plan"
    if not (plan / "plan.json").is_file():
        selfcal(["plan", "--add", str(add), str(root / "dataset"), "--out", str(plan), "--quiet"])
    doc = json.loads((plan / "plan.json").read_text())
    second = root / "added"
    second.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(plan / "replay.csv", second / "replay.csv")
    after = _achieved(_write(second, setup, target, bp, "replay.csv", seed), root / "calibrated")
    kept = [len(json.loads((root / d / "calibration.json").read_text())["selection"]["identified"])
            for d in ("dataset", "calibrated")]  # fmt: skip
    return {"seed": seed, "frames": len(q), "predicted_before_mm": doc["predicted_before_tool_rms_mm"],
            "achieved_before_mm": before, "predicted_after_mm": doc["predicted_tool_rms_mm"],
            "achieved_after_mm": after, "kept_before": kept[0], "kept_after": kept[1]}  # fmt: skip


def _row(item: tuple[str, int, int]) -> dict:
    root, seed, add = item
    return wrist_only_row(Path(root) / f"truth{seed}", seed, add)


def main(argv: list[str] | None = None) -> int:
    """Run the truths and print the table."""
    from multiprocessing import get_context

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--truths", type=int, default=6)
    ap.add_argument("--add", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="runs/plan-add")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the table of this --add in docs/plan.md")  # fmt: skip
    a = ap.parse_args(argv)
    items = [(a.out, s, a.add) for s in range(1, a.truths + 1)]
    with get_context("spawn").Pool(a.jobs) as pool:
        rows = pool.map(_row, items)
    lines = ["| truth | frames | predicted before -> after (mm) | achieved before -> after (mm) "
             "| parameters kept |", "|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        lines.append(f"| {r['seed']} | {r['frames']} + {a.add} | {r['predicted_before_mm']:.3f} -> "
                     f"{r['predicted_after_mm']:.3f} | {r['achieved_before_mm']:.3f} -> "
                     f"{r['achieved_after_mm']:.3f} | {r['kept_before']} -> {r['kept_after']} |")  # fmt: skip
    pr = np.median([r["predicted_before_mm"] / r["predicted_after_mm"] for r in rows])
    ac = np.median([r["achieved_before_mm"] / r["achieved_after_mm"] for r in rows])
    fit = np.median([r["achieved_after_mm"] / r["predicted_after_mm"] for r in rows])
    lines += ["", f"Median ratio before/after: predicted {pr:.2f}, achieved {ac:.2f}; "
              f"achieved/predicted after {fit:.2f} (`python -m selfcal.benchmarks.plan.add "
              f"--truths {a.truths} --add {a.add} --write-docs`)."]  # fmt: skip
    return print_table("\n".join(lines), ROOT / "docs" / "plan.md",
                       f"benchmark_plan_add_{a.add}", write=a.write_docs)  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
