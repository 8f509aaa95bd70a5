"""The one visibility rule: which points (or markers) a camera sees from a pose.

A point is seen when the camera model projects it (:meth:`selfcal.camera.model.CameraModel.valid`:
in front of a perspective camera, inside the field of view of a model past 180 deg) within a depth
range (:meth:`~selfcal.camera.model.CameraModel.depth`), projects inside the image with a margin and -- given its surface normal -- faces the camera within an incidence angle. A
marker (a flat patch with several corner points) is seen when all its corners are seen (depth and
image tests) and its centre faces the camera. The simulator's analytic observations, the planner,
the D-optimal selection and the predicted Cramer-Rao bounds all ask this rule (with their own
thresholds); a camera model with a lens term changes what "inside the image" means through its own
:meth:`selfcal.camera.model.CameraModel.project`, not here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.camera.model import CameraModel
from selfcal.transforms import inv_pose

__all__ = ["Visibility"]


@dataclass(frozen=True)
class Visibility:
    """Thresholds of the visibility rule (defaults: what the analytic simulator reports).

    ``margin_px``: distance a projection must keep from the image border (pixel centres
    ``0 .. W - 1``); ``min_depth_m``, ``max_depth_m``: depth range (m) along the optical axis
    (a model past 180 deg: distance from the camera centre);
    ``max_incidence_deg``: largest angle between a surface normal and the direction to the
    camera centre.
    """

    margin_px: float = 2.0
    min_depth_m: float = 0.01
    max_depth_m: float = np.inf
    max_incidence_deg: float = 75.0

    def in_view(
        self, camera: CameraModel, T_world_cam: np.ndarray, X_world: np.ndarray
    ) -> np.ndarray:
        """(m, ...) bool: points ``X_world`` (..., 3) (m) inside the depth range and the image
        of ``camera`` at poses ``T_world_cam`` (m, 4, 4) (no facing test)."""
        T_cw = inv_pose(np.asarray(T_world_cam, dtype=float))
        X = np.asarray(X_world, dtype=float)
        # R X + t per pose, summed over j in einsum's order (the same bits, 3x faster than
        # np.einsum("mij,...j->m...i", R, X) on 4096 poses x 36 points)
        lead = (len(T_cw),) + (1,) * (X.ndim - 1)
        R = T_cw[:, :3, :3].reshape(lead + (3, 3))
        Xc = R[..., 0] * X[..., None, 0] + R[..., 1] * X[..., None, 1] + R[..., 2] * X[..., None, 2]
        Xc += T_cw[:, :3, 3].reshape(lead + (3,))
        d = camera.depth(Xc)
        ok = camera.valid(Xc) & (d > self.min_depth_m) & (d < self.max_depth_m)
        return ok & camera.in_image(camera.project_valid(Xc)[0], self.margin_px)

    def facing(
        self, T_world_cam: np.ndarray, P_world: np.ndarray, normals_world: np.ndarray
    ) -> np.ndarray:
        """(m, k) bool: surfaces at ``P_world`` (k, 3) with unit normals ``normals_world`` (k, 3)
        face the camera centres of ``T_world_cam`` (m, 4, 4) within ``max_incidence_deg``."""
        to_cam = np.asarray(T_world_cam)[:, None, :3, 3] - np.asarray(P_world)[None]
        cosang = np.einsum("mkj,kj->mk", to_cam, normals_world) / np.linalg.norm(to_cam, axis=-1)
        return cosang > np.cos(np.radians(self.max_incidence_deg))

    def points(
        self,
        camera: CameraModel,
        T_world_cam: np.ndarray,
        X_world: np.ndarray,
        normals_world: np.ndarray | None = None,
    ) -> np.ndarray:
        """(m, k) bool: which points ``X_world`` (k, 3) (m; unit ``normals_world`` (k, 3) or
        None for no facing test) ``camera`` sees from each pose ``T_world_cam`` (m, 4, 4)."""
        ok = self.in_view(camera, T_world_cam, X_world)
        if normals_world is not None:
            ok &= self.facing(T_world_cam, X_world, normals_world)
        return ok

    def markers(
        self,
        camera: CameraModel,
        T_world_cam: np.ndarray,
        corners_world: np.ndarray,
        normals_world: np.ndarray,
    ) -> np.ndarray:
        """(m, K) bool: which markers (corners (K, c, 3) m, unit face normals (K, 3)) ``camera``
        sees from each pose ``T_world_cam`` (m, 4, 4): every corner in view, the marker's centre
        facing the camera."""
        corners = np.asarray(corners_world, dtype=float)
        ok = self.in_view(camera, T_world_cam, corners).all(axis=-1)
        return ok & self.facing(T_world_cam, corners.mean(axis=1), normals_world)
