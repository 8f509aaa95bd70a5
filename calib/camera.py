"""Pinhole camera model in the OpenCV convention.

Image coordinates: x right, y down, pixel centres at integer coordinates (the top-left pixel's
centre is (0, 0)). Camera frame: x right, y down, z forward along the optical axis (metres).
Intrinsics follow the paper's eq. 19 with the principal point kept explicit:
``K = [[fx, 0, cx], [0, mu * fx, cy], [0, 0, 1]]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Intrinsics", "project", "centered_principal_point"]


def centered_principal_point(width: int, height: int) -> tuple[float, float]:
    """The image centre in OpenCV pixel coordinates: ``((W - 1) / 2, (H - 1) / 2)``."""
    return (width - 1) / 2.0, (height - 1) / 2.0


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics: focal length ``fx`` (px), aspect ratio ``mu`` (fy = mu fx), principal
    point ``(cx, cy)`` (px, OpenCV convention) and image size (px)."""

    fx: float
    mu: float
    cx: float
    cy: float
    width: int
    height: int

    @classmethod
    def centered(cls, fx: float, mu: float, width: int, height: int) -> Intrinsics:
        """Intrinsics with the principal point at the image centre."""
        cx, cy = centered_principal_point(width, height)
        return cls(float(fx), float(mu), cx, cy, int(width), int(height))

    @property
    def fy(self) -> float:
        """Vertical focal length (px)."""
        return self.mu * self.fx

    @property
    def K(self) -> np.ndarray:
        """3x3 calibration matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


def project(K: np.ndarray, T_cam_world: np.ndarray, X_world: np.ndarray) -> np.ndarray:
    """Project world points ``X_world`` (..., 3) (m) through cameras ``T_cam_world`` (..., 4, 4).

    Returns pixel coordinates (..., 2) in the OpenCV convention. Points behind the camera give
    meaningless values; callers check depth with ``(T_cam_world @ X)[2] > 0``.
    """
    X = np.asarray(X_world, dtype=float)
    T = np.asarray(T_cam_world, dtype=float)
    Xc = np.einsum("...ij,...j->...i", T[..., :3, :3], X) + T[..., :3, 3]
    uvw = np.einsum("ij,...j->...i", np.asarray(K, dtype=float), Xc)
    return uvw[..., :2] / uvw[..., 2:3]
