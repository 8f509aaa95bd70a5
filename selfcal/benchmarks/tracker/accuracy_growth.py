"""Probe: how the tracker benchmark's model error grows with the distance, true and predicted
(issue #29, docs/tool-accuracy.md).

The draws of :mod:`selfcal.benchmarks.tracker.accuracy` (the same set-up and seeds). Per draw: the
variogram the calibration read from its folds (:mod:`selfcal.calibration.growth`: the level
``c0`` and the growth counted ``c1`` as sizes, mm and mm per unit distance; the growth's point
estimate, signed, and its t; whether the cap set it; the held-out rows' largest distance and the
reference distance), or, when it counts no model error, the folds' held-out excess in standard
errors and the smallest model error the test counts
(:func:`selfcal.calibration.accuracy.excess_test`); and per region (inside, edge, workspace) the median distance from the
calibration postures, the true model error and the predicted one (per coordinate, mm). The true
model error is what the true error leaves beyond the estimation's predicted part: ``sqrt(mean(|e|^2
- tr S) / 3)`` over the region's joint vectors (the benchmark knows the truth; the calibration
does not). The last lines pool them over the draws (root of the mean variance), and the folds'
held-out excess per coordinate (what a model error would have to explain, counted or not).

Run: ``uv run python -m selfcal.benchmarks.tracker.accuracy_growth --robot ur5e --noise-mm 0.1
[--draws 20] [--model compliance]``.
"""

from __future__ import annotations

import sys

import numpy as np

from selfcal.benchmarks.tracker.accuracy import COUNT, MODELS, REGIONS, calibrate, true_points
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.accuracy import Z_MODEL_ERROR, ModelError, excess_test
from selfcal.errors import InputError
from selfcal.kinematics.tool_error import (
    joint_spans,
    posture_distance,
    revolute_joints,
    workspace_sample,
)
from selfcal.robot.definition import load_robot
from selfcal.threads import limit_threads

__all__ = ["probe", "main"]


def _spans(limits: np.ndarray, revolute: np.ndarray) -> np.ndarray:
    """The joints' spans (:func:`joint_spans`) of the robot's ``limits`` (n, 2) rad / m."""
    span = joint_spans(limits, revolute)
    if span is None:
        raise InputError("the robot's joint limits are not finite ranges",
                         fix="give the robot file finite joint limits")  # fmt: skip
    return span


def probe(robot_name: str, noise_mm: float, draws: int, model: str) -> list[str]:
    """The lines the module docstring describes, one per draw and one per region."""
    robot = load_robot(robot_name)
    pooled: dict[str, list[tuple[float, float]]] = {r: [] for r in REGIONS}
    lines, held = [], []
    for seed in range(draws):
        case, q, acc, bend = calibrate(robot, noise_mm / 1e3, model, seed)
        me, em = acc.model_error, acc.error_model
        g = None if me is None else me.growth
        if me is not None:  # the folds' excess per coordinate, m^2, whether counted or not
            held.append((me.held_out_rms_m**2 - me.estimation_rms_m**2) / 3.0 - me.noise_m**2)
        if g is None:
            head = f"draw {seed:2d}: no growing model error counted{_test(me)}"
        else:
            capped = g.level == 0.0
            head = (f"draw {seed:2d}: c0 {np.sqrt(g.level) * 1e3:.3f} mm, c1 "
                    f"{np.sqrt(g.growth) * 1e3:.3f} mm/unit (estimate "
                    f"{np.sign(g.estimate) * np.sqrt(abs(g.estimate)) * 1e3:+.3f}, t {g.t:+.2f}"
                    f"{', capped' if capped else ''}), measured to {me.limit:.3f}, reach "
                    f"{me.reach_distance:.3f}")  # fmt: skip
        sample = workspace_sample(q, robot.limits, count=COUNT, seed=seed + 1)
        for name in REGIONS:
            qq = getattr(sample, name)
            p = em.predicted(qq)
            e2 = np.sum((p["position_mm"] - true_points(case, bend, qq)) ** 2, axis=1)
            est2 = np.trace(em.estimation_covariance(qq)[:, :3, :3], axis1=1, axis2=2) * 1e6
            true2 = float(np.mean(e2 - est2)) / 3.0
            pred2 = float(np.mean(em.model_error_factor(qq))) * (em.model_error_m * 1e3) ** 2
            wrap = revolute_joints(em.model.joint_types)
            d = posture_distance(qq, q, _spans(robot.limits, wrap), wrap)
            pooled[name].append((true2, pred2))
            head += (f" | {name}: d {np.median(d):.2f}, true {np.sqrt(max(true2, 0.0)):.3f}, "
                     f"predicted {np.sqrt(pred2):.3f} mm")  # fmt: skip
        lines.append(head)
    for name in REGIONS:
        t, p = np.mean(pooled[name], axis=0)
        lines.append(f"{robot_name} {noise_mm:g} mm {model} {name}: model error per coordinate "
                     f"true {np.sqrt(max(t, 0.0)):.3f} mm, predicted {np.sqrt(p):.3f} mm")  # fmt: skip
    if held:
        h = float(np.mean(held))
        lines.append(f"{robot_name} {noise_mm:g} mm {model}: the folds' held-out excess pooled "
                     f"over the draws, per coordinate {np.sign(h) * np.sqrt(abs(h)) * 1e3:+.3f} "
                     "mm (signed root of the mean; counted in a draw or not)")  # fmt: skip
    return lines


def _test(me: ModelError | None) -> str:
    """The held-out test's line part when no model error is counted: the folds' excess in
    standard errors against the :data:`Z_MODEL_ERROR` needed, and the smallest model error per
    coordinate it would count (:func:`excess_test`)."""
    if me is None:
        return ""
    expected = me.estimation_rms_m**2 + 3.0 * me.noise_m**2
    z, smallest = excess_test(me.held_out_rms_m**2, expected, me.rows)
    return (
        f" (held-out excess {z:+.2f} standard errors, {Z_MODEL_ERROR:g} needed: counted from "
        f"{smallest * 1e3:.3f} mm per coordinate)"
    )


def main(argv: list[str] | None = None) -> int:
    """Print the probe's lines (one BLAS thread)."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="ur5e", help="robot file (default ur5e)")
    ap.add_argument("--noise-mm", type=float, default=0.1, help="tracker noise (default 0.1)")
    ap.add_argument("--draws", type=int, default=20, help="draws (default 20)")
    ap.add_argument("--model", choices=MODELS, default="compliance", help="default compliance")
    args = ap.parse_args(argv)
    print("\n".join(probe(args.robot, args.noise_mm, args.draws, args.model)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
