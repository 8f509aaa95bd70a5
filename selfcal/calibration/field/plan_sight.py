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
tile's corners (the printed square with its quiet zone) clear of every other support. A plan
with clear views (:attr:`selfcal.calibration.field.plan.FieldPlanSetup.clear_views`) takes no
posture whose camera shows a marker partly hidden by another's support either
(:func:`partly_hidden`): the detector may return such a marker with corners off by more than
the noise and less than the field route's outlier floor, which keeps them. SI units.
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

__all__ = [
    "FOUND",
    "QUIET_REACH",
    "SIGHT_GRID",
    "Supports",
    "found_markers",
    "partly_hidden",
    "registers",
]

FOUND = Visibility(
    margin_px=PLANNING_VISIBILITY.margin_px,
    min_depth_m=Visibility().min_depth_m,
    max_depth_m=Visibility().max_depth_m,
    max_incidence_deg=Visibility().max_incidence_deg,
)
"""The image margin of a found marker: the planner's (12 px, room for the arm's deviation from
its drawing); the obliquity is the detector's own test in :func:`found_markers`."""
SIGHT_GRID = 9
"""Points per side of the grid over a marker's square whose lines of sight :func:`partly_hidden`
checks (81 a marker: about 4 mm apart on the example's 30 mm markers)."""
QUIET_REACH = 0.5
"""How far into the quiet zone (its share of the zone's width) :func:`partly_hidden` checks the
lines of sight: the detector's edge profiles reach 0.45 module past the black square
(:func:`selfcal.target.aruco_detect.refine_corners_lines`); on rendered KR 6 views a marker
hidden only beyond half the zone was detected as well as a clear one (docs/plan.md)."""


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

    def sight_grid(self, corners_world: np.ndarray) -> np.ndarray:
        """(K, SIGHT_GRID**2, 3) m points spread evenly over the black squares of markers
        ``corners_world`` (K, 4, 3) m widened :data:`QUIET_REACH` of the way into their quiet
        zones (what the detector's edge profiles see), the region's corners and sides among
        them."""
        c = np.asarray(corners_world, dtype=float)
        mid = c.mean(axis=1, keepdims=True)
        t = mid + (1.0 + QUIET_REACH * (self.tile_ratio - 1.0)) * (c - mid)
        a = np.linspace(0.0, 1.0, SIGHT_GRID)
        u, v = (g.ravel()[None, :, None] for g in np.meshgrid(a, a, indexing="ij"))
        top = t[:, None, 0] + u * (t[:, None, 1] - t[:, None, 0])  # (K, p, 3)
        bottom = t[:, None, 3] + u * (t[:, None, 2] - t[:, None, 3])
        return top + v * (bottom - top)

    def hidden(self, centres_world: np.ndarray, points_world: np.ndarray) -> np.ndarray:
        """(m, K) bool: a line of sight from camera centres ``centres_world`` (m, 3) to any of
        the points ``points_world`` (K, p, 3) (marker k's) crosses a box other than marker k's
        own support."""
        return np.asarray(self.hidden_points(centres_world, points_world).any(axis=2))

    def hidden_points(self, centres_world: np.ndarray, points_world: np.ndarray) -> np.ndarray:
        """(m, K, p) bool: the line of sight from camera centre i (``centres_world`` (m, 3) m)
        to point j of marker k (``points_world`` (K, p, 3) m) crosses a box other than marker
        k's own support."""
        m, (K, p, _) = len(centres_world), points_world.shape
        out = np.zeros((m, K, p), bool)
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
            cross = cross.reshape(m, K, p)
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
    ok = FOUND.markers(camera, T, c, normals_world) & _upright(camera, T, c)
    if supports is not None:
        ok &= ~supports.hidden(T[:, :3, 3], supports.tiles(c))
    return ok


def _upright(camera: CameraModel, T_world_cam: np.ndarray, corners_world: np.ndarray) -> np.ndarray:
    """(m, K) bool: the markers (corners (K, 4, 3) m) whose image from poses ``T_world_cam``
    (m, 4, 4) is foreshortened no more than the detector's :data:`MIN_ASPECT` allows."""
    T_cw = inv_pose(T_world_cam)
    c = corners_world
    Xc = np.einsum("mij,kcj->mkci", T_cw[:, :3, :3], c) + T_cw[:, None, None, :3, 3]
    uv = camera.project_valid(Xc.reshape(-1, 3))[0].reshape(len(T_cw), len(c), 4, 2)
    with np.errstate(invalid="ignore"):
        return foreshortening(uv.reshape(-1, 4, 2)).reshape(len(T_cw), len(c)) >= MIN_ASPECT


def partly_hidden(
    camera: CameraModel,
    T_world_cam: np.ndarray,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    supports: Supports,
) -> np.ndarray:
    """(m, K) bool: the markers (corners (K, 4, 3) m, unit normals (K, 3)) that ``camera``
    sees from poses ``T_world_cam`` (m, 4, 4) in its image (every corner in view and the face
    turned to it, :class:`selfcal.camera.Visibility`'s analytic rule) within the detector's
    foreshortening limit, some of whose black square and the inner :data:`QUIET_REACH` of its
    quiet zone (:meth:`Supports.sight_grid`) another marker's support hides and some not. On
    rendered KR 6 views the detector returned such markers with corners 0.2 - 4 px off
    (the raised neighbour's edge across the square or beside it), and the field route's 1 px
    outlier floor keeps those below 1 px (docs/plan.md, "A marker field"): a plan with clear
    views shows none."""
    T = np.asarray(T_world_cam, dtype=float)
    c = np.asarray(corners_world, dtype=float)
    ok = Visibility().markers(camera, T, c, normals_world) & _upright(camera, T, c)
    h = supports.hidden_points(T[:, :3, 3], supports.sight_grid(c))
    return ok & h.any(axis=2) & ~h.all(axis=2)


def registers(found: np.ndarray) -> np.ndarray:
    """(m,) bool: the postures whose camera finds (``found`` (m, K) from :func:`found_markers`)
    at least :data:`selfcal.estimation.epipolar.MIN_SHARED` corners, the field route's first
    pass's least to register a view."""
    return CORNERS_PER_MARKER * np.asarray(found).sum(axis=1) >= MIN_SHARED
