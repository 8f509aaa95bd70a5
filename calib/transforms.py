"""Homogeneous transforms, batched over leading axes.

Conventions: a pose ``T_a_b`` (4x4) maps coordinates in frame ``b`` to frame ``a``; twists are
``[v; w]`` (translation first, then rotation), in metres and radians. Every function accepts arrays
with arbitrary leading batch dimensions.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

__all__ = [
    "rot_x",
    "rot_y",
    "rot_z",
    "trans",
    "make_pose",
    "inv_pose",
    "adjoint",
    "skew",
    "xyz_euler_from_matrix",
    "pose_from_vec",
    "vec_from_pose",
    "kabsch",
]


def _rot(axis: int, angle: np.ndarray | float) -> np.ndarray:
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    T = np.zeros(angle.shape + (4, 4))
    T[..., 3, 3] = 1.0
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    T[..., axis, axis] = 1.0
    T[..., i, i] = c
    T[..., j, j] = c
    T[..., i, j] = -s
    T[..., j, i] = s
    return T


def rot_x(angle: np.ndarray | float) -> np.ndarray:
    """Homogeneous rotation about x by ``angle`` (rad); shape ``angle.shape + (4, 4)``."""
    return _rot(0, angle)


def rot_y(angle: np.ndarray | float) -> np.ndarray:
    """Homogeneous rotation about y by ``angle`` (rad)."""
    return _rot(1, angle)


def rot_z(angle: np.ndarray | float) -> np.ndarray:
    """Homogeneous rotation about z by ``angle`` (rad)."""
    return _rot(2, angle)


def trans(xyz: np.ndarray) -> np.ndarray:
    """Homogeneous translation by ``xyz`` (m, shape ``(..., 3)``)."""
    xyz = np.asarray(xyz, dtype=float)
    T = np.zeros(xyz.shape[:-1] + (4, 4))
    T[..., :3, :3] = np.eye(3)
    T[..., :3, 3] = xyz
    T[..., 3, 3] = 1.0
    return T


def make_pose(R: npt.ArrayLike, p: npt.ArrayLike) -> np.ndarray:
    """Pose from rotation ``R`` (..., 3, 3) and translation ``p`` (..., 3)."""
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    shape = np.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def inv_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms ``T`` (..., 4, 4), using R^T."""
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_pose(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v]x`` of vectors (..., 3)."""
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def adjoint(T: np.ndarray) -> np.ndarray:
    """6x6 adjoint of ``T`` acting on twists ``[v; w]``: twist in frame b -> twist in frame a."""
    T = np.asarray(T, dtype=float)
    R, p = T[..., :3, :3], T[..., :3, 3]
    A = np.zeros(T.shape[:-2] + (6, 6))
    A[..., :3, :3] = R
    A[..., 3:, 3:] = R
    A[..., :3, 3:] = skew(p) @ R
    return A


def xyz_euler_from_matrix(R: np.ndarray) -> np.ndarray:
    """Angles ``(a, b, g)`` (rad) with ``R = Rx(a) Ry(b) Rz(g)``; shape (..., 3).

    Singular at ``b = +-90 deg``; MCPC frames stay far from it.
    """
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    # scipy's intrinsic "XYZ" is exactly Rx(a) Ry(b) Rz(g).
    eul = Rotation.from_matrix(flat).as_euler("XYZ")
    return eul.reshape(R.shape[:-2] + (3,))


def pose_from_vec(v: np.ndarray) -> np.ndarray:
    """Pose from ``[rotvec (rad), translation (m)]`` vectors of shape (..., 6)."""
    v = np.asarray(v, dtype=float)
    R = Rotation.from_rotvec(v.reshape(-1, 6)[:, :3]).as_matrix().reshape(v.shape[:-1] + (3, 3))
    return make_pose(R, v[..., 3:])


def vec_from_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pose_from_vec`: ``[rotvec, translation]`` (..., 6)."""
    T = np.asarray(T, dtype=float)
    rv = Rotation.from_matrix(T[..., :3, :3].reshape(-1, 3, 3)).as_rotvec()
    return np.concatenate([rv.reshape(T.shape[:-2] + (3,)), T[..., :3, 3]], axis=-1)


def kabsch(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Best proper rigid ``T_b_a`` (4x4: rotation and translation, no scale, no mirror)
    minimising ``sum |R A_i + t - B_i|^2`` over point sets (k, 3), k >= 3."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.shape != B.shape or A.ndim != 2 or A.shape[1] != 3 or len(A) < 3:
        raise ValueError(
            f"kabsch needs two (k, 3) point sets with k >= 3, got {A.shape}, {B.shape}"
        )
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    return make_pose(R, cb - R @ ca)
