"""Synthetic stereo scenes for the self-calibration: a random marker field seen by a stereo rig.

Ground truth and detections, no images: corners are projected with :func:`selfcal.camera.project`
(field frame: z up, m; pixels OpenCV). For tests and benchmarks of :mod:`selfcal.calibration.field.self_calibration`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.camera import Intrinsics, project
from selfcal.estimation.observations import Observations
from selfcal.target import CORNERS_PER_MARKER, marker_features
from selfcal.transforms import inv_pose, make_pose, rot_y

__all__ = ["SyntheticScene", "synthetic_stereo_scene", "look_at"]


@dataclass
class SyntheticScene:
    """Ground truth and detections of :func:`synthetic_stereo_scene` (field frame: z up)."""

    detections: dict
    intrinsics: Intrinsics
    T_world_cam: np.ndarray  # (m, 2, 4, 4)
    T_left_right: np.ndarray
    point_ids: np.ndarray
    X_world: np.ndarray
    scale_markers: tuple[int, int]
    scale_distance_m: float
    outlier_rows: list = field(default_factory=list)

    def observations(self) -> Observations:
        return Observations.from_corners(self.detections, n_configs=len(self.T_world_cam))


def look_at(C: np.ndarray, target: np.ndarray, roll: float) -> np.ndarray:
    """Camera pose ``T_world_cam`` (4, 4) at ``C`` (3,) looking at ``target`` (3,) (m), rolled by
    ``roll`` (rad) about its optical axis (OpenCV camera frame)."""
    z = target - C
    z /= np.linalg.norm(z)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1)
    c, s = np.cos(roll), np.sin(roll)
    R = R @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return make_pose(R, C)


def synthetic_stereo_scene(
    n_configs: int,
    *,
    seed: int = 0,
    fx: float = 800.0,
    mu: float = 1.0,
    width: int = 640,
    height: int = 480,
    n_markers: int = 20,
    marker_size_m: float = 0.03,
    field_m: float = 0.3,
    relief_m: float = 0.08,
    baseline_m: float = 0.06,
    distance_m: tuple[float, float] = (0.2, 0.4),
    tilt_max_deg: float = 35.0,
    roll_max_deg: float = 30.0,
    aim_jitter_m: float = 0.08,
    vergence_distance_m: float | None = None,
    fixate: bool = False,
    noise_px: float = 0.0,
    outlier_fraction: float = 0.0,
    outlier_px: float = 20.0,
    T_world_left: np.ndarray | None = None,
    camera: Intrinsics | None = None,
    camera_right: Intrinsics | None = None,
) -> SyntheticScene:
    """Random marker field + stereo rig views, projected with :func:`selfcal.camera.project`.

    Markers: squares of ``marker_size_m`` at random positions in ``field_m`` x ``field_m``, heights
    uniform in ``[0, relief_m]``, facing +z. Each configuration places the rig midpoint at a
    distance in ``distance_m`` from an aim point (field centre +- ``aim_jitter_m``), tilted up to
    ``tilt_max_deg`` from vertical, rolled up to ``roll_max_deg``; the right camera sits
    ``baseline_m`` along the left x axis (slightly misaligned, or toed-in to meet at
    ``vergence_distance_m``). ``fixate``: every configuration aims both cameras at the field
    centre from the vergence distance (optical axes through one point -- degenerate for fx).
    ``T_world_left`` (m, 4, 4) overrides the sampled left-camera poses; ``camera`` (a
    :class:`selfcal.camera.Pinhole` or a camera with a lens) overrides ``fx``, ``mu``, ``width``,
    ``height`` and the centred principal point; ``camera_right`` (default: the same as the left)
    gives the right camera its own model (the scene's ``intrinsics`` stays the left camera's).
    Markers with a corner outside the image or behind the camera are dropped. Gaussian noise
    ``noise_px`` per coordinate; ``outlier_fraction`` of the corners displaced by ``outlier_px``.
    """
    rng = np.random.default_rng(seed)
    intr = Intrinsics.centered(fx, mu, width, height) if camera is None else camera
    centres = np.c_[
        rng.uniform(-field_m / 2, field_m / 2, (n_markers, 2)), rng.uniform(0, relief_m, n_markers)
    ]
    ang = rng.uniform(0, 2 * np.pi, n_markers)
    h = marker_size_m / 2
    local = np.array([[-h, h], [h, h], [h, -h], [-h, -h]])
    corners = np.zeros((n_markers, CORNERS_PER_MARKER, 3))
    for i in range(n_markers):
        c, s = np.cos(ang[i]), np.sin(ang[i])
        corners[i, :, :2] = centres[i, :2] + local @ np.array([[c, s], [-s, c]])
        corners[i, :, 2] = centres[i, 2]
    X = corners.reshape(-1, 3)
    if vergence_distance_m is None and not fixate:
        toe = 0.02
        T_lr = make_pose(
            Rotation.from_rotvec([0.01, -toe, 0.005]).as_matrix(), [baseline_m, 0.001, -0.002]
        )
    else:
        D = vergence_distance_m if vergence_distance_m is not None else np.mean(distance_m)
        toe = 2 * np.arctan2(baseline_m / 2, D)
        T_lr = make_pose(rot_y(-toe)[:3, :3], rot_y(-toe / 2)[:3, :3] @ [baseline_m, 0.0, 0.0])
    # rig midpoint frame -> left camera: left camera at -b/2 along x, toed in by +toe/2
    if vergence_distance_m is None and not fixate:
        T_mid_left = make_pose(np.eye(3), [-baseline_m / 2, 0.0, 0.0])
    else:
        T_mid_left = make_pose(rot_y(toe / 2)[:3, :3], [-baseline_m / 2, 0.0, 0.0])
    zc = relief_m / 2
    Twc = np.zeros((n_configs, 2, 4, 4))
    for i in range(n_configs):
        if fixate:
            target = np.array([0.0, 0.0, zc])
            dist = vergence_distance_m if vergence_distance_m is not None else np.mean(distance_m)
        else:
            target = np.r_[rng.uniform(-aim_jitter_m, aim_jitter_m, 2), zc]
            dist = rng.uniform(*distance_m)
        tilt = np.deg2rad(tilt_max_deg) * np.sqrt(rng.uniform())
        az = rng.uniform(0, 2 * np.pi)
        d = np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        roll = np.deg2rad(rng.uniform(-roll_max_deg, roll_max_deg))
        T_mid = look_at(target + dist * d, target, roll)
        Twc[i, 0] = T_mid @ T_mid_left if T_world_left is None else T_world_left[i]
        Twc[i, 1] = Twc[i, 0] @ T_lr
    Tcw = inv_pose(Twc)
    det: dict = {}
    rows: list[tuple[int, int, int, int]] = []
    for i in range(n_configs):
        for c in range(2):
            cam = camera_right if c == 1 and camera_right is not None else intr
            uvp = project(cam, Tcw[i, c], X).reshape(n_markers, CORNERS_PER_MARKER, 2)
            uvp = uvp + noise_px * rng.standard_normal(uvp.shape)
            z = (X @ Tcw[i, c, :3, :3].T + Tcw[i, c, :3, 3])[:, 2].reshape(n_markers, -1)
            inside = (
                (uvp[..., 0] >= 0)
                & (uvp[..., 0] <= width - 1)
                & (uvp[..., 1] >= 0)
                & (uvp[..., 1] <= height - 1)
                & (z > 0)
            ).all(axis=1)
            markers = {}
            for mk in np.flatnonzero(inside):
                markers[int(mk)] = uvp[mk]
                rows.extend((i, c, int(mk), j) for j in range(CORNERS_PER_MARKER))
            if markers:
                det[(i, c)] = markers
    outliers = []
    if outlier_fraction > 0 and rows:
        n_out = int(round(outlier_fraction * len(rows)))
        for idx in rng.choice(len(rows), n_out, replace=False):
            i, c, mk, j = rows[idx]
            phi = rng.uniform(0, 2 * np.pi)
            moved = det[(i, c)][mk][j] + outlier_px * np.array([np.cos(phi), np.sin(phi)])
            if 0 <= moved[0] <= width - 1 and 0 <= moved[1] <= height - 1:
                det[(i, c)][mk][j] = moved
                outliers.append(rows[idx])
    # scale markers: the two markers closest to the centre-left and centre-right of the field
    a = int(np.argmin(np.linalg.norm(centres[:, :2] - [-field_m / 4, 0], axis=1)))
    b = int(np.argmin(np.linalg.norm(centres[:, :2] - [field_m / 4, 0], axis=1)))
    dist_ab = float(np.linalg.norm(X[marker_features(a)].mean(0) - X[marker_features(b)].mean(0)))
    ids = marker_features(np.arange(n_markers)).ravel()
    return SyntheticScene(det, intr, Twc, T_lr, ids, X, (a, b), dist_ab, outliers)
