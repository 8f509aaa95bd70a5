"""Reprojection residuals of image observations, and their residual block for the solver.

The projection is the camera model's (:class:`selfcal.camera.CameraModel`, e.g. the paper's pinhole
with a known principal point); ``T_cam_world`` maps world coordinates to the camera frame. Rows
are observations ``(view, point index, uv)``; residual = projected - observed (px).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from selfcal.camera.camera_set import Cameras, project_free_views, project_views
from selfcal.estimation.pose_models import PoseModel
from selfcal.solver import Evaluation, JacobianPiece, Loss

__all__ = [
    "RAYLEIGH_MEDIAN",
    "camera_points",
    "projection_blocks",
    "reprojection_residuals",
    "robust_sigma",
    "twist_jacobian",
    "ReprojectionBlock",
]

CHUNK_ROWS = 8192
"""Rows per chunk of :meth:`ReprojectionBlock.evaluate` (bounds its temporaries to a few MB)."""

RAYLEIGH_MEDIAN = 1.1774  # median of |r| for 2-D Gaussian noise with unit sigma per axis


def robust_sigma(norms: np.ndarray) -> float:
    """Pixel noise per coordinate (px) from residual norms ``|r|`` (k,) px of 2-D Gaussian noise:
    ``median |r| / 1.1774`` (robust to outliers)."""
    return float(np.median(norms) / RAYLEIGH_MEDIAN)


def camera_points(
    T_cam_world: np.ndarray, X: np.ndarray, view: np.ndarray, pidx: np.ndarray
) -> np.ndarray:
    """Camera-frame coordinates (k, 3) (m) of the points ``X[pidx]`` in the views ``view``."""
    return _camera_points(T_cam_world[view], X, pidx)


def _camera_points(T_rows: np.ndarray, X: np.ndarray, pidx: np.ndarray) -> np.ndarray:
    """:func:`camera_points` from the rows' poses ``T_rows = T_cam_world[view]`` (k, 4, 4),
    gathered once (one fancy index instead of one for the rotations and one for the
    translations)."""
    return np.einsum("kij,kj->ki", T_rows[:, :3, :3], X[pidx]) + T_rows[:, :3, 3]


def reprojection_residuals(
    camera: Cameras,
    T_cam_world: np.ndarray,
    X: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals ``projected - observed`` (k, 2) px and depths (k,) m for rows (view, point
    index), world points ``X`` (P, 3) m, poses ``T_cam_world`` (V, 4, 4); ``camera``: one model
    shared by every view, or a :class:`selfcal.camera.camera_set.CameraSet` (each view's own)."""
    Xc = camera_points(T_cam_world, X, view, pidx)
    return project_views(camera, Xc, view) - uv, Xc[:, 2]


def projection_blocks(
    camera: Cameras, T_cam_world: np.ndarray, X: np.ndarray, view: np.ndarray, pidx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixels (k, 2) and the Jacobian blocks of the projection for rows (view, point index):
    w.r.t. the camera's free parameters (k, 2, n_free), w.r.t. a camera-frame twist ``[v; w]`` of
    ``T_cam_world`` (k, 2, 6) and w.r.t. the world point (k, 2, 3); px per unit."""
    T_rows = T_cam_world[view]
    Xc = _camera_points(T_rows, X, pidx)
    uv, A, J_cam = project_free_views(camera, Xc, view)
    return uv, J_cam, twist_jacobian(A, Xc), A @ T_rows[:, :3, :3]


def twist_jacobian(A: np.ndarray, Xc: np.ndarray) -> np.ndarray:
    """``A @ [I | -skew(Xc)]`` (k, 2, 6) for the projection Jacobians ``A`` (k, 2, 3) at the
    camera-frame points ``Xc`` (k, 3) m: the derivative w.r.t. a twist ``[v; w]`` of the pose,
    written out (``-a^T skew(x) = (x cross a)^T``) instead of k small matrix products."""
    J = np.empty(A.shape[:-1] + (6,))
    J[..., :3] = A
    x, y, z = (Xc[:, None, i] for i in range(3))
    a0, a1, a2 = A[..., 0], A[..., 1], A[..., 2]
    np.subtract(y * a2, z * a1, out=J[..., 3])
    np.subtract(z * a0, x * a2, out=J[..., 4])
    np.subtract(x * a1, y * a0, out=J[..., 5])
    return J


class ReprojectionBlock:
    """Image observations as one residual block (``dim`` 2, px): rows ``(view, pidx, uv)``.

    Parameter blocks (names configurable): ``intrinsics`` the free parameters of ``camera`` (one
    model shared by every camera of the rig, as the paper assumes, or a
    :class:`selfcal.camera.camera_set.CameraSet`: each camera its own, the rows of a view
    depending on its camera's only), ``poses`` the pose model's
    parameters ``p``, ``points`` the world points (3 P) raveled, m. A pose model whose
    ``view_jacobian`` returns None yields NaN pose derivatives (finite differences belong to the
    caller; the engine refuses them with a :class:`selfcal.errors.SolverError`).
    """

    dim = 2

    def __init__(
        self,
        camera: Cameras,
        pose_model: PoseModel,
        view: np.ndarray,
        pidx: np.ndarray,
        uv: np.ndarray,
        loss: Loss | None = None,
        *,
        name: str = "reprojection",
        intrinsics: str = "intrinsics",
        poses: str = "poses",
        points: str = "points",
    ) -> None:
        self.name = name
        self.loss = loss or Loss()
        self.camera = camera
        self.model = pose_model
        self.view = np.asarray(view, dtype=np.int64)
        self.pidx = np.asarray(pidx, dtype=np.int64)
        self.uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        self.keys = (intrinsics, poses, points)
        self.pose_cols = pose_model.view_columns()[self.view]
        self.point_cols = 3 * self.pidx[:, None] + np.arange(3)
        self.camera_cols = np.arange(camera.n_free)[None]

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (k, 2) px and the pieces d/d(camera), d/dp, d/dX."""
        ki, kp, kx = self.keys
        cam = self.camera.with_free_values(values[ki])
        p = values[kp]
        X = values[kx].reshape(-1, 3)
        T = self.model.poses(p)
        k, nc = len(self.view), cam.n_free
        r = np.empty((k, 2))
        if not jacobian:
            for a in range(0, k, CHUNK_ROWS):
                sl = slice(a, a + CHUNK_ROWS)
                r[sl] = reprojection_residuals(
                    cam, T, X, self.view[sl], self.pidx[sl], self.uv[sl]
                )[0]
            return Evaluation(r)
        Jv = self.model.view_jacobian(p)
        Jc, Jx = np.empty((k, 2, nc)), np.empty((k, 2, 3))
        shape = self.pose_cols.shape[:1] + (2,) + self.pose_cols.shape[1:]
        Jp = np.full(shape, np.nan) if Jv is None else np.empty(shape)
        # by chunks of rows: whole-block temporaries (the rows' poses, their view Jacobians: a
        # kinematic pose model's are (k, 6, ~30), 0.3 GB at 3000 postures) cost more in fresh
        # pages than in arithmetic; a chunk's stay in the cache (row by row the same numbers)
        for a in range(0, k, CHUNK_ROWS):
            sl = slice(a, a + CHUNK_ROWS)
            uv, Jc[sl], Jt, Jx[sl] = projection_blocks(cam, T, X, self.view[sl], self.pidx[sl])
            np.subtract(uv, self.uv[sl], out=r[sl])
            if Jv is not None:
                np.matmul(Jt, Jv[self.view[sl]], out=Jp[sl])
        return Evaluation(
            r,
            (
                JacobianPiece(ki, Jc, self.camera_cols),
                JacobianPiece(kp, Jp, self.pose_cols),
                JacobianPiece(kx, Jx, self.point_cols),
            ),
        )
