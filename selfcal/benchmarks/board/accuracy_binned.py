"""Benchmark: a board calibration's true flange error against the posture distance (issue #29).

Per robot, model and corner noise level, ``--draws`` draws of the board accuracy Monte Carlo
(:func:`selfcal.benchmarks.board.accuracy_draw.draw`: the same seeds, calibrations and
workspace samples as :mod:`selfcal.benchmarks.board.accuracy`'s rows; analytic path), every
joint vector of the three regions' samples pooled and binned by its posture distance to the
nearest calibration posture (:func:`selfcal.kinematics.tool_error.posture_distance` in the unit
of :func:`selfcal.kinematics.tool_error.joint_spans`: each joint's range, a revolute joint's at
most a turn, so 1 is one joint moved across all its distinct postures). Per bin: the points,
their median distance, the true flange error's RMS (mm: the calibrated chain's flange against
the true chain's, no noise), the predicted RMS, the coverage of the predicted 95 % bound and the
share the calibration flags as not measured (farther than its folds' reach); under the table the
median of the draws' reach (the folds' largest held-out distance, the same unit).

Run: ``uv run python -m selfcal.benchmarks.board.accuracy_binned [--draws 10] [--jobs 1]
[--robots R,..] [--models M,..] [--noise-px S,..] [--edges 0,0.05,..]`` (prints the table;
no docs block).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import DEFAULT_MODELS, REGIONS, ROBOTS, draw
from selfcal.benchmarks.pool import map_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.errors import UsageError
from selfcal.threads import limit_threads

__all__ = ["EDGES", "binned", "main", "table"]

EDGES = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, np.inf)
"""The bins' edges (unit-free posture distance); the last bin is open."""


def binned(points: list[np.ndarray], edges: tuple[float, ...] = EDGES) -> list[dict]:
    """The bins of the joint vectors ``points`` (each (9, m): a draw's region rows, as
    :func:`selfcal.benchmarks.board.accuracy_draw.draw` returns them: predicted 95 % bound,
    the same without model error, predicted RMS, true error (mm), three orientation rows, the
    not-measured flag, the posture distance) by their distance within ``edges`` (a point at an
    edge goes to the bin above it); empty bins are left out. Each: ``low``, ``high``,
    ``points``, ``median_distance``, ``true_rms_mm``, ``predicted_rms_mm``, ``coverage`` and
    ``not_measured_share``.

    Raises:
        UsageError: fewer than two edges or not increasing.
    """
    e = np.asarray(edges, dtype=float)
    if len(e) < 2 or np.any(np.diff(e) <= 0):
        raise UsageError(f"bin edges {list(edges)} must be at least two, increasing",
                         fix="e.g. --edges 0,0.1,0.3,inf")  # fmt: skip
    a = np.concatenate(points, axis=1)
    d = a[8]
    out = []
    for lo, hi in zip(e[:-1], e[1:], strict=True):
        inside = (d >= lo) & (d < hi)
        if not inside.any():
            continue
        x = a[:, inside]
        out.append({
            "low": float(lo), "high": float(hi), "points": int(inside.sum()),
            "median_distance": float(np.median(x[8])),
            "true_rms_mm": float(np.sqrt(np.mean(x[3] ** 2))),
            "predicted_rms_mm": float(np.sqrt(np.mean(x[2] ** 2))),
            "coverage": float(np.mean(x[3] <= x[0])),
            "not_measured_share": float(np.mean(x[7] > 0.5)),
        })  # fmt: skip
    return out


def table(head: str, bins: list[dict], reach: list[float]) -> str:
    """The Markdown table of one row's ``bins`` (:func:`binned`) under the line ``head``, with
    the median of the draws' finite ``reach`` (the folds' largest held-out distance)."""
    lines = [head, "", "| distance | points | median | true RMS (mm) | predicted RMS (mm) | "
             "coverage of the 95 % bound | not measured |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for b in bins:
        hi = "" if not np.isfinite(b["high"]) else f"{b['high']:g}"
        lines.append(f"| {b['low']:g}-{hi} | {b['points']} | {b['median_distance']:.3f} | "
                     f"{b['true_rms_mm']:.4f} | {b['predicted_rms_mm']:.4f} | "
                     f"{100 * b['coverage']:.1f} % | {100 * b['not_measured_share']:.0f} % |")  # fmt: skip
    finite = [r for r in reach if np.isfinite(r)]
    lines.append("")
    lines.append("folds' reach (median over the draws): "
                 + (f"{np.median(finite):.3f}" if finite else "none (no folds)"))  # fmt: skip
    return "\n".join(lines)


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=10, help="draws per row (default 10)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    for flag, default in (("--robots", ROBOTS), ("--models", DEFAULT_MODELS)):
        ap.add_argument(flag, type=lambda t: tuple(t.split(",")), default=default,
                        help=f"comma-separated (default {','.join(default)})")  # fmt: skip
    ap.add_argument(
        "--noise-px",
        type=lambda t: tuple(float(x) for x in t.split(",")),
        default=(0.2,),
        help="comma-separated corner noise levels (px; default 0.2)",
    )
    ap.add_argument("--edges", type=lambda t: tuple(float(x) for x in t.split(",")),
                    default=EDGES, help="the bins' edges (default "
                    f"{','.join(f'{x:g}' for x in EDGES)})")  # fmt: skip
    ap.add_argument("--first-seed", type=int, default=1, help="the first draw's seed (default 1)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the draws (one BLAS thread per process) and print one table per row."""
    limit_threads(1)
    args = _arguments(argv)
    for robot in args.robots:
        for model in args.models:
            for s in args.noise_px:
                seeds = range(args.first_seed, args.first_seed + args.draws)
                got = map_jobs(draw, [(robot, s, model, seed) for seed in seeds], args.jobs)
                ok = [g for g in got if g["status"] == "ok"]
                head = (f"{robot} {model} {s:g} px: {len(ok)}/{len(got)} draws (seeds "
                        f"{seeds.start}-{seeds.stop - 1}), the regions "
                        f"{', '.join(REGIONS)} pooled")  # fmt: skip
                if not ok:
                    print(f"{head}: every draw failed ({got[0]['status']})")
                    continue
                points = [g[r] for g in ok for r in REGIONS]
                print(table(head, binned(points, args.edges), [g["measured_to"] for g in ok]))
                print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
