"""The seed paper's Tables I and II against the er4u-paper model.

Table I gives the nominal DH parameters and the posture theta = (38.15, -30, 45, -63.54, 0) deg;
Table II lists five tool-tip positions with "Pitch (theta4) = -63.54 deg, Roll (theta5) = 0 deg".
Those two columns are joint angles (joint 4 and joint 5), not the controller's Cartesian pitch and
roll: with Table I's frames the tool axis at Table I's posture points down and back towards the
base, at a Cartesian pitch of theta2 + theta3 + theta4 - 90 = -138.54 deg.
"""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.config.paper_data import TABLE_I_THETA_DEG, TABLE_II_MM, TABLE_II_THETA4_DEG
from selfcal.kinematics.forward import fk_frames, fk_nominal
from selfcal.kinematics.ik import ik_nearest, nearest_reachable
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.tool_pose import tool_pose
from selfcal.robot.definition import load_robot

DEG = np.pi / 180
THETA4 = TABLE_II_THETA4_DEG * DEG  # Table II "Pitch (theta4)"
THETA5 = 0.0  # Table II "Roll (theta5)"


@pytest.fixture(scope="module")
def robot():
    return load_robot("er4u-paper")


def test_table_one_dh_matches_the_model(robot):
    np.testing.assert_allclose(np.degrees(robot.dh.alpha), [90, 0, 0, 90, 0])
    np.testing.assert_allclose(robot.dh.a * 1000, [101.25, 220, 220, 0, 0])
    np.testing.assert_allclose(robot.dh.d * 1000, [334.25, 0, 0, 0, 137.35])
    np.testing.assert_allclose(np.degrees(robot.home), TABLE_I_THETA_DEG)


def test_table_one_posture_gives_table_two_row_one(robot):
    """FK at Table I's theta column puts the tool point at Table II row 1 within 0.1 mm (the
    table prints 0.1 mm; the model gives (315.618, 247.921, 190.251) mm)."""
    q = TABLE_I_THETA_DEG * DEG
    for T in (fk_frames(nominal_mcpc(robot), q)[0, -1], fk_nominal(robot, q)[0, -1]):
        np.testing.assert_allclose(T[:3, 3] * 1000, TABLE_II_MM[0], atol=0.1)
    _, pitch, roll = tool_pose(fk_nominal(robot, q)[0, -1])
    assert abs(np.degrees(pitch) - (-138.54)) < 1e-9  # Cartesian pitch, not -63.54
    assert abs(roll) < 1e-12


def _fixed_wrist_reach(robot, theta4: float) -> tuple[float, float]:
    """With joint 4 fixed at ``theta4`` the elbow-to-tool vector is rigid. In frame 3 it is
    ``(a3 + d5 sin theta4, -d5 cos theta4)`` (elbow at (-a3, 0), tool at A4(theta4) Tz(d5)).
    Returns its length L and the elbow angle theta3 that aligns it with the upper arm."""
    a3, d5 = robot.dh.a[2], robot.dh.d[4]
    v = np.array([a3 + d5 * np.sin(theta4), -d5 * np.cos(theta4)])
    return float(np.hypot(*v)), float(-np.arctan2(v[1], v[0]))


def test_table_two_with_joint_four_fixed(robot):
    """Table II as printed: theta4 = -63.54 deg, theta5 = 0 held, the other joints free in range.

    Rows 1, 3, 4, 5 are reachable (tool point within 1e-6 mm). Row 2 is NOT: it lies
    rho = 342.048 mm from the shoulder axis point (joint 2's axis, a1 = 101.25 mm out at height
    d1 = 334.25 mm, in the vertical plane through the target), while with theta4 fixed the
    elbow-to-tool link is rigid with length L = sqrt(a3^2 + d5^2 + 2 a3 d5 sin theta4) = 114.725 mm,
    so the arm reaches at most a2 + L = 334.725 mm. The stretched posture that attains it is inside
    every joint range, so the true distance from row 2 to the reachable set is rho - (a2 + L) =
    7.324 mm. The issue text says "about 5.2 mm"; that is not the distance (5.2 mm is merely the
    x-difference between rows 1 and 2). The paper's Table II is therefore inconsistent with its own
    Table I model: its row 2 cannot be reached with the printed pitch theta4 = -63.54 deg.
    """
    a1, d1, a2 = robot.dh.a[0], robot.dh.d[0], robot.dh.a[1]
    fixed = {3: THETA4, 4: THETA5}
    L, th3_stretch = _fixed_wrist_reach(robot, THETA4)
    for i, p_mm in enumerate(TABLE_II_MM):
        p = p_mm / 1000
        q, dist = nearest_reachable(robot, p, fixed)
        robot.check_joints(q)
        assert q[3] == THETA4 and q[4] == THETA5
        np.testing.assert_allclose(
            np.linalg.norm(fk_nominal(robot, q)[0, -1, :3, 3] - p), dist, atol=0
        )
        rho = np.hypot(np.hypot(p[0], p[1]) - a1, p[2] - d1)
        if i == 1:
            # Analytic witness: the stretched posture aimed at row 2, checked to be in range.
            th2 = np.arctan2(p[2] - d1, np.hypot(p[0], p[1]) - a1)
            q_star = np.array([np.arctan2(p[1], p[0]), th2, th3_stretch, THETA4, THETA5])
            robot.check_joints(q_star)
            tip = fk_nominal(robot, q_star)[0, -1, :3, 3]
            analytic = rho - (a2 + L)
            assert np.linalg.norm(tip - p) == pytest.approx(analytic, abs=1e-12)
            assert dist == pytest.approx(analytic, abs=1e-9)  # numeric optimum = analytic, 1e-6 mm
            assert analytic > 5e-3  # row 2 is millimetres out of reach, not a rounding matter
        else:
            assert dist < 1e-9, f"row {i + 1}: nearest reachable point {dist * 1000:.6f} mm away"
            assert rho < a2 + L


def test_table_two_with_cartesian_pitch_of_row_one(robot):
    """Holding instead the Cartesian tool pitch and roll that FK gives at Table I's posture
    (-138.54 deg, 0), all five rows have an in-range IK solution that reproduces them."""
    _, pitch, roll = tool_pose(fk_nominal(robot, robot.home)[0, -1])
    for p_mm in TABLE_II_MM:
        q = ik_nearest(robot, p_mm / 1000, pitch, roll)
        robot.check_joints(q)
        xyz, p2, r2 = tool_pose(fk_nominal(robot, q)[0, -1])
        np.testing.assert_allclose(xyz * 1000, p_mm, atol=1e-6)
        assert abs(p2 - pitch) < 1e-9 and abs(r2 - roll) < 1e-9
        # The branch nearest home is Table I's elbow configuration (theta3 within 10 deg of 45).
        assert abs(np.degrees(q[2]) - 45.0) < 10.0
