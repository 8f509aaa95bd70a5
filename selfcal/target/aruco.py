"""Today's target: ArUco markers at unknown positions, each contributing its four corners.

Feature ids: corner ``c`` (0..3, cv2.aruco order: top-left, top-right, bottom-right, bottom-left
of the upright marker) of marker ``k`` is feature ``4 k + c``. That mapping lives here and only
here (:func:`feature_id`, :func:`marker_corner`, :func:`marker_features`); a marker's centre is
the mean of its corners. The corner detector and its sub-pixel refinement are in
:mod:`selfcal.target.aruco_detect`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError
from selfcal.target.aruco_detect import detect_markers
from selfcal.target.base import Features, Target

__all__ = [
    "CORNERS_PER_MARKER",
    "ArucoField",
    "feature_id",
    "marker_corner",
    "marker_features",
    "markers_to_features",
]

CORNERS_PER_MARKER = 4


def feature_id(marker: np.ndarray | int, corner: np.ndarray | int) -> np.ndarray | int:
    """Feature id of corner ``corner`` (0..3) of marker ``marker`` (ints or broadcast arrays)."""
    if np.ndim(marker) or np.ndim(corner):
        return CORNERS_PER_MARKER * np.asarray(marker) + np.asarray(corner)
    return CORNERS_PER_MARKER * int(marker) + int(corner)


def marker_corner(fid: np.ndarray | int) -> tuple[np.ndarray, np.ndarray] | tuple[int, int]:
    """Inverse of :func:`feature_id`: ``(marker, corner)``."""
    if np.ndim(fid):
        return np.divmod(np.asarray(fid), CORNERS_PER_MARKER)
    return divmod(int(fid), CORNERS_PER_MARKER)


def marker_features(marker: np.ndarray | int) -> np.ndarray:
    """The feature ids (..., 4) of markers ``marker`` (...,), corners in order."""
    return np.asarray(feature_id(np.asarray(marker)[..., None], np.arange(CORNERS_PER_MARKER)))


def markers_to_features(markers: Mapping[int, np.ndarray], where: str = "") -> Features:
    """``{marker id: corners (4, 2) px}`` (what :func:`detect_markers` returns) as features.

    Raises ``ValueError`` naming the marker (and ``where``) when its corners are not (4, 2)."""
    try:  # every marker at once (a frame's 20-40 markers: a tenth of the time of the loop)
        mids = np.fromiter(markers.keys(), dtype=np.int64, count=len(markers))
        stacked = np.asarray(list(markers.values()), dtype=float)
    except (TypeError, ValueError):  # a marker the loop below names (or an id int() refuses)
        stacked = None
    if stacked is not None and stacked.shape == (len(markers), CORNERS_PER_MARKER, 2):
        return Features(marker_features(mids).reshape(-1), stacked.reshape(-1, 2))
    ids, uv = [], []
    for mid, corners in markers.items():
        c = np.asarray(corners, dtype=float)
        if c.shape != (CORNERS_PER_MARKER, 2):
            raise InputError(
                f"marker {mid}{' in ' + where if where else ''}: corners must have shape "
                f"({CORNERS_PER_MARKER}, 2), got {c.shape}"
            )
        ids.append(marker_features(int(mid)))
        uv.append(c)
    if not ids:
        return Features(np.zeros(0, np.int64), np.zeros((0, 2)))
    return Features(np.concatenate(ids), np.concatenate(uv))


@dataclass(frozen=True)
class ArucoField(Target):
    """Markers of ArUco dictionary ``dictionary`` at unknown positions; corners refined by
    ``refine`` (see :data:`selfcal.target.aruco_detect.REFINE_METHODS`)."""

    dictionary: str = "DICT_4X4_50"
    refine: str = "lines"

    def detect_markers(self, image: np.ndarray) -> dict[int, np.ndarray]:
        """``{marker id: corners (4, 2) px}`` (:func:`detect_markers`)."""
        return detect_markers(image, dictionary=self.dictionary, refine=self.refine)

    def detect(self, image: np.ndarray) -> Features:
        return markers_to_features(self.detect_markers(image))

    def points(self, ids: np.ndarray) -> np.ndarray:
        """All NaN: the field's marker positions are unknown (the self-calibration estimates
        them)."""
        return np.full((len(np.asarray(ids).reshape(-1)), 3), np.nan)
