"""Benchmark: how much of the simulated compliance the calibration postures show (issue #29).

The board accuracy Monte Carlo's misfit (:mod:`selfcal.benchmarks.board.accuracy`, model
``compliance``: :data:`selfcal.sim.compliance.SHOULDER`, joint 2 bends by 0.05 deg x
cos(q2 + q3)) is judged over three regions of the workspace. A calibration can absorb the
bend's mean over its postures (joint 2's offset does); what a held-out check can see of the
rest is the bend's spread over the calibration postures, while the tool point's error over a
region grows with the bend's deviation there from that mean. Per robot, over the same draws
(:func:`selfcal.benchmarks.board.accuracy.scenario`: postures seeded by the draw) and the same
workspace sample as the Monte Carlo (:func:`selfcal.kinematics.tool_error.workspace_sample`,
the acquired postures' joint ranges): the RMS (deg) of the bend less its mean over the
calibration postures, at the calibration postures and over each region, pooled over the draws,
and the workspace's against the postures'. No calibration is run: the postures come from the
acquisition alone (analytic path).

Run: ``uv run python -m selfcal.benchmarks.board.compliance_reach [--draws 10] [--robots R,..]
[--write-docs]`` (rewrites the table in docs/tool-accuracy.md).
"""

from __future__ import annotations

import sys
import tempfile
import warnings
from contextlib import redirect_stderr, redirect_stdout
from io import StringIO
from pathlib import Path

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import COUNT, REGIONS, ROBOTS, scenario, simulated
from selfcal.benchmarks.board.accuracy_tables import DOC
from selfcal.benchmarks.doc_blocks import print_table
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.io.dataset import Dataset
from selfcal.kinematics.tool_error import workspace_sample
from selfcal.pipeline.run import run_acquire
from selfcal.robot.definition import load_robot
from selfcal.sim.compliance import JointCompliance
from selfcal.threads import limit_threads

__all__ = ["BLOCK", "bend_spread", "main", "reach", "table"]

BLOCK = "benchmark_compliance_reach"


def bend_spread(
    compliance: JointCompliance, q_cal: np.ndarray, regions: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """The bend (rad) of ``compliance`` less its mean over the calibration postures ``q_cal``
    (m, n) rad: at those postures (key ``"postures"``) and at each region's joint vectors
    ``regions[name]`` (k, n) rad."""
    j = compliance.joint

    def bend(q: np.ndarray) -> np.ndarray:
        return compliance.bent(q)[:, j] - np.asarray(q, float)[:, j]

    mean = float(np.mean(bend(q_cal)))
    return {"postures": bend(q_cal) - mean, **{k: bend(q) - mean for k, q in regions.items()}}


def reach(robot: str, draws: int) -> dict:
    """One robot's row: the pooled RMS (deg) per key of :func:`bend_spread` over ``draws``
    draws (seeds 1..draws, as the Monte Carlo's)."""
    got: dict[str, list[np.ndarray]] = {}
    for seed in range(1, draws + 1):
        s = scenario(robot, 0.05, seed)
        setup = simulated(s, "compliance")
        assert isinstance(setup.compliance, JointCompliance)
        with (tempfile.TemporaryDirectory(prefix="selfcal-reach-") as d, warnings.catch_warnings(),
              redirect_stdout(StringIO()), redirect_stderr(StringIO())):  # fmt: skip
            warnings.simplefilter("ignore")
            run_acquire(s, Path(d) / "run", quiet=True, setup=setup)
            ds = Dataset.open(Path(d) / "run")
            q_cal = np.radians(ds.joints_deg)
            limits = np.asarray(load_robot(ds.robot_source).limits, float)
        sample = workspace_sample(q_cal, limits, count=COUNT, seed=seed + 1)
        spread = bend_spread(setup.compliance, q_cal, {r: getattr(sample, r) for r in REGIONS})
        for k, v in spread.items():
            got.setdefault(k, []).append(v)
    rms = {k: float(np.degrees(np.sqrt(np.mean(np.concatenate(v) ** 2)))) for k, v in got.items()}
    return {"robot": robot, "draws": draws, **rms}


def table(rows: list[dict]) -> str:
    """The Markdown table of :func:`reach`'s rows."""
    head = ("| robot | at the calibration postures (deg) | inside (deg) | edge (deg) | workspace "
            "(deg) | workspace / postures |\n|---|---|---|---|---|---|\n")  # fmt: skip
    lines = [f"| {r['robot']} | {r['postures']:.4f} | {r['inside']:.4f} | {r['edge']:.4f} | "
             f"{r['workspace']:.4f} | {r['workspace'] / r['postures']:.0f} |" for r in rows]  # fmt: skip
    draws = "/".join(sorted({str(r["draws"]) for r in rows}))
    lines += ["", f"RMS of joint 2's bend less its mean over the calibration postures; {draws} "
              "draws per robot (the board accuracy Monte Carlo's postures and workspace sample); "
              "`uv run python -m selfcal.benchmarks.board.compliance_reach --write-docs`."]  # fmt: skip
    return head + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread) and print, or write, the table."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=10, help="draws per robot (default 10)")
    ap.add_argument("--robots", type=lambda t: tuple(t.split(",")), default=ROBOTS,
                    help=f"comma-separated (default {','.join(ROBOTS)})")  # fmt: skip
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the table in docs/tool-accuracy.md")  # fmt: skip
    args = ap.parse_args(argv)
    rows = [reach(r, args.draws) for r in args.robots]
    return print_table(table(rows), DOC, BLOCK, write=args.write_docs)


if __name__ == "__main__":
    sys.exit(main())
