"""The capsule self-collision and floor check of planning (selfcal.kinematics.self_collision)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import examples
from hypothesis import example, given, settings
from hypothesis import strategies as st

from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.self_collision import CapsuleChain, segment_distances
from selfcal.robot.definition import load_robot

coords = st.floats(-1.0, 1.0, allow_nan=False)
points = st.lists(coords, min_size=3, max_size=3)


@settings(max_examples=examples(100), deadline=None)
@given(a0=points, a1=points, b0=points, b1=points)
# a 3e-10 m segment against a point: the closed form alone overestimated by 2e-10 (found by
# hypothesis in CI); the endpoint candidates make it exact
@example(a0=[-0.35, 0.18, -0.32], a1=[-0.35 + 1e-10, 0.18 - 2e-10, -0.32 + 1.5e-10],
         b0=[0.86, -0.28, 0.14], b1=[0.86, -0.28, 0.14])  # fmt: skip
def test_segment_distance_matches_dense_sampling(a0, a1, b0, b1):
    a0, a1, b0, b1 = map(np.asarray, (a0, a1, b0, b1))
    d = segment_distances(a0, a1, b0, b1)
    s = np.linspace(0, 1, 201)
    pa = a0 + s[:, None] * (a1 - a0)
    pb = b0 + s[:, None] * (b1 - b0)
    brute = np.min(np.linalg.norm(pa[:, None] - pb[None], axis=-1))
    # sampling overestimates by at most half a step of each segment
    step = (np.linalg.norm(a1 - a0) + np.linalg.norm(b1 - b0)) / 200
    assert d <= brute + 1e-12
    assert d >= brute - step - 1e-12


@pytest.mark.parametrize("name", ["er4u-paper", "er4u-vendor", "ur5e", "kr6-r900"])
def test_home_is_free(name):
    robot = load_robot(name)
    chain = CapsuleChain(nominal_mcpc(robot), robot.T_flange_cam)
    assert chain.ok(robot.home[None]).all()


def test_folded_ur5e_collides_and_floor_is_checked():
    robot = load_robot("ur5e")
    chain = CapsuleChain(nominal_mcpc(robot), robot.T_flange_cam)
    folded = robot.home.copy()
    folded[2] = np.radians(175.0)  # forearm folded back onto the upper arm
    assert not chain.ok(folded[None])[0]
    down = robot.home.copy()
    down[1] = np.radians(10.0)  # upper arm pointing below the horizontal: wrist under the table
    P = chain.points(down[None])[0]
    assert P[2:, 2].min() < 0  # the premise: part of the arm is below the table
    assert not chain.ok(down[None])[0]
    # the same posture with the table 1 m lower is fine as far as the floor goes
    low = CapsuleChain(chain.model, robot.T_flange_cam, floor_z_m=-1.0)
    assert low.ok(down[None])[0]
