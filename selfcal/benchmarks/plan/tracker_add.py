"""``python -m selfcal.benchmarks.plan.tracker_add [--truths 6] [--add 5] [--robot ur5e]
[--out DIR] [--write-docs]``: ``selfcal plan --add K`` on a poorly identified tracker
calibration, simulated through the commands (docs/plan.md, issue #30).

For every truth (seed s = 1, 2, ...): the robot with a reflector 50 mm in front of the flange
(``TOOL_POINT_M``), every minimal parameter, the tracker's placement and the tool point moved
within +-1 mm and +-0.5 deg (the deviation the plan assumes; :func:`selfcal.sim.actual.perturb`,
seed s), :data:`WRIST_ROWS` rows that move only the wrist (the arm's other joints at one
posture free of collision, the wrist's joints uniform within their ranges, at most +-180 deg),
measured with 0.1 mm of noise per coordinate; ``selfcal identify`` calibrates them;
``selfcal plan --add K`` plans K postures from that calibration; the K rows are measured with
the same truth (the dataset's rows keep their noise) and ``selfcal identify`` calibrates all of
them. A row: the predicted tool-point RMS before and after (``plan.json``), the achieved one
before and after (the RMS over :data:`CHECK_POSTURES` postures of the robot file's planning
window of the distance between the calibration's tool point and the truth's, in the tracker
frame: the quantity the plan predicts), the same of each calibration's fair nominal (the robot
file's chain with the tracker frame and the tool point fitted, ``calibration.json``'s
``nominal``: what a calibration has to beat; ``plan.json`` predicts it) and the parameters each
calibration estimated. Prints the
first truth's ``selfcal plan --add`` lines, the table and the medians of the before/after
ratios; ``--write-docs`` puts them between docs/plan.md's ``benchmark_plan_tracker_add_K``
markers (K the ``--add``; ``benchmark_plan_tracker_add_K_ROBOT`` for a ``--robot`` other than the
UR5e).
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import warnings
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, print_table
from selfcal.benchmarks.plan.tracker import TOOL_POINT_M
from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["CHECK_POSTURES", "SIGMA_M", "WRIST_ROWS", "wrist_rows", "tracker_add_row", "main"]

WRIST_ROWS = 12
"""The dataset's rows (36 equations: more than the 27 parameters positions identify on the
UR5e, so the route identifies from them, and far fewer than the arm's joints need)."""
SIGMA_M = 1e-4
"""The tracker's noise per coordinate (m): ``selfcal identify``'s default."""
CHECK_POSTURES = 200
"""Postures of the planning window the achieved error is averaged over (seed 999)."""


def wrist_rows(setup, seed: int) -> np.ndarray:
    """(WRIST_ROWS, n) rad: one arm posture of the planning window free of collision (the seed's)
    with the wrist's joints (the last three, the last two of a 5-joint arm) drawn uniformly
    within their ranges (at most +-180 deg), each row free of collision too."""
    from selfcal.calibration.board.plan.ground import workspace_sample
    from selfcal.kinematics.keep_out import collision_free

    robot = setup.robot
    arm = workspace_sample(setup, 1, seed=100 + seed)[0]
    wrist = slice(robot.n - (3 if robot.n >= 6 else 2), robot.n)
    lo = np.maximum(robot.limits[wrist, 0], -np.pi)
    hi = np.minimum(robot.limits[wrist, 1], np.pi)
    rng = np.random.default_rng(seed)
    q = np.tile(arm, (8 * WRIST_ROWS, 1))
    q[:, wrist] = rng.uniform(lo, hi, (len(q), hi.size))
    return q[collision_free(setup.chain, q, setup.boxes)][:WRIST_ROWS]


def _measurements(path: Path, true, q: np.ndarray, seed: int) -> Path:
    """A measurements CSV (``selfcal identify``'s format, joints in deg / mm) of the truth
    ``true`` at ``q`` (m, n) SI with noise of ``seed`` (the first rows' noise the same for
    any m)."""
    from selfcal.io.atomic import write_text_atomic
    from selfcal.kinematics.forward import fk_tool

    rng = np.random.default_rng(10_000 + seed)
    xyz = fk_tool(true, q)[:, :3, 3] + rng.normal(0.0, SIGMA_M, (len(q), 3))
    n = q.shape[1]
    header = [f"j{i + 1}" for i in range(n)] + ["x_mm", "y_mm", "z_mm"]
    rows = np.column_stack([np.degrees(q), xyz * 1e3])
    return write_text_atomic(path, ",".join(header) + "\n"
                             + "".join(",".join(f"{v:.9f}" for v in r) + "\n" for r in rows))  # fmt: skip


def _selfcal(*argv: str) -> str:
    """Run ``selfcal ARGV`` in this process; its printed text (an error if it failed)."""
    from selfcal.cli.main import main
    from selfcal.errors import InternalError

    out = io.StringIO()
    with contextlib.redirect_stdout(out), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # identify's rank notes: the wrist-only data are meant
        code = main(list(argv))
    if code != 0:
        raise InternalError(f"selfcal {' '.join(argv)} exited {code}")
    return out.getvalue()


def tracker_add_row(folder: str | Path, seed: int, add: int = 5, robot: str = "ur5e") -> dict:
    """One truth (module docstring) in ``folder`` (made anew): ``predicted_before_mm``,
    ``predicted_after_mm``, ``achieved_before_mm``, ``achieved_after_mm``, ``kept_before``,
    ``kept_after`` (the parameters each calibration estimated), the plan's printed ``line``
    and its ``plan`` (plan.json)."""
    from selfcal.calibration.board.plan.ground import workspace_sample
    from selfcal.calibration.tracker.calibration_file import read_tracker_calibration
    from selfcal.calibration.tracker.plan import TrackerPlanSetup
    from selfcal.kinematics.forward import fk_tool
    from selfcal.robot.definition import load_robot
    from selfcal.sim.actual import perturb

    folder = Path(folder)
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    setup = TrackerPlanSetup(load_robot(robot), TOOL_POINT_M)
    true = perturb(setup.model, seed=seed, translation_m=1e-3, rotation_rad=np.radians(0.5))
    qc = workspace_sample(setup, CHECK_POSTURES, seed=999)

    truth = fk_tool(true, qc)[:, :3, 3]

    def rms(xyz: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum((xyz - truth) ** 2, axis=1))))

    def identify(csv: Path, out: Path) -> tuple[float, float, int]:
        """The calibration's and its fair nominal's achieved RMS (m), its estimated count."""
        _selfcal("identify", str(csv), "--robot", robot, "--joint-units", "deg", "--out",
                 str(out))  # fmt: skip
        cal = read_tracker_calibration(out / "calibration.json")
        nom = cal.nominal
        assert nom is not None  # identify writes it
        fair = (nom.T_meas_fit @ fk_tool(nom.model, qc))[:, :3, 3]
        return rms(cal.predict(qc)), rms(fair), len(cal.identifiable)

    q = wrist_rows(setup, seed)
    before, fair_before, kept_before = identify(_measurements(folder / "wrist.csv", true, q, seed),
                                   folder / "cal")  # fmt: skip
    line = _selfcal("plan", "--add", str(add), str(folder / "cal"), "--out", str(folder / "plan"))
    plan = json.loads((folder / "plan" / "plan.json").read_text())
    q_add = np.radians(np.asarray(plan["joints_deg"], dtype=float))
    both = _measurements(folder / "added.csv", true, np.concatenate([q, q_add]), seed)
    after, fair_after, kept_after = identify(both, folder / "cal-added")
    return {
        "truth": seed,
        "predicted_before_mm": plan["predicted_before_tool_rms_mm"],
        "predicted_after_mm": plan["predicted_tool_rms_mm"],
        "achieved_before_mm": before * 1e3,
        "achieved_after_mm": after * 1e3,
        "fair_nominal_before_mm": fair_before * 1e3,
        "fair_nominal_after_mm": fair_after * 1e3,
        "fair_predicted_before_mm": plan["fair_nominal_before_tool_rms_mm"],
        "fair_predicted_after_mm": plan["fair_nominal_tool_rms_mm"],
        "kept_before": kept_before,
        "kept_after": kept_after,
        "line": line.strip(),
        "plan": plan,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the truths and print the table."""
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--truths", type=int, default=6)
    ap.add_argument("--add", type=int, default=5)
    ap.add_argument("--robot", default="ur5e")
    ap.add_argument("--out", default="runs/bench-tracker-add")
    ap.add_argument("--write-docs", action="store_true")
    a = ap.parse_args(argv)
    rows = [tracker_add_row(Path(a.out) / f"truth{s}", s, a.add, a.robot)
            for s in range(1, a.truths + 1)]  # fmt: skip
    cmd = (f"python -m selfcal.benchmarks.plan.tracker_add --truths {a.truths} --add {a.add} "
           f"--robot {a.robot}")  # fmt: skip
    lines = [f"`{cmd}` ({a.robot}, {WRIST_ROWS} wrist-only rows, {SIGMA_M * 1e3:g} mm noise); "
             f"truth 1's `selfcal plan --add {a.add} {Path(a.out) / 'truth1' / 'cal'}` printed:",
             "", "```text", rows[0]["line"], "```", "",
             "| truth | predicted before (mm) | after | achieved before (mm) | after | fair "
             "nominal before (mm) | after | parameters estimated before | after |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        lines.append(f"| {r['truth']} | {r['predicted_before_mm']:.3f} | "
                     f"{r['predicted_after_mm']:.3f} | {r['achieved_before_mm']:.3f} | "
                     f"{r['achieved_after_mm']:.3f} | {r['fair_nominal_before_mm']:.3f} | "
                     f"{r['fair_nominal_after_mm']:.3f} | {r['kept_before']} | "
                     f"{r['kept_after']} |")  # fmt: skip
    pred = [r["predicted_before_mm"] / r["predicted_after_mm"] for r in rows]
    ach = [r["achieved_before_mm"] / r["achieved_after_mm"] for r in rows]
    lines += ["", f"before / after, median over {len(rows)} truths: predicted "
              f"{np.median(pred):.1f} times ({min(pred):.1f} - {max(pred):.1f}), achieved "
              f"{np.median(ach):.1f} times ({min(ach):.1f} - {max(ach):.1f})"]  # fmt: skip

    def span(key: str, over: str) -> str:
        v = [r[key] / r[over] for r in rows]
        return f"{min(v):.2f} - {max(v):.2f}"

    no_gain = sum(r["fair_nominal_before_mm"] < 1.1 * r["achieved_before_mm"] for r in rows)
    lines += [f"achieved / predicted: before {span('achieved_before_mm', 'predicted_before_mm')}, "
              f"after {span('achieved_after_mm', 'predicted_after_mm')}; fair nominal / "
              f"calibration, achieved: before {span('fair_nominal_before_mm', 'achieved_before_mm')} "
              f"(below 1.1, no clear gain, in {no_gain} of {len(rows)}), after "
              f"{span('fair_nominal_after_mm', 'achieved_after_mm')}; the fair nominal achieved / "
              f"predicted: before {span('fair_nominal_before_mm', 'fair_predicted_before_mm')}, "
              f"after {span('fair_nominal_after_mm', 'fair_predicted_after_mm')}"]  # fmt: skip
    marker = f"benchmark_plan_tracker_add_{a.add}" + ("" if a.robot == "ur5e" else f"_{a.robot}")
    return print_table("\n".join(lines), ROOT / "docs" / "plan.md", marker, write=a.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
