"""One source for the joint read-back and its noise: the robot file's encoder table.

The simulator's read-back (:func:`selfcal.sim.kinematic_robot.read_back`) rounds the motors'
counts as the controller's table converts them (:class:`selfcal.hw.encoders.EncoderTable`, the
ER-4u's differential wrist included), and the noise the calibration assumes
(:func:`selfcal.estimation.joint_report.encoder_sigma`) is what that rounding gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.estimation.joint_report import encoder_sigma
from selfcal.hw.encoders import EncoderTable
from selfcal.robot.definition import load_robot
from selfcal.sim.kinematic_robot import read_back


def _postures(robot, k: int, seed: int) -> np.ndarray:
    """``k`` uniform postures (rad) inside the joint limits."""
    return np.random.default_rng(seed).uniform(*robot.limits.T, size=(k, robot.n))


@pytest.mark.parametrize("name", ["er4u-paper", "er4u-vendor", "ur5e"])
def test_the_simulated_read_back_is_the_controllers(name):
    robot = load_robot(name)
    table = EncoderTable.for_robot(robot)
    q = _postures(robot, 2000, 1)
    controller = table.to_degrees(table.to_counts(np.degrees(q)))
    # the table's counts per degree are rounded to 1e-9: far below one count (>= 1e-4 deg)
    np.testing.assert_allclose(np.degrees(read_back(q, robot.encoder, True)), controller,
                               rtol=0, atol=1e-8)  # fmt: skip
    np.testing.assert_array_equal(read_back(q, robot.encoder, False), q)


@pytest.mark.parametrize("name", ["er4u-paper", "ur5e"])
def test_the_assumed_read_back_noise_is_the_roundings(name):
    """Over uniform postures the read-back errors' standard deviation is encoder_sigma (within
    the 20 000 draws' ~1 % sampling spread) and the joints' errors are uncorrelated; on the
    ER-4u's wrist (pitch and roll from two motors' rounded counts) sqrt 2 times a joint read at
    the file's counts_per_deg would have."""
    robot = load_robot(name)
    q = _postures(robot, 20_000, 2)
    err = read_back(q, robot.encoder, True) - q
    sigma = encoder_sigma(robot)
    assert sigma is not None
    np.testing.assert_allclose(err.std(axis=0), sigma, rtol=0.03)
    corr = np.corrcoef(err.T)
    assert np.abs(corr[~np.eye(robot.n, dtype=bool)]).max() < 0.05
    if robot.encoder is not None and robot.encoder.differential is not None:
        wrist = list(robot.encoder.differential)
        per_joint = 1.0 / (robot.counts_per_unit[wrist] * np.sqrt(12.0))
        np.testing.assert_allclose(err[:, wrist].std(axis=0) / per_joint, np.sqrt(2), rtol=0.03)


def test_a_robot_without_an_encoder_table_reads_exactly():
    robot = load_robot("kr6-r900")
    assert robot.encoder is None and encoder_sigma(robot) is None
    q = _postures(robot, 5, 3)
    np.testing.assert_array_equal(read_back(q, robot.encoder, True), q)


def test_the_differential_wrist_arithmetic_has_one_home():
    """The ER-4u's motors 4 and 5 read pitch + roll and roll - pitch; the hardware's encoder
    table and the simulator's read-back both convert through motor_counts / joint_counts."""
    from selfcal.robot.encoder import joint_counts, motor_counts

    diff = (3, 4)
    joint = np.array([[10.0, -20.0, 30.0, 1.0, 0.0], [0.0, 0.0, 0.0, 3.0, 5.0]])
    motors = motor_counts(joint, diff)
    np.testing.assert_array_equal(motors, [[10, -20, 30, 1, -1], [0, 0, 0, 8, 2]])
    np.testing.assert_array_equal(joint_counts(motors, diff), joint)
    np.testing.assert_array_equal(motor_counts(joint, None), joint)
    table = EncoderTable.for_robot("er4u-vendor")
    assert table.differential == diff
    counts = table.to_counts(np.zeros(5) + table.home_deg)
    np.testing.assert_array_equal(counts, table.home_counts)
    step = np.zeros(5)
    step[3] = 1.0 / table.counts_per_deg[3]  # one joint-space count of pitch
    np.testing.assert_array_equal(table.to_counts(table.home_deg + step), [0, 0, 0, 1, -1])
    np.testing.assert_allclose(
        table.resolution_deg, 1 / np.abs(table.counts_per_deg) / [1, 1, 1, 2, 2]
    )
