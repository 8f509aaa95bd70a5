"""The static transforms of a board calibration with joints, with sigmas from its covariance.

A board calibration's chain (:func:`selfcal.calibration.board.robot.calibrate_robot_with_board`)
holds the cell's two mounts in its first and last rows. Read out in the robot's frames:

- eye-to-hand (world = the camera, tool = the board): base -> camera (``inv`` of the
  robot's base frame rebuilt on the identified axes 1 and 2,
  :func:`selfcal.kinematics.dh_table.canonical_base`) and flange -> board (the tool in the
  nominal flange of joint n);
- eye-in-hand (world = the board, tool = the camera): flange -> camera and base -> board.

Their sigmas (rotation about the parent's axes, rad; translation along them, m) are carried to
first order from the covariance of the chain's minimal parameters (the Cramer-Rao covariance of
:mod:`selfcal.calibration.board.bounds`, correlations included) by central differences. SI units.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.io.board_calibration import Mount
from selfcal.kinematics.dh_table import canonical_base
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, nominal_mcpc, shape_matrices
from selfcal.robot.definition import RobotDef
from selfcal.transforms import inv_pose, rot_z

__all__ = ["Mount", "flange_to_tool", "mounts"]


def _last_link_tool(model: MCPCModel) -> np.ndarray:
    """The last joint's frame -> the tool (its zero offset and last shape matrix)."""
    return rot_z(model.joint_offsets[-1]) @ shape_matrices(model.params[-1])


def flange_to_tool(model: MCPCModel, robot: RobotDef) -> np.ndarray:
    """``model``'s tool (4, 4, m) in the nominal flange of joint n: its last link relative to
    the nominal robot's. The chain's frames are fixed up to a half turn about each joint's
    axis (a common normal's sign: ``a, alpha -> -a, -alpha``; a fit placed in a turned world
    can come out so): of the last link and the last link turned half about joint n's axis, the
    one taken is that with which the nominal chain turns the tool as ``model`` does at zero
    joints and at home, seen from the frame rebuilt on axes 1 and 2
    (:func:`selfcal.kinematics.dh_table.canonical_base`; as it stands when that frame cannot be
    rebuilt). The last joint frame's x axis at zero joints, compared before, told the two apart
    only where it stands near the nominal's or against it: the ER-4u's board calibrations' came
    out across it (dot product -0.007), and the camera was read out turned half about the
    flange's z axis (179.6 deg, 90 mm from the robot file's mount;
    tests/integration/test_plan_check.py)."""
    L = _last_link_tool(model)
    to_flange = inv_pose(_last_link_tool(nominal_mcpc(robot)))
    try:
        base = canonical_base(model, robot)
    except ValueError:
        return to_flange @ L
    q = np.stack([np.zeros(model.n), np.asarray(robot.home, float)])
    R_model = (inv_pose(base) @ fk_tool(model, q))[:, :3, :3]
    nominal = nominal_mcpc(robot)

    def agreement(T_flange_tool: np.ndarray) -> float:
        """The traces of the tool's rotation from ``model``'s, summed (6 where they agree)."""
        R = fk_tool(nominal.with_tool(T_flange_tool), q)[:, :3, :3]
        return float(np.einsum("kij,kij->", R_model, R))

    turned = to_flange @ rot_z(np.pi) @ L
    return turned if agreement(turned) > agreement(to_flange @ L) else to_flange @ L


def _poses(model: MCPCModel, robot: RobotDef) -> tuple[np.ndarray, np.ndarray]:
    """(base -> the world's object, flange -> the tool) of ``model``."""
    return inv_pose(canonical_base(model, robot)), flange_to_tool(model, robot)


def mounts(model: MCPCModel, robot: RobotDef, *, eye_to_hand: bool,
           covariance: np.ndarray | None = None) -> tuple[Mount, Mount]:  # fmt: skip
    """The hand-eye and the board mount of ``model`` (module docstring): eye-to-hand
    ``(base -> camera, flange -> board)``, eye-in-hand ``(flange -> camera, base -> board)``;
    ``covariance`` (k, k) of its minimal parameters (SI, the order of
    :func:`selfcal.kinematics.mcpc.minimal_indices`) gives their sigmas.

    Raises:
        ValueError: joint 1 or 2 is prismatic or their axes are parallel (no base frame can be
            rebuilt on them).
    """
    base, tool = _poses(model, robot)
    sig: list[tuple[np.ndarray | None, np.ndarray | None]] = [(None, None), (None, None)]
    if covariance is not None:
        idx = minimal_indices(model.joint_types)
        J = np.zeros((2, 6, idx.size))
        h = 1e-7
        for j, k in enumerate(idx.tolist()):
            moved = []
            for s in (h, -h):
                p = model.params.reshape(-1).copy()
                p[k] += s
                moved.append(_poses(model.with_params(p), robot))
            for t in range(2):
                a, b = moved[0][t], moved[1][t]
                w = Rotation.from_matrix(a[:3, :3] @ b[:3, :3].T).as_rotvec()
                J[t, :, j] = np.r_[w, a[:3, 3] - b[:3, 3]] / (2 * h)
        for t in range(2):
            sd = np.sqrt(np.clip(np.diag(J[t] @ covariance @ J[t].T), 0, None))
            sig[t] = (sd[:3], sd[3:])
    world = "camera" if eye_to_hand else "board"
    tool_name = "board" if eye_to_hand else "camera"
    m_base = Mount(f"base -> {world}", "base", world, base, *sig[0])
    m_tool = Mount(f"flange -> {tool_name}", "flange", tool_name, tool, *sig[1])
    return (m_base, m_tool) if eye_to_hand else (m_tool, m_base)
