"""Trajectory planning keeps the target in view; the degenerate trajectory is caught."""

import numpy as np
import pytest

from selfcal.camera import Intrinsics, Rig
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.trajectory import (
    DegenerateTrajectoryError,
    DegenerateTrajectoryWarning,
    axes_convergence_m,
    check_not_degenerate,
    plan_postures,
    visible_counts,
)
from selfcal.robot.definition import load_robot
from selfcal.transforms import make_pose, trans

INTR = Intrinsics.centered(800.0, 1.0, 640, 480)


def field_points(n=20, seed=0):
    rng = np.random.default_rng(seed)
    pts = np.column_stack(
        [rng.uniform(0.32, 0.62, n), rng.uniform(0.24, 0.54, n), rng.uniform(0, 0.08, n)]
    )
    return pts, np.tile([0.0, 0.0, 1.0], (n, 1))


def test_planned_postures_are_in_range_and_see_the_target():
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    pts, nrm = field_points()
    T_lr = trans(np.array([0.06, 0.0, 0.0]))
    rig = Rig.stereo(INTR, T_lr)
    q = plan_postures(robot, model, rig, pts, 25, seed=3, min_visible=6, normals_world=nrm)
    assert q.shape == (25, 5)
    robot.check_joints(q)
    T = fk_tool(model, q)
    assert np.all(visible_counts(T, INTR, pts, nrm) >= 6)
    assert np.all(visible_counts(T @ T_lr, INTR, pts, nrm) >= 6)
    again = plan_postures(robot, model, rig, pts, 25, seed=3, min_visible=6, normals_world=nrm)
    np.testing.assert_array_equal(q, again)
    assert check_not_degenerate(T) > 0.01


def test_impossible_visibility_is_an_error():
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    pts = np.array([[-2.0, -2.0, 0.0]])  # behind the robot, far away
    with pytest.raises(DegenerateTrajectoryError, match="min_markers"):
        plan_postures(
            robot, model, Rig.stereo(INTR, trans(np.array([0.06, 0.0, 0.0]))), pts, 5,
            seed=0, min_visible=1, max_candidates=8192,
        )  # fmt: skip


def look_at(eye, target):
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return make_pose(np.column_stack([x, np.cross(z, x), z]), eye)


def test_axes_through_one_point_are_degenerate():
    rng = np.random.default_rng(1)
    target = np.array([0.4, 0.3, 0.0])
    eyes = target + rng.normal(size=(10, 3)) * 0.1 + [0, 0, 0.3]
    T = np.stack([look_at(e, target) for e in eyes])
    assert axes_convergence_m(T) < 1e-9
    with pytest.raises(DegenerateTrajectoryError, match="one point"):
        check_not_degenerate(T)
    T_off = np.stack([look_at(e, target + rng.normal(size=3) * 0.004) for e in eyes])
    with pytest.warns(DegenerateTrajectoryWarning):
        check_not_degenerate(T_off)
