"""Analytic observations: marker corners projected through the true cameras, with pixel noise.

The fast path of the simulator (``[noise] render = false``): instead of rendering and detecting,
project the true corners with the camera model and add Gaussian noise. Which markers a camera sees
is decided by the one visibility rule (:class:`selfcal.camera.Visibility`, its defaults: all four
corners in front of the camera and inside the image, the marker facing the camera). A board's
features (:func:`project_board`) are points: each one seen by the same rule, the board's printed
face turned to the camera.
"""

from __future__ import annotations

import numpy as np

from selfcal.camera import CameraModel, Visibility, project
from selfcal.errors import UsageError
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = ["project_board", "project_markers"]


def _noise_rng(pixel_sigma: float, rng: np.random.Generator | None) -> np.random.Generator:
    """The generator for pixel noise of ``pixel_sigma`` px: ``rng``; without noise an unused
    stand-in. Raises ``UsageError`` for noise without ``rng`` (reproducibility)."""
    if rng is not None:
        return rng
    if pixel_sigma > 0:
        raise UsageError("pixel_sigma > 0 needs a random generator (rng) for reproducibility")
    return np.random.default_rng(0)  # never drawn from: pixel_sigma == 0


def project_markers(
    T_world_cam: np.ndarray,
    intr: CameraModel,
    ids: np.ndarray,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    *,
    pixel_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
    visibility: Visibility | None = None,
) -> dict[int, np.ndarray]:
    """Corners (px, OpenCV convention) of the markers one camera sees.

    Args:
        T_world_cam: (4, 4) camera pose, OpenCV camera frame, m.
        intr: the camera model.
        ids: (k,) marker ids; corners_world: (k, 4, 3) in cv2.aruco corner order (m);
        normals_world: (k, 3) marker face normals.
        pixel_sigma: standard deviation of the Gaussian noise added to each coordinate (px).
        visibility: the rule's thresholds (default :class:`selfcal.camera.Visibility`).
    Returns:
        ``{marker id: (4, 2) corners}``.
    """
    noise = _noise_rng(pixel_sigma, rng)
    rule = visibility or Visibility()
    T = np.asarray(T_world_cam, dtype=float)
    ok = rule.markers(intr, T[None], corners_world, normals_world)[0]
    uv = project(intr, inv_pose(T), corners_world)
    out: dict[int, np.ndarray] = {}
    for k in np.flatnonzero(ok):
        c = uv[k].copy()
        if pixel_sigma > 0:
            c += noise.normal(0.0, pixel_sigma, size=c.shape)
            # like a detector, never report a corner outside the image
            if not (np.all((c >= 0) & (c <= [intr.width - 1, intr.height - 1]))):
                continue
        out[int(ids[k])] = c
    return out


def project_board(
    T_world_cam: np.ndarray,
    camera: CameraModel,
    board: Board,
    T_world_board: np.ndarray,
    *,
    pixel_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
    visibility: Visibility | None = None,
) -> dict[int, np.ndarray]:
    """The features (px, OpenCV convention) of ``board`` (posed at ``T_world_board``, board ->
    world, m; its printed face the board frame's -z side) that one camera at ``T_world_cam``
    (m) sees by the visibility rule, with Gaussian noise of ``pixel_sigma`` px per coordinate.

    Returns:
        ``{feature id: (1, 2) px}`` (a feature whose noisy pixel leaves the image is dropped,
        as a detector would; a view with fewer than the board's ``min_features`` is empty, and
        of a board whose detector finds the whole grid or nothing (``whole_grid``: chessboard,
        circles grid) a view without every feature).
    """
    noise = _noise_rng(pixel_sigma, rng)
    rule = visibility or Visibility()
    ids, pts = board.layout()
    Tb = np.asarray(T_world_board, dtype=float)
    X = pts @ Tb[:3, :3].T + Tb[:3, 3]
    normals = np.tile(-Tb[:3, 2], (len(X), 1))
    T = np.asarray(T_world_cam, dtype=float)
    ok = rule.points(camera, T[None], X, normals)[0]
    uv = project(camera, inv_pose(T), X[ok])
    if pixel_sigma > 0:
        uv = uv + noise.normal(0.0, pixel_sigma, size=uv.shape)
    inside = np.all((uv >= 0) & (uv <= [camera.width - 1, camera.height - 1]), axis=1)
    if inside.sum() < (board.n_features if board.whole_grid else board.min_features):
        return {}
    return {int(i): p[None] for i, p in zip(ids[ok][inside], uv[inside], strict=True)}
