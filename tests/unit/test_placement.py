"""The closed-form placement of the nominal chain (selfcal/calibration/board/nominal_fit.py): the
start of the fair nominal's least squares. Its alternation used to fit the hand-eye on the
inverted poses (another misfit than the placement's): from a robot file's camera mount a
quarter-turn off it climbed away from the answer, and on the Nachi MZ25 photoneo set's first 12
rows the fair nominal then started 35 - 92 deg off and did not converge (#fairnom12)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.board.nominal_fit import placement
from selfcal.errors import UsageError
from selfcal.kinematics.alignment import AXIS_TIPS, fit_placement_and_hand_eye
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.transforms import kabsch, make_pose, pose_from_vec


def test_a_mount_a_quarter_turn_off_the_drawing_is_found_from_the_drawing():
    """Wrist-only motion around three arm configurations (as the real set's groups); the true
    mount a quarter turn about the optical axis and 15 deg off the drawn one (identity): the
    placement from the drawing alone recovers the placement and mount."""
    rng = np.random.default_rng(7)
    robot = load_robot("ur5e")
    base = robot.home + np.radians(rng.uniform(-20, 20, (3, robot.n)))
    q = np.repeat(base, 4, axis=0)
    q[:, 3:] += np.radians(rng.uniform(-25, 25, (12, robot.n - 3)))
    F = fk_tool(nominal_mcpc(robot), q)
    B = pose_from_vec(np.r_[0.3, -1.2, 2.0, 0.4, -0.2, 1.1])  # board <- base
    c, s = np.cos(np.radians(15)), np.sin(np.radians(15))
    R = np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]]) @ np.array(
        [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    )
    C = make_pose(R, [-0.04, 0.1, 0.04])  # flange <- camera
    T = B @ F @ C
    B_fit, C_fit = placement(F, T)
    misfit = float(np.sum(((B_fit @ F @ C_fit - T) @ AXIS_TIPS)[:, :3] ** 2))
    # noise-free data: recovered to rounding (measured misfit 2e-29 m^2, poses 5e-15); the bounds
    # sit far above that on purpose, since rounding differs between BLAS builds, and still far
    # below what the old alternation reached (it climbed away: misfit ~1 m^2)
    assert misfit < 1e-24, misfit
    np.testing.assert_allclose(C_fit, C, atol=1e-12)
    np.testing.assert_allclose(B_fit, B, atol=1e-12)


def test_the_alternation_needs_a_round():
    T = np.broadcast_to(np.eye(4), (3, 4, 4))
    with pytest.raises(UsageError, match="at least one round"):
        fit_placement_and_hand_eye(T, T, np.eye(4), rounds=0)  # used to raise UnboundLocalError


def test_several_guesses_descend_each_as_it_would_alone():
    """The 24 starts of an unknown mount run as one array (a speed-up only): each guess ends
    where it ends alone, to the bit, on noisy poses, where the guesses stop after different
    rounds (measured 118, 114 and 123)."""
    rng = np.random.default_rng(3)
    robot = load_robot("ur5e")
    q = robot.home + np.radians(rng.uniform(-20, 20, (8, robot.n)))
    F = fk_tool(nominal_mcpc(robot), q)
    B = pose_from_vec(np.r_[0.3, -1.2, 2.0, 0.4, -0.2, 1.1])
    C = make_pose(np.diag([1.0, -1.0, -1.0]), [-0.12, 0.09, 0.05])
    T = B @ F @ C @ pose_from_vec(rng.normal(0, 1e-3, (8, 6)))
    guesses = pose_from_vec(rng.normal(0, 2.0, (5, 6)) * [1, 1, 1, 0, 0, 0])[:3]
    B_all, C_all = fit_placement_and_hand_eye(T, F, guesses)
    assert B_all.shape == C_all.shape == (3, 4, 4)
    for i, guess in enumerate(guesses):
        B_one, C_one = fit_placement_and_hand_eye(T, F, guess)
        assert np.array_equal(B_one, B_all[i]) and np.array_equal(C_one, C_all[i])


def test_kabsch_of_a_stack_is_each_fit_alone():
    """Point sets (s, k, 3) fit one by one (the placement's starts together), a mirrored set
    (where the best orthogonal map is a reflection) too: still a proper rotation."""
    rng = np.random.default_rng(11)
    A = rng.normal(size=(4, 9, 3))
    R = pose_from_vec(np.c_[rng.normal(size=(4, 3)), np.zeros((4, 3))])[:, :3, :3]
    Bp = A @ np.swapaxes(R, 1, 2) + rng.normal(size=(4, 1, 3)) + 1e-3 * rng.normal(size=A.shape)
    Bp[3] = A[3] * [1.0, 1.0, -1.0]  # a mirror image
    T = kabsch(A, Bp)
    for i in range(4):
        assert np.array_equal(T[i], kabsch(A[i], Bp[i]))
    np.testing.assert_allclose(T[:3, :3, :3], R[:3], atol=1e-3)
    assert np.allclose(np.linalg.det(T[:, :3, :3]), 1.0)
