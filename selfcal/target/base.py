"""The target interface: features with ids, their 3-D positions where known, and their detection.

A *target* is what the cameras photograph: a field of markers at unknown positions (the paper's
setting, :class:`selfcal.target.aruco.ArucoField`), later a printed board of known geometry
(chessboard, ChArUco, AprilGrid). Each of its *features* (a marker corner, a board corner) has an
integer id that is the same in every image; detection returns the ids it found and their pixel
coordinates (:class:`Features`, OpenCV convention: x right, y down, pixel centres at integers).
Positions are in the target's own frame (m) and NaN where the target does not know them (they are
then estimated with the cameras).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from selfcal.errors import UsageError

__all__ = ["Features", "Target"]


@dataclass(frozen=True)
class Features:
    """Features of a target found in one image: ``ids`` (k,) int, ``uv`` (k, 2) px (OpenCV)."""

    ids: np.ndarray
    uv: np.ndarray

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=np.int64).reshape(-1)
        uv = np.asarray(self.uv, dtype=float).reshape(-1, 2)
        if len(ids) != len(uv):
            raise UsageError(f"Features: {len(ids)} ids but {len(uv)} pixel coordinates")
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "uv", uv)

    def __len__(self) -> int:
        return len(self.ids)


class Target(ABC):
    """A calibration target (see the module docstring)."""

    @abstractmethod
    def detect(self, image: np.ndarray) -> Features:
        """The target's features in an RGB (H, W, 3) or gray (H, W) uint8 image (none: empty).

        Raises ``ValueError`` for an image of the wrong type or shape."""

    @abstractmethod
    def points(self, ids: np.ndarray) -> np.ndarray:
        """Positions (k, 3) in the target frame (m) of features ``ids`` (k,); NaN where the
        target does not know them."""
