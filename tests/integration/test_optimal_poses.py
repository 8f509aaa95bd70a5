"""D-optimal calibration postures (selfcal.calibration.field.optimal_poses) and the MuJoCo collision check.

- the per-posture information proxy equals J^T J of central differences of the stereo
  projections of the visible grid points (1e-6 relative);
- greedy + exchange selection finds the best subset of a small pool (exhaustive search);
- the collision check passes home, rejects a folded arm and a camera below the table;
- optimal postures lower the Cramer-Rao bound of the validation tool tip (full joint model,
  :mod:`selfcal.calibration.field.bounds`, simulator's marker field) against the random planner's postures of the
  same count by at least 25 % (measured: see docs/bounds.md).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from selfcal.acquisition.backends import plan_optimal, planning_inputs
from selfcal.calibration.field.optimal_poses import pose_information, select_d_optimal
from selfcal.camera import project
from selfcal.config.scenario import load_scenario
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.trajectory import PLANNING_VISIBILITY, plan_postures
from selfcal.sim.collision import collision_checker
from selfcal.studies.montecarlo.plan_comparison import predicted_bound
from selfcal.transforms import inv_pose, pose_from_vec


@pytest.fixture(scope="module")
def inp():
    return planning_inputs(load_scenario(None, {"noise": {"render": False}}))


def test_pose_information_matches_finite_differences(inp):
    model, rig = inp["model_cam"], inp["rig"]
    intr, T_lr = rig.cameras[0], rig.T_first_cam[1]
    pts, nrm = inp["points_world"], inp["normals_world"]
    q = inp["robot"].home[None] + np.radians([[5.0, 3.0, -4.0, 6.0, 20.0]])
    W = pose_information(model, rig, q, pts, nrm, pixel_sigma_px=1.0)[0]
    TL = fk_tool(model, q)[0]
    vL = PLANNING_VISIBILITY.points(intr, TL[None], pts, nrm)[0]
    vR = PLANNING_VISIBILITY.points(intr, (TL @ T_lr)[None], pts, nrm)[0]
    assert vL.sum() >= 6 and vR.sum() >= 6

    def f(xi):  # body twist [v; w] of the left camera
        T = TL @ pose_from_vec(np.r_[xi[3:], xi[:3]])
        uL = project(intr, inv_pose(T), pts[vL])
        uR = project(intr, inv_pose(T @ T_lr), pts[vR])
        return np.r_[uL.ravel(), uR.ravel()]

    h = 1e-7
    J = np.stack([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(6)], axis=1)
    np.testing.assert_allclose(W, J.T @ J, rtol=0, atol=1e-6 * np.abs(W).max())


def test_exchange_finds_the_best_subset_of_a_small_pool():
    rng = np.random.default_rng(4)
    B = rng.standard_normal((9, 5, 2)) * rng.uniform(0.2, 2.0, (9, 1, 1))
    chosen, logdet, _ = select_d_optimal(B, 4)
    best = max(
        np.linalg.slogdet(np.einsum("nir,njr->ij", B[list(c)], B[list(c)]))[1]
        for c in itertools.combinations(range(9), 4)
    )
    assert len(set(chosen.tolist())) == 4
    assert logdet == pytest.approx(best, abs=1e-3)  # the reg term adds ~1e-6


def test_collision_checker():
    from selfcal.robot.definition import load_robot

    robot = load_robot("er4u-paper")
    ok = collision_checker("er4u-paper")
    folded = np.radians([-36.1, 129.5, 125.0, 48.2, 171.5])  # forearm folded onto the base
    into_table = np.radians([38.15, -35.0, -20.0, -60.0, 0.0])  # elbow below z = 0
    res = ok(np.stack([robot.home, folded, into_table]))
    assert res.tolist() == [True, False, False]


@pytest.mark.slow
def test_optimal_postures_lower_the_tool_tip_bound(inp):
    s = load_scenario(None, {"noise": {"render": False}, "trajectory": {"poses": 10}})
    plan = plan_optimal(s, n_candidates=1500)
    q_rand = plan_postures(
        inp["robot"],
        inp["model_cam"],
        inp["rig"],
        inp["points_world"],
        10,
        seed=1,
        min_visible=inp["min_visible"],
        normals_world=inp["normals_world"],
    )
    assert plan.q.shape == q_rand.shape == (10, 5)
    lo, hi = inp["robot"].limits.T
    assert np.all((plan.q >= lo) & (plan.q <= hi))
    assert plan.logdet > plan.logdet_random
    b_opt = predicted_bound(s, plan.q)
    b_rand = predicted_bound(s, q_rand)
    print(b_opt["tool_tip_rms_mm"], b_rand["tool_tip_rms_mm"])
    assert b_opt["tool_tip_rms_mm"] < 0.75 * b_rand["tool_tip_rms_mm"]
    assert b_opt["median_param_bound"] < b_rand["median_param_bound"]
