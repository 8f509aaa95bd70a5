"""One calibration of the image drift benchmark (:mod:`selfcal.benchmarks.drift.images`, its
docstring says what is drawn and counted) and its checks: the simulated calibration
(:func:`drawn_calibration`), the joints as the controller reads them back (:func:`read_joints`)
and the counts of its ``checks`` checks per kind (:func:`calibration_checks`), with the
benchmark's sizes (:data:`NEW_VIEWS` new views a check, the mount's :data:`TOOL_SHIFT_M` and the
joint's :data:`JOINT_OFFSET_RAD`, postures within :data:`SPREAD_RAD` of the calibration's).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import SCENARIO, simulated_calibration
from selfcal.calibration.drift.choose import chosen_views
from selfcal.calibration.drift.covariance import change_information
from selfcal.calibration.drift.fold_error import fold_error_model
from selfcal.calibration.drift.images import (
    ALPHA,
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    fold_recheck,
    image_drift_check,
    view_noise,
)
from selfcal.calibration.drift.p_value import known_change_power, known_size_power
from selfcal.calibration.drift.power import shift_power
from selfcal.config.scenario import scenarios_dir
from selfcal.errors import InternalError
from selfcal.io.target_toml import parse_target
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.sim.analytic import project_board
from selfcal.sim.kinematic_robot import read_back
from selfcal.target.boards import Board

__all__ = [
    "JOINT_OFFSET_RAD",
    "KINDS",
    "NEW_VIEWS",
    "NOISE_PX",
    "SCENARIOS",
    "SPREAD_RAD",
    "TOOL_SHIFT_M",
    "calibration_checks",
    "drawn_calibration",
    "read_joints",
]

NOISE_PX = (0.05, 0.2)
NEW_VIEWS = 5
TOOL_SHIFT_M, JOINT_OFFSET_RAD = 0.2e-3, np.radians(0.05)
SPREAD_RAD = np.radians(10.0)
KINDS = ("unchanged", "tool", "joint")
SCENARIOS = {"eye-in-hand": SCENARIO, "eye-to-hand": scenarios_dir() / "eye-to-hand.toml"}


def read_joints(robot: RobotDef, q: np.ndarray) -> np.ndarray:
    """The joints (rad / m) the controller of ``robot`` reports with the arm at the true
    posture ``q`` (..., n): its motors' counts rounded as its robot file's encoder table reads
    them, as the simulated acquisition does (:func:`selfcal.sim.kinematic_robot.read_back`);
    exact for a robot file without an encoder resolution."""
    return read_back(np.asarray(q, float), robot.encoder, True)


def drawn_calibration(sigma_px: float, seed: int, setup: str, robot_name: str | None) -> tuple:
    """One simulated calibration of the benchmark (the ``setup``'s scenario, its robot replaced
    by ``robot_name`` unless None, noise ``sigma_px``, ``seed``) and what its check uses:
    ``(cal, truth, robot, board, em, C, wide)`` (the error model, the estimate covariance and
    the folds' error model, None where the check runs no second null)."""
    cal, truth = simulated_calibration(sigma_px, seed, scenario_file=SCENARIOS[setup],
                                       robot=robot_name)  # fmt: skip
    robot = load_robot(cal.robot_model)
    board = parse_target(cal.target, "calibration.json: target")
    assert isinstance(board, Board)
    em = calibration_error_model(cal, "calibration.json")
    C = estimate_covariance(cal, em)
    wide = fold_error_model(em, cal.accuracy, view_noise(cal).misfit_counted)  # as check's
    return cal, truth, robot, board, em, C, wide


def calibration_checks(args: tuple) -> dict:
    """One calibration (noise ``sigma_px``, ``seed``, ``setup``, ``robot``: the setup's
    scenario's robot replaced, or None; optionally the new views per check, default
    :data:`NEW_VIEWS`, whether the check combines its tests by their smallest p-value's
    exact distribution rather than Bonferroni's bound: ``exact`` of
    :func:`selfcal.calibration.drift.images.image_drift_check`, and a pool of postures to
    choose the views from, 0: none,
    :func:`selfcal.calibration.drift.choose.chosen_views`) checked ``checks`` times: per kind the count of "changed" verdicts, and
    of the changes the causes named right and wrong."""
    sigma_px, seed, checks, setup, robot_name = args[:5]
    new_views = int(args[5]) if len(args) > 5 else NEW_VIEWS
    exact = bool(args[6]) if len(args) > 6 else False
    choose = int(args[7]) if len(args) > 7 else 0
    e2h = setup == "eye-to-hand"
    out: dict = {"status": "ok"} | {k: 0 for k in KINDS} | {"checks": 0}
    out |= {f"{k}_{w}": 0 for k in ("tool", "joint") for w in ("right", "wrong")}
    out |= {"tool_oracle": 0.0, "tool_size": 0.0, "tool_axes": 0.0, "tool_power": 0.0}
    out["fold_error"] = 0
    out |= {f"{k}_cannot_tell": 0 for k in KINDS}
    try:
        cal, truth, robot, board, em, C, wide = drawn_calibration(sigma_px, seed, setup,
                                                                  robot_name)  # fmt: skip
        out["fold_error"] = int(wide is not None)
        camera, true = truth.intrinsics_left, truth.true_model
        board_doc = truth.board or {}
        T_static = np.asarray(board_doc.get("T_world_cam" if e2h else "T_world_board"), float)
        q_cal = np.array([f.joints_rad for f in truth.frames])
        rng = np.random.default_rng(seed + 7000)
        n = true.n

        def seen(T_tool: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
            """The board's features seen with the chain's tool at ``T_tool`` (world frame)."""
            T_cam, T_board = (T_static, T_tool) if e2h else (T_tool, T_static)
            got = project_board(T_cam, camera, board, T_board, pixel_sigma=sigma_px, rng=rng)
            if not got:
                return None
            ids = np.array(sorted(got))
            return board.points(ids), np.concatenate([got[i] for i in ids])

        for _ in range(checks):
            views: dict[str, list] = {k: [] for k in KINDS}
            u = rng.normal(size=3)
            shift = np.eye(4)
            shift[:3, 3] = TOOL_SHIFT_M * u / np.linalg.norm(u)
            joint = int(rng.integers(n))
            q_new: list[np.ndarray] = []
            drawn = max(new_views, choose)
            for _ in range(10_000):
                if len(q_new) == drawn:
                    break
                q = q_cal[rng.integers(len(q_cal))] + rng.uniform(-SPREAD_RAD, SPREAD_RAD, n)
                q_off = q.copy()
                q_off[joint] += JOINT_OFFSET_RAD
                T = fk_tool(true, np.stack([q, q_off]))
                got = {"unchanged": seen(T[0]), "tool": seen(T[0] @ shift), "joint": seen(T[1])}
                if any(g is None for g in got.values()):
                    continue
                for k, g in got.items():
                    assert g is not None
                    views[k].append((len(q_new), *g))
                q_new.append(q)
            if len(q_new) < drawn:
                raise InternalError(f"no {drawn} postures near the calibration's see the board")
            if choose:
                pool = calibration_views(cal, em, read_joints(robot, np.array(q_new)),
                                         views["unchanged"])  # fmt: skip
                pick = chosen_views(C, pool, new_views, eye_to_hand=e2h)
                q_new = [q_new[i] for i in pick]
                views = {k: [(j, *views[k][i][1:]) for j, i in enumerate(pick)] for k in KINDS}
            qs = read_joints(robot, np.array(q_new))
            for k in KINDS:
                vj = calibration_views(cal, em, qs, views[k])
                res = image_drift_check(C, vj, eye_to_hand=e2h, camera_names=cal.cameras[0].free,
                                        exact=exact)  # fmt: skip
                res = fold_recheck(res, wide, partial(calibration_views, cal, q=qs, views=views[k]),
                                   C, eye_to_hand=e2h)  # fmt: skip
                out[f"{k}_cannot_tell"] += res.undecided
                if k == "tool":  # the shift's own pixels' noncentrality: mu^T Sigma^-1 mu
                    F = change_information(C, vj, np.concatenate([v.tool[:, :3] for v in vj]))
                    lam2 = float(shift[:3, 3] @ F @ shift[:3, 3])
                    out["tool_oracle"] += float(known_change_power(lam2, ALPHA))
                    out["tool_size"] += known_size_power(F, shift[:3, 3], ALPHA)
                    out["tool_axes"] += float(known_change_power(lam2, ALPHA, dof=3))
                    out["tool_power"] += shift_power(C, vj, eye_to_hand=e2h, alpha=ALPHA,
                                                     search=False).power  # fmt: skip
                out[k] += res.changed
                if k != "unchanged" and res.attribution is not None:
                    right = "hand-eye" if k == "tool" else f"joint {joint + 1}"
                    cause = res.attribution.cause
                    if cause is not None:
                        ok = right in res.attribution.explaining
                        out[f"{k}_right" if ok else f"{k}_wrong"] += 1
            out["checks"] += 1
        return out
    except Exception as exc:  # noqa: BLE001 - a benchmark counts failed draws
        return {"status": f"failed: {type(exc).__name__}: {str(exc)[:200]}"}
