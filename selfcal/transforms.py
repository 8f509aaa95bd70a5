"""Homogeneous transforms, batched over leading axes.

Conventions: a pose ``T_a_b`` (4x4) maps coordinates in frame ``b`` to frame ``a``; twists are
``[v; w]`` (translation first, then rotation), in metres and radians. Every function accepts arrays
with arbitrary leading batch dimensions.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from selfcal.errors import UsageError

# Plain numpy, no scipy.spatial.transform: importing it loads scipy.spatial's k-d trees, hulls
# and distances and scipy.special (0.04 s of `selfcal run`'s serial start, issue 32; 0.5 s of
# `selfcal fk`'s with scipy.sparse, issue 17). The rotations follow scipy's Rotation step by step
# (tests/unit/test_transforms.py compares them).

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
    "rpy_from_matrix",
    "quat_from_matrix",
    "matrix_from_rotvec",
    "rotvec_from_matrix",
    "mean_rotation",
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


# A middle Euler angle within this of +-90 deg (rad) is a gimbal lock (xyz_euler_from_matrix,
# rpy_from_matrix): the third angle is set to 0, as scipy's Rotation.as_euler does.
GIMBAL_EPS = 1e-7


def _quat_xyzw(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(x, y, z, w)`` of rotations (..., 3, 3), sign not canonical: Markley's
    method (from the largest of the diagonal and the trace), as scipy's ``Rotation.from_matrix``
    for orthonormal matrices."""
    R = np.asarray(R, dtype=float)
    t = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    choice = np.argmax(np.stack([R[..., 0, 0], R[..., 1, 1], R[..., 2, 2], t], axis=-1), axis=-1)
    s01, s02, s12 = (
        R[..., 1, 0] + R[..., 0, 1],
        R[..., 2, 0] + R[..., 0, 2],
        R[..., 2, 1] + R[..., 1, 2],
    )
    v = (R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1])
    cases = np.stack(  # (..., case, (x, y, z, w))
        [
            np.stack([1 - t + 2 * R[..., 0, 0], s01, s02, v[0]], axis=-1),
            np.stack([s01, 1 - t + 2 * R[..., 1, 1], s12, v[1]], axis=-1),
            np.stack([s02, s12, 1 - t + 2 * R[..., 2, 2], v[2]], axis=-1),
            np.stack([v[0], v[1], v[2], 1 + t], axis=-1),
        ],
        axis=-2,
    )
    q = np.take_along_axis(cases, choice[..., None, None], axis=-2)[..., 0, :]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _tait_bryan(q: np.ndarray, axes: tuple[int, int, int], extrinsic: bool) -> np.ndarray:
    """Euler angles (rad, (..., 3), in the order of ``axes``) of quaternions ``(x, y, z, w)`` for a
    sequence of three different axes (0 = x, 1 = y, 2 = z), about fixed axes (``extrinsic``) or
    moving ones. The direct method of Bernardes and Viollet (PLoS ONE 17(11), 2022), which scipy's
    ``Rotation.as_euler`` uses: the middle angle in [-pi/2, pi/2], the others in [-pi, pi]."""
    i, j, k = axes if extrinsic else axes[::-1]
    sign = (i - j) * (j - k) * (k - i) // 2
    w = q[..., 3]
    a, b = w - q[..., j], q[..., i] + sign * q[..., k]
    c, d = q[..., j] + w, sign * q[..., k] - q[..., i]
    middle = 2 * np.arctan2(np.hypot(c, d), np.hypot(a, b))
    half_sum, half_diff = np.arctan2(b, a), np.arctan2(d, c)
    at_0, at_pi = np.abs(middle) <= GIMBAL_EPS, np.abs(middle - np.pi) <= GIMBAL_EPS
    lock = at_0 | at_pi
    # at a gimbal lock the last angle is 0 and the first takes the whole rotation
    locked = np.where(at_0, 2 * half_sum, 2 * half_diff * (-1 if extrinsic else 1))
    if extrinsic:
        first = np.where(lock, locked, half_sum - half_diff)
        last = np.where(lock, 0.0, (half_sum + half_diff) * sign)
    else:
        first = np.where(lock, locked, half_sum + half_diff) * sign
        last = np.where(lock, 0.0, half_sum - half_diff)
    angles = np.stack([first, middle - np.pi / 2, last], axis=-1)
    return np.where(
        angles < -np.pi, angles + 2 * np.pi, np.where(angles > np.pi, angles - 2 * np.pi, angles)
    )


def xyz_euler_from_matrix(R: np.ndarray) -> np.ndarray:
    """Angles ``(a, b, g)`` (rad) with ``R = Rx(a) Ry(b) Rz(g)`` (scipy's intrinsic ``"XYZ"``);
    shape (..., 3).

    Singular at ``b = +-90 deg`` (within ``GIMBAL_EPS``: then ``g = 0``); MCPC frames stay far
    from it. Plain numpy: ``selfcal fk`` loads no scipy (issue 17).
    """
    R = np.asarray(R, dtype=float)
    if R.shape == (3, 3):
        return _xyz_euler_one(R)
    return _tait_bryan(_quat_xyzw(R), (0, 1, 2), extrinsic=False)


def _xyz_euler_one(R: np.ndarray) -> np.ndarray:
    """:func:`xyz_euler_from_matrix` of one rotation, the same steps on Python floats (a model's
    gauge fixing converts one matrix at a time, hundreds of times per calibration: numpy's
    per-call overhead was most of it)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
    t = r00 + r11 + r22
    s01, s02, s12 = r10 + r01, r20 + r02, r21 + r12
    v0, v1, v2 = r21 - r12, r02 - r20, r10 - r01
    cases = (
        (1 - t + 2 * r00, s01, s02, v0),
        (s01, 1 - t + 2 * r11, s12, v1),
        (s02, s12, 1 - t + 2 * r22, v2),
        (v0, v1, v2, 1 + t),
    )
    diag = (r00, r11, r22, t)
    x, y, z, w = cases[max(range(4), key=lambda i: (diag[i], -i))]
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    # _tait_bryan(q, (0, 1, 2), extrinsic=False): i, j, k = 2, 1, 0 and sign = -1
    a, b, c, d = w - y, z - x, y + w, -z - x
    middle = 2 * math.atan2(math.hypot(c, d), math.hypot(a, b))
    half_sum, half_diff = math.atan2(b, a), math.atan2(d, c)
    if abs(middle) <= GIMBAL_EPS:
        first, last = -(2 * half_sum), 0.0
    elif abs(middle - math.pi) <= GIMBAL_EPS:
        first, last = -(2 * half_diff), 0.0
    else:
        first, last = -(half_sum + half_diff), half_sum - half_diff
    out = [first, middle - math.pi / 2, last]
    return np.array([u + 2 * math.pi if u < -math.pi else u - 2 * math.pi if u > math.pi else u
                     for u in out])  # fmt: skip


def rpy_from_matrix(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw ``(r, p, y)`` (rad) about the fixed axes x, y, z: ``R = Rz(y) Ry(p) Rx(r)``
    (the URDF/ROS convention, scipy's extrinsic ``"xyz"``), of rotations (..., 3, 3); shape (..., 3).

    At a gimbal lock (pitch within ``GIMBAL_EPS`` of +-90 deg) yaw is 0 and roll takes the whole
    rotation about the vertical. Plain numpy.
    """
    return _tait_bryan(_quat_xyzw(R), (0, 1, 2), extrinsic=True)


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` (scalar first, ``w >= 0``) of rotations (..., 3, 3).

    Plain numpy; the method of scipy's ``Rotation.from_matrix`` for orthonormal matrices.
    """
    q = _quat_xyzw(R)
    q = np.concatenate([q[..., 3:], q[..., :3]], axis=-1)
    return np.where(q[..., :1] < 0, -q, q)


def matrix_from_rotvec(rotvec: npt.ArrayLike) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors ``rotvec`` (..., 3) (axis times angle,
    rad): through the unit quaternion, its scale by the Taylor series below 1e-3 rad, as scipy's
    ``Rotation.from_rotvec(...).as_matrix()``. One vector (3,) on Python floats: the
    calibration converts one at a time hundreds of times, where numpy's per-call cost is most
    of the work."""
    w = np.asarray(rotvec, dtype=float)
    if w.shape == (3,):
        return _quat_matrix_one(*_rotvec_quat_one(*w.tolist()))
    angle = np.sqrt(np.einsum("...i,...i->...", w, w))[..., None]
    small = angle <= 1e-3
    a2 = angle * angle
    scale = np.where(small, 0.5 - a2 / 48 + a2 * a2 / 3840, np.sin(angle / 2) / (angle + small))
    q = np.concatenate([w * scale, np.cos(angle / 2)], axis=-1)
    qq = (q[..., :, None] * q[..., None, :]).reshape(q.shape[:-1] + (16,))
    return (qq @ _QUAT_PRODUCTS_TO_MATRIX).reshape(q.shape[:-1] + (3, 3))


def _rotvec_quat_one(x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """The unit quaternion ``(x, y, z, w)`` of one rotation vector (rad), on Python floats."""
    angle = math.sqrt(x * x + y * y + z * z)
    if angle <= 1e-3:
        a2 = angle * angle
        scale = 0.5 - a2 / 48 + a2 * a2 / 3840
    else:
        scale = math.sin(angle / 2) / angle
    return x * scale, y * scale, z * scale, math.cos(angle / 2)


def _quat_matrix_one(x: float, y: float, z: float, w: float) -> np.ndarray:
    """The rotation matrix (3, 3) of one unit quaternion ``(x, y, z, w)``, as scipy's
    ``Rotation.as_matrix``."""
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])  # fmt: skip


def _quat_products_to_matrix() -> np.ndarray:
    """(16, 9): the row-major rotation matrix of a unit quaternion ``q = (x, y, z, w)`` is the
    products ``q_a q_b`` (row ``4 a + b``) times this: the terms of :func:`_quat_matrix_one`."""
    x, y, z, w = range(4)
    terms = {  # (row, column) of the matrix: (coefficient, a, b) of its terms
        (0, 0): [(1, x, x), (-1, y, y), (-1, z, z), (1, w, w)],
        (0, 1): [(2, x, y), (-2, z, w)],
        (0, 2): [(2, x, z), (2, y, w)],
        (1, 0): [(2, x, y), (2, z, w)],
        (1, 1): [(-1, x, x), (1, y, y), (-1, z, z), (1, w, w)],
        (1, 2): [(2, y, z), (-2, x, w)],
        (2, 0): [(2, x, z), (-2, y, w)],
        (2, 1): [(2, y, z), (2, x, w)],
        (2, 2): [(-1, x, x), (-1, y, y), (1, z, z), (1, w, w)],
    }
    out = np.zeros((16, 9))
    for (i, j), row in terms.items():
        for c, a, b in row:
            out[4 * a + b, 3 * i + j] = c
    return out


_QUAT_PRODUCTS_TO_MATRIX = _quat_products_to_matrix()


def _unit_quat_xyzw(R: np.ndarray) -> np.ndarray:
    """:func:`_quat_xyzw` of rotations (..., 3, 3), each not orthonormal to 1e-12 (``R R^T``)
    first replaced by the nearest one (SVD), as scipy's ``Rotation.from_matrix`` does.

    Raises:
        UsageError: a matrix with a determinant <= 0 (mirrored or singular), no rotation.
    """
    R = np.asarray(R, dtype=float)
    det = np.linalg.det(R)
    if (det <= 0).any():
        k = int(np.flatnonzero(det.ravel() <= 0)[0])
        raise UsageError(f"matrix {k} has a determinant <= 0 ({det.ravel()[k]:.3g}): a mirror "
                         "or a singular matrix is no rotation")  # fmt: skip
    eye = np.eye(3)
    off = (np.abs(R @ np.swapaxes(R, -1, -2) - eye) > 1e-12 + 1e-5 * eye).any(axis=(-2, -1))
    if off.any():
        U, _, Vt = np.linalg.svd(R[off])
        R = R.copy()
        R[off] = U @ Vt
    return _quat_xyzw(R)


def rotvec_from_matrix(R: npt.ArrayLike) -> np.ndarray:
    """Rotation vectors (..., 3) (axis times angle in [0, pi], rad) of rotations ``R``
    (..., 3, 3): the steps of scipy's ``Rotation.from_matrix(R).as_rotvec()``.

    Raises:
        UsageError: a matrix with a determinant <= 0 (no rotation).
    """
    q = _unit_quat_xyzw(np.asarray(R, dtype=float))
    q = np.where(q[..., 3:] < 0, -q, q)  # w >= 0: the angle in [0, pi]
    angle = 2 * np.arctan2(np.linalg.norm(q[..., :3], axis=-1, keepdims=True), q[..., 3:])
    small = angle <= 1e-3
    a2 = angle**2
    scale = np.where(small, 2 + a2 / 12 + 7 * a2**2 / 2880, angle / (np.sin(angle / 2) + small))
    return scale * q[..., :3]


def mean_rotation(R: npt.ArrayLike) -> np.ndarray:
    """The mean (3, 3) of rotations ``R`` (k, 3, 3), k >= 1, that minimises the sum of squared
    chordal distances: the eigenvector of the largest eigenvalue of ``sum q q^T`` over their
    unit quaternions, as scipy's ``Rotation.mean``.

    Raises:
        UsageError: no rotation, or a matrix with a determinant <= 0.
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    if len(R) == 0:
        raise UsageError("the mean of no rotation is undefined: give at least one")
    q = _unit_quat_xyzw(R)
    return _quat_matrix_one(*np.linalg.eigh(q.T @ q)[1][:, -1].tolist())


def pose_from_vec(v: np.ndarray) -> np.ndarray:
    """Pose from ``[rotvec (rad), translation (m)]`` vectors of shape (..., 6)."""
    v = np.asarray(v, dtype=float)
    return make_pose(matrix_from_rotvec(v[..., :3]), v[..., 3:])


def vec_from_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pose_from_vec`: ``[rotvec, translation]`` (..., 6)."""
    T = np.asarray(T, dtype=float)
    return np.concatenate([rotvec_from_matrix(T[..., :3, :3]), T[..., :3, 3]], axis=-1)


def kabsch(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Best proper rigid ``T_b_a`` (4x4: rotation and translation, no scale, no mirror)
    minimising ``sum |R A_i + t - B_i|^2`` over point sets (..., k, 3), k >= 3: one fit per
    leading index, (..., 4, 4)."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.shape != B.shape or A.ndim < 2 or A.shape[-1] != 3 or A.shape[-2] < 3:
        raise UsageError(
            f"kabsch needs two (k, 3) point sets with k >= 3, got {A.shape}, {B.shape}"
        )
    ca, cb = A.mean(axis=-2), B.mean(axis=-2)
    U, _, Vt = np.linalg.svd(np.swapaxes(A - ca[..., None, :], -1, -2) @ (B - cb[..., None, :]))
    V, Ut = np.swapaxes(Vt, -1, -2), np.swapaxes(U, -1, -2)
    d = np.sign(np.linalg.det(V @ Ut))  # -1 where the best orthogonal map mirrors
    D = np.stack(np.broadcast_arrays(1.0, 1.0, np.where(d == 0, 1.0, d)), axis=-1)
    R = (V * D[..., None, :]) @ Ut  # V diag(D) U^T
    return make_pose(R, cb - (R @ ca[..., None])[..., 0])
