"""Benchmark: what limits the power of ``selfcal check`` against a mount shift (issue #29).

The drift benchmark (:mod:`selfcal.benchmarks.drift_images`) reports, beside the check's power,
the power of a test that knew the 0.2 mm mount shift's direction, from the noncentrality
``mu^T Sigma^-1 mu`` of the shift's linearised pixels ``mu`` under the check's covariance
``Sigma``. ``Sigma`` has four parts: the corner noise, the joint read-back noise (the robot file's
encoder table, :func:`selfcal.estimation.joint_report.encoder_sigma`), the calibration's model
error and the calibration's own uncertainty (its estimate's covariance carried to the new
views). This benchmark computes that noncentrality on the same simulated calibrations (the
analytic eye-in-hand board scenario, seeded by the draw) and 5 new views near their postures,
with the whole covariance and with one part left out, or one joint's read-back noise, and prints
per variant the median noncentrality over the checks and the mean power of the test that knew
the direction and of the one that knew only the mount's 3 translation axes (alpha = 0.01).
A part whose removal raises the power most is what keeps the check from finding the shift.

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.drift_parts [--calibrations 6]
[--checks 10] [--noise-px 0.2] [--robot er4u-paper]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from selfcal.benchmarks.board_accuracy_draw import SCENARIO, simulated_calibration
from selfcal.benchmarks.drift_images import NEW_VIEWS, SPREAD_RAD, TOOL_SHIFT_M, read_joints
from selfcal.calibration.drift.images import (
    ALPHA,
    calibration_error_model,
    estimate_covariance,
    image_drift_check,
)
from selfcal.calibration.drift.p_value import known_change_power
from selfcal.calibration.drift.views import view_jacobians
from selfcal.errors import InternalError
from selfcal.io.target_toml import parse_target
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot
from selfcal.sim.analytic import project_board
from selfcal.target.boards import Board
from selfcal.threads import limit_threads

__all__ = ["noncentralities", "main"]

TINY_RAD = 1e-12  # a joint's read-back noise left out (the views' covariance needs all joints)


def _variants(
    js: np.ndarray | None, wrist: tuple[int, int] | None
) -> dict[str, tuple[np.ndarray | None, bool, bool]]:
    """Per variant: (joint read-back noise (n,) rad or None, model error kept, estimate's
    covariance kept); ``wrist``: the 0-based joints of a differential wrist, or None."""
    out: dict[str, tuple[np.ndarray | None, bool, bool]] = {
        "the check's covariance": (js, True, True),
        "without the joint read-back noise": (None, True, True),
        "without the model error": (js, False, True),
        "without the calibration's uncertainty": (js, True, False),
        "the corner noise alone": (None, False, False),
    }
    for j in range(0 if js is None else len(js)):
        assert js is not None
        one = js.copy()
        one[j] = TINY_RAD
        out[f"without joint {j + 1}'s read-back noise"] = (one, True, True)
    if js is not None and wrist is not None:
        both = js.copy()
        both[list(wrist)] = TINY_RAD
        joints = f"{wrist[0] + 1} and {wrist[1] + 1}"
        out[f"without the differential wrist's (joints {joints}) read-back noise"] = (
            both, True, True)  # fmt: skip
    return out


def noncentralities(sigma_px: float, seed: int, checks: int, robot: str | None) -> dict:
    """Per variant (:func:`_variants`) the noncentralities of ``checks`` random 0.2 mm mount
    shifts, each over 5 new views, on the calibration of draw ``seed`` at ``sigma_px``."""
    cal, truth = simulated_calibration(sigma_px, seed, scenario_file=SCENARIO, robot=robot)
    arm = load_robot(cal.robot_model)
    board = parse_target(cal.target, "calibration.json: target")
    assert isinstance(board, Board) and cal.bounds is not None
    em = calibration_error_model(cal, "calibration.json")
    C = estimate_covariance(cal, em)
    no_error = dataclasses.replace(em, model_error_m=0.0, model_error_rad=0.0)
    js_deg = cal.bounds.joint_sigma_deg
    js = None if js_deg is None else np.radians(np.asarray(js_deg, float))
    variants = _variants(js, None if arm.encoder is None else arm.encoder.differential)
    T_board = np.asarray((truth.board or {})["T_world_board"], float)
    q_cal = np.array([f.joints_rad for f in truth.frames])
    rng = np.random.default_rng(seed + 7000)
    n = q_cal.shape[1]
    out: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(checks):
        u = rng.normal(size=3)
        shift = TOOL_SHIFT_M * u / np.linalg.norm(u)
        views: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for _ in range(10_000):
            if len(views) == NEW_VIEWS:
                break
            q = q_cal[rng.integers(len(q_cal))] + rng.uniform(-SPREAD_RAD, SPREAD_RAD, n)
            T_cam = fk_tool(truth.true_model, q[None])[0]
            got = project_board(T_cam, truth.intrinsics_left, board, T_board,
                                pixel_sigma=sigma_px, rng=rng)  # fmt: skip
            if got:
                ids = np.array(sorted(got))
                views.append((read_joints(arm, q), board.points(ids),
                              np.concatenate([got[i] for i in ids])))  # fmt: skip
        if len(views) < NEW_VIEWS:
            raise InternalError(f"no {NEW_VIEWS} postures near the calibration's see the board")
        for key, (jsv, keep_error, keep_c) in variants.items():
            vj = [view_jacobians(em if keep_error else no_error, cal.cameras[0], q, X, uv,
                                 eye_to_hand=False, pixel_sigma_px=cal.bounds.pixel_sigma_px,
                                 joint_sigma_rad=jsv) for q, X, uv in views]  # fmt: skip
            mean = [dataclasses.replace(v, r=v.tool[:, :3] @ shift) for v in vj]
            cv = C if keep_c else np.zeros_like(C)
            out[key].append(float(image_drift_check(cv, mean, eye_to_hand=False).statistic))
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread) and print one line per variant."""
    limit_threads(1)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calibrations", type=int, default=6, help="draws (default 6)")
    ap.add_argument("--checks", type=int, default=10, help="per calibration (default 10)")
    ap.add_argument("--noise-px", type=float, default=0.2, help="pixel noise (default 0.2)")
    ap.add_argument("--robot", default=None, help="the scenario's robot replaced (default ER-4u)")
    args = ap.parse_args(argv)
    rows: dict[str, list[float]] = {}
    for seed in range(1, args.calibrations + 1):
        for key, values in noncentralities(args.noise_px, seed, args.checks, args.robot).items():
            rows.setdefault(key, []).extend(values)
    print(f"| covariance ({args.noise_px:g} px, {args.calibrations} calibrations x "
          f"{args.checks} checks) | median noncentrality | test knowing the direction | "
          "knowing its 3 axes |\n|---|---|---|---|")  # fmt: skip
    for key, values in rows.items():
        lam2 = np.array(values)
        print(f"| {key} | {np.median(lam2):.1f} | "
              f"{100 * np.mean(known_change_power(lam2, ALPHA)):.1f} % | "
              f"{100 * np.mean(known_change_power(lam2, ALPHA, dof=3)):.1f} % |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
