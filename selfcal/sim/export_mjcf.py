"""MJCF export of a calibrated robot: the nominal ``er4u-*.xml`` with corrected body frames.

The file is built exactly like the committed nominal models (``selfcal.sim.robot_mjcf.robot_spec`` through
``mujoco.MjSpec``; same body, joint, site, camera, actuator and keyframe names, same visuals), but
from the deployed chain of :func:`selfcal.export.deploy.deploy`: the MuJoCo world is the robot's base frame
(DH frame 0 of the identified joint axes 1 and 2, which for the nominal robot is the nominal
models' world), body ``link<k>`` is the calibrated link frame, ``rig`` holds the calibrated stereo
cameras (calibrated intrinsics and baseline when the calibration has them) and site ``tool_tip``
is the calibrated tool tip. ``qpos`` = the controller's joint readings (rad), so a controller
model, a planner or a digital twin can use it in place of the nominal file (e.g. ``<include>`` it
from ``scene.xml`` instead of ``er4u-paper.xml``). Poses are written with full float64 precision
(as ``selfcal.sim.build_models`` does), so the file reproduces the calibrated frames to ~1e-15 m.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from selfcal.errors import InputError
from selfcal.export.deploy import BASE_FRAME, DeployedModel, as_deployed
from selfcal.io.atomic import write_text_atomic
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.sim.build_models import precise_xml
from selfcal.sim.robot_mjcf import TOOL_SITE, RigConfig, robot_spec
from selfcal.transforms import inv_pose

__all__ = ["calibrated_spec", "calibrated_mjcf", "write_calibrated_mjcf"]


def _rig(dep: DeployedModel) -> RigConfig | None:
    if dep.intrinsics is None:
        return None
    T_lr = dep.T_left_right if dep.T_left_right is not None else RigConfig().T_left_right
    return RigConfig(intrinsics=dep.intrinsics, T_left_right=T_lr)


def calibrated_spec(dep: DeployedModel, robot: RobotDef | None = None) -> mujoco.MjSpec:
    """An ``MjSpec`` of the robot with the calibrated chain ``dep`` (world = base frame).

    ``robot`` (default: ``dep.robot_name``) supplies joint names, ranges, home and visuals' layout.

    Raises:
        ValueError: ``robot`` and ``dep`` disagree on the joints.
    """
    robot = load_robot(dep.robot_name) if robot is None else robot
    if tuple(robot.joint_names) != dep.joint_names or tuple(robot.joint_types) != dep.joint_types:
        raise InputError(
            f"the calibrated model's joints {dep.joint_names} do not match {robot.name}'s "
            f"{robot.joint_names}: export with the robot the calibration was made for"
        )
    spec = robot_spec(robot, dep.camera_model(), _rig(dep))
    spec.modelname = f"{robot.name}-calibrated"
    # robot_spec puts the tip at the robot file's T_cam_tip; use the deployed one (equal to
    # rounding for a calibration, but a parameter file may carry its own).
    tip = spec.site(TOOL_SITE)
    T = inv_pose(dep.T_tip_cam)
    tip.pos = T[:3, 3].copy()
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(T[:3, :3]).reshape(-1))
    tip.quat = q
    return spec


def calibrated_mjcf(calibration, robot: RobotDef | None = None) -> str:
    """MJCF text of the calibrated robot: ``calibration`` is a
    :class:`selfcal.io.calibration.CalibrationResult` or a :class:`selfcal.export.deploy.DeployedModel` (see
    the module docstring)."""
    dep = as_deployed(calibration, robot)
    spec = calibrated_spec(dep, robot)
    spec.compile()  # validates; to_xml reflects the compiled spec
    text = precise_xml(spec, spec.to_xml())
    comment = (
        f"{dep.robot_name} with CALIBRATED kinematics, written by scorbot-selfcal "
        f"(selfcal.sim.export_mjcf; source: {dep.source or 'n/a'}). World = {BASE_FRAME}. Site tool_tip = "
        "the calibrated tool tip; rig/cam_left, cam_right = the calibrated stereo cameras. "
        "qpos = joint readings (rad)."
    )
    return f"<!-- {comment.replace('--', '-')} -->\n{text}"


def write_calibrated_mjcf(path: str | Path, calibration, robot: RobotDef | None = None) -> Path:
    """Write :func:`calibrated_mjcf` to ``path`` (parent folders created); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, calibrated_mjcf(calibration, robot))
    return path
