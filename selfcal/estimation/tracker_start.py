"""Closed-form starts for tracker estimations: where the robot's base sits in the tracker frame
and where the measured tool sits on the flange.

- Positions (:func:`initial_placement`): a rigid fit (Kabsch) alternated with the linear tool
  point. With few rows the alternation can settle in a wrong placement (3 positions of a 2-axis
  positioner: the tool point and the frame trade off).
- Poses (:func:`pose_placement`): ``T_i = B F_i X`` is the robot-world hand-eye problem
  ``A_i X' = Z B_i`` (``A_i = T_i``, ``X' = X^-1``, ``Z = B``, ``B_i = F_i``), solved in closed
  form as Shah (2013) does: the rotations from the null vector of the stacked Kronecker system,
  projected onto SO(3), then the translations by linear least squares. Exact for noise-free
  data from two poses whose rotations differ about non-parallel axes.

Units: SI (m, rad). These are starts for the solver, not estimates.
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.transforms import inv_pose, kabsch, make_pose

__all__ = ["initial_placement", "mean_rotation", "pose_placement"]


def initial_placement(
    model: MCPCModel, q: np.ndarray, xyz: np.ndarray, *, iterations: int = 50
) -> tuple[np.ndarray, np.ndarray]:
    """``(T_meas_base (4, 4), s (3,))``: the rigid placement of ``model`` in the tracker frame and
    the tool point ``s`` in its tool frame (m) that best fit the positions ``xyz`` (m, 3) at
    ``q`` (m, n), by alternating the closed-form rigid fit (Kabsch) with the linear
    least-squares tool point (a fixed-point start for the estimation, not an estimate)."""
    T = fk_tool(model, q)
    R, t = T[:, :3, :3], T[:, :3, 3]
    s = np.zeros(3)
    B = np.eye(4)
    for _ in range(iterations):
        x = R @ s + t
        B = kabsch(x, xyz) if len(q) >= 3 else make_pose(np.eye(3), np.mean(xyz - x, axis=0))
        rhs = (xyz - B[:3, 3]) @ B[:3, :3] - t  # R_i s = B^-1 p_i - t_i
        # least squares over the rows: the normal matrix sum R_i^T R_i is m I
        s_new = np.einsum("kji,kj->i", R, rhs) / len(q)
        done = np.linalg.norm(s_new - s) <= 1e-6  # a start for LM: 1 um is plenty
        s = s_new
        if done:
            break
    return B, s


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """The chordal mean (3, 3) of rotations ``R`` (m, 3, 3): the proper rotation nearest their sum."""
    U, _, Vt = np.linalg.svd(np.sum(R, axis=0))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def pose_placement(
    model: MCPCModel, q: np.ndarray, T_meas: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(T_meas_base (4, 4), T_tool_measured (4, 4))``: the placement of ``model`` in the tracker
    frame and the measured tool frame on ``model``'s tool that best fit the measured poses
    ``T_meas`` (m, 4, 4) at ``q`` (m, n), in closed form (module docstring)."""
    F = fk_tool(model, q)
    RA, RB = T_meas[:, :3, :3], F[:, :3, :3]
    eye = np.eye(3)
    # vec(R_A R_X') - vec(R_Z R_B) = 0 (column-major vec): (I kron R_A) x - (R_B^T kron I) z
    K = np.concatenate(
        [np.stack([np.kron(eye, a) for a in RA]), -np.stack([np.kron(b.T, eye) for b in RB])],
        axis=2,
    ).reshape(-1, 18)
    v = np.linalg.svd(K)[2][-1]
    Xp, Z = v[:9].reshape(3, 3, order="F"), v[9:].reshape(3, 3, order="F")
    sign = np.sign(np.linalg.det(Z)) or 1.0
    Xp, Z = _nearest_rotation(sign * Xp), _nearest_rotation(sign * Z)
    # R_A t_X' - t_Z = R_Z t_B - t_A
    M = np.concatenate([RA, -np.broadcast_to(eye, RA.shape)], axis=2).reshape(-1, 6)
    rhs = (F[:, :3, 3] @ Z.T - T_meas[:, :3, 3]).reshape(-1)
    t = np.linalg.lstsq(M, rhs, rcond=None)[0]
    return make_pose(Z, t[3:]), inv_pose(make_pose(Xp, t[:3]))
