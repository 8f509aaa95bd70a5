"""Benchmark: MCPC identification (selfcal.calibration.identify.identify) for 10, 30, 100, 300 poses.

Simulated data: the nominal model with every minimal parameter perturbed within +-1 mm / +-0.5 deg,
camera poses in a random world frame with 0.05 mm / 0.02 deg noise. Prints the median wall time,
iterations, the condition number and O1 index, and the RMS of the normalised parameter errors
(error / reported std; ~1 when the std are honest).

Run: ``uv run python -m selfcal.benchmarks.timing.identify [--robot er4u-vendor]``
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.identify import identify
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc, param_is_angle
from selfcal.robot.definition import load_robot
from selfcal.transforms import make_pose, pose_from_vec


def run(robot_name: str, sizes: tuple[int, ...], repeats: int) -> None:
    """Print one line per number of poses."""
    robot = load_robot(robot_name)
    nom = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    idx = minimal_indices(nom.joint_types)
    ang = param_is_angle(idx)
    st, sr = 0.05e-3, np.radians(0.02)
    print(f"robot {robot_name}, noise {st * 1e3} mm / {np.degrees(sr)} deg, {repeats} repeats")
    print(
        f"{'poses':>6s} {'median ms':>10s} {'iters':>6s} {'cond':>7s} {'O1':>7s} "
        f"{'max std mm':>11s} {'max std deg':>12s} {'RMS z':>6s}"
    )
    for m in sizes:
        times, iters, zs, conds, o1s, smm, sdeg = [], [], [], [], [], [], []
        for rep in range(repeats):
            rng = np.random.default_rng(1000 * m + rep)
            p = nom.params.reshape(-1).copy()
            p[idx] += np.where(
                ang,
                np.radians(rng.uniform(-0.5, 0.5, idx.size)),
                rng.uniform(-1e-3, 1e-3, idx.size),
            )
            true = nom.with_params(p)
            T_w = make_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
            q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (m, robot.n))
            noise = np.concatenate([rng.normal(0, sr, (m, 3)), rng.normal(0, st, (m, 3))], axis=1)
            T_meas = T_w @ fk_tool(true, q) @ pose_from_vec(noise)
            t0 = time.perf_counter()
            res = identify(nom, q, T_meas, sigma_t_m=st, sigma_r_rad=sr)
            times.append(time.perf_counter() - t0)
            iters.append(res.iterations)
            conds.append(res.condition_number)
            o1s.append(res.o1)
            smm.append(np.nanmax(res.std[~ang]) * 1e3)
            sdeg.append(np.degrees(np.nanmax(res.std[ang])))
            truth = express_in_frame(true, T_w, like=res.model)
            zs.append(minimal_difference(res.model, truth) / res.std)
        z = np.concatenate(zs)
        print(
            f"{m:6d} {np.median(times) * 1e3:10.1f} {np.median(iters):6.0f} {np.median(conds):7.1f} "
            f"{np.median(o1s):7.3f} {np.median(smm):11.4f} {np.median(sdeg):12.5f} "
            f"{np.sqrt(np.mean(z**2)):6.2f}"
        )


def main() -> None:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="er4u-vendor")
    ap.add_argument("--repeats", type=int, default=10)
    args = ap.parse_args()
    run(args.robot, (10, 30, 100, 300), args.repeats)


if __name__ == "__main__":
    main()
