"""``python -m selfcal.benchmarks.plan.rehearse [--plans ur5e:12 ... arm7:24] [--seeds 8]
[--jobs 1] [--out DIR] [--write-docs]``: ``selfcal plan``'s predictions and verdict against
its plans rehearsed in simulation (docs/plan.md's rehearsal table, issue #30).

Each plan is docs/plan.md's command (``ur5e``: the UR5e example; ``arm7``: the 7-axis arm of
``tests/data/arm7.toml`` with the board 500 mm in front of it) with ``--count`` the number after
the colon, run in-process as ``selfcal plan``. Its ``scenario.toml`` is then replayed by
``selfcal run`` for every seed s of 1 .. ``--seeds``, with ``[perturbation] seed`` and
``[noise] seed`` set to s: one arm drawn within the plan's deviation and one noise draw each.
A row gives what ``plan.json`` states (the prediction with the parameters the selection is
forecast to keep and, where it may keep the smaller set, that set's; the verdict against the
reference, the smaller of the chain as drawn and the fair nominal; the more postures it
suggests), the predictions of the chain as drawn and of the fair nominal, and over the runs the
validation tool tip's RMS over the seeds and its range: calibrated and the chain as drawn
(``report.json``'s calibrated and nominal) and the fair nominal (``calibration.json``'s
``nominal_mcpc`` at the same validation postures against ``truth.json``, as ``report.json``'s
camera pose rows compare it), and the kinematic parameters beyond the placement each run kept.
``--write-docs`` puts the table between docs/plan.md's ``benchmark_plan_rehearse`` markers.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, print_table
from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["PLANS", "aggregate", "main", "plan_args", "rehearse_row", "seeded", "table"]

PLANS = ("ur5e:12", "ur5e:24", "ur5e:48", "arm7:12", "arm7:16", "arm7:24")
"""The plans rehearsed by default: robot and ``--count``."""
CELLS = {
    "ur5e": ["--robot", "ur5e", "--target", "models/targets/charuco.toml", "--fov-deg", "60",
             "--resolution", "640x480", "--board-pose=-472,-133,3",
             "--keep-out=-300,50,0,-100,400,600"],
    "arm7": ["--robot", "tests/data/arm7.toml", "--target", "models/targets/charuco.toml",
             "--fov-deg", "60", "--resolution", "640x480", "--board-pose", "500,0,0"],
}  # fmt: skip
"""docs/plan.md's ``selfcal plan`` arguments of each cell, paths relative to the repository."""


def plan_args(spec: str, out: Path) -> list[str]:
    """``selfcal plan``'s arguments of the plan ``spec`` (``ROBOT:COUNT``, ROBOT a key of
    :data:`CELLS`) written to ``out``, the repository's paths made absolute."""
    robot, count = spec.split(":")
    args = [str(ROOT / a) if a.endswith(".toml") else a for a in CELLS[robot]]
    return ["plan", *args, "--count", count, "--out", str(out), "--quiet"]


def seeded(text: str, seed: int) -> str:
    """The scenario ``text`` (as ``selfcal plan`` writes it) with ``[perturbation] seed`` and
    ``[noise] seed`` set to ``seed``."""
    from selfcal.errors import InternalError

    out, n = re.subn(r"(\[perturbation\]\n)seed = \d+\n", rf"\g<1>seed = {seed}\n", text)
    if n != 1 or "[noise]\n" not in out:
        raise InternalError("the plan's scenario.toml has no [perturbation] seed or [noise] table")
    return out.replace("[noise]\n", f"[noise]\nseed = {seed}\n", 1)


def rehearse_row(item: tuple[str, str, int]) -> dict:
    """One run (``(spec, plan folder, seed)``): ``selfcal run`` of the plan's scenario with
    ``seed`` (:func:`seeded`) in ``PLAN/seedS``; the validation tool tip's RMS (mm) of the
    calibration, the chain as drawn and the fair nominal, and the kinematic parameters beyond the
    placement kept; ``error`` instead when the run wrote no report."""
    from selfcal.calibration.board.nominal_fit import placement_indices
    from selfcal.cli.main import main as selfcal
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.board_calibration import read_board_calibration
    from selfcal.io.dataset import Dataset
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.accuracy import aligned_errors, tool_tips
    from selfcal.kinematics.mcpc import param_names

    spec, plan, seed = item
    folder = Path(plan).parent / f"seed{seed}"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    for name in ("joints.csv", "target.toml"):
        shutil.copyfile(Path(plan) / name, folder / name)
    write_text_atomic(
        folder / "scenario.toml", seeded((Path(plan) / "scenario.toml").read_text(), seed)
    )
    run = folder / "run"
    code = selfcal(["run", str(folder / "scenario.toml"), "--out", str(run), "--quiet"])
    if not (run / "report.json").is_file():
        return {"plan": spec, "seed": seed, "error": f"selfcal run exited {code} without a report"}
    v = json.loads((run / "report.json").read_text())["validation"]["tool_tip_error_mm"]
    cal = read_board_calibration(run / "calibration.json")
    truth = read_truth(run / "truth.json")
    qv = np.radians(Dataset.open(run).info.validation_joints_deg)
    p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    fair = aligned_errors(tool_tips(cal.nominal_model, qv, truth.T_cam_tip), p_true)["rms"]
    identified = json.loads((run / "calibration.json").read_text())["selection"]["identified"]
    placement = set(param_names(placement_indices(cal.model.n)))
    return {"plan": spec, "seed": seed, "calibrated_mm": float(v["calibrated"]["rms"]),
            "drawn_mm": float(v["nominal"]["rms"]), "fair_mm": float(fair),
            "kept": len([p for p in identified if p not in placement])}  # fmt: skip


def _plan(item: tuple[str, str]) -> dict:
    from selfcal.cli.main import main as selfcal
    from selfcal.io.plan_files import read_plan

    spec, out = item
    selfcal(plan_args(spec, Path(out)))
    return read_plan(Path(out) / "plan.json", ("camera",))


def aggregate(rows: list[dict]) -> dict:
    """Per plan of the run ``rows`` (:func:`rehearse_row`'s): ``runs``, ``failed``, for each
    of ``calibrated_mm``, ``drawn_mm``, ``fair_mm`` the RMS over the runs, their minimum and
    maximum (mm), ``kept`` ``{count: runs}`` (most common first) and ``ratios``: each run's
    calibrated RMS over its chain as drawn's (the same arm)."""
    out: dict = {}
    for spec in dict.fromkeys(r["plan"] for r in rows):
        mine = [r for r in rows if r["plan"] == spec]
        ok = [r for r in mine if "error" not in r]
        s: dict = {"runs": len(mine), "failed": len(mine) - len(ok),
                   "kept": dict(Counter(r["kept"] for r in ok).most_common()),
                   "ratios": [r["calibrated_mm"] / r["drawn_mm"] for r in ok]}  # fmt: skip
        for key in ("calibrated_mm", "drawn_mm", "fair_mm"):
            e = np.array([r[key] for r in ok], dtype=float)
            s[key] = ((float(np.sqrt(np.mean(e**2))), float(e.min()), float(e.max()))
                      if len(e) else None)  # fmt: skip
        out[spec] = s
    return out


def _rms(x: tuple[float, float, float] | None) -> str:
    if x is None:
        return ""
    return f"{x[0]:.3f}" if x[1] == x[2] else f"{x[0]:.3f} ({x[1]:.2f} - {x[2]:.2f})"


def _verdict(doc: dict) -> str:
    """plan.json's verdict in a cell: beats / NOT, times the reference, the smaller set's times
    as a caveat and the plan it suggests instead."""
    sel, nom = doc["selection"], doc["nominal"]
    ref = min(nom["drawn_tool_rms_mm"], nom["fair_nominal_tool_rms_mm"])
    cell = f"{'beats' if doc['beats_nominal'] else 'NOT'}: {sel['tool_rms_mm'] / ref:.2f}"
    if sel.get("rival_tool_rms_mm") is not None:
        cell += f" (smaller set {sel['rival_tool_rms_mm'] / ref:.2f})"
    more = doc.get("more_postures")
    if not doc["beats_nominal"] and more:
        cell += f"; {more['count']} postures: {more['tool_rms_mm']:.4f} mm"
    return cell


def table(plans: dict, rows: list[dict]) -> str:
    """The markdown table of the ``plans`` ``{spec: plan.json}`` and their runs ``rows``
    (:func:`rehearse_row`'s): predictions as plan.json states them (to 0.1 um as it stores them:
    rounded again to 1 um they could differ by one from what ``selfcal plan`` prints), achieved RMS over the seeds
    (range), the parameters kept, each run's calibrated RMS over its drawn chain's against the
    plan's clear margin."""
    head = ("| plan | predicted: kept, mm (smaller set) | verdict: times the reference | "
            "chain as drawn, predicted (mm) | fair nominal, predicted (mm) | runs | "
            "calibrated: RMS (range) | chain as drawn: RMS (range) | "
            "fair nominal: RMS (range) | kept in the runs: count x runs | "
            "calibrated / drawn, same draw |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|")  # fmt: skip
    lines, stats = [head], aggregate(rows)
    for spec, doc in plans.items():
        sel, nom = doc["selection"], doc["nominal"]
        pred = f"{sel['kinematic_parameters']}: {sel['tool_rms_mm']:.4f}"
        if sel.get("rival_tool_rms_mm") is not None:
            pred += f" ({sel['rival_kinematic_parameters']}: {sel['rival_tool_rms_mm']:.4f})"
        s = stats.get(spec, {"runs": 0, "failed": 0, "kept": {}, "ratios": [],
                             "calibrated_mm": None, "drawn_mm": None, "fair_mm": None})  # fmt: skip
        runs = f"{s['runs']}" + (f" ({s['failed']} failed)" if s["failed"] else "")
        kept = ", ".join(f"{k} x {n}" for k, n in s["kept"].items())
        r, margin = np.array(s["ratios"]), nom["clear_margin"]
        clear = (f"{r.min():.2f} - {r.max():.2f} (at most {margin:g} in {int(np.sum(r <= margin))} "
                 f"of {len(r)})" if len(r) else "")  # fmt: skip
        robot, count = spec.split(":")
        lines.append(f"| {robot} {count} | {pred} | {_verdict(doc)} | "
                     f"{nom['drawn_tool_rms_mm']:.4f} | {nom['fair_nominal_tool_rms_mm']:.4f} | "
                     f"{runs} | {_rms(s['calibrated_mm'])} | {_rms(s['drawn_mm'])} | "
                     f"{_rms(s['fair_mm'])} | {kept} | {clear} |")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Plan, rehearse, print the table and, with ``--write-docs``, put it in docs/plan.md."""
    from multiprocessing import get_context

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--plans", nargs="+", default=list(PLANS),
                    help="ROBOT:COUNT (ROBOT one of ur5e, arm7)")  # fmt: skip
    ap.add_argument("--seeds", type=int, default=8, help="runs per plan, seeds 1 .. this")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default="runs/plan-rehearse", help="the plans and the runs")
    ap.add_argument("--write-docs", action="store_true")
    a = ap.parse_args(argv)
    for spec in a.plans:
        if not re.fullmatch(rf"({'|'.join(CELLS)}):[1-9]\d*", spec):
            ap.error(f"--plans {spec}: ROBOT:COUNT with ROBOT one of {', '.join(CELLS)}")
    root = Path(a.out)
    folders = {spec: root / spec.replace(":", "-") / "plan" for spec in a.plans}
    with get_context("spawn").Pool(a.jobs) as pool:
        docs = pool.map(_plan, [(spec, str(f)) for spec, f in folders.items()])
        plans = dict(zip(a.plans, docs))
        items = [(spec, str(f), s) for s in range(1, a.seeds + 1) for spec, f in folders.items()]
        rows = sorted(
            pool.map(rehearse_row, items), key=lambda r: (a.plans.index(r["plan"]), r["seed"])
        )
    args = [x for x in (sys.argv[1:] if argv is None else argv) if x != "--write-docs"]
    counts: dict[str, list[str]] = {}
    for spec in a.plans:
        counts.setdefault(spec.split(":")[0], []).append(spec.split(":")[1])
    cmds = "; ".join(f"`selfcal plan {' '.join(CELLS[r])} --count N` (N = {', '.join(n)})"
                     for r, n in counts.items())  # fmt: skip
    seeds = "1" if a.seeds == 1 else f"1 .. {a.seeds}"
    text = table(plans, rows) + (
        f"\n\nPlans: {cmds}; each replayed by `selfcal run PLAN/scenario.toml` with "
        f"`[perturbation] seed` and `[noise] seed` = {seeds}. Command: "
        f"`python -m selfcal.benchmarks.plan.rehearse {' '.join(shlex.quote(x) for x in args)}`."
    )
    return print_table(text, ROOT / "docs/plan.md", "benchmark_plan_rehearse", write=a.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
