"""Benchmark: forward kinematics, identification Jacobian and inverse kinematics.

Target (foundation issue): FK of all frames plus the identification Jacobian for 1000
configurations in under 50 ms on 2 cores. Run:

    .venv/bin/python -m selfcal.benchmarks.timing.kinematics [--robot er4u-paper] [--m 1000] [--repeat 7]

Any robot (``--robot ur5e``): the numerical IK's time, success rate and precision on the full tool
poses of ``--ik-targets`` random in-range postures; the ER-4u's closed form too for ER-type arms.
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.cli.pose import is_er
from selfcal.kinematics.forward import fk_frames, fk_nominal, fk_tool, identification_jacobian
from selfcal.kinematics.ik import UnreachableError, ik, ik_nearest, nearest_reachable
from selfcal.kinematics.ik_numeric import ToolTarget, ik_robot, solve_ik
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.tool_pose import tool_pose
from selfcal.robot.definition import load_robot

TARGET_MS = 50.0


def _time(fn: Callable[[], object], repeat: int) -> float:
    """Median wall time of ``fn()`` in ms (one untimed warm-up call)."""
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1000.0 * float(np.median(ts))


def _analytic_ik_rows(robot, qs: np.ndarray) -> list[tuple[str, float, str]]:
    """The ER-4u's closed-form IK (``selfcal.kinematics.ik``)."""
    all_poses = [
        tool_pose(T, azimuth_rad=a) for T, a in zip(fk_nominal(robot, qs)[:, -1], qs[:, 0])
    ]
    poses = [(x, float(p), float(r)) for x, p, r in all_poses if np.hypot(x[0], x[1]) > 1e-3]
    k = len(poses)
    t_ik = _time(lambda: [ik(robot, x, p, r) for x, p, r in poses], 3) / k
    reachable = [(x, p, r) for x, p, r in poses if any(s.in_range for s in ik(robot, x, p, r))]

    def _ikn():
        for x, p, r in reachable:
            ik_nearest(robot, x, p, r)

    t_ikn = _time(_ikn, 3) / max(len(reachable), 1)
    fixed: dict[int | str, float] = {3: float(robot.home[3]), 4: float(robot.home[4])}
    t_nr = _time(lambda: [nearest_reachable(robot, x, fixed) for x, _, _ in poses[:5]], 1) / 5
    return [
        ("ik (all branches), per target", t_ik, f"mean over {k} targets"),
        ("ik_nearest, per target", t_ikn, f"mean over {len(reachable)} targets"),
        ("nearest_reachable (2 fixed), per target", t_nr, "26 least-squares starts"),
    ]


def _numeric_ik_rows(robot, qs: np.ndarray) -> list[tuple[str, float, str]]:
    """The numerical IK of any arm (``selfcal.kinematics.ik_numeric``) on the full tool poses of random
    in-range postures: time per target, success rate and the worst pose errors."""
    model = nominal_mcpc(robot)
    T = fk_tool(model, qs)
    solved, e_pos, e_ang = 0, 0.0, 0.0
    t0 = time.perf_counter()
    for Ti in T:
        try:
            res = ik_robot(robot, ToolTarget(Ti[:3, 3], Ti[:3, :3]))
        except UnreachableError:
            continue
        T2 = fk_tool(model, res.joints[None])[0]
        solved += 1
        e_pos = max(e_pos, float(np.linalg.norm(T2[:3, 3] - Ti[:3, 3])))
        e_ang = max(
            e_ang,
            float(np.linalg.norm(Rotation.from_matrix(T2[:3, :3].T @ Ti[:3, :3]).as_rotvec())),
        )
    t = 1000.0 * (time.perf_counter() - t0) / len(T)
    note = f"{solved}/{len(T)} solved; worst {e_pos:.1e} m, {e_ang:.1e} rad"
    rows = [("ik_robot (full pose), per target", t, note + " (closed form first on an ER arm)")]
    t0 = time.perf_counter()
    for Ti in T[:50]:
        try:
            solve_ik(model, robot.limits, ToolTarget(Ti[:3, 3], Ti[:3, :3]), reference=robot.home)
        except UnreachableError:
            pass
    t = 1000.0 * (time.perf_counter() - t0) / len(T[:50])
    return rows + [("solve_ik (numeric only, full pose), per target", t, "first 50 targets")]


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="er4u-paper")
    ap.add_argument("--m", type=int, default=1000, help="configurations per batch")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--ik-targets", type=int, default=200)
    args = ap.parse_args(argv)

    robot = load_robot(args.robot)
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (args.m, robot.n))

    rows: list[tuple[str, float, str]] = []
    t_fk = _time(lambda: fk_frames(model, q), args.repeat)
    t_jac = _time(lambda: identification_jacobian(model, q), args.repeat)
    t_both = _time(lambda: (fk_frames(model, q), identification_jacobian(model, q)), args.repeat)
    t_dh = _time(lambda: fk_nominal(robot, q), args.repeat)
    rows += [
        (f"fk_frames, {args.m} configs", t_fk, ""),
        (f"identification_jacobian, {args.m} configs", t_jac, "(includes its own FK)"),
        (f"fk_frames + jacobian, {args.m} configs", t_both, f"target < {TARGET_MS:.0f} ms"),
        (f"fk_nominal, {args.m} configs", t_dh, ""),
    ]

    qs = q[: args.ik_targets]
    if is_er(robot):
        rows += _analytic_ik_rows(robot, qs)
    rows += _numeric_ik_rows(robot, qs)

    print(
        f"robot {robot.name}, numpy {np.__version__}, {platform.python_implementation()} "
        f"{platform.python_version()}, {os.cpu_count()} CPUs, median of {args.repeat}"
    )
    w = max(len(r[0]) for r in rows)
    print(f"{'operation':<{w}}  {'time (ms)':>10}  note")
    for name, t, note in rows:
        print(f"{name:<{w}}  {t:>10.3f}  {note}")
    ok = t_both < TARGET_MS
    print(
        f"FK + Jacobian target {'MET' if ok else 'MISSED'}: {t_both:.1f} ms vs {TARGET_MS:.0f} ms"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
