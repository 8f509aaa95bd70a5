""":func:`selfcal.calibration.board.mounts.flange_to_tool` reads the camera's mount out of a
chain placed in any world frame (a board calibration's world is the board): every shipped
robot's nominal chain, carrying its robot file's mount, under random world frames, gives that
mount back. The rule before b88a795 (the last joint frame's x axis at zero joints against the
nominal's) turned the ER-4u's camera half round the flange's z axis in 34 of 200 such frames:
that x axis's dot product is exactly 0 there, so rounding decided (review of session 28,
finding 8); its only guard was a slow test (tests/integration/test_plan_check.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.mounts import flange_to_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import list_robots, load_robot

FRAMES = 12  # the rule before b88a795 fails the ER-4u's (er4u-paper) in these


@pytest.mark.parametrize("name", list_robots())
def test_the_mount_is_read_out_in_any_world_frame(name):
    robot = load_robot(name)
    T = np.eye(4) if robot.T_flange_cam is None else np.asarray(robot.T_flange_cam)
    rng = np.random.default_rng(0)
    worst_deg, worst_m = 0.0, 0.0
    for _ in range(FRAMES):
        world = np.eye(4)  # world <- base: a random turn and a shift of about 1 m
        world[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        world[:3, 3] = rng.normal(0.0, 1.0, 3)
        F = flange_to_tool(nominal_mcpc(robot, world, T), robot)
        turn = Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude()
        worst_deg = max(worst_deg, float(np.degrees(turn)))
        worst_m = max(worst_m, float(np.linalg.norm(F[:3, 3] - T[:3, 3])))
    # exact chains: the mount comes back to rounding (1e-14 deg measured); a half turn is 180
    assert worst_deg < 1e-6, f"{name}: mount turned by {worst_deg} deg"
    assert worst_m < 1e-9, f"{name}: mount moved by {worst_m} m"
