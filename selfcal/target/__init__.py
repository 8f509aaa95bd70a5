"""Calibration targets: the :class:`Target` interface and today's ArUco marker field.

- :mod:`selfcal.target.base`: :class:`Target` (detection, feature ids -> 3-D points) and
  :class:`Features` (ids and pixels found in one image);
- :mod:`selfcal.target.aruco`: :class:`ArucoField` and the id <-> (marker, corner) mapping;
- :mod:`selfcal.target.aruco_detect`: the ArUco corner detector with sub-pixel refinement.

- :mod:`selfcal.target.boards`: printed boards of known geometry (:class:`Chessboard`,
  :class:`Charuco`, :class:`CirclesGrid`, :class:`AprilGrid`), their feature ids and generated
  images; :mod:`selfcal.target.board_detect` their OpenCV detectors.

A target is declared in a target TOML (:mod:`selfcal.io.target_toml`).
"""

from selfcal.target.aruco import (
    CORNERS_PER_MARKER,
    ArucoField,
    feature_id,
    marker_corner,
    marker_features,
    markers_to_features,
)
from selfcal.target.base import Features, Target
from selfcal.target.boards import AprilGrid, Board, BoardImage, Charuco, Chessboard, CirclesGrid

__all__ = [
    "CORNERS_PER_MARKER",
    "AprilGrid",
    "ArucoField",
    "Board",
    "BoardImage",
    "Charuco",
    "Chessboard",
    "CirclesGrid",
    "Features",
    "Target",
    "feature_id",
    "marker_corner",
    "marker_features",
    "markers_to_features",
]
