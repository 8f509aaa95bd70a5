"""``python -m selfcal.benchmarks.plan.robots [--robot R ...] [--render] [--draws 30] [--first-seed 1] [--jobs 1]
[--sets SET ...] [--pixel-sigma PX] [--min-pitch-px PX --max-tilt-deg DEG] [--from-draws]
[--block NAME] [--write-docs]``: the postures of ``selfcal plan`` against random ones on every
simulated robot, achieved in simulation on the analytic or the rendered path (docs/plan.md,
issue #30).

Each robot's cell is laid out like docs/plan.md's UR5e example (:func:`cell_values`): the 60 deg
640 x 480 wrist camera of the robot file's ``[camera_mount]``, the ChArUco (the example's, or
one of larger markers where the camera cannot see the example's: :data:`CELL_TARGETS`) printed
face up on the table (3 mm thick) where the home posture's optical axis meets it, and one
keep-out box of the example's size placed about the base as the example's lies about its board.
Per cell: the
plan of 12 and the first 12 and 30 of its candidate pool (random postures under the same
filters; :func:`selfcal.benchmarks.plan.compare.sets_of`), each replayed in ``--draws``
simulated draws as :mod:`selfcal.benchmarks.plan.compare` does (one truth ``[perturbation]
seed`` = the draw and one noise draw each, dithered read-back, calibrated by the board route as
``selfcal calibrate`` does; :func:`selfcal.studies.montecarlo.run.draw_one`). ``--render``
renders every posture with MuJoCo and detects the board in the images, as ``selfcal run`` with
``[noise] render = true`` does, instead of projecting the corners with 0.5 px of noise; the
table counts the frames in which every corner of the board was found. The achieved error is
the validation tool tip's RMS after the best rigid alignment against the truth; the prediction
is the plan's (:func:`selfcal.calibration.board.plan.planner.predict_kept`), for ``--pixel-sigma`` of
corner noise (0.5 px; the plan is made for it too), with the view rule ``selfcal plan`` uses
unless ``--min-pitch-px``/``--max-tilt-deg`` say otherwise. The table also gives, per set, how
many calibrations held parameters the plan's rank test keeps (their cross-validation decides)
and the prediction with each draw's held parameters held. Draws go to ``OUT/PATH/draws.jsonl``
as they end, the plan's first, seed by seed; a stopped run resumes, and ``--from-draws`` tables
what is there.
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, print_table
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.io.atomic import write_text_atomic

__all__ = [
    "CELL_TARGETS",
    "ROBOTS",
    "Forecast",
    "forecast_spread",
    "cell",
    "cell_target",
    "cell_values",
    "main",
    "parser",
    "table",
]

ROBOTS = ("ur5e", "er4u-paper", "kr6-r900")
"""The simulated robots, docs/plan.md's example first."""
EXAMPLE_BOARD_XY = np.array([-472.0, -133.0])
"""mm: where the UR5e example's board lies (where its home posture looks)."""
EXAMPLE_BOX = np.array([-300.0, 50.0, 0.0, -100.0, 400.0, 600.0])
"""mm: the UR5e example's keep-out box."""
BOARD_THICKNESS_MM = 3.0
"""The board's centre height on the table (its thickness)."""
CELL_TARGETS = {"er4u-paper": "charuco-a3.toml"}
"""The boards of cells whose 640 x 480 camera cannot see the example's ChArUco's marker cells
(2.1 mm) at 2.5 px from a posture that reaches (the ER-4u's board lies 650 mm from its base:
2.1 px at most): an A3 board of 5 mm cells (``models/targets/``)."""


def cell_values(robot) -> tuple[np.ndarray, np.ndarray]:
    """Board pose (6,) mm, deg and keep-out box (1, 6) mm of ``robot``'s cell: the board face up
    where the home posture's optical axis meets the table (rounded to 1 mm), the box of the UR5e
    example's size with its centre turned about the base's z axis by the angle between the
    example's board direction and this one and scaled by their distances' ratio (rounded to
    5 mm); for the UR5e this is the example's cell."""
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.kinematics.trajectory import home_target_center

    xy = np.round(1000.0 * np.array(
        home_target_center(robot, nominal_mcpc(robot).with_tool(robot.T_flange_cam))))  # fmt: skip
    turn = np.arctan2(xy[1], xy[0]) - np.arctan2(EXAMPLE_BOARD_XY[1], EXAMPLE_BOARD_XY[0])
    scale = np.linalg.norm(xy) / np.linalg.norm(EXAMPLE_BOARD_XY)
    c, s = np.cos(turn), np.sin(turn)
    lo, hi = EXAMPLE_BOX[:3], EXAMPLE_BOX[3:]
    mid = (lo[:2] + hi[:2]) / 2.0
    centre = np.round(scale * np.array([[c, -s], [s, c]]) @ mid / 5.0) * 5.0
    half = (hi[:2] - lo[:2]) / 2.0
    box = np.concatenate([centre - half, [lo[2]], centre + half, [hi[2]]])
    return np.array([xy[0], xy[1], BOARD_THICKNESS_MM, 0.0, 0.0, 0.0]), box[None, :]


def cell_target(name: str) -> Path:
    """The printed board of robot ``name``'s cell: :data:`CELL_TARGETS`'s, else the UR5e
    example's ChArUco (``models/targets/charuco.toml``)."""
    from selfcal.robot.definition import models_dir

    return models_dir() / "targets" / CELL_TARGETS.get(name, "charuco.toml")


def cell(name: str, rule=None):
    """``(setup, board_pose (6,) mm deg, keep_out (1, 6) mm)`` of robot ``name``'s cell
    (:func:`cell_values`, :func:`cell_target`): a
    :class:`selfcal.calibration.board.plan.views.PlanSetup` with the view ``rule``
    (:class:`selfcal.calibration.board.plan.views.ViewRule`; None: ``selfcal plan``'s)."""
    from selfcal.calibration.board.plan.views import PlanSetup, ViewRule
    from selfcal.io.camera_file import camera_from_fov
    from selfcal.io.target_toml import load_board
    from selfcal.robot.definition import load_robot
    from selfcal.target.placement import board_pose

    robot = load_robot(name)
    bp, box = cell_values(robot)
    board = load_board(cell_target(name))
    setup = PlanSetup(robot, camera_from_fov(60.0, 640, 480), board,
                      board_pose(board, bp[:3] / 1000.0), box / 1000.0,
                      rule or ViewRule())  # fmt: skip
    return setup, bp, box


def _draw(item: tuple[str, str, str, list, int, bool, float]) -> dict:
    from selfcal.studies.montecarlo.run import draw_one

    robot, name, config, joints_deg, seed, render, sigma = item
    row = draw_one({"config": config, "poses": len(joints_deg), "pixel_sigma": sigma,
                    "seed": seed, "traj_seed": 1, "perturb_seed": seed, "dither": True,
                    "joints_deg": joints_deg, "render": render})  # fmt: skip
    return {"robot": robot, "set": name, "seed": seed, "render": render,
            "tip_mm": row.get("joint_tip_rms_mm"), "frames": row.get("frames"),
            "whole": row.get("frames_whole"), "sigma_px": row.get("sigma_hat_px"),
            "held": sorted(k[5:] for k, v in row.items() if k.startswith("held_") and v),
            "status": str(row["status"]),
            "seconds": row["seconds"]}  # fmt: skip


def _items(robot: str, root: Path, render: bool, seeds: range, sets: tuple[str, ...], sigma: float,
           rule):  # fmt: skip
    """The draws of ``robot``'s cell, one per set and seed of ``seeds`` (scenarios written under
    ``root``), the forecasts (mm, :class:`Forecast`)
    of the posture sets planned for ``sigma`` px of corner noise, and per set a function of a
    calibration's held parameter names giving the prediction with those held too
    (:func:`_held_prediction`)."""
    from selfcal.benchmarks.plan.compare import sets_of
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.io.plan_files import joints_csv

    setup, bp, _ = cell(robot, rule)
    got = sets_of(setup, 12, (12, 30), pixel_sigma_px=sigma)
    items, predicted, held = [], {}, {}
    for name, (q, pred) in got["sets"].items():
        if name not in sets:
            continue
        predicted[name] = Forecast(
            pred * 1000.0, *forecast_spread(setup, q, got["workspace"], sigma)
        )
        held[name] = _held_prediction(setup, q, got["workspace"], sigma)
        folder = root / robot / name.replace(" ", "-")
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(cell_target(robot), folder / "target.toml")
        write_text_atomic(folder / "joints.csv", joints_csv(q, setup.robot.edge_unit))
        write_text_atomic(folder / "scenario.toml", scenario_text(robot, setup.camera, bp, len(q)))
        deg = (q / setup.robot.edge_unit).tolist()
        cfg = str(folder / "scenario.toml")
        items += [(robot, name, cfg, deg, s, render, sigma) for s in seeds]
    return items, predicted, held


@dataclass(frozen=True)
class Forecast:
    """A posture set's forecast (mm): ``mean`` the plan's prediction (every parameter the rank
    test keeps), ``median`` and ``p90`` those of the calibration's error over arms and noise
    draws with its selection drawn in each, and ``smaller`` the share of those draws whose
    selection kept fewer parameters than its largest candidate
    (:func:`selfcal.calibration.board.plan.spread.selection_spread`)."""

    mean: float
    median: float
    p90: float
    smaller: float


def forecast_spread(setup, q: np.ndarray, workspace: np.ndarray, sigma: float) -> tuple[float, ...]:
    """(median mm, 90th percentile mm, share of draws keeping a smaller set) of the
    linearised draws of the calibration at the postures ``q``, its selection drawn in each."""
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.plan.information import board_model
    from selfcal.calibration.board.plan.spread import plan_spread
    from selfcal.estimation.joint_report import aligned_tool_weight, encoder_sigma

    model = board_model(setup)
    G = aligned_tool_weight(model, workspace, setup.T_tool_tip)
    var = Deviation().variance(setup.robot.joint_types)
    sp = plan_spread(setup, q, G, var, sigma, encoder_sigma(setup.robot), seed=1)
    smaller = 1.0 - sp.kept_share(len(sp.labels) - 1)
    return 1000.0 * sp.percentile(50), 1000.0 * sp.percentile(90), smaller


def _held_prediction(setup, q: np.ndarray, workspace: np.ndarray, sigma: float):
    """``f(held names) -> mm``: the plan's prediction for the postures ``q`` with the
    parameters the rank test keeps less those a calibration held (its joint offsets as the rank
    test keeps them: a draw's row names only the minimal parameters held)."""
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.plan.information import board_model, frame_information
    from selfcal.calibration.board.plan.planner import predict_kept
    from selfcal.calibration.board.plan.predict import kept_by_rank
    from selfcal.estimation.joint_report import aligned_tool_weight, encoder_sigma
    from selfcal.kinematics.mcpc import param_names

    js = encoder_sigma(setup.robot)
    model = board_model(setup)
    F = frame_information(setup, q, sigma, js).sum(axis=0)
    G = aligned_tool_weight(model, workspace, setup.T_tool_tip)
    var = Deviation().variance(setup.robot.joint_types)
    free, offsets = kept_by_rank(model, q)
    cache: dict = {}

    def predict(held: list[str]) -> float:
        key = tuple(sorted(held))
        if key not in cache:
            keep = free[~np.isin(param_names(free), key)]
            cache[key] = 1000.0 * predict_kept(setup, q, F, G, var, kept=(keep, offsets))
        return cache[key]

    return predict


def table(rows: list[dict], predicted: dict, held: dict) -> str:
    """The markdown table of the draws ``rows`` (:func:`_draw`'s), the forecasts
    ``{(robot, set): Forecast}`` (mm) and the predictions with each draw's held parameters
    ``{(robot, set): f(held names) -> mm}``, with a closing line on issue #30's three criteria
    per robot."""
    head = ("| robot | path | postures | predicted (mm) | achieved median (mm) | 90th percentile | "
            "median / predicted | forecast median / 90th, selection drawn (mm) | "
            "failed | frames with every corner | corner noise (px) | "
            "held more than the rank test | forecast: a smaller set kept | "
            "predicted with the held (median) | achieved / that (median) |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")  # fmt: skip
    lines, stats = [head], {}
    for (robot, name), fc in predicted.items():
        pred = fc.mean
        mine = [r for r in rows if r["robot"] == robot and r["set"] == name]
        if not mine:
            continue
        path = "rendered" if mine and mine[0]["render"] else "analytic"
        e = np.array([r["tip_mm"] for r in mine if r["status"] == "ok"], dtype=float)
        med, p90 = (np.median(e), np.percentile(e, 90)) if len(e) else (np.nan, np.nan)
        whole = sum(int(r["whole"] or 0) for r in mine if r["status"] == "ok")
        frames = sum(int(r["frames"] or 0) for r in mine if r["status"] == "ok")
        stats[robot, name] = (med, p90, med / pred, whole, frames, fc)
        # the calibration's corner noise: its reprojection RMS over sqrt(2), median of the draws
        noise = np.median([r["sigma_px"] for r in mine if r["status"] == "ok"] or [np.nan])
        # the prediction with the parameters each calibration held (draws that name them), and
        # each draw's achieved error over it; the draws holding more than the rank test
        ok = [r for r in mine if r["status"] == "ok" and "held" in r]
        ph = np.array([held[robot, name](r["held"]) for r in ok])
        ratio = np.median([r["tip_mm"] for r in ok] / ph) if len(ok) else np.nan
        more = int(np.sum(ph > pred * (1 + 1e-9)))
        lines.append(f"| {robot} | {path} | {name} | {pred:.3f} | {med:.3f} | {p90:.3f} | "
                     f"{med / pred:.2f} | {fc.median:.3f} / {fc.p90:.3f} | "
                     f"{len(mine) - len(e)} of {len(mine)} | "
                     f"{whole} of {frames} | {noise:.3f} | {more} of {len(ok)} | "
                     f"{100 * fc.smaller:.0f} % | "
                     f"{np.median(ph) if len(ok) else np.nan:.3f} | {ratio:.2f} |")  # fmt: skip
    verdict = {True: "met", False: "NOT met"}
    for robot in dict.fromkeys(r for r, _ in predicted):
        p, r30 = stats.get((robot, "plan 12")), stats.get((robot, "random 30"))
        if p is None:
            continue
        parts = [f"every frame of the plan's draws with every corner {p[3]} of {p[4]} "
                 f"({verdict[p[3] == p[4]]})"]  # fmt: skip
        if r30 is not None:  # a set with draws; its frames must satisfy the same view rule
            parts.append(f"of the random 30's {r30[3]} of {r30[4]} ({verdict[r30[3] == r30[4]]})")
            parts.append(
                f"plan 12 against random 30 at the median {p[0]:.3f} / {r30[0]:.3f} mm "
                f"({verdict[bool(p[0] <= r30[0])]}) and the 90th percentile {p[1]:.3f} / "
                f"{r30[1]:.3f} mm ({verdict[bool(p[1] <= r30[1])]})"
            )
        inside = bool(0.7 <= 1.0 / p[2] <= 1.4)
        parts.append(f"predicted / achieved median {1.0 / p[2]:.2f} ({verdict[inside]}: 0.7-1.4)")
        if r30 is not None:  # what the forecast with the selection drawn expected
            parts.append(f"forecast with the selection drawn, plan 12 against random 30: median "
                         f"{p[5].median:.3f} / {r30[5].median:.3f} mm, 90th percentile "
                         f"{p[5].p90:.3f} / {r30[5].p90:.3f} mm")  # fmt: skip
        lines.append(f"\n{robot}: " + "; ".join(parts) + ".")
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    """The command line of :func:`main` (also how
    :mod:`selfcal.benchmarks.plan.robots_forecast` reads a docs block's command back)."""
    from selfcal.calibration.board.plan.views import ViewRule

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    ap.add_argument("--render", action="store_true", help="rendered and detected images")
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument(
        "--first-seed",
        type=int,
        default=1,
        help="the draws' seeds are this .. this + draws - 1 (a second seed set: 31)",
    )
    ap.add_argument("--sets", nargs="+", default=["plan 12", "random 12", "random 30"],
                    choices=["plan 12", "random 12", "random 30"])  # fmt: skip
    ap.add_argument(
        "--pixel-sigma",
        type=float,
        default=0.5,
        help="corner noise the plan assumes (px; analytic: also the noise drawn)",
    )
    ap.add_argument(
        "--min-pitch-px",
        type=float,
        default=ViewRule.min_pitch_px,
        help="the view rule's shortest feature pitch (selfcal plan's by default)",
    )
    ap.add_argument(
        "--max-tilt-deg",
        type=float,
        default=ViewRule.max_tilt_deg,
        help="the view rule's largest board tilt (selfcal plan's by default)",
    )
    ap.add_argument(
        "--min-module-px",
        type=float,
        default=ViewRule.min_module_px,
        help="the view rule's shortest marker cell (selfcal plan's by default)",
    )
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument(
        "--from-draws",
        action="store_true",
        help="table the draws of OUT's draws.jsonl instead of drawing",
    )
    ap.add_argument("--out", default="runs/plan-robots",
                    help="the scenarios and draws.jsonl, under PATH[-NOISE][-RULE]/ (the docs "
                         "block's name too); a run resumes its draws")  # fmt: skip
    ap.add_argument("--block", default=None,
                    help="the docs block's name after benchmark_plan_robots_ (default: the "
                         "run's folder, PATH[-NOISE][-RULE])")  # fmt: skip
    ap.add_argument("--write-docs", action="store_true")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Draw, print the table and, with ``--write-docs``, put it in docs/plan.md."""
    from multiprocessing import get_context

    from selfcal.calibration.board.plan.views import ViewRule
    from selfcal.robot.definition import load_robot

    a = parser().parse_args(argv)
    rule = ViewRule(min_pitch_px=a.min_pitch_px, max_tilt_deg=a.max_tilt_deg,
                    min_module_px=a.min_module_px)  # fmt: skip
    path = "rendered" if a.render else "analytic"
    noise = "" if a.pixel_sigma == 0.5 else f"-{a.pixel_sigma:g}px-noise"
    rules = "" if rule == ViewRule() else \
        f"-{a.min_pitch_px:g}px-{a.max_tilt_deg:g}deg-{a.min_module_px:g}cell"  # fmt: skip
    folder = f"{path}{noise}{rules}"
    root = Path(a.out) / folder
    items, predicted, held = [], {}, {}
    for robot in a.robot:
        seeds = range(a.first_seed, a.first_seed + a.draws)
        its, pred, hp = _items(robot, root, a.render, seeds, tuple(a.sets), a.pixel_sigma, rule)
        items += its
        predicted.update({(robot, k): v for k, v in pred.items()})
        held.update({(robot, k): v for k, v in hp.items()})
    # the plans' draws first, then the others, seed by seed: a run stopped early keeps balanced rows
    items.sort(key=lambda it: (it[1] != "plan 12", it[4]))
    done = root / "draws.jsonl"
    rows = [json.loads(x) for x in done.read_text().splitlines()] if done.is_file() else []
    if not a.from_draws:  # the draws not yet in draws.jsonl (a stopped run resumes)
        have = {(r["robot"], r["set"], r["seed"]) for r in rows}
        items = [it for it in items if (it[0], it[1], it[4]) not in have]
        with get_context("spawn").Pool(a.jobs) as pool:
            for row in pool.imap_unordered(_draw, items):
                rows.append(row)
                write_text_atomic(root / "draws.jsonl", "".join(json.dumps(r) + "\n" for r in rows))
    text = table(rows, predicted, held)
    cells = "; ".join(
        f"{r} board ({cell_target(r).name}) at {v[0][0]:g}, {v[0][1]:g}, {v[0][2]:g} mm, keep-out "
        + ",".join(f"{x:g}" for x in v[1][0])
        for r, v in ((r, cell_values(load_robot(r))) for r in a.robot)
    )
    args = [x for x in (sys.argv[1:] if argv is None else argv)
            if x not in ("--from-draws", "--write-docs")]  # fmt: skip
    text += (
        f"\n\nCells: {cells}. Command: `python -m selfcal.benchmarks.plan.robots "
        f"{' '.join(shlex.quote(x) for x in args)}` (draws per row: the failed column's "
        "count; a run stopped early tabled with `--from-draws`)."
    )
    return print_table(text, ROOT / "docs/plan.md", f"benchmark_plan_robots_{a.block or folder}",
                       write=a.write_docs)  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
