"""The linear start of hand-eye calibration: ``X C_i = A_i B`` solved in closed form.

``C_i = T_cam_board_i`` are the board poses of the camera stage
(:func:`selfcal.calibration.board.calibrate.calibrate_board`), ``A_i`` the robot's motions
(:mod:`selfcal.estimation.pose_chain` says which for each setup). Park and Martin's rotation
(1994) on the view pairs: ``A_i^-1 A_j B = B C_i^-1 C_j``, so the rotation vectors of the pairs'
motions satisfy ``alpha_ij = R_B beta_ij``, solved by Kabsch (scipy's ``align_vectors``, always
a proper rotation); then ``R_X`` is the mean of ``R_Ai R_B R_Ci^T`` (scipy's quaternion mean)
and both translations one linear least squares, ``t_X - R_Ai t_B = t_Ai - R_X t_Ci``. No
branch or sign choice is made, and no NaN can come out: motions that turn about one axis only
(or not at all) are refused with an :class:`HandEyeStartError`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.errors import EstimationError
from selfcal.transforms import inv_pose, make_pose

__all__ = ["HandEyeStartError", "MIN_TURN_DEG", "linear_hand_eye", "turn_misfit_deg"]

MIN_TURN_DEG = 1.0
"""Pairs of views whose relative rotation is below this (deg) carry no axis and are not used;
above 179 deg the axis' sign is ill-defined and they are not used either."""
_AXES_RATIO = 0.05
"""The rotation axes span 2 dimensions when the second singular value of the weighted axes is
at least this fraction of the first (one axis only: the hand-eye rotation about it is free)."""


class HandEyeStartError(EstimationError):
    """The poses do not determine the hand-eye (every motion about one axis, or no motion)."""


def linear_hand_eye(A: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``X``, ``B`` (4, 4) with ``X C_i ~ A_i B`` for the motions ``A`` (n, 4, 4) and the board
    poses ``C`` (n, 4, 4) (m; see the module docstring).

    Raises:
        HandEyeStartError: fewer than 3 views, or the pairs' rotations turn about one axis only.
    """
    A, C = np.asarray(A, float), np.asarray(C, float)
    n = len(A)
    if n < 3:
        raise HandEyeStartError(f"{n} views show the board; the hand-eye needs at least 3 whose "
                                "motions turn about two different axes", fix="add poses")  # fmt: skip
    i, j = np.triu_indices(n, 1)
    Aij = inv_pose(A[i]) @ A[j]
    Cij = inv_pose(C[i]) @ C[j]
    alpha = Rotation.from_matrix(Aij[:, :3, :3]).as_rotvec()
    beta = Rotation.from_matrix(Cij[:, :3, :3]).as_rotvec()
    ang = np.degrees(np.linalg.norm(alpha, axis=1))
    ok = (ang > MIN_TURN_DEG) & (ang < 179.0)
    s = np.linalg.svd(beta[ok], compute_uv=False) if ok.sum() >= 2 else np.zeros(2)
    if ok.sum() < 2 or s[1] < _AXES_RATIO * s[0]:
        raise HandEyeStartError(
            f"the robot's motions between the {n} views turn about one axis only (or less than "
            f"{MIN_TURN_DEG:g} deg): the hand-eye rotation about it is not determined",
            fix="add poses that tilt the flange about two or more different axes",
        )
    R_B = Rotation.align_vectors(alpha[ok], beta[ok])[0].as_matrix()
    R_X = Rotation.from_matrix(A[:, :3, :3] @ R_B @ np.transpose(C[:, :3, :3], (0, 2, 1))).mean()
    R_X = R_X.as_matrix()
    M = np.zeros((3 * n, 6))
    M[:, :3] = np.tile(np.eye(3), (n, 1))
    M[:, 3:] = -A[:, :3, :3].reshape(3 * n, 3)
    rhs = (A[:, :3, 3] - C[:, :3, 3] @ R_X.T).reshape(-1)
    t = np.linalg.lstsq(M, rhs, rcond=None)[0]
    return make_pose(R_X, t[:3]), make_pose(R_B, t[3:])


def turn_misfit_deg(A: np.ndarray, C: np.ndarray) -> float:
    """Median over the view pairs of ``| angle(A_i^-1 A_j) - angle(C_i^-1 C_j) |`` (deg): the
    robot's motion and the camera's motion relative to the board turn by the same angle in
    either setup, whatever the hand-eye (0.1-0.2 deg on a real arm). Large: the orientations are
    not read as the robot meant them (convention, column order) or rows and images are paired
    wrongly."""
    A, C = np.asarray(A, float), np.asarray(C, float)
    i, j = np.triu_indices(len(A), 1)
    a = Rotation.from_matrix((inv_pose(A[i]) @ A[j])[:, :3, :3]).magnitude()
    c = Rotation.from_matrix((inv_pose(C[i]) @ C[j])[:, :3, :3]).magnitude()
    return float(np.degrees(np.median(np.abs(a - c)))) if len(i) else 0.0
