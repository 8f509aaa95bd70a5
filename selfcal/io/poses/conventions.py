"""Rotation conventions of robot controllers: a flange pose's orientation as a rotation matrix.

A controller reports the tool (flange) pose as a position and an orientation in its own
convention; each is turned into the rotation matrix ``R_base_flange`` (flange axes in base
coordinates) by :func:`rotation_matrices`:

- ``quaternion-xyzw``: a unit quaternion ``qx, qy, qz, qw`` (ROS, Eigen's coefficients, scipy);
- ``abb-quaternion``: ABB RAPID's ``orient`` ``q1, q2, q3, q4`` = ``w, x, y, z`` (scalar first);
- ``kuka-abc``: KUKA's ``A, B, C`` in degrees, intrinsic Z-Y'-X'': ``R = Rz(A) Ry(B) Rx(C)``;
- ``fanuc-wpr``: Fanuc's ``W, P, R`` in degrees, fixed (extrinsic) X-Y-Z:
  ``R = Rz(R) Ry(P) Rx(W)`` -- the same matrix as KUKA's with ``A = R, B = P, C = W``;
- ``ur-rotvec``: Universal Robots' ``rx, ry, rz``, a rotation vector (axis x angle) in radians.

The conversions are scipy's (:class:`scipy.spatial.transform.Rotation`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.errors import InputError

__all__ = ["CONVENTIONS", "QUATERNION_TOLERANCE", "rotation_matrices", "unit_quaternions"]

CONVENTIONS: dict[str, str] = {
    "quaternion-xyzw": "unit quaternion qx, qy, qz, qw (ROS, Eigen, scipy)",
    "abb-quaternion": "ABB quaternion q1, q2, q3, q4 = w, x, y, z",
    "kuka-abc": "KUKA A, B, C deg, intrinsic Z-Y'-X''",
    "fanuc-wpr": "Fanuc W, P, R deg, fixed X-Y-Z",
    "ur-rotvec": "UR rx, ry, rz rotation vector, rad",
}
"""The ``--rotation`` conventions and what each means."""

QUATERNION_TOLERANCE = 0.01
"""Largest ``| |q| - 1 |`` of a quaternion taken as a unit quaternion rounded by its printout
(4 decimals give ~1e-4); beyond it the columns are not a quaternion."""


def unit_quaternions(q_xyzw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The quaternions ``q_xyzw`` (n, 4) normalised, and a bool (n,) of the rows whose norm
    is off 1 by more than :data:`QUATERNION_TOLERANCE` (not a rounded unit quaternion)."""
    q = np.asarray(q_xyzw, dtype=float).reshape(-1, 4)
    norm = np.linalg.norm(q, axis=1)
    bad = ~(np.abs(norm - 1.0) <= QUATERNION_TOLERANCE)
    return q / np.where(norm > 0, norm, 1.0)[:, None], bad


def rotation_matrices(convention: str, values: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of the orientations ``values`` (n, 4) for the quaternion
    conventions, (n, 3) for the others, in the order :data:`CONVENTIONS` names them (degrees
    for KUKA and Fanuc, radians for UR); quaternions are normalised (check them first with
    :func:`unit_quaternions`). Raises ``ValueError`` for an unknown convention."""
    v = np.asarray(values, dtype=float)
    if convention == "quaternion-xyzw":
        R = Rotation.from_quat(unit_quaternions(v)[0])
    elif convention == "abb-quaternion":
        R = Rotation.from_quat(unit_quaternions(v[:, [1, 2, 3, 0]])[0])
    elif convention == "kuka-abc":
        R = Rotation.from_euler("ZYX", v, degrees=True)
    elif convention == "fanuc-wpr":
        R = Rotation.from_euler("xyz", v, degrees=True)
    elif convention == "ur-rotvec":
        R = Rotation.from_rotvec(v)
    else:
        raise InputError(
            f"unknown rotation convention {convention!r}; use one of {list(CONVENTIONS)}"
        )
    return R.as_matrix().reshape(-1, 3, 3)
