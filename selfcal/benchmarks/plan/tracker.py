"""``python -m selfcal.benchmarks.plan.tracker [--draws 30] [--robot ur5e]``: the postures of
``selfcal plan --measure tracker`` against random ones, achieved in simulation (docs/plan.md,
issue #30).

The cell: the robot with a reflector 50 mm in front of the flange (``--tool-point 0,0,50``),
0.1 mm tracker noise per coordinate, no keep-out box. Posture sets: the plan of 12, the first 12
and the first 30 of its candidate pool (random postures under the same filters). Every draw is
one simulated truth (every minimal parameter, the tracker's placement and the tool point
included, moved uniformly within +-1 mm and +-0.5 deg: the deviation the plan assumes; seed =
the draw) and one noise draw; the tracker route identifies the chain from the positions
(:func:`selfcal.calibration.tracker.identify.identify_tracker`, 0.1 mm); the achieved error is
the RMS over the plan's 50 workspace postures of the distance between the predicted and the
true tool point in the tracker frame, the quantity the plan predicts. Prints, per posture set,
the prediction, the achieved median and 90th percentile and their ratio to the prediction.
"""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["TOOL_POINT_M", "achieved", "main"]

TOOL_POINT_M = np.array([0.0, 0.0, 0.05])
"""The reflector in the flange frame (m)."""


def achieved(setup, q: np.ndarray, qw: np.ndarray, seed: int) -> float:
    """The achieved tool-point RMS (m) over ``qw`` of the tracker route on the postures ``q``
    (m, n) rad for the truth and noise of ``seed`` (module docstring); NaN when it fails."""
    from selfcal.calibration.tracker.identify import identify_tracker
    from selfcal.errors import SelfCalError
    from selfcal.estimation.tracker import TrackerMeasurements
    from selfcal.kinematics.forward import fk_tool
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.sim.actual import perturb

    true = perturb(setup.model, seed=seed, translation_m=1e-3, rotation_rad=np.radians(0.5))
    rng = np.random.default_rng(10_000 + seed)
    xyz = fk_tool(true, q)[:, :3, 3] + rng.normal(0.0, setup.sigma_m, size=(len(q), 3))
    try:
        res = identify_tracker(nominal_mcpc(setup.robot), TrackerMeasurements(q=q, xyz=xyz),
                               sigma_t_m=setup.sigma_m)  # fmt: skip
    except SelfCalError:
        return float("nan")
    err = res.predict(qw) - fk_tool(true, qw)[:, :3, 3]
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


def main(argv: list[str] | None = None) -> int:
    """Draw and print the table."""
    import warnings

    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.plan.ground import workspace_sample
    from selfcal.calibration.tracker.plan import (
        TrackerPlanSetup,
        plan_tracker,
        position_jacobian,
        posture_information,
        predict_tracker,
    )
    from selfcal.robot.definition import load_robot

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument("--robot", default="ur5e")
    ap.add_argument("--count", type=int, default=12)
    a = ap.parse_args(argv)
    setup = TrackerPlanSetup(load_robot(a.robot), TOOL_POINT_M)
    plan = plan_tracker(setup, a.count, seed=1)
    pool = workspace_sample(setup, 400, seed=1)
    Jw = position_jacobian(setup.model, plan.workspace)
    G = np.einsum("wri,wrj->ij", Jw, Jw) / len(Jw)
    var = Deviation().variance(setup.model.joint_types)
    sets = {f"plan {a.count}": (plan.q, plan.predicted_m)}
    for n in (a.count, 30):
        q = pool[:n]
        sets[f"random {n}"] = (q, predict_tracker(setup, q, posture_information(setup, q).sum(0),
                                                  G, var))  # fmt: skip
    print(f"{a.robot}, {a.draws} draws")
    print("| postures | predicted (mm) | achieved median (mm) | 90th percentile | median / "
          "predicted | failed |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, (q, pred) in sets.items():
            e = np.array([achieved(setup, q, plan.workspace, s) for s in range(1, a.draws + 1)])
            ok = e[np.isfinite(e)] * 1000
            med, p90 = np.median(ok), np.percentile(ok, 90)
            print(f"| {name} | {pred * 1000:.3f} | {med:.3f} | {p90:.3f} | "
                  f"{med / (pred * 1000):.2f} | {int((~np.isfinite(e)).sum())} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
