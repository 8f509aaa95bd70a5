"""Calibration targets: the :class:`Target` interface and today's ArUco marker field.

- :mod:`calib.target.base`: :class:`Target` (detection, feature ids -> 3-D points) and
  :class:`Features` (ids and pixels found in one image);
- :mod:`calib.target.aruco`: :class:`ArucoField` and the id <-> (marker, corner) mapping;
- :mod:`calib.target.aruco_detect`: the ArUco corner detector with sub-pixel refinement.

- :mod:`calib.target.boards`: printed boards of known geometry (:class:`Chessboard`,
  :class:`Charuco`, :class:`CirclesGrid`, :class:`AprilGrid`), their feature ids and generated
  images; :mod:`calib.target.board_detect` their OpenCV detectors.

A target is declared in a target TOML (:mod:`calib.io.target_toml`).
"""

from calib.target.aruco import (
    CORNERS_PER_MARKER,
    ArucoField,
    feature_id,
    marker_corner,
    marker_features,
    markers_to_features,
)
from calib.target.base import Features, Target
from calib.target.boards import AprilGrid, Board, BoardImage, Charuco, Chessboard, CirclesGrid

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
