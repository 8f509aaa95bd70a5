"""``python -m selfcal.benchmarks.plan.add [--truths 6] [--add 5] [--mount eye-in-hand|eye-to-hand]
[--jobs 2] [--out DIR] [--write-docs]``:
``selfcal plan --add`` on a poorly identified dataset, simulated (docs/plan.md, issue #30).

For every truth (the scenario's ``[perturbation] seed``): a UR5e with a 60 deg wrist camera
records 12 postures that move only the wrist (the arm's first three joints at home, the board
on the table where home looks: as the Nachi groups of real data), ``selfcal run`` acquires and
calibrates them; ``selfcal plan --add K`` plans K postures for that dataset; the dataset's
postures and the added ones are acquired again in simulation with the same truth and
calibrated. A row: the predicted tool-point RMS before and after (``plan.json``), the median
after of its forecast's draws (the selection deciding in each: ``forecast_draws``), the
achieved one (``report.json``'s validation tool tip against the simulated truth), the
kinematic parameters each calibration estimated beyond the placement (as ``plan --add`` counts
them: :func:`kept_beyond_placement`) and how many postures ``plan.json`` predicts to halve the error
(``halved_with``: K or more, planned as K is, by the medians of the forecast's draws). Prints the table, the medians of the before/after
ratios (the achieved ratio's quartiles and range) and in how many truths K are predicted to
halve it; ``--write-docs`` puts them between
docs/plan.md's ``benchmark_plan_add_K`` markers (K the ``--add``).

``--mount eye-to-hand`` (:func:`still_camera_row`): the nominal cell of
``scenarios/eye-to-hand.toml`` (:func:`still_cell`: the UR5e, the ChArUco on its flange, a
900 px 640 x 480 camera still 0.6 m in front of the board at the cell's home) records
:data:`STILL_POSTURES` postures of one arm configuration (the wrist alone moves, as the
scenario's own postures are planned: :func:`selfcal.sim.static_camera.plan_static_postures`
with one configuration); the arm drawn within the plan's default deviation (1 mm, 0.5 deg);
the rest as above, and the achieved error is the quantity the plan predicts: the flange centre over the same 50 workspace postures before and after (the plan's
workspace sample of the nominal cell, seed 2) after the best rigid alignment, against the
truth (:func:`selfcal.pipeline.static_report.flange_centre_errors`). Markers
``benchmark_plan_add_e2h_K``. On either mount a truth whose calibration or plan stops with an
error (a wrist-only draw with fewer feasible postures than ``selfcal run`` takes, say) is a row
that says so, left out of the medians.

A truth's folder is reused (a stopped run goes on, ``--write-docs`` tables a finished one) only
when its ``benchmark.json`` names this run's ``--add``, mount and code, a clean commit
(:func:`selfcal.benchmarks.doc_blocks.code_version`); any other folder is measured anew, so a
table never holds rows of another K or of other code.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, code_version, print_table
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.choices import SETUPS
from selfcal.io.atomic import write_text_atomic

__all__ = ["STILL_POSTURES", "fresh_truth", "kept_beyond_placement", "still_camera_row",
           "wrist_cell", "wrist_only_row", "main"]  # fmt: skip

WRIST_SPAN_DEG = (40.0, 40.0, 90.0)
"""How far the wrist's three joints move from home in the wrist-only dataset (deg)."""
STILL_POSTURES = 12
"""Eye-to-hand: the postures of the one arm configuration of the dataset."""


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


def _write(folder: Path, setup, target: Path, pose: np.ndarray, joints: str, seed: int) -> Path:
    """The scenario replaying ``joints`` in ``folder``: the board at ``pose`` (mm, deg) or,
    eye-to-hand, the camera there."""
    from selfcal.cli.plan_scenario import scenario_text

    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(target, folder / "target.toml")
    n = len((folder / joints).read_text().splitlines()) - 1
    e2h = setup.eye_to_hand
    write_text_atomic(folder / "scenario.toml", scenario_text(
        "ur5e", setup.camera, None if e2h else pose, n, joints=joints, seed=seed,
        camera_pose=pose if e2h else None))  # fmt: skip
    return folder / "scenario.toml"


def _achieved(scenario: Path, out: Path) -> float | None:
    """``selfcal run``'s validation tool-tip RMS (mm); a run marked failed (worse than the
    nominal) still reports it; None when the run stopped before its report (the scenario
    refused, say: its error is on stderr)."""
    from selfcal.cli.main import main as selfcal

    if not (out / "report.json").is_file():
        selfcal(["run", str(scenario), "--out", str(out), "--quiet"])
    if not (out / "report.json").is_file():
        return None
    rep = json.loads((out / "report.json").read_text())
    return float(rep["validation"]["tool_tip_error_mm"]["calibrated"]["rms"])


def wrist_only_row(root: Path, seed: int, add: int = 5) -> dict:
    """One truth (module docstring) in ``root``: predicted and achieved tool-point RMS (mm)
    before and after adding ``add`` postures, and the parameters each calibration kept;
    ``error`` says why a step stopped (a draw with fewer feasible postures than ``selfcal run``
    takes, say; the figures it would have given NaN), as :func:`still_camera_row`."""
    from selfcal.calibration.board.plan.feasible import feasible
    from selfcal.cli.main import main as selfcal
    from selfcal.io.plan_files import joints_csv, read_plan

    setup, target, bp = wrist_cell()
    robot = setup.robot
    rng = np.random.default_rng(seed)
    q = np.tile(robot.home, (4000, 1))
    q[:, 3:] += rng.uniform(-1, 1, size=(4000, 3)) * np.radians(WRIST_SPAN_DEG)
    q = q[feasible(setup, q)][:12]
    nan = float("nan")
    row: dict = {"seed": seed, "frames": len(q), "error": "", "halved_with": ""}
    row |= dict.fromkeys(("predicted_before_mm", "achieved_before_mm", "predicted_after_mm",
                          "drawn_after_mm", "achieved_after_mm", "kept_before", "kept_after"),
                         nan)  # fmt: skip
    first = root / "wrist"
    first.mkdir(parents=True, exist_ok=True)
    write_text_atomic(first / "joints.csv", joints_csv(q, robot.edge_unit))
    before = _achieved(_write(first, setup, target, bp, "joints.csv", seed), root / "dataset")
    if before is None:
        return row | {"error": f"the dataset's {len(q)} postures: selfcal run stopped"}
    row |= {"achieved_before_mm": before,
            "kept_before": kept_beyond_placement(root / "dataset")}  # fmt: skip
    plan = root / "plan"
    if not (plan / "plan.json").is_file():
        selfcal(["plan", "--add", str(add), str(root / "dataset"), "--out", str(plan), "--quiet"])
    if not (plan / "plan.json").is_file():
        return row | {"error": "selfcal plan --add stopped"}
    doc = read_plan(plan / "plan.json", ("add",))
    row |= {"predicted_before_mm": doc["predicted_before_tool_rms_mm"],
            "predicted_after_mm": doc["predicted_tool_rms_mm"],
            "drawn_after_mm": doc["forecast_draws"]["after"]["median_mm"],
            "halved_with": _halved(doc)}  # fmt: skip
    second = root / "added"
    second.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(plan / "replay.csv", second / "replay.csv")
    after = _achieved(_write(second, setup, target, bp, "replay.csv", seed), root / "calibrated")
    if after is None:
        return row | {"error": "the calibration with the added postures stopped (selfcal run)"}
    return row | {"achieved_after_mm": after,
                  "kept_after": kept_beyond_placement(root / "calibrated")}  # fmt: skip


def _flange_rms(run: Path, qw: np.ndarray) -> float:
    """The flange centre's RMS error (mm) over ``qw`` (w, n) rad of the eye-to-hand
    calibration in ``run`` against its truth, after the best rigid alignment."""
    from selfcal.io.board_calibration import read_board_calibration
    from selfcal.io.truth import read_truth
    from selfcal.pipeline.static_report import flange_centre_errors
    from selfcal.robot.definition import load_robot
    from selfcal.transforms import inv_pose

    cal, truth = read_board_calibration(run), read_truth(run / "truth.json")
    assert truth.board is not None
    chain = truth.true_model.with_base(inv_pose(np.asarray(truth.board["T_world_cam"])))
    return flange_centre_errors(cal.model, chain, truth.board["T_flange_board"],
                                load_robot("ur5e"), qw)["rms"]  # fmt: skip


def still_cell():
    """The eye-to-hand benchmark's cell: a :class:`selfcal.calibration.board.plan.views.PlanSetup`
    (UR5e, the ChArUco on its flange, a 900 px 640 x 480 camera 0.6 m in front of the board at
    the cell's home: the nominal cell of ``scenarios/eye-to-hand.toml``,
    :func:`selfcal.sim.static_camera.static_camera_truth`), the simulator's nominal cell, the
    target file and the camera's pose (mm, deg)."""
    from selfcal.calibration.board.plan.views import PlanSetup
    from selfcal.camera import Intrinsics
    from selfcal.io.target_toml import load_target
    from selfcal.robot.definition import load_robot, models_dir
    from selfcal.sim.static_camera import static_camera_truth
    from selfcal.target.placement import camera_pose_values

    robot = load_robot("ur5e")
    target = models_dir() / "targets/charuco.toml"
    board = load_target(target)
    camera = Intrinsics.centered(900.0, 1.0, 640, 480)
    cell = static_camera_truth(robot, board, camera, translation_m=0.0, rotation_rad=0.0)
    centre, rpy = camera_pose_values(cell.T_base_cam)
    pose = np.concatenate([centre * 1000.0, np.degrees(rpy)])
    setup = PlanSetup.eye_to_hand_setup(robot, camera, board, cell.T_base_cam,
                                        cell.T_flange_board_nominal)  # fmt: skip
    return setup, cell, target, pose


def still_camera_row(root: Path, seed: int, add: int = 5) -> dict:
    """One eye-to-hand truth (module docstring) in ``root``: as :func:`wrist_only_row`, the
    achieved errors over the plan's workspace sample; ``error`` says why a calibration
    stopped (the figures it would have given NaN)."""
    from selfcal.calibration.board.plan.ground import workspace_sample
    from selfcal.cli.main import main as selfcal
    from selfcal.io.plan_files import joints_csv, read_plan
    from selfcal.sim.static_camera import plan_static_postures

    setup, cell, target, pose = still_cell()
    qw = workspace_sample(setup, 50, seed=2)
    q = plan_static_postures(cell, 1, STILL_POSTURES, seed=seed)
    nan = float("nan")
    row: dict = {"seed": seed, "frames": len(q), "error": "", "halved_with": ""}
    row |= dict.fromkeys(("predicted_before_mm", "achieved_before_mm", "predicted_after_mm",
                          "drawn_after_mm",
                          "achieved_after_mm", "kept_before", "kept_after"), nan)  # fmt: skip
    first = root / "wrist"
    first.mkdir(parents=True, exist_ok=True)
    write_text_atomic(first / "joints.csv", joints_csv(q, setup.robot.edge_unit))
    scenario = _write(first, setup, target, pose, "joints.csv", seed)
    if not (root / "dataset/calibration.json").is_file():
        selfcal(["run", str(scenario), "--out", str(root / "dataset"), "--quiet"])
    if not (root / "dataset/calibration.json").is_file():
        return row | {"error": "the dataset's calibration stopped (selfcal run)"}
    row |= {"achieved_before_mm": _flange_rms(root / "dataset", qw),
            "kept_before": kept_beyond_placement(root / "dataset")}  # fmt: skip
    plan = root / "plan"
    if not (plan / "plan.json").is_file():
        selfcal(["plan", "--add", str(add), str(root / "dataset"), "--out", str(plan), "--quiet"])
    if not (plan / "plan.json").is_file():
        return row | {"error": "selfcal plan --add stopped"}
    doc = read_plan(plan / "plan.json", ("add",))
    row |= {"predicted_before_mm": doc["predicted_before_tool_rms_mm"],
            "predicted_after_mm": doc["predicted_tool_rms_mm"],
            "drawn_after_mm": doc["forecast_draws"]["after"]["median_mm"],
            "halved_with": _halved(doc)}  # fmt: skip
    second = root / "added"
    second.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(plan / "replay.csv", second / "replay.csv")
    scenario = _write(second, setup, target, pose, "replay.csv", seed)
    if not (root / "calibrated/calibration.json").is_file():
        selfcal(["run", str(scenario), "--out", str(root / "calibrated"), "--quiet"])
    if not (root / "calibrated/calibration.json").is_file():
        return row | {"error": "the calibration with the added postures stopped (selfcal run)"}
    return row | {"achieved_after_mm": _flange_rms(root / "calibrated", qw),
                  "kept_after": kept_beyond_placement(root / "calibrated")}  # fmt: skip


def _halved(doc: dict) -> str:
    """How many postures ``plan.json`` predicts to halve the error: a count, or none up to the
    largest tried."""
    h = doc["halved_with"]
    return str(h["count"]) if h["count"] is not None else f"none up to {h['tried_up_to']}"


def kept_beyond_placement(run: Path) -> int:
    """How many kinematic parameters the board calibration in ``run`` estimated beyond its
    placement (:func:`selfcal.calibration.board.nominal_fit.beyond_placement`): the count
    ``selfcal calibrate``'s line and ``selfcal plan --add``'s give (its ``kinematic_parameters``
    before and after), the placement's 12 (board pose and hand-eye) not counted."""
    from selfcal.calibration.board.bounds import estimated_parameters
    from selfcal.calibration.board.nominal_fit import beyond_placement
    from selfcal.io.board_calibration import read_board_calibration

    cal = read_board_calibration(run)
    return beyond_placement(*estimated_parameters(cal), cal.model.n)


def fresh_truth(root: Path, add: int, mount: str) -> None:
    """Make ``root`` a truth's folder for ``--add add`` on ``mount`` with this code: kept when
    its ``benchmark.json`` says so and the code is a clean commit, else emptied (its plan and
    calibrations were made for another K, mount or code, or by uncommitted code that need not be
    this), and the stamp written."""
    stamp = {"add": add, "mount": mount, "code": code_version()}
    file = root / "benchmark.json"
    clean = stamp["code"] is not None and not str(stamp["code"]).endswith("+changes")
    if root.exists() and not (clean and file.is_file() and json.loads(file.read_text()) == stamp):
        shutil.rmtree(root)
    root.mkdir(parents=True, exist_ok=True)
    write_text_atomic(file, json.dumps(stamp) + "\n")


def _row(item: tuple[str, int, int, str]) -> dict:
    root, seed, add, mount = item
    folder = Path(root) / f"truth{seed}"
    fresh_truth(folder, add, mount)
    if mount == "eye-to-hand":
        return still_camera_row(folder, seed, add)
    return wrist_only_row(folder, seed, add)


def main(argv: list[str] | None = None) -> int:
    """Run the truths and print the table."""
    from multiprocessing import get_context

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--truths", type=int, default=6)
    ap.add_argument("--add", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--mount", default="eye-in-hand", choices=SETUPS,
                    help="the wrist camera's dataset (default) or the still camera's")  # fmt: skip
    ap.add_argument("--out", default=None, help="default runs/plan-add-K, runs/plan-add-e2h-K")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the table of this --add (and mount) in docs/plan.md")  # fmt: skip
    a = ap.parse_args(argv)
    e2h = a.mount == "eye-to-hand"
    out = a.out or (f"runs/plan-add-e2h-{a.add}" if e2h else f"runs/plan-add-{a.add}")
    items = [(out, s, a.add, a.mount) for s in range(1, a.truths + 1)]
    with get_context("spawn").Pool(a.jobs) as pool:
        rows = pool.map(_row, items)
    lines = ["| truth | frames | predicted before -> after (mm) | draws' median after (mm) "
             "| achieved before -> after (mm) | parameters beyond the placement estimated "
             "| postures predicted to halve |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        kept = (f"{r['kept_before']} -> {r['kept_after']}" if not r.get("error") else
                f"{r['error']}")  # fmt: skip
        lines.append(f"| {r['seed']} | {r['frames']} + {a.add} | {r['predicted_before_mm']:.3f} -> "
                     f"{r['predicted_after_mm']:.3f} | {r['drawn_after_mm']:.3f} | "
                     f"{r['achieved_before_mm']:.3f} -> {r['achieved_after_mm']:.3f} | {kept} | "
                     f"{r['halved_with']} |")  # fmt: skip
    ok = [r for r in rows if not r.get("error")]
    pr = np.median([r["predicted_before_mm"] / r["predicted_after_mm"] for r in ok])
    dr = np.median([r["predicted_before_mm"] / r["drawn_after_mm"] for r in ok])
    ratios = np.array([r["achieved_before_mm"] / r["achieved_after_mm"] for r in ok])
    ac = np.median(ratios)
    q1, q3 = np.percentile(ratios, [25, 75])
    halved = sum(r["halved_with"] == str(a.add) for r in ok)
    fit = np.median([r["achieved_after_mm"] / r["predicted_after_mm"] for r in ok])
    of = f" of the {len(ok)} truths that calibrated" if len(ok) < len(rows) else ""
    mount = " --mount eye-to-hand" if e2h else ""
    lines += ["", f"Median ratio before/after{of}: predicted {pr:.2f} (the first line's before "
              f"to the draws' median after {dr:.2f}), achieved {ac:.2f} (quartiles {q1:.2f} - {q3:.2f}, {ratios.min():.2f} - "
              f"{ratios.max():.2f} in all); predicted halved by {a.add} postures (the draws' "
              f"medians) in {halved} of "
              f"{len(ok)}; "
              f"achieved/predicted after {fit:.2f} (`python -m selfcal.benchmarks.plan.add "
              f"--truths {a.truths} --add {a.add}{mount} --write-docs`)."]  # fmt: skip
    marker = f"benchmark_plan_add_{'e2h_' if e2h else ''}{a.add}"
    return print_table("\n".join(lines), ROOT / "docs" / "plan.md", marker, write=a.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
