"""Tool pose convention and inverse kinematics (selfcal.kinematics.tool_pose, selfcal.kinematics.ik).

Ground truth: forward kinematics straight from the DH table (``fk_nominal``) and the MCPC chain
(``fk_frames``); the geometric definitions of pitch and roll written out independently here.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import examples
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from selfcal.kinematics.forward import fk_frames, fk_nominal
from selfcal.kinematics.ik import (
    IKStructureError,
    UnreachableError,
    check_er_structure,
    ik,
    ik_nearest,
    nearest_reachable,
    wrap_into_range,
)
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.tool_pose import tool_frame, tool_pose
from selfcal.robot.definition import load_robot, with_dh

ROBOTS = ("er4u-paper", "er4u-vendor")
DEG = np.pi / 180
_CACHE = {name: load_robot(name) for name in ROBOTS}


def _angle_diff(a, b):
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


def fk_pose(robot, q):
    """(xyz, pitch, roll) of the MCPC tool frame, azimuth hint = joint 1 direction."""
    q = np.atleast_2d(q)
    T = fk_frames(nominal_mcpc(robot), q)[:, -1]
    return tool_pose(T, azimuth_rad=q[:, 0] + robot.dh.offset[0])


# --------------------------------------------------------------------------------------------
# Convention
# --------------------------------------------------------------------------------------------


def test_zero_posture_pitch_of_both_models():
    """Paper model at theta = 0: tool axis straight down (pitch -90). Vendor: horizontal (0)."""
    for name, want in (("er4u-paper", -90.0), ("er4u-vendor", 0.0)):
        robot = _CACHE[name]
        T = fk_nominal(robot, np.zeros(5))[0, -1]
        _, pitch, roll = tool_pose(T)
        assert abs(np.degrees(pitch) - want) < 1e-9, name
        assert abs(np.degrees(roll)) < 1e-9, name
    z = fk_nominal(_CACHE["er4u-paper"], np.zeros(5))[0, -1, :3, 2]
    np.testing.assert_allclose(z, [0, 0, -1], atol=1e-15)


def test_table_one_cartesian_pitch_is_not_joint_four():
    """Table II's "Pitch (theta4)" = -63.54 deg is joint 4's angle: the Cartesian pitch of the
    tool axis at Table I's posture is theta2 + theta3 + theta4 - 90 = -138.54 deg (down, back)."""
    robot = _CACHE["er4u-paper"]
    _, pitch, _ = tool_pose(fk_nominal(robot, robot.home)[0, -1])
    assert abs(np.degrees(pitch) - (-30 + 45 - 63.54 - 90)) < 1e-9


@settings(max_examples=examples(60), deadline=None, derandomize=True)
@given(name=st.sampled_from(ROBOTS), u=st.lists(st.floats(0, 1), min_size=5, max_size=5))
def test_pitch_roll_match_geometric_definition(name, u):
    """Independent geometry: pitch from atan2 of the tool axis against r_hat; roll = theta5 +
    offset5 on the front branch (tool point on joint 1's x side), + 180 deg on the back branch."""
    robot = _CACHE[name]
    q = robot.limits[:, 0] + np.array(u) * (robot.limits[:, 1] - robot.limits[:, 0])
    F = fk_nominal(robot, q)[0]
    p, z = F[-1, :3, 3], F[-1, :3, 2]
    assume(np.hypot(p[0], p[1]) > 1e-3)
    r_hat = np.array([p[0], p[1], 0.0]) / np.hypot(p[0], p[1])
    _, pitch, roll = tool_pose(F[-1])
    assert abs(_angle_diff(pitch, np.arctan2(z[2], z @ r_hat))) < 1e-12
    front = F[0, :3, 0] @ r_hat > 0  # DH x1 is the joint-1 direction
    want_roll = q[4] + robot.dh.offset[4] + (0.0 if front else np.pi)
    assert abs(_angle_diff(roll, want_roll)) < 1e-9


def test_tool_frame_inverts_tool_pose():
    rng = np.random.default_rng(3)
    xyz = rng.uniform(-0.5, 0.5, (50, 3))
    pitch, roll = rng.uniform(-np.pi, np.pi, 50), rng.uniform(-np.pi, np.pi, 50)
    T = tool_frame(xyz, pitch, roll)
    np.testing.assert_allclose(
        T[:, :3, :3] @ T[:, :3, :3].transpose(0, 2, 1),
        np.eye(3)[None] * np.ones((50, 1, 1)),
        atol=1e-14,
    )
    np.testing.assert_allclose(np.linalg.det(T[:, :3, :3]), 1.0, atol=1e-14)
    xyz2, p2, r2 = tool_pose(T)
    np.testing.assert_allclose(xyz2, xyz, atol=0)
    assert np.max(np.abs(_angle_diff(p2, pitch))) < 1e-12
    assert np.max(np.abs(_angle_diff(r2, roll))) < 1e-12


def test_tool_point_on_base_axis_needs_azimuth():
    T = tool_frame(np.array([0.0, 0.0, 0.5]), -0.3, 0.2, azimuth_rad=0.7)
    with pytest.raises(ValueError, match="azimuth_rad"):
        tool_pose(T)
    _, p, r = tool_pose(T, azimuth_rad=0.7)
    assert abs(p - -0.3) < 1e-12 and abs(r - 0.2) < 1e-12


# --------------------------------------------------------------------------------------------
# IK <-> FK
# --------------------------------------------------------------------------------------------


@settings(
    max_examples=examples(150),
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.filter_too_much],
)
@given(name=st.sampled_from(ROBOTS), u=st.lists(st.floats(0, 1), min_size=5, max_size=5))
def test_ik_inverts_fk(name, u):
    """Every branch reproduces position (1e-6 mm) and pitch/roll (1e-6 deg); one branch reproduces
    the joints. Joint tolerance 1e-6 rad: at a stretched elbow (theta3 = 0, a hypothesis favourite)
    theta3 is the square root of a rounding error, ~5e-8 rad; elsewhere the match is ~1e-12 rad.
    Targets within 1 mm of the base axis are excluded: there pitch/roll are measured from the
    joint-1 direction, which is ill-conditioned from the position alone."""
    robot = _CACHE[name]
    q = robot.limits[:, 0] + np.array(u) * (robot.limits[:, 1] - robot.limits[:, 0])
    xyz, pitch, roll = (v[0] for v in fk_pose(robot, q))
    assume(np.hypot(xyz[0], xyz[1]) > 1e-3)
    sols = ik(robot, xyz, pitch, roll)
    assert 1 <= len(sols) <= 4
    assert len({s.branch for s in sols}) == len(sols)
    Q = np.array([s.joints for s in sols])
    xyz2, p2, r2 = fk_pose(robot, Q)
    assert np.max(np.linalg.norm(xyz2 - xyz, axis=1)) < 1e-9  # 1e-6 mm
    assert np.max(np.abs(_angle_diff(p2, pitch))) < 1e-6 * DEG
    assert np.max(np.abs(_angle_diff(r2, roll))) < 1e-6 * DEG
    err = np.max(np.abs(_angle_diff(Q, q[None])), axis=1)
    assert np.min(err) < 1e-6, f"no branch reproduces q; closest differs by {np.min(err):.3g} rad"
    best = sols[int(np.argmin(err))]
    assert best.in_range and best.violations == ()
    # Flags are honest: in_range <=> inside the limits.
    for s in sols:
        inside = np.all(
            (s.joints >= robot.limits[:, 0] - 1e-12) & (s.joints <= robot.limits[:, 1] + 1e-12)
        )
        assert s.in_range == bool(inside)
        assert len(s.violations) == int(
            np.sum(
                (s.joints < robot.limits[:, 0] - 1e-12) | (s.joints > robot.limits[:, 1] + 1e-12)
            )
        )


def test_ik_branches_near_the_base_axis():
    """Tool point 224 mm from the base axis, tool axis horizontal outwards: the wrist centre is
    within reach of the shoulder in both base orientations, so all four branches exist; only the
    reach-over one (back, elbow above the shoulder-wrist line) is inside the paper's ranges."""
    robot = _CACHE["er4u-paper"]
    xyz = np.array([0.2, 0.1, 0.5])
    sols = {s.branch: s for s in ik(robot, xyz, 0.0, 0.3)}
    assert sorted(sols) == [
        "back/elbow-down",
        "back/elbow-up",
        "front/elbow-down",
        "front/elbow-up",
    ]
    assert [b for b, s in sols.items() if s.in_range] == ["back/elbow-up"]
    back = sols["back/elbow-up"].joints
    assert abs(_angle_diff(back[0], np.arctan2(0.1, 0.2) + np.pi)) < 1e-12
    # Roll on the back branch is theta5 + 180 deg.
    assert abs(_angle_diff(back[4], 0.3 - np.pi)) < 1e-12
    # Elbow-up: the elbow (DH frame 2 origin) lies above the shoulder->wrist line.
    F = fk_nominal(robot, back)[0]
    s, e, w = F[0, :3, 3], F[1, :3, 3], F[2, :3, 3]
    t = np.dot(e - s, w - s) / np.dot(w - s, w - s)
    assert e[2] > (s + t * (w - s))[2]
    np.testing.assert_allclose(ik_nearest(robot, xyz, 0.0, 0.3), back, atol=0)


def test_front_elbow_up_is_the_usual_posture():
    """Table I's posture (elbow below the line: theta3 = +45 deg) is front/elbow-down for the
    paper model; the vendor home (theta3 = -95 deg) is front/elbow-up."""
    for name, want in (("er4u-paper", "front/elbow-down"), ("er4u-vendor", "front/elbow-up")):
        robot = _CACHE[name]
        xyz, pitch, roll = (v[0] for v in fk_pose(robot, robot.home))
        match = [
            s.branch
            for s in ik(robot, xyz, pitch, roll)
            if np.max(np.abs(_angle_diff(s.joints, robot.home))) < 1e-9
        ]
        assert match == [want], name


def test_ik_nearest_prefers_reference_and_wraps_roll():
    """Roll has +-570 deg: the equivalent nearest the reference is chosen; so is the branch."""
    robot = _CACHE["er4u-paper"]
    q = np.array([20.0, 30.0, -50.0, 10.0, 400.0]) * DEG
    xyz, pitch, roll = (v[0] for v in fk_pose(robot, q))
    np.testing.assert_allclose(ik_nearest(robot, xyz, pitch, roll, reference=q), q, atol=1e-9)
    # Default reference (home, roll 0): the principal roll 40 deg.
    assert abs(ik_nearest(robot, xyz, pitch, roll)[4] - 40 * DEG) < 1e-9
    # Reference on the other elbow branch with roll near -320 deg: that branch, roll -320 deg.
    sols = ik(robot, xyz, pitch, roll)
    alt = next(s.joints for s in sols if s.in_range and abs(s.joints[2] - q[2]) > 0.1)
    ref = alt.copy()
    ref[4] = -300 * DEG
    got = ik_nearest(robot, xyz, pitch, roll, reference=ref)
    np.testing.assert_allclose(got[:4], alt[:4], atol=1e-9)
    assert abs(got[4] - -320 * DEG) < 1e-9


def test_wrap_into_range():
    assert wrap_into_range(np.radians(200), -np.pi, np.pi)[0] == pytest.approx(np.radians(-160))
    lo, hi = np.radians([-570, 570])
    v, ok = wrap_into_range(np.radians(10), lo, hi, reference=np.radians(500))
    assert ok and v == pytest.approx(np.radians(370))
    v, ok = wrap_into_range(np.radians(140), *np.radians([-130, 130]))
    assert not ok and v == pytest.approx(np.radians(140))


# --------------------------------------------------------------------------------------------
# Unreachable targets and bad input
# --------------------------------------------------------------------------------------------


def test_out_of_reach_target_says_how_far():
    """Ground truth: the wrist centre (tool point - d5 * tool axis) at distance rho from the
    shoulder axis point; the arm reaches a2 + a3. Tool axis straight down (pitch -90 deg)."""
    robot = _CACHE["er4u-paper"]
    a1, d1, a2, a3, d5 = robot.dh.a[0], robot.dh.d[0], robot.dh.a[1], robot.dh.a[2], robot.dh.d[4]
    xyz = np.array([0.3, 0.4, 0.9])
    wrist = xyz + np.array([0, 0, d5])
    rho = np.hypot(np.hypot(wrist[0], wrist[1]) - a1, wrist[2] - d1)
    assert rho > a2 + a3
    assert ik(robot, xyz, -np.pi / 2, 0.0) == []
    with pytest.raises(UnreachableError, match="out of reach") as exc:
        ik_nearest(robot, xyz, -np.pi / 2, 0.0)
    assert exc.value.distance_m == pytest.approx(rho - a2 - a3, abs=1e-12)
    assert f"{(rho - a2 - a3) * 1000:.3f} mm" in str(exc.value)
    assert isinstance(exc.value, ValueError)


def test_range_blocked_target_names_joint_and_range():
    """Straight behind the base (azimuth 180 deg): front branch needs base 180, outside +-155;
    back branch reaches over the top and needs shoulder beyond 130 deg."""
    robot = _CACHE["er4u-paper"]
    xyz = np.array([-0.45, 0.0, 0.2])
    sols = ik(robot, xyz, -np.pi / 2, 0.0)
    assert sols and not any(s.in_range for s in sols)
    with pytest.raises(
        UnreachableError, match=r"joint 1 \(base\) = .*\[-155\.00, 155\.00\]"
    ) as exc:
        ik_nearest(robot, xyz, -np.pi / 2, 0.0)
    assert exc.value.distance_m is None and len(exc.value.blocked_by) == len(sols)


def test_ik_rejects_other_structures():
    robot = _CACHE["er4u-paper"]
    check_er_structure(robot)
    bad = with_dh(robot, dataclasses.replace(robot.dh, a=robot.dh.a + np.array([0, 0, 0, 0.01, 0])))
    with pytest.raises(IKStructureError, match=r"a4 = 10 mm must be 0"):
        ik(bad, np.array([0.3, 0.2, 0.2]), 0.0, 0.0)
    dh = robot.dh
    bad = with_dh(robot, dataclasses.replace(dh, alpha=dh.alpha + np.array([0, 0.1, 0, 0, 0])))
    with pytest.raises(IKStructureError, match="alpha2"):
        ik(bad, np.array([0.3, 0.2, 0.2]), 0.0, 0.0)


def test_ik_rejects_bad_target():
    robot = _CACHE["er4u-paper"]
    with pytest.raises(ValueError, match="3-vector"):
        ik(robot, np.zeros(2), 0.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        ik(robot, np.array([np.nan, 0, 0]), 0.0, 0.0)


# --------------------------------------------------------------------------------------------
# nearest_reachable
# --------------------------------------------------------------------------------------------


def test_nearest_reachable_finds_reachable_point_and_respects_fixed_joints():
    robot = _CACHE["er4u-vendor"]
    q_true = np.array([30.0, 60.0, -40.0, -50.0, 10.0]) * DEG
    p = fk_nominal(robot, q_true)[0, -1, :3, 3]
    q, dist = nearest_reachable(robot, p, {"pitch": q_true[3], 4: q_true[4]})
    assert dist < 1e-12
    assert q[3] == q_true[3] and q[4] == q_true[4]
    robot.check_joints(q)
    np.testing.assert_allclose(fk_nominal(robot, q)[0, -1, :3, 3], p, atol=1e-12)


def test_nearest_reachable_out_of_reach_distance_is_analytic():
    """All joints free, target far along +x at shoulder height: nearest point is the stretched arm,
    distance = |p - shoulder| - (a2 + a3 + d5) (the tool axis can align with the arm)."""
    robot = _CACHE["er4u-vendor"]
    a1, d1, a2, a3, d5 = robot.dh.a[0], robot.dh.d[0], robot.dh.a[1], robot.dh.a[2], robot.dh.d[4]
    p = np.array([1.0, 0.0, d1])
    q, dist = nearest_reachable(robot, p, {})
    assert dist == pytest.approx(1.0 - a1 - (a2 + a3 + d5), abs=1e-9)
    robot.check_joints(q)


def test_nearest_reachable_rejects_bad_fixed_joint():
    robot = _CACHE["er4u-paper"]
    with pytest.raises(ValueError, match=r"joint 4 \(pitch\) = 140\.000 deg"):
        nearest_reachable(robot, np.array([0.3, 0.2, 0.2]), {3: 140 * DEG})
    with pytest.raises(ValueError, match="unknown joint 'wrist'"):
        nearest_reachable(robot, np.array([0.3, 0.2, 0.2]), {"wrist": 0.0})
    with pytest.raises(ValueError, match="joint index 5"):
        nearest_reachable(robot, np.array([0.3, 0.2, 0.2]), {5: 0.0})
