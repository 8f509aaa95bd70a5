"""Triangulation of points seen by cameras of known pose: linear (DLT) and robust (RANSAC).

Poses ``T_cam_world`` (V, 4, 4) map world to camera coordinates (OpenCV frame, m); rays come from
the camera model's :meth:`selfcal.camera.CameraModel.unproject_normalised`.
"""

from __future__ import annotations

import numpy as np

from selfcal.camera.camera_set import Cameras, project_views, unproject_views
from selfcal.estimation.reprojection import reprojection_residuals

__all__ = ["triangulate", "robust_triangulate", "ray_angle"]


def triangulate(
    T_cam_world: np.ndarray, view: np.ndarray, pidx: np.ndarray, xn: np.ndarray, n_points: int
) -> tuple[np.ndarray, np.ndarray]:
    """Linear (DLT) multi-view triangulation in normalised image coordinates ``xn`` (k, 2).

    Returns ``X`` (n_points, 3) (NaN where fewer than 2 observations) and the number of
    observations per point.
    """
    P = T_cam_world[view, :3, :]
    a1 = xn[:, 0:1] * P[:, 2] - P[:, 0]
    a2 = xn[:, 1:2] * P[:, 2] - P[:, 1]
    a1 /= np.linalg.norm(a1, axis=1, keepdims=True)
    a2 /= np.linalg.norm(a2, axis=1, keepdims=True)
    M = np.zeros((n_points, 4, 4))
    np.add.at(M, pidx, a1[:, :, None] * a1[:, None, :] + a2[:, :, None] * a2[:, None, :])
    cnt = np.bincount(pidx, minlength=n_points)
    X = np.full((n_points, 3), np.nan)
    ok = cnt >= 2
    if ok.any():
        _, vec = np.linalg.eigh(M[ok])
        h = vec[:, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            X[ok] = h[:, :3] / h[:, 3:4]
    return X, cnt


def robust_triangulate(
    T_cam_world: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
    camera: Cameras,
    n_points: int,
    threshold_px: float,
    X_current: np.ndarray | None = None,
    n_samples: int = 40,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-point RANSAC triangulation with known poses: two-view DLT hypotheses (plus
    ``X_current`` if given) scored by the number of observations reprojecting within
    ``threshold_px`` in front of the camera, refitted on the inliers of the best one.

    Returns ``X`` (n_points, 3) (NaN with < 2 inliers) and the inlier mask (k,) of the rows.
    """
    rng = np.random.default_rng(seed)
    xn = unproject_views(camera, uv, view)
    X = np.full((n_points, 3), np.nan)
    inlier = np.zeros(len(view), bool)
    order = np.argsort(pidx, kind="stable")
    bounds = np.searchsorted(pidx[order], np.arange(n_points + 1))
    for p in range(n_points):
        rows = order[bounds[p] : bounds[p + 1]]
        if len(rows) < 2:
            continue
        n = len(rows)
        pairs = rng.integers(0, n, size=(n_samples, 2))
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        if n <= 8:
            ii, jj = np.triu_indices(n, 1)
            pairs = np.stack([ii, jj], axis=1)
        Tv = T_cam_world[view[rows]]
        # the current point explaining every row wins the vote whatever the samples give (it is
        # hypothesis 0, argmax takes the first of equal counts): the samples are drawn anyway, so
        # the generator's stream and every other point's outcome stay the same
        cur = X_current[p] if X_current is not None else None
        if cur is not None and not np.isfinite(cur).all():
            cur = None
        if cur is not None:
            hyp = cur[None]
            ok = _votes(camera, Tv, hyp, view[rows], uv[rows], threshold_px)
        if cur is None or not ok[0].all():
            sel = rows[pairs]  # (s, 2)
            s_idx = np.repeat(np.arange(len(sel)), 2)
            hyp, _ = triangulate(T_cam_world, view[sel.ravel()], s_idx, xn[sel.ravel()], len(sel))
            if cur is not None:
                hyp = np.vstack([cur, hyp])
            hyp = hyp[np.isfinite(hyp).all(axis=1)]
            if not len(hyp):
                continue
            ok = _votes(camera, Tv, hyp, view[rows], uv[rows], threshold_px)
        best = int(np.argmax(ok.sum(axis=1)))
        use = rows[ok[best]]
        if len(use) < 2:
            continue
        Xp, _ = triangulate(T_cam_world, view[use], np.zeros(len(use), int), xn[use], 1)
        r, z = reprojection_residuals(
            camera, T_cam_world, Xp, view[rows], np.zeros(n, int), uv[rows]
        )
        ok2 = (z > 0) & (np.linalg.norm(r, axis=1) < threshold_px)
        if ok2.sum() >= ok[best].sum():
            X[p] = Xp[0]
            inlier[rows] = ok2
        else:
            X[p] = hyp[best]
            inlier[rows] = ok[best]
    return X, inlier


def _votes(
    camera: Cameras,
    Tv: np.ndarray,
    hyp: np.ndarray,
    view: np.ndarray,
    uv: np.ndarray,
    threshold_px: float,
) -> np.ndarray:
    """(h, n) whether each of the hypotheses ``hyp`` (h, 3) reprojects within ``threshold_px``
    of each row (poses ``Tv`` (n, 4, 4) of the rows' views, pixels ``uv``), in front of the
    camera."""
    Xc = np.einsum("kij,hj->hki", Tv[:, :3, :3], hyp) + Tv[:, :3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        d = project_views(camera, Xc, view) - uv
    return (Xc[..., 2] > 0) & (np.hypot(d[..., 0], d[..., 1]) < threshold_px)


def ray_angle(
    T_cam_world: np.ndarray, view: np.ndarray, pidx: np.ndarray, X: np.ndarray, n_points: int
) -> np.ndarray:
    """Largest angle (n_points,) (rad) between the viewing rays of each point and its first ray,
    for observation rows ``(view, pidx)``."""
    C = -np.einsum("kji,kj->ki", T_cam_world[view, :3, :3], T_cam_world[view, :3, 3])
    d = X[pidx] - C
    with np.errstate(invalid="ignore"):
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    first = np.full((n_points, 3), np.nan)
    order = np.argsort(pidx, kind="stable")
    starts = np.r_[True, np.diff(pidx[order]) != 0]
    first[pidx[order][starts]] = d[order][starts]
    cosang = np.nan_to_num(np.clip(np.einsum("ki,ki->k", d, first[pidx]), -1, 1), nan=1.0)
    ang = np.zeros(n_points)
    np.maximum.at(ang, pidx, np.nan_to_num(np.arccos(cosang), nan=0.0))
    return ang
