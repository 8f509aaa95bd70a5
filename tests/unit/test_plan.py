"""selfcal plan's mathematics (selfcal/calibration/board/plan/planner.py, plan/views.py): the planned
postures are reachable, collision-free, outside the keep-out boxes and see the whole board; the
prediction is the board route's Cramer-Rao bound and beats a random plan of the same size."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.board.bounds import board_cramer_rao
from selfcal.calibration.board.plan.information import board_model
from selfcal.calibration.board.plan.path import order_path, path_length
from selfcal.calibration.board.plan.planner import plan_recording
from selfcal.calibration.board.plan.views import PlanSetup, board_views_ok
from selfcal.camera import project
from selfcal.io.camera_file import camera_from_fov, read_camera_file
from selfcal.io.target_toml import load_target
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.keep_out import outside_boxes
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.trajectory import home_target_center
from selfcal.robot.definition import load_robot, models_dir
from selfcal.target.base import Features
from selfcal.target.placement import board_pose
from selfcal.transforms import inv_pose

BOX = np.array(
    [-0.30, 0.05, 0.0, -0.10, 0.40, 0.60]
)  # m: beside the board, where the arm may reach


@pytest.fixture(scope="module")
def setup() -> PlanSetup:
    robot = load_robot("ur5e")
    cx, cy = home_target_center(robot, nominal_mcpc(robot).with_tool(robot.T_flange_cam))
    board = load_target(models_dir() / "targets/charuco.toml")
    T = board_pose(board, np.array([cx, cy, 0.003]))
    return PlanSetup(robot, camera_from_fov(60.0, 640, 480), board, T, BOX[None])


@pytest.fixture(scope="module")
def plan(setup):
    return plan_recording(setup, 8, seed=3, candidates=80, workspace=20)


def test_postures_within_limits_and_collision_free(setup, plan):
    lim = setup.robot.limits
    assert plan.q.shape == (8, 6)
    assert np.all((plan.q >= lim[:, 0]) & (plan.q <= lim[:, 1]))
    assert setup.chain.ok(plan.q).all()
    assert outside_boxes(setup.chain, plan.q, BOX[None]).all()


def test_keep_out_box_rejects_a_posture_inside_it(setup):
    chain = setup.chain
    q = setup.robot.home[None]
    tool = chain.points(q)[0, -1]
    box = np.concatenate([tool - 0.02, tool + 0.02])
    assert outside_boxes(chain, q, np.zeros((0, 6))).all()
    assert not outside_boxes(chain, q, box[None]).any()


def test_whole_board_in_view_and_facing_the_camera(setup, plan):
    T_bc = inv_pose(fk_tool(board_model(setup), plan.q))  # board -> camera
    _, pts = setup.board.layout()
    x0, y0, x1, y1 = setup.board.image(1.0).extent_m
    corners = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]])
    for X in (pts, corners):
        uv = project(setup.camera, T_bc[:, None], X[None])
        assert np.all((uv >= 0) & (uv <= [639, 479]))
        depth = np.einsum("mj,kj->mk", T_bc[:, 2, :3], X) + T_bc[:, None, 2, 3]
        assert np.all(depth > 0)
    # the optical axis within 60 deg of the board's normal
    assert np.all(T_bc[:, 2, 2] >= np.cos(np.radians(60.0)))


def test_a_view_from_the_side_is_refused(setup):
    # the camera beside the board looking along the table: board edge-on
    T = np.eye(4)
    T[:3, :3] = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]]).T
    T[:3, 3] = setup.T_base_board[:3, 3] + [-0.5, 0.0, 0.05]
    assert not board_views_ok(setup, inv_pose(T[None]) @ setup.T_base_board).any()


def test_prediction_is_the_board_route_bound_and_beats_random(setup, plan):
    model = board_model(setup)
    ids, pts = setup.board.layout()
    feats = [Features(ids, project(setup.camera, T, pts)) for T in inv_pose(fk_tool(model, plan.q))]
    cr = board_cramer_rao(setup.board, [setup.camera], model, plan.q, [feats], 0.5)
    bound = cr.aligned_tool_rms(plan.workspace, inv_pose(setup.robot.T_flange_cam))
    assert plan.predicted_m == pytest.approx(bound, rel=1e-6)
    assert plan.predicted_m < plan.random_m


def test_path_order_is_no_longer_than_the_given_order():
    rng = np.random.default_rng(0)
    q = np.linspace(0, 1, 9)[:, None] * np.ones((1, 3))
    shuffled = q[rng.permutation(9)]
    order = order_path(shuffled, np.zeros(3))
    assert np.allclose(shuffled[order], q)
    x = rng.uniform(-1, 1, size=(12, 4))
    o = order_path(x, np.zeros(4))
    assert sorted(o.tolist()) == list(range(12))
    assert path_length(x[o], np.zeros(4)) <= path_length(x, np.zeros(4))


def test_board_pose_face_up_is_the_simulators_table_pose():
    from selfcal.sim.board_scene import BOARD_THICKNESS_M, board_on_table

    board = load_target(models_dir() / "targets/charuco.toml")
    T = board_pose(board, np.array([0.4, -0.1, BOARD_THICKNESS_M]))
    assert np.allclose(T, board_on_table(board, (0.4, -0.1)))
    T = board_pose(board, np.array([0.4, -0.1, 0.2]), np.radians([0.0, 90.0, 0.0]))
    assert np.allclose(T[:3, 2], [-1.0, 0.0, 0.0], atol=1e-12)  # into the board: along -x


@pytest.mark.parametrize("fmt", ["opencv", "ros"])
def test_camera_file_reads_what_export_writes(tmp_path, fmt):
    from selfcal.camera import camera_model
    from selfcal.export.camera import to_camera_info_yaml, to_opencv_yaml

    cam = camera_model("opencv", fx=910.0, mu=1.01, cx=641.0, cy=355.0, width=1280, height=720,
                       coeffs={"k1": -0.21, "k2": 0.07, "p1": 1e-3, "p2": -4e-4})  # fmt: skip
    path = tmp_path / "cam.yaml"
    path.write_text(to_opencv_yaml(cam) if fmt == "opencv" else to_camera_info_yaml(cam))
    back = read_camera_file(path)
    assert (back.width, back.height) == (1280, 720)
    assert np.allclose(back.values(), cam.values(), rtol=1e-9, atol=1e-12)
    assert "k1" in back.free


def test_prediction_with_joint_noise_is_the_board_route_bound(setup, plan):
    from selfcal.calibration.board.plan.greedy import predicted_error
    from selfcal.calibration.board.plan.information import frame_information
    from selfcal.estimation.joint_report import aligned_tool_weight

    js = np.full(6, np.radians(0.02))
    model = board_model(setup)
    ids, pts = setup.board.layout()
    feats = [Features(ids, project(setup.camera, T, pts)) for T in inv_pose(fk_tool(model, plan.q))]
    cr = board_cramer_rao(setup.board, [setup.camera], model, plan.q, [feats], 0.5, joint_sigma=js)
    T_cam_tip = inv_pose(setup.robot.T_flange_cam)
    F = frame_information(setup, plan.q, 0.5, js).sum(axis=0)
    G = aligned_tool_weight(model, plan.workspace, T_cam_tip)
    got = predicted_error(F, G, setup.camera.n_free)
    assert got == pytest.approx(cr.aligned_tool_rms(plan.workspace, T_cam_tip), rel=1e-6)
    assert got > plan.predicted_m  # noisy joints: a larger error than with exact ones


def _facing(setup: PlanSetup, dx: float, depth: float = 0.4) -> np.ndarray:
    """(1, 4, 4) board -> camera: the optical axis along the board's normal through its centre
    moved by ``dx`` (m) along the board's x axis, ``depth`` m away."""
    _, X = setup.board.layout()
    T = np.eye(4)
    T[:3, 3] = -X.mean(axis=0) + [dx, 0.0, depth]
    return T[None]


def test_a_view_of_part_of_the_board_sees_the_features_whose_cells_are_in_view(setup):
    """The whole-board rule refuses a view with part of the board out of the image; a check's
    rule (min_corners) counts the features whose cells about them (one pitch each way) lie in
    the image with the margin: some but not all here, each of them inside, every feature with
    room to spare among them; the view passes when that many are asked and not one more."""
    from dataclasses import replace

    from selfcal.calibration.board.plan.views import seen_features

    _, X = setup.board.layout()
    T = _facing(setup, 0.2)
    assert not board_views_ok(setup, T).any() and not seen_features(setup, T).any()
    part = replace(setup, rule=replace(setup.rule, min_corners=6))
    assert seen_features(part, _facing(setup, 0.0)).all()  # the whole board in view
    seen = seen_features(part, T)[0]
    assert 12 <= seen.sum() <= len(X) - 12
    uv = project(setup.camera, T[0], X)
    margin, w, h = setup.rule.margin_px, setup.camera.width, setup.camera.height
    assert np.all((uv[seen] >= margin) & (uv[seen] <= [w - margin, h - margin]))
    pitch = np.min(np.linalg.norm(X[1:] - X[0], axis=1))
    room = [project(setup.camera, T[0], X + pitch * np.array([a, b, 0.0]))
            for a in (-1.5, 1.5) for b in (-1.5, 1.5)]  # fmt: skip
    roomy = np.all([np.all((u >= 2 * margin) & (u <= [w - 2 * margin, h - 2 * margin]), axis=1)
                    for u in room], axis=0)  # fmt: skip
    assert roomy.any() and np.all(seen[roomy])
    assert not np.any(seen[uv[:, 0] > w - margin])
    k = int(seen.sum())
    for need, passes in ((k, True), (k + 1, False)):
        rule = replace(setup.rule, min_corners=need)
        assert board_views_ok(replace(setup, rule=rule), T).tolist() == [passes]
