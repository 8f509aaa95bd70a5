"""Where the robot's link bodies sit: the MCPC chain realised as MuJoCo body frames.

Body ``link_k`` sits at ``V_{k-1} Rz(o_k)`` in its parent (``V`` the MCPC shape matrices, ``o_k``
the joint's constant offset) and moves about its own z axis, so its frame IS the MCPC link frame
``F_k`` of :func:`selfcal.kinematics.forward.fk_frames`; the rig (the left camera) sits at ``V_n`` on the last
link. ``selfcal.sim.robot_mjcf`` builds the model from these poses, ``selfcal.sim.robot_shapes`` lays the shapes
out along them.
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc, shape_matrices
from selfcal.robot.definition import RobotDef
from selfcal.transforms import inv_pose, rot_z

__all__ = [
    "link_body_names",
    "nominal_camera_model",
    "link_body_poses",
    "flange_in_last_link",
    "next_joint",
]


def link_body_names(n: int) -> tuple[str, ...]:
    """Body names of an n-joint arm's links: ``link1`` ... ``link<n>``."""
    return tuple(f"link{k + 1}" for k in range(n))


def _motion_offset(model: MCPCModel, k: int) -> np.ndarray:
    """``Rz(o_k)`` for revolute joint index k (0-based); identity for a prismatic joint."""
    if model.joint_types[k] == "revolute":
        return rot_z(model.joint_offsets[k])
    return np.eye(4)


def nominal_camera_model(robot: RobotDef) -> MCPCModel:
    """The nominal MCPC chain with the left camera (OpenCV frame) as its tool:
    ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)``."""
    return nominal_mcpc(robot).with_tool(robot.T_flange_cam)


def link_body_poses(model: MCPCModel) -> np.ndarray:
    """Body poses relative to their parents, (n + 1, 4, 4): ``V_{k-1} Rz(o_k)`` for ``link_k``
    (k = 1..n, the first relative to the fixed base = world) and ``V_n`` for the rig."""
    V = shape_matrices(model.params)
    out = np.empty((model.n + 1, 4, 4))
    for k in range(model.n):
        out[k] = V[k] @ _motion_offset(model, k)
    out[model.n] = V[model.n]
    out[0] = rot_z(model.base_offset) @ out[0]
    return out


def flange_in_last_link(robot: RobotDef, model: MCPCModel) -> np.ndarray:
    """Pose (4, 4) of the nominal flange (last DH frame) in the last link's body frame.

    The nominal camera chain ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)`` puts the camera at
    ``V_n`` and so the flange at ``V_n inv(T_flange_cam)``; a different constant offset of the last
    joint in ``model`` (from the gauge fix) rotates the link frame about its axis.
    """
    nominal = nominal_camera_model(robot)
    n = robot.n
    V_n = shape_matrices(nominal.params[n])
    corr = np.eye(4)
    if robot.joint_types[n - 1] == "revolute":
        corr = rot_z(nominal.joint_offsets[n - 1] - model.joint_offsets[n - 1])
    return corr @ V_n @ inv_pose(robot.T_flange_cam)


def next_joint(model: MCPCModel, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Origin and axis of joint k + 2's frame (1-based k + 1 is this link) in link k + 1's frame."""
    T = shape_matrices(model.params[k + 1]) @ _motion_offset(model, k + 1)
    return T[:3, 3].copy(), T[:3, 2].copy()
