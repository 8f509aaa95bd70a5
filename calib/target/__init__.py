"""Calibration targets: the :class:`Target` interface and today's ArUco marker field.

- :mod:`calib.target.base`: :class:`Target` (detection, feature ids -> 3-D points) and
  :class:`Features` (ids and pixels found in one image);
- :mod:`calib.target.aruco`: :class:`ArucoField` and the id <-> (marker, corner) mapping;
- :mod:`calib.target.aruco_detect`: the ArUco corner detector with sub-pixel refinement.

A printed board (chessboard, ChArUco, AprilGrid) is a new :class:`Target` next to the field.
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

__all__ = [
    "CORNERS_PER_MARKER",
    "ArucoField",
    "Features",
    "Target",
    "feature_id",
    "marker_corner",
    "marker_features",
    "markers_to_features",
]
