"""Forward kinematics and the MCPC identification Jacobian, vectorised over configurations.

Frames (world = the frame ``V_0`` starts from, metres):
- ``F_k`` (k = 1..n): link k's frame, right after joint k's motion ``Q_k``; its z-axis is joint k's
  axis. These are the MJCF body frames of the links.
- the tool frame ``F_n V_n``.

Pose error (paper eqs. 6-9): ``T_actual = T_model (I + dT)`` to first order, with
``dT = [[Omega(delta), d], [0, 0]]`` expressed in the model's tool frame; ``y = [d; delta]``.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import UsageError
from selfcal.kinematics.mcpc import MCPCModel, shape_matrices
from selfcal.robot.chain import chain_frames, dh_frames
from selfcal.robot.definition import RobotDef
from selfcal.transforms import inv_pose, rot_x, rot_y, rot_z, rotvec_from_matrix, skew, trans

__all__ = [
    "motion_matrices",
    "fk_frames",
    "fk_tool",
    "fk_nominal",
    "pose_error",
    "identification_jacobian",
    "pose_error_jacobian",
]


def motion_matrices(model: MCPCModel, q: np.ndarray) -> np.ndarray:
    """``Q_k(q_k)`` for joint vectors ``q`` (m, n) (rad or m); shape (m, n, 4, 4)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    Q = rot_z(q + model.joint_offsets)
    for k, kind in enumerate(model.joint_types):
        if kind == "prismatic":
            Q[:, k] = trans(np.stack([0 * q[:, k], 0 * q[:, k], q[:, k]], axis=-1))
    return Q


def _check_q(model: MCPCModel, q: np.ndarray) -> np.ndarray:
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.ndim != 2 or q.shape[1] != model.n:
        raise UsageError(f"joint array must have shape (m, {model.n}), got {np.shape(q)}")
    return q


def fk_frames(model: MCPCModel, q: np.ndarray) -> np.ndarray:
    """All frames for joint vectors ``q`` (m, n): shape (m, n + 1, 4, 4).

    ``out[:, k - 1]`` is link frame ``F_k`` (k = 1..n) and ``out[:, n]`` the tool frame, in the world
    frame (m).
    """
    q = _check_q(model, q)
    V = shape_matrices(model.params)
    Q = motion_matrices(model, q)
    out = np.empty((q.shape[0], model.n + 1, 4, 4))
    P = np.broadcast_to(rot_z(model.base_offset) @ V[0], (q.shape[0], 4, 4))
    for k in range(model.n):
        F = P @ Q[:, k]
        out[:, k] = F
        P = F @ V[k + 1]
    out[:, model.n] = P
    return out


def fk_tool(model: MCPCModel, q: np.ndarray) -> np.ndarray:
    """Tool poses ``T_world_tool`` (m, 4, 4) for joint vectors ``q`` (m, n)."""
    return fk_frames(model, q)[:, -1]


def fk_nominal(robot: RobotDef, q: np.ndarray) -> np.ndarray:
    """The robot's own frames 1..n (m, n, 4, 4) for joint vectors ``q`` (m, n), in its base frame.

    A cross-check of the MCPC chain computed straight from the robot's description: for a DH or
    modified-DH robot from its table rows (:func:`selfcal.robot.chain.dh_frames`: DH frames
    ``A_1 ... A_k``, or Craig's frames), for a URDF robot from the chain ``G_0 Q_1 ...``
    (:func:`selfcal.robot.chain.chain_frames`: frame k on joint k's axis). Frame n is the flange.
    """
    if robot.dh is not None:
        return dh_frames(robot.dh, robot.joint_types, q)
    return chain_frames(robot.chain, robot.joint_types, q)


def pose_error(T_model: np.ndarray, T_actual: np.ndarray) -> np.ndarray:
    """``y = [d; delta]`` (..., 6) with ``T_actual = T_model exp(dT)``, in the model tool frame.

    ``d`` in metres, ``delta`` a rotation vector in radians (exact, not only first order).
    """
    E = inv_pose(T_model) @ np.asarray(T_actual, dtype=float)
    return np.concatenate([E[..., :3, 3], rotvec_from_matrix(E[..., :3, :3])], axis=-1)


def identification_jacobian(
    model: MCPCModel, q: np.ndarray, frames: np.ndarray | None = None
) -> np.ndarray:
    """Analytic Jacobian of the tool pose error w.r.t. every MCPC parameter (eqs. 6-13).

    Returns shape (m, 6, 6 (n + 1)): rows ``[d; delta]`` in the tool frame, columns the flat
    parameters ``params.reshape(-1)`` (select the minimal set with ``mcpc.minimal_indices``).
    Units: rows m and rad, columns per rad (angles) and per m (lengths). ``frames``: the
    :func:`fk_frames` of ``model`` at ``q`` when the caller has them already.
    """
    q = _check_q(model, q)
    m, n = q.shape[0], model.n
    frames = fk_frames(model, q) if frames is None else frames
    p = model.params
    # World frame in which each shape matrix V_k starts: F_0 = Rz(base offset), F_k for k >= 1.
    start = np.empty((m, n + 1, 4, 4))
    start[:, 0] = rot_z(model.base_offset)
    start[:, 1:] = frames[:, :n]
    # The frames where each parameter acts, expressed in the tool frame: X0 = T^-1 start (alpha
    # acts about its x axis), X1 = X0 Rx(alpha) (beta, y), X2 = X1 Ry(beta) (gamma, z),
    # X3 = X2 Rz(gamma) (the translations, along its axes).
    X = inv_pose(frames[:, n])[:, None] @ start  # (m, n + 1, 4, 4)
    J = np.empty((m, n + 1, 6, 6))  # (config, frame, column, row [d; delta])
    for col, R in enumerate((rot_x(p[:, 0]), rot_y(p[:, 1]), rot_z(p[:, 2]))):
        w = X[..., :3, col]  # rotation axis in the tool frame
        J[:, :, col, 3:] = w
        J[:, :, col, :3] = np.cross(X[..., :3, 3], w)
        X = X @ R
    J[:, :, 3:, :3] = np.swapaxes(X[..., :3, :3], -1, -2)
    J[:, :, 3:, 3:] = 0.0
    return np.transpose(J, (0, 3, 1, 2)).reshape(m, 6, 6 * (n + 1))


def _so3_left_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """Inverse left Jacobian of SO(3) for rotation vectors (..., 3): (..., 3, 3)."""
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = th < 1e-4
    th_s = np.where(small, 1.0, th)
    coef = np.where(
        small,
        1.0 / 12.0 + th**2 / 720.0,
        1.0 / th_s**2 - (1.0 + np.cos(th_s)) / (2.0 * th_s * np.sin(th_s)),
    )
    return np.eye(3) - 0.5 * K + coef * (K @ K)


def pose_error_jacobian(J: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Exact ``-d y / d params`` of ``y = pose_error(T_model, T_meas)`` from the tool Jacobian ``J``.

    ``J`` (m, 6, p) gives the model's tool-frame twist per parameter (e.g.
    :func:`identification_jacobian`), ``y`` (m, 6) the current error: ``d x delta`` corrects the
    translation rows, the inverse left Jacobian of SO(3) the rotation rows.
    """
    Jv, Jw = J[:, :3], J[:, 3:]
    out = np.empty_like(J)
    out[:, :3] = Jv - skew(y[:, :3]) @ Jw
    out[:, 3:] = _so3_left_jacobian_inv(y[:, 3:]) @ Jw
    return out
