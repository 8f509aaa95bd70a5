"""Benchmark of the one-step maximum-likelihood refinement (selfcal.calibration.field.joint_refine) on the analytic path.

For 10, 30 and 100 calibration postures of the default scenario (0.5 px corner noise, joints read
back at encoder resolution) acquires a dataset into a temporary folder, runs the two-stage
calibration and then the joint refinement, and prints the refinement's time, iterations and
size next to the accuracy of both methods (tool-tip RMS over the 20 validation postures after
rigid alignment, fx) and the Cramer-Rao bound of that metric from the final Jacobian.

Run: ``MUJOCO_GL=egl .venv/bin/python selfcal/benchmarks/timing/joint.py [--poses 10 30 100]
[--seeds 1 2 3]``.
"""

from __future__ import annotations

import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.field.calibrate import calibrate_detailed
from selfcal.calibration.field.joint_refine import aligned_tool_rms_bound
from selfcal.config.scenario import load_scenario
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.accuracy import aligned_errors, tool_tips
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.pipeline.run import run_acquire


def run(poses: list[int], seeds: list[int], pixel_sigma: float) -> None:
    head = (
        f"{'poses':>5} {'seed':>4} {'obs':>6} {'unkn':>5} {'two-st s':>8} {'joint s':>7} "
        f"{'iter':>4} {'nominal':>7} {'2-stage':>7} {'joint':>6} {'CRB':>6} {'fx 2-st':>8} "
        f"{'fx joint':>8}"
    )
    print(f"analytic path, {pixel_sigma} px corner noise; tool-tip RMS in mm")
    print(head)
    print("-" * len(head))
    for n in poses:
        for seed in seeds:
            with tempfile.TemporaryDirectory() as tmp:
                root = Path(tmp) / "ds"
                s = load_scenario(
                    overrides={
                        "noise": {"render": False, "pixel_sigma": pixel_sigma, "seed": seed},
                        "trajectory": {"poses": n},
                    }
                )
                run_acquire(s, root, quiet=True)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t0 = time.perf_counter()
                    out = calibrate_detailed(root, method="joint")
                    total = time.perf_counter() - t0
                jr = out.joint
                if jr is None:  # pragma: no cover - method="joint" sets it
                    raise SystemExit(f"{root}: the joint calibration gave no joint refinement")
                truth = read_truth(root / "truth.json")
                qv = np.radians(Dataset.open(root).info.validation_joints_deg)
                p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
                two = MCPCModel(
                    out.result.methods["two-stage"].mcpc_params_si,
                    out.model.joint_types,
                    out.model.joint_offsets,
                )

                def err(model, qv=qv, truth=truth, p_true=p_true):
                    return aligned_errors(tool_tips(model, qv, truth.T_cam_tip), p_true)["rms"]

                crb = 1000 * aligned_tool_rms_bound(jr, qv, truth.T_cam_tip)
                fx2 = out.result.methods["two-stage"].intrinsics.fx
                print(
                    f"{n:5d} {seed:4d} {jr.n_inliers:6d} {jr.n_unknowns:5d} "
                    f"{total - jr.seconds:8.2f} {jr.seconds:7.2f} {jr.iterations:4d} "
                    f"{err(truth.nominal_model):7.3f} {err(two):7.3f} {err(out.model):6.3f} "
                    f"{crb:6.3f} {fx2:8.2f} {jr.fx:8.2f}",
                    flush=True,
                )


def main() -> None:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, nargs="+", default=[10, 30, 100])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--pixel-sigma", type=float, default=0.5)
    args = ap.parse_args()
    run(args.poses, args.seeds, args.pixel_sigma)


if __name__ == "__main__":
    main()
