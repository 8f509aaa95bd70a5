"""Reprojection residuals of image observations, and their residual block for the solver.

Pinhole model with a known principal point (paper eq. 19): ``K = [[fx, 0, cx], [0, mu fx, cy],
[0, 0, 1]]``; OpenCV pixel convention; ``T_cam_world`` maps world coordinates to the camera frame.
Rows are observations ``(view, point index, uv)``; residual = projected - observed (px).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from calib.estimation.pose_models import PoseModel
from calib.solver import Evaluation, JacobianPiece, Loss
from calib.transforms import skew

__all__ = ["projection_blocks", "reprojection_residuals", "ReprojectionBlock"]


def projection_blocks(
    fx: float, mu: float, T_cam_world: np.ndarray, X: np.ndarray, view: np.ndarray, pidx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jacobian blocks of the pixel projection for rows (view, point index), OpenCV model:
    w.r.t. ``(fx, mu)`` (k, 2, 2), w.r.t. a camera-frame twist ``[v; w]`` of ``T_cam_world``
    (k, 2, 6) and w.r.t. the world point (k, 2, 3); px per unit."""
    R = T_cam_world[view, :3, :3]
    Xc = np.einsum("kij,kj->ki", R, X[pidx]) + T_cam_world[view, :3, 3]
    xx, yy, z = Xc[:, 0], Xc[:, 1], Xc[:, 2]
    k = len(Xc)
    A = np.zeros((k, 2, 3))
    A[:, 0, 0] = fx / z
    A[:, 0, 2] = -fx * xx / z**2
    A[:, 1, 1] = mu * fx / z
    A[:, 1, 2] = -mu * fx * yy / z**2
    Ji = np.zeros((k, 2, 2))
    Ji[:, 0, 0] = xx / z
    Ji[:, 1, 0] = mu * yy / z
    Ji[:, 1, 1] = fx * yy / z
    D = np.concatenate([np.broadcast_to(np.eye(3), (k, 3, 3)), -skew(Xc)], axis=2)
    return Ji, A @ D, A @ R


def reprojection_residuals(
    fx: float,
    mu: float,
    cx: float,
    cy: float,
    T_cam_world: np.ndarray,
    X: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals ``projected - observed`` (k, 2) px and depths (k,) for rows (view, point index)."""
    R = T_cam_world[view, :3, :3]
    Xc = np.einsum("kij,kj->ki", R, X[pidx]) + T_cam_world[view, :3, 3]
    z = Xc[:, 2]
    r = np.empty((len(view), 2))
    r[:, 0] = fx * Xc[:, 0] / z + cx - uv[:, 0]
    r[:, 1] = mu * fx * Xc[:, 1] / z + cy - uv[:, 1]
    return r, z


class ReprojectionBlock:
    """Image observations as one residual block (``dim`` 2, px): rows ``(view, pidx, uv)``.

    Parameter blocks (names configurable): ``intrinsics`` ``[fx, mu]`` (px, 1), ``poses`` the
    pose model's parameters ``p``, ``points`` the world points (3 P) raveled, m. A pose model
    whose ``view_jacobian`` returns None yields NaN pose derivatives (finite differences belong
    to the caller; the engine refuses them with a :class:`calib.errors.SolverError`).
    """

    dim = 2

    def __init__(
        self,
        pose_model: PoseModel,
        view: np.ndarray,
        pidx: np.ndarray,
        uv: np.ndarray,
        cx: float,
        cy: float,
        loss: Loss | None = None,
        *,
        name: str = "reprojection",
        intrinsics: str = "intrinsics",
        poses: str = "poses",
        points: str = "points",
    ) -> None:
        self.name = name
        self.loss = loss or Loss()
        self.model = pose_model
        self.view = np.asarray(view, dtype=np.int64)
        self.pidx = np.asarray(pidx, dtype=np.int64)
        self.uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        self.cx, self.cy = float(cx), float(cy)
        self.keys = (intrinsics, poses, points)
        self.pose_cols = pose_model.view_columns()[self.view]
        self.point_cols = 3 * self.pidx[:, None] + np.arange(3)

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (k, 2) px and the pieces d/d(fx, mu), d/dp, d/dX."""
        ki, kp, kx = self.keys
        fx, mu = values[ki]
        p = values[kp]
        X = values[kx].reshape(-1, 3)
        T = self.model.poses(p)
        r, _ = reprojection_residuals(fx, mu, self.cx, self.cy, T, X, self.view, self.pidx, self.uv)
        if not jacobian:
            return Evaluation(r)
        Ji, Jt, Jx = projection_blocks(fx, mu, T, X, self.view, self.pidx)
        Jv = self.model.view_jacobian(p)
        if Jv is None:
            Jp = np.full(self.pose_cols.shape[:1] + (2,) + self.pose_cols.shape[1:], np.nan)
        else:
            Jp = Jt @ Jv[self.view]
        return Evaluation(
            r,
            (
                JacobianPiece(ki, Ji, np.arange(2)[None]),
                JacobianPiece(kp, Jp, self.pose_cols),
                JacobianPiece(kx, Jx, self.point_cols),
            ),
        )
