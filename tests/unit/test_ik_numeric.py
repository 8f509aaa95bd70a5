"""Numerical IK of any serial arm (selfcal.kinematics.ik_numeric): IK of FK reproduces the tool pose.

Ground truth: forward kinematics of the robots' nominal MCPC chains (``fk_tool``), which
tests/unit/test_kinematics.py checks against the DH tables.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from conftest import examples
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from selfcal.kinematics import ik_numeric
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.ik import UnreachableError
from selfcal.kinematics.ik_numeric import (
    STALL_TOL,
    ToolTarget,
    ik_robot,
    pose_jacobian,
    pose_residual,
    solve_ik,
)
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import list_robots, load_robot

ROBOTS = tuple(list_robots())
_CACHE = {name: load_robot(name) for name in ROBOTS}
# Measured over 1000 random postures per robot: worst position error 6e-16 m, rotation 2e-15 rad.
TOL = 1e-9


def _posture(robot, u):
    lo, hi = robot.limits.T
    return lo + np.asarray(u) * (hi - lo)


def _assert_same_pose(model, q, T, tol=TOL):
    T2 = fk_tool(model, q[None])[0]
    assert np.linalg.norm(T2[:3, 3] - T[:3, 3]) < tol
    assert np.linalg.norm(Rotation.from_matrix(T2[:3, :3].T @ T[:3, :3]).as_rotvec()) < tol


# the ER-4u's vendor table (the paper's ER-4u with other numbers, the same closed form first) in
# the slow tier: the default tier keeps to ~90 s
@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.slow) if n == "er4u-vendor" else n for n in ROBOTS]
)
@settings(max_examples=examples(15), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(u=st.lists(st.floats(0.0, 1.0), min_size=7, max_size=7))
@example(u=[0.0, 0.0, 0.0, 0.4375, 1e-08, 0.0, 0.0])
def test_ik_of_fk_reproduces_the_pose(name, u):
    """Both the dispatch (closed form first for an ER-type arm) and the numerical solver. At a
    singular posture (the Jacobian's condition over 1e3; the @example is the UR5e's wrist
    singularity at q5 = -360 deg that hypothesis found, 2e-18 * sv[0]) the steps may stall short
    of the 1e-10 tolerance (1e-9 m / up to 8e-8 rad measured there, once called "out of reach,
    0.000 mm"): the pose within :data:`STALL_TOL`, and the result states its own error."""
    robot = _CACHE[name]
    model = nominal_mcpc(robot)
    q = _posture(robot, u[: robot.n])
    sv = np.linalg.svd(pose_jacobian(model, q[None])[0], compute_uv=False)
    tol = TOL if sv[-1] > 1e-3 * sv[0] else STALL_TOL
    T = fk_tool(model, q[None])[0]
    target = ToolTarget(T[:3, 3], T[:3, :3])
    res = ik_robot(robot, target)
    _assert_same_pose(model, res.joints, T, tol)
    robot.check_joints(res.joints)
    if res.start == "analytic":  # the closed form answered: now the numerical solver alone
        num = solve_ik(model, robot.limits, target, reference=robot.home, home=robot.home)
    else:  # ik_robot ran solve_ik with these very arguments (deterministic): not twice
        num = res
    _assert_same_pose(model, num.joints, T, tol)
    robot.check_joints(num.joints)
    T2 = fk_tool(model, num.joints[None])[0]
    assert num.position_error_m == pytest.approx(np.linalg.norm(T2[:3, 3] - T[:3, 3]), abs=1e-15)


@pytest.mark.parametrize("name", ["er4u-paper", "er4u-vendor"])
def test_er_type_arms_take_the_closed_form(name):
    robot = _CACHE[name]
    q = robot.home + np.radians(3.0)
    robot.check_joints(q)
    T = fk_tool(nominal_mcpc(robot), q[None])[0]
    res = ik_robot(robot, ToolTarget(T[:3, 3], T[:3, :3]))
    assert res.start == "analytic"
    np.testing.assert_allclose(res.joints, q, atol=1e-9)


@pytest.fixture
def few_starts(monkeypatch):
    """ik_robot's solve_ik with 8 random starts instead of 64: an unreachable target fails every
    start (0.1-0.2 s each on 2 loaded cores); 8 give the same closest distance (131.073 mm below, 16.187 mm for the ER-4u pose)."""
    monkeypatch.setattr(ik_numeric, "solve_ik", functools.partial(solve_ik, n_random=8))


@pytest.mark.usefixtures("few_starts")
def test_er_pose_the_5_axis_arm_cannot_take_is_unreachable():
    """An orientation off the closed form's family goes to the numerical solver, which says so."""
    robot = _CACHE["er4u-paper"]
    T = fk_tool(nominal_mcpc(robot), robot.home[None])[0]
    R = Rotation.from_rotvec([0.3, 0.2, 0.1]).as_matrix() @ T[:3, :3]
    with pytest.raises(UnreachableError, match="from 10 starts"):
        ik_robot(robot, ToolTarget(T[:3, 3], R))


@pytest.mark.parametrize("name", ROBOTS)
def test_position_only_target(name):
    robot = _CACHE[name]
    model = nominal_mcpc(robot)
    q = robot.home + 0.2
    p = fk_tool(model, q[None])[0, :3, 3]
    res = ik_robot(robot, ToolTarget(p))
    assert res.angle_error_rad == 0.0
    np.testing.assert_allclose(fk_tool(model, res.joints[None])[0, :3, 3], p, atol=TOL)


def test_reference_selects_the_nearby_solution():
    """A 6-axis arm has up to 8 solutions; starting from the reference keeps its branch."""
    robot = _CACHE["ur5e"]
    model = nominal_mcpc(robot)
    q = robot.home + np.radians([10, 5, -8, 12, 7, 30])
    T = fk_tool(model, q[None])[0]
    res = ik_robot(robot, ToolTarget(T[:3, 3], T[:3, :3]), reference=q + 0.05)
    np.testing.assert_allclose(res.joints, q, atol=1e-9)
    assert res.start == "reference"


@pytest.mark.usefixtures("few_starts")
def test_unreachable_target_raises_with_distance():
    robot = _CACHE["ur5e"]
    # beyond the sum of the link lengths (1.3123 m): refused at once, by how much
    with pytest.raises(UnreachableError, match="longest possible reach") as err:
        ik_robot(robot, ToolTarget(np.array([2.0, 0.0, 0.5])))
    assert err.value.distance_m == pytest.approx(np.hypot(2.0, 0.5) - 1.3123, abs=1e-9)
    # within that bound but beyond the arm's real reach (about 0.95 m from the shoulder)
    with pytest.raises(UnreachableError, match="from 10 starts") as err:
        ik_robot(robot, ToolTarget(np.array([1.1, 0.0, 0.1625])))
    assert err.value.distance_m > 0.1


def test_joint_ranges_are_respected():
    """A target reachable only outside a (narrowed) range is refused. (With +-50 deg the other
    shoulder solution, joint 1 = -24 deg, would reach it.)"""
    robot = _CACHE["ur5e"]
    model = nominal_mcpc(robot)
    q = robot.home.copy()
    q[0] = np.radians(120.0)
    T = fk_tool(model, q[None])[0]
    limits = robot.limits.copy()
    limits[0] = np.radians([-20.0, 20.0])
    with pytest.raises(UnreachableError):
        solve_ik(model, limits, ToolTarget(T[:3, 3], T[:3, :3]), n_random=8)


def test_jacobian_matches_finite_differences():
    robot = _CACHE["ur5e"]
    model = nominal_mcpc(robot)
    q = robot.home + 0.1
    T = fk_tool(model, q[None])[0]
    target = ToolTarget(T[:3, 3] + 0.01, T[:3, :3])
    J = pose_jacobian(model, q[None])[0]
    h = 1e-7
    Jfd = np.column_stack(
        [
            (
                pose_residual(model, q + h * e, target)[0]
                - pose_residual(model, q - h * e, target)[0]
            )
            / (2 * h)
            for e in np.eye(robot.n)
        ]
    )
    # the rotation rows are exact at zero rotation error only: the target has the same rotation
    np.testing.assert_allclose(J, Jfd, atol=1e-7)


def test_bad_targets_are_input_errors():
    with pytest.raises(ValueError, match="finite 3-vector"):
        ToolTarget.checked([0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="not a rotation"):
        ToolTarget.checked([0.0, 0.0, 0.0], 2 * np.eye(3))
