"""Compensated IK of any serial arm (selfcal.export.compensate.solve_compensated_pose, `selfcal ik
--calibration` with --rpy-deg / --quat): the calibrated chain reaches the target exactly.

Ground truth: a perturbed UR5e chain (selfcal.sim.actual.perturb, 2 mm / 0.5 deg) plays the calibrated
model; its forward kinematics at a known posture gives the target.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.cli.main import main
from selfcal.export.compensate import solve_compensated_pose
from selfcal.export.deploy import as_deployed
from selfcal.export.robot_toml import to_toml
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.ik import UnreachableError
from selfcal.kinematics.ik_numeric import ToolTarget
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.sim.actual import perturb

ROBOT = load_robot("ur5e")


@pytest.fixture(scope="module")
def calibrated():
    actual = perturb(nominal_mcpc(ROBOT), seed=3, translation_m=0.002, rotation_rad=np.radians(0.5))
    return as_deployed(actual, ROBOT)


def test_calibrated_pose_is_reached_exactly(calibrated):
    q = ROBOT.home + np.radians([6.0, -4.0, 5.0, 3.0, -7.0, 20.0])
    T = calibrated.tool_tip(q[None])[0]
    res = solve_compensated_pose(calibrated, ROBOT, ToolTarget(T[:3, 3], T[:3, :3]))
    T2 = calibrated.tool_tip(res.joints[None])[0]
    # measured: 1e-16 m / 1e-16 rad
    assert np.linalg.norm(T2[:3, 3] - T[:3, 3]) < 1e-9
    assert np.linalg.norm(Rotation.from_matrix(T2[:3, :3].T @ T[:3, :3]).as_rotvec()) < 1e-9
    np.testing.assert_allclose(res.joints, q, atol=1e-9)  # the nominal start keeps the branch
    assert res.branch == "nominal"
    # the nominal IK misses the real pose: the commands differ by the kinematic errors
    assert np.max(np.abs(res.nominal_joints - q)) > np.radians(0.1)
    T_nom = calibrated.tool_tip(res.nominal_joints[None])[0]
    assert np.linalg.norm(T_nom[:3, 3] - T[:3, 3]) > 1e-4


def test_position_only_and_unreachable(calibrated):
    q = ROBOT.home + 0.1
    p = calibrated.tool_tip(q[None])[0, :3, 3]
    res = solve_compensated_pose(calibrated, ROBOT, ToolTarget(p))
    assert np.linalg.norm(calibrated.tool_tip(res.joints[None])[0, :3, 3] - p) < 1e-9
    with pytest.raises(UnreachableError, match="calibrated"):
        solve_compensated_pose(calibrated, ROBOT, ToolTarget(np.array([1.5, 0.0, 0.2])))


def test_cli_ik_with_calibration_takes_rpy(calibrated, capsys, tmp_path):
    path = tmp_path / "ur5e-calibrated.toml"
    path.write_text(to_toml(calibrated, ROBOT))
    q = ROBOT.home + np.radians([5.0, 3.0, -4.0, 6.0, 2.0, -10.0])
    T = calibrated.tool_tip(q[None])[0]
    xyz = ",".join(f"{v:.9f}" for v in T[:3, 3] * 1000)
    rpy = ",".join(f"{v:.9f}" for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz", True))
    argv = ["ik", f"--xyz={xyz}", f"--rpy-deg={rpy}", "--calibration", str(path)]
    assert main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    # 1e-9 mm / 1e-9 deg text rounding of the target moves the posture by ~1e-9 deg
    np.testing.assert_allclose(doc["joints_deg"], np.degrees(q), atol=1e-6)
    assert doc["residual_mm"] < 1e-6
    nominal = fk_tool(nominal_mcpc(ROBOT), np.radians([doc["nominal_joints_deg"]]))[0]
    np.testing.assert_allclose(nominal[:3, 3], T[:3, 3], atol=1e-9)
