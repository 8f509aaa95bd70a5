"""The fair nominal's start when the mount is unknown (eye-to-hand, #28): the board can sit on
the flange any way round; from the 24 quarter-turn starts the best fit is the true placement and
mount (the start of the fair nominal's least squares). Since each round of the alternation is
the exact least-squares step of the one misfit (#fairnom12) the bare flange alone gets there
too here (measured 5e-15 off both ways; before, with the hand-eye fitted on the inverted poses
and 20 rounds, 7e-4 and 0.09)."""

from __future__ import annotations

import numpy as np

from selfcal.calibration.board.nominal_fit import placement
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.transforms import make_pose, pose_from_vec


def test_any_mount_recovers_a_board_half_a_turn_round():
    rng = np.random.default_rng(5)
    robot = load_robot("ur5e")
    q = robot.home + np.radians(rng.uniform(-20, 20, (12, robot.n)))
    F = fk_tool(nominal_mcpc(robot), q)
    B = pose_from_vec(np.r_[0.3, -1.2, 2.0, 0.4, -0.2, 1.1])  # camera <- base
    C = make_pose(np.diag([1.0, -1.0, -1.0]), [-0.12, 0.09, 0.05])  # flange <- board, flipped
    B_fit, C_fit = placement(F, B @ F @ C, any_mount=True)
    # noise-free: recovered to rounding (measured 5e-15); 1e-12 leaves room for other BLAS builds
    np.testing.assert_allclose(B_fit, B, atol=1e-12)
    np.testing.assert_allclose(C_fit, C, atol=1e-12)
    B_one, C_one = placement(F, B @ F @ C)  # from the bare flange alone, half a turn off
    np.testing.assert_allclose(B_one, B, atol=1e-12)
    np.testing.assert_allclose(C_one, C, atol=1e-12)
