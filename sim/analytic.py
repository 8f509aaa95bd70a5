"""Analytic observations: marker corners projected through the true cameras, with pixel noise.

The fast path of the simulator (``[noise] render = false``): instead of rendering and detecting,
project the true corners with the OpenCV pinhole model and add Gaussian noise. A marker counts as
seen when all four corners are in front of the camera, inside the image and it faces the camera.
"""

from __future__ import annotations

import numpy as np

from calib.camera import Intrinsics, project
from calib.transforms import inv_pose

__all__ = ["project_markers"]


def project_markers(
    T_world_cam: np.ndarray,
    intr: Intrinsics,
    ids: np.ndarray,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    *,
    pixel_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
    margin_px: float = 2.0,
    max_incidence_deg: float = 75.0,
) -> dict[int, np.ndarray]:
    """Corners (px, OpenCV convention) of the markers one camera sees.

    Args:
        T_world_cam: (4, 4) camera pose, OpenCV camera frame, m.
        ids: (k,) marker ids; corners_world: (k, 4, 3) in cv2.aruco corner order (m);
        normals_world: (k, 3) marker face normals.
        pixel_sigma: standard deviation of the Gaussian noise added to each coordinate (px).
    Returns:
        ``{marker id: (4, 2) corners}``.
    """
    if pixel_sigma > 0 and rng is None:
        raise ValueError("pixel_sigma > 0 needs a random generator (rng) for reproducibility")
    T_cam_world = inv_pose(T_world_cam)
    Xc = corners_world @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
    uv = project(intr.K, T_cam_world, corners_world)
    to_cam = T_world_cam[:3, 3] - corners_world.mean(axis=1)
    facing = np.einsum("kj,kj->k", to_cam, normals_world) / np.linalg.norm(to_cam, axis=1)
    ok = np.all(Xc[..., 2] > 0.01, axis=1)
    ok &= np.all((uv[..., 0] > margin_px) & (uv[..., 0] < intr.width - 1 - margin_px), axis=1)
    ok &= np.all((uv[..., 1] > margin_px) & (uv[..., 1] < intr.height - 1 - margin_px), axis=1)
    ok &= facing > np.cos(np.radians(max_incidence_deg))
    out: dict[int, np.ndarray] = {}
    for k in np.flatnonzero(ok):
        c = uv[k].copy()
        if pixel_sigma > 0:
            c += rng.normal(0.0, pixel_sigma, size=c.shape)
            # like a detector, never report a corner outside the image
            if not (np.all((c >= 0) & (c <= [intr.width - 1, intr.height - 1]))):
                continue
        out[int(ids[k])] = c
    return out
