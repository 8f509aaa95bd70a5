"""selfcal plan with the camera static and the board on the flange (eye-to-hand): the planned
postures are reachable, collision-free (arm, board plate, camera, lines of sight) and show the
whole board; the prediction is the eye-to-hand board route's Cramer-Rao bound and beats a random
plan; the scenario the plan writes places the camera where the plan did."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.board.bounds import board_cramer_rao
from selfcal.calibration.board.plan.feasible import _plate_clear, _sight_clear, feasible
from selfcal.calibration.board.plan.greedy import exchange, select_greedy
from selfcal.calibration.board.plan.ground import PlanOptions, plan_ground
from selfcal.calibration.board.plan.information import board_model, frame_information
from selfcal.calibration.board.plan.planner import plan_recording
from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.camera import project
from selfcal.io.camera_file import camera_from_fov
from selfcal.io.target_toml import load_target
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot, models_dir
from selfcal.target.base import Features
from selfcal.target.placement import board_on_flange, camera_pose, look_at

POSE = np.array([-1062.0, -133.0, 613.0, -90.0, 0.0, -90.0])  # mm, deg: beside the UR5e


@pytest.fixture(scope="module")
def setup() -> PlanSetup:
    robot = load_robot("ur5e")
    board = load_target(models_dir() / "targets/charuco.toml")
    T_bc = camera_pose(POSE[:3] / 1000, np.radians(POSE[3:]))
    return PlanSetup.eye_to_hand_setup(robot, camera_from_fov(40.0, 640, 480), board, T_bc,
                                       board_on_flange(board))  # fmt: skip


@pytest.fixture(scope="module")
def plan(setup):
    return plan_recording(setup, 8, seed=3, candidates=80, workspace=20)


def test_the_camera_pose_looks_along_the_base_x_axis():
    T = camera_pose(POSE[:3] / 1000, np.radians(POSE[3:]))
    assert np.allclose(T[:3, 2], [1, 0, 0], atol=1e-12)  # the view along +x, to the robot
    assert np.allclose(T[:3, 1], [0, 0, -1], atol=1e-12)  # image down = base down
    L = look_at(T[:3, 3], T[:3, 3] + [0.5, 0.0, 0.0])
    assert np.allclose(L, T, atol=1e-12)


def test_postures_reachable_collision_free_and_clear(setup, plan):
    lim = setup.robot.limits
    assert plan.q.shape == (8, 6)
    assert np.all((plan.q >= lim[:, 0]) & (plan.q <= lim[:, 1]))
    assert setup.chain.ok(plan.q).all()
    assert _plate_clear(setup, plan.q).all() and _sight_clear(setup, plan.q).all()
    assert feasible(setup, plan.q).all()


def test_whole_board_in_view_of_the_static_camera(setup, plan):
    T_cb = np.linalg.inv(setup.T_base_cam) @ fk_tool(setup.model_tool, plan.q)  # board -> cam
    assert np.allclose(T_cb, setup.T_cam_board(plan.q), atol=1e-12)
    _, pts = setup.board.layout()
    uv = project(setup.camera, T_cb[:, None], pts[None])
    assert np.all((uv >= 12) & (uv <= np.array([639, 479]) - 12))
    assert np.all(T_cb[:, 2, 2] >= np.cos(np.radians(45.0)))  # facing the camera (EYE_TO_HAND_RULE)


def test_an_arm_across_the_line_of_sight_is_refused(setup, plan):
    q = plan.q[:1]
    elbow = setup.chain.points(q)[0, 3]  # a joint frame of the upper arm
    T = fk_tool(setup.model_tool, q)[0]
    centre = T[:3, :3] @ setup.board_points()[-4:].mean(axis=0) + T[:3, 3]
    behind = centre + 2.0 * (elbow - centre)  # the elbow halfway between camera and board
    moved = PlanSetup.eye_to_hand_setup(setup.robot, setup.camera, setup.board,
                                        look_at(behind, centre), setup.T_flange_board)  # fmt: skip
    from selfcal.kinematics.keep_out import chain_samples

    assert np.linalg.norm(chain_samples(setup.chain, q)[0] - behind, axis=1).min() > 0.12
    assert not _sight_clear(moved, q).any()  # not the camera's clearance: the line of sight
    at_elbow = PlanSetup.eye_to_hand_setup(setup.robot, setup.camera, setup.board,
                                           look_at(elbow + [0, 0, 0.05], centre),
                                           setup.T_flange_board)  # fmt: skip
    assert not _sight_clear(at_elbow, q).any()  # the camera's body in the arm's way


def test_a_board_plate_in_a_keep_out_box_is_refused(setup, plan):
    q = plan.q[:1]
    T = fk_tool(setup.model_tool, q)[0]
    corner = T[:3, :3] @ setup.board_points()[-1] + T[:3, 3]  # one printed corner, base frame
    box = np.concatenate([corner - 0.005, corner + 0.005])[None]
    boxed = PlanSetup.eye_to_hand_setup(setup.robot, setup.camera, setup.board, setup.T_base_cam,
                                        setup.T_flange_board, box)  # fmt: skip
    assert _plate_clear(setup, q).all()
    assert not _plate_clear(boxed, q).any()


def test_prediction_is_the_eye_to_hand_board_route_bound_and_beats_random(setup, plan):
    model = board_model(setup)
    ids, pts = setup.board.layout()
    feats = [Features(ids, project(setup.camera, T, pts)) for T in fk_tool(model, plan.q)]
    cr = board_cramer_rao(setup.board, [setup.camera], model, plan.q, [feats], 0.5,
                          eye_to_hand=True)  # fmt: skip
    bound = cr.aligned_tool_rms(plan.workspace, setup.T_tool_tip)
    assert plan.predicted_m == pytest.approx(bound, rel=1e-6)
    assert plan.predicted_m < plan.random_m


def test_the_plan_is_where_no_swap_lowers_its_criterion(setup, plan):
    """Eye-to-hand plans are improved by swaps as eye-in-hand's are (Fedorov's exchange after
    the greedy choice): no single swap of a planned posture for another candidate lowers the
    criterion (the greedy choice alone left one here)."""
    opts = PlanOptions(seed=3, candidates=80, workspace=20)
    g = plan_ground(setup, 8, opts)
    F = frame_information(setup, g.pool, opts.pixel_sigma_px, opts.joint_sigma)
    n_cam = setup.camera.n_free
    chosen = np.array([int(np.flatnonzero((g.pool == q).all(axis=1))[0]) for q in plan.q])
    assert sorted(exchange(F, g.G, n_cam, chosen)) == sorted(chosen)
    assert sorted(select_greedy(F, g.G, n_cam, 8)) != sorted(chosen)


def test_a_plan_no_posture_serves_says_which_rule_stopped_them(setup):
    """A still camera turned away from the arm: the refusal listed every rule at once (view,
    collision, lines of sight) and left the user to guess which one no posture passed (a
    3-joint arm's eye-to-hand plan, its board facing down and the camera above it); it now counts
    how many of the last postures drawn pass each rule in turn, up to the first none passes."""
    import re

    from selfcal.calibration.board.plan.candidates import candidate_pool
    from selfcal.errors import InputError

    away = PlanSetup.eye_to_hand_setup(
        setup.robot, setup.camera, setup.board,
        camera_pose(POSE[:3] / 1000, np.radians([-90.0, 0.0, 90.0])), setup.T_flange_tool,
    )  # fmt: skip
    with pytest.raises(InputError) as err:
        candidate_pool(away, 4, seed=1, batch=64, max_draws=64)
    said = re.escape("(of the last 64 drawn (home window): 64 lie within the joint ranges, 0 see "
                     "the whole board as the view rule asks)")  # fmt: skip
    assert re.search(said, err.value.message)
    pool, _ = candidate_pool(setup, 4, seed=1)  # the camera facing the arm: candidates
    assert len(pool) == 4
