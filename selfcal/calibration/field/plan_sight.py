"""Which markers of a field a planned posture's camera finds, as the renderer and the detector
do (issue #30: every planned posture renders and registers).

The forecast counts a marker seen when its corners lie in the image and its face turns to the
camera within 75 deg (:class:`selfcal.camera.Visibility`, what the analytic simulator reports).
The rendered images' detector keeps fewer (docs/plan.md, "A marker field"): it drops a marker
seen more obliquely than its foreshortening limit (:data:`selfcal.target.aruco_detect.
MIN_ASPECT`, about 60 deg) and one whose quiet zone another marker's raised support hides
(:func:`selfcal.target.aruco_detect.detect_markers`' side screening); a posture near the
image's edge loses markers to the arm's deviation from its drawing. A posture whose camera then
finds fewer than :data:`selfcal.estimation.epipolar.MIN_SHARED` corners is dropped by the field
route's first pass, so a field plan takes only postures whose camera finds that many by
:func:`found_markers`: every corner :data:`FOUND.margin_px <FOUND>` inside the image, the
marker's foreshortening in the image at least :data:`MIN_ASPECT`, and the lines of sight to its
tile's corners (the printed square with its quiet zone) clear of every other support. SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.camera import CameraModel, Visibility
from selfcal.estimation.epipolar import MIN_SHARED
from selfcal.kinematics.trajectory import PLANNING_VISIBILITY
from selfcal.target import CORNERS_PER_MARKER
from selfcal.target.aruco_detect import MIN_ASPECT, foreshortening
from selfcal.transforms import inv_pose

__all__ = ["FOUND", "Supports", "found_markers", "registers"]

FOUND = Visibility(
    margin_px=PLANNING_VISIBILITY.margin_px,
    min_depth_m=Visibility().min_depth_m,
    max_depth_m=Visibility().max_depth_m,
    max_incidence_deg=Visibility().max_incidence_deg,
)
"""The image margin of a found marker: the planner's (12 px, room for the arm's deviation from
its drawing); the obliquity is the detector's own test in :func:`found_markers`."""


@dataclass(frozen=True)
class Supports:
    """The raised supports of a field's markers as boxes: ``T_world_box`` (s, 4, 4) each box's
    centre and axes, ``half_m`` (s, 3) its half sizes (m), ``of_marker`` (K,) the box each
    marker lies on (-1: the table), and ``tile_ratio`` the printed tile's side over the marker's
    (the quiet zone around the black square)."""

    T_world_box: np.ndarray
    half_m: np.ndarray
    of_marker: np.ndarray
    tile_ratio: float

    def tiles(self, corners_world: np.ndarray) -> np.ndarray:
        """(K, 4, 3) m the tile's corners of markers ``corners_world`` (K, 4, 3) m."""
        c = np.asarray(corners_world, dtype=float)
        mid = c.mean(axis=1, keepdims=True)
        return mid + self.tile_ratio * (c - mid)

    def hidden(self, centres_world: np.ndarray, points_world: np.ndarray) -> np.ndarray:
        """(m, K) bool: a line of sight from camera centres ``centres_world`` (m, 3) to any of
        the points ``points_world`` (K, p, 3) (marker k's) crosses a box other than marker k's
        own support."""
        m, (K, p, _) = len(centres_world), points_world.shape
        out = np.zeros((m, K), bool)
        for b in range(len(self.half_m)):
            R, t = self.T_world_box[b, :3, :3], self.T_world_box[b, :3, 3]
            a = (np.asarray(centres_world) - t) @ R  # (m, 3) in the box frame
            e = (points_world.reshape(-1, 3) - t) @ R  # (K p, 3)
            d = e[None] - a[:, None]  # (m, K p, 3) the segment a -> e
            h = self.half_m[b]
            with np.errstate(divide="ignore", invalid="ignore"):
                t0 = (-h - a[:, None]) / d
                t1 = (h - a[:, None]) / d
            lo = np.where(
                d == 0, np.where(np.abs(a[:, None]) <= h, -np.inf, np.inf), np.minimum(t0, t1)
            )
            hi = np.where(
                d == 0, np.where(np.abs(a[:, None]) <= h, np.inf, -np.inf), np.maximum(t0, t1)
            )
            enter, leave = lo.max(axis=2), hi.min(axis=2)
            cross = (enter < leave) & (leave > 0.0) & (enter < 1.0 - 1e-9)
            cross = cross.reshape(m, K, p).any(axis=2)
            cross[:, self.of_marker == b] = False  # a marker's own block does not hide it
            out |= cross
        return out


def found_markers(
    camera: CameraModel,
    T_world_cam: np.ndarray,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    supports: Supports | None,
) -> np.ndarray:
    """(m, K) bool: the markers (corners (K, 4, 3) m, unit normals (K, 3)) the detector finds
    in ``camera``'s images from poses ``T_world_cam`` (m, 4, 4) (module docstring); without
    ``supports`` no line of sight is checked."""
    T = np.asarray(T_world_cam, dtype=float)
    c = np.asarray(corners_world, dtype=float)
    ok = FOUND.markers(camera, T, c, normals_world)
    T_cw = inv_pose(T)
    Xc = np.einsum("mij,kcj->mkci", T_cw[:, :3, :3], c) + T_cw[:, None, None, :3, 3]
    uv = camera.project_valid(Xc.reshape(-1, 3))[0].reshape(len(T), len(c), 4, 2)
    with np.errstate(invalid="ignore"):
        ok &= foreshortening(uv.reshape(-1, 4, 2)).reshape(len(T), len(c)) >= MIN_ASPECT
    if supports is not None:
        ok &= ~supports.hidden(T[:, :3, 3], supports.tiles(c))
    return ok


def registers(found: np.ndarray) -> np.ndarray:
    """(m,) bool: the postures whose camera finds (``found`` (m, K) from :func:`found_markers`)
    at least :data:`selfcal.estimation.epipolar.MIN_SHARED` corners, the field route's first
    pass's least to register a view."""
    return CORNERS_PER_MARKER * np.asarray(found).sum(axis=1) >= MIN_SHARED
