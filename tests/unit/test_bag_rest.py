"""The rest test of `selfcal import --bag` (selfcal/ros/bag_rest.py): interpolation of the joint readings
at image stamps and the five verdicts (rest, moving, gap, outside, empty)."""

from __future__ import annotations

import numpy as np
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from selfcal.ros.bag_rest import EMPTY, GAP, MOVING, OUTSIDE, REST, JointTrack, RestRule

NS = 1_000_000_000
RULE = RestRule()  # 0.5 s window, 0.3 deg/s, 0.05 s gap


def track(t_s, q, types=("revolute",)):
    return JointTrack(
        (np.asarray(t_s) * NS).astype(np.int64), np.asarray(q, float).reshape(len(t_s), -1), types
    )


@settings(max_examples=examples(50), deadline=None)
@given(st.lists(st.integers(0, 10**12), min_size=2, max_size=40, unique=True),
       st.integers(0, 2**31))  # fmt: skip
def test_readings_at_their_stamps_come_back_unchanged(stamps, seed):
    rng = np.random.default_rng(seed)
    q = rng.normal(0, 2, (len(stamps), 3))
    tr = JointTrack(np.array(stamps, np.int64), q, ("revolute",) * 3)
    for t, row in zip(stamps, q, strict=True):
        np.testing.assert_array_equal(tr.at(t), row)


def test_interpolation_is_linear_and_sorts_by_stamp():
    tr = track([2.0, 0.0, 1.0], [2.0, 0.0, 1.0])
    assert tr.at(int(0.25 * NS))[0] == 0.25 and tr.at(int(1.5 * NS))[0] == 1.5


def test_verdicts():
    t = np.arange(0, 10, 0.01)
    still = track(t, np.full_like(t, 0.3))
    assert still.status(5 * NS, RULE) == REST
    assert still.status(int(0.1 * NS), RULE) == OUTSIDE  # the window starts before the recording
    assert still.status(20 * NS, RULE) == OUTSIDE
    slow = track(t, 0.9 * RULE.speed_rad_s * t)  # just below the threshold
    fast = track(t, 1.1 * RULE.speed_rad_s * t)
    assert slow.status(5 * NS, RULE) == REST and fast.status(5 * NS, RULE) == MOVING
    holes = np.r_[t[t < 4.9], t[t > 5.0]]  # a 0.1 s pause within the window
    assert track(holes, np.zeros_like(holes)).status(5 * NS, RULE) == GAP
    hole = np.r_[t[t < 4], t[t > 6]]  # no message at all within +-0.25 s
    assert track(hole, np.zeros_like(hole)).status(5 * NS, RULE) == EMPTY


def test_a_prismatic_joint_has_its_own_threshold():
    t = np.arange(0, 10, 0.01)
    q = np.c_[np.zeros_like(t), 0.5 * RULE.speed_m_s * t]
    assert track(t, q, ("revolute", "prismatic")).status(5 * NS, RULE) == REST
    q = np.c_[np.zeros_like(t), 2.0 * RULE.speed_m_s * t]
    assert track(t, q, ("revolute", "prismatic")).status(5 * NS, RULE) == MOVING


def test_same_rest_spans_the_time_between_two_stamps():
    t = np.arange(0, 10, 0.01)
    q = np.where(t < 5, 0.0, 0.1)  # a step at 5 s
    tr = track(t, q)
    assert tr.same_rest(1 * NS, 4 * NS, RULE) and tr.same_rest(6 * NS, 9 * NS, RULE)
    assert not tr.same_rest(4 * NS, 6 * NS, RULE)
