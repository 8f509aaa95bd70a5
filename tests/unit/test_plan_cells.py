"""The plan Monte Carlo's cells (selfcal/benchmarks/plan/robots.py): the rule that lays out each
robot's cell gives docs/plan.md's UR5e example for the UR5e, puts every robot's board where its
home posture looks, keeps the keep-out box off the board, and leaves postures that reach, do not
collide and see the board whole by selfcal plan's view rule."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.plan.compare import BOARD_POSE, KEEP_OUT
from selfcal.benchmarks.plan.robots import ROBOTS, cell, cell_values
from selfcal.calibration.board.plan.candidates import candidate_pool
from selfcal.calibration.board.plan.feasible import feasible
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot


def test_the_rule_gives_the_ur5e_example_its_own_cell() -> None:
    bp, box = cell_values(load_robot("ur5e"))
    np.testing.assert_array_equal(bp, BOARD_POSE)
    np.testing.assert_array_equal(box, KEEP_OUT)


@pytest.mark.parametrize("name", ROBOTS)
def test_each_cell_sees_its_board_from_home_and_has_postures(name: str) -> None:
    # selfcal plan's view rule (the ER-4u's board of 5 mm marker cells: cell_target)
    setup, bp, box = cell(name)
    robot = setup.robot
    # the optical axis at home meets the table's plane (z = 0) within 1 mm of the board's centre
    T = fk_tool(nominal_mcpc(robot).with_tool(robot.T_flange_cam), robot.home[None])[0]
    hit = T[:3, 3] - T[:3, 2] * T[2, 3] / T[2, 2]
    assert np.linalg.norm(hit[:2] * 1000.0 - bp[:2]) < 1.0
    # the box stands beside the board, not over it, and the same size as the example's
    lo, hi = box[0, :2], box[0, 3:5]
    assert np.any((bp[:2] < lo - 150.0) | (bp[:2] > hi + 150.0))
    np.testing.assert_allclose(hi - lo, KEEP_OUT[0, 3:5] - KEEP_OUT[0, :2])
    # postures around home that reach, stay out of the box and see the whole board
    pool, where = candidate_pool(setup, 12, seed=1)
    assert len(pool) == 12 and where == "home window"
    assert feasible(setup, pool).all()
