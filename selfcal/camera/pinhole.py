"""The pinhole camera in the OpenCV convention: the first :class:`selfcal.camera.model.CameraModel`.

Intrinsics follow the paper's eq. 19 with the principal point kept explicit and an optional
skew: ``K = [[fx, skew, cx], [0, mu * fx, cy], [0, 0, 1]]`` (px), i.e.
``u = fx x / z + skew y / z + cx``, ``v = mu fx y / z + cy`` (OpenCV's and ROS's ``K``; ``skew``
is ``K[0, 1]``, OpenCV's fisheye ``alpha`` times ``fx``). Parameters, in order: ``fx`` (px),
``mu = fy / fx`` (the paper's aspect ratio), ``cx``, ``cy`` (px, OpenCV pixel centres), ``skew``
(px). By default ``fx`` and ``mu`` are free, the principal point stays at its value (the image
centre, as the paper assumes) and the skew at 0.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from selfcal.camera.model import CameraModel, perspective, perspective_jacobian

__all__ = ["Pinhole", "Intrinsics", "PinholeValues", "centered_principal_point"]


def centered_principal_point(width: int, height: int) -> tuple[float, float]:
    """The image centre in OpenCV pixel coordinates: ``((W - 1) / 2, (H - 1) / 2)``."""
    return (width - 1) / 2.0, (height - 1) / 2.0


@dataclass(frozen=True)
class Pinhole(CameraModel):
    """Pinhole intrinsics: focal length ``fx`` (px), aspect ratio ``mu`` (fy = mu fx), principal
    point ``(cx, cy)`` (px, OpenCV convention), image size (px), the ``free`` parameters and the
    ``skew`` (px, ``K[0, 1]``; keyword only, default 0)."""

    names: ClassVar[tuple[str, ...]] = ("fx", "mu", "cx", "cy", "skew")
    model_name: ClassVar[str] = "pinhole"

    fx: float
    mu: float
    cx: float
    cy: float
    width: int
    height: int
    free: tuple[str, ...] = ("fx", "mu")
    skew: float = field(default=0.0, kw_only=True)

    def __post_init__(self) -> None:
        object.__setattr__(self, "free", tuple(self.free))
        self._check_free()

    @classmethod
    def centered(
        cls, fx: float, mu: float, width: int, height: int, free: tuple[str, ...] = ("fx", "mu")
    ) -> Pinhole:  # skew 0
        """Intrinsics with the principal point at the image centre."""
        cx, cy = centered_principal_point(width, height)
        return cls(float(fx), float(mu), cx, cy, int(width), int(height), tuple(free))

    @property
    def fy(self) -> float:
        """Vertical focal length (px)."""
        return self.mu * self.fx

    @property
    def K(self) -> np.ndarray:
        """3x3 calibration matrix."""
        return np.array([[self.fx, self.skew, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def values(self) -> np.ndarray:
        return np.array([self.fx, self.mu, self.cx, self.cy, self.skew], dtype=float)

    def with_values(self, values: np.ndarray) -> Pinhole:
        fx, mu, cx, cy, skew = (float(v) for v in np.asarray(values, dtype=float).reshape(5))
        return dataclasses.replace(self, fx=fx, mu=mu, cx=cx, cy=cy, skew=skew)

    # ------------------------------------------------------------ normalised <-> pixels
    def pixels(self, xn: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of normalised coordinates ``xn`` (..., 2): the last link of the
        projection chain, also for models with a lens term."""
        xn = np.asarray(xn, dtype=float)
        x, y = xn[..., 0], xn[..., 1]
        u = self.fx * x + self.cx if self.skew == 0.0 else self.fx * x + self.skew * y + self.cx
        return np.stack([u, self.mu * self.fx * y + self.cy], axis=-1)

    def pixels_jacobians(self, xn: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`pixels`, its Jacobian w.r.t. ``xn`` (..., 2, 2) (px) and w.r.t.
        ``(fx, mu, cx, cy, skew)`` (..., 2, 5)."""
        xn = np.asarray(xn, dtype=float)
        x, y = xn[..., 0], xn[..., 1]
        J_xn = np.zeros(xn.shape[:-1] + (2, 2))
        J_xn[..., 0, 0] = self.fx
        J_xn[..., 0, 1] = self.skew
        J_xn[..., 1, 1] = self.mu * self.fx
        J_par = np.zeros(xn.shape[:-1] + (2, 5))
        J_par[..., 0, 0] = x
        J_par[..., 1, 0] = self.mu * y
        J_par[..., 1, 1] = self.fx * y
        J_par[..., 0, 2] = 1.0
        J_par[..., 1, 3] = 1.0
        J_par[..., 0, 4] = y
        return self.pixels(xn), J_xn, J_par

    def normalised(self, uv: np.ndarray) -> np.ndarray:
        """Normalised coordinates (..., 2) of pixels ``uv`` (..., 2): the inverse of
        :meth:`pixels`."""
        uv = np.asarray(uv, dtype=float)
        y = (uv[..., 1] - self.cy) / (self.mu * self.fx)
        return np.stack([(uv[..., 0] - self.cx - self.skew * y) / self.fx, y], axis=-1)

    # ------------------------------------------------------------ the CameraModel interface
    def project(self, X_cam: np.ndarray) -> np.ndarray:
        return self.pixels(perspective(X_cam))

    def project_jacobians(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xn, J_persp = perspective_jacobian(X_cam)
        uv, J_xn, J_par = self.pixels_jacobians(xn)
        return uv, J_xn @ J_persp, J_par

    def unproject_normalised(self, uv: np.ndarray) -> np.ndarray:
        return self.normalised(uv)

    @classmethod
    def starts(cls, width: int, height: int, free: tuple[str, ...]) -> list:
        """Principal point at the centre, aspect 1, no lens, half fields of view across the
        shorter side of 10, 20, 30, 45, 60 and 75 deg (``fx = (side / 2) / tan(half angle)``)."""
        cx, cy = centered_principal_point(width, height)
        side = 0.5 * min(width, height)
        return [
            cls(side / np.tan(np.radians(a)), 1.0, cx, cy, int(width), int(height), tuple(free))
            for a in (10.0, 20.0, 30.0, 45.0, 60.0, 75.0)
        ]


Intrinsics = Pinhole
"""The name the rest of the project has used for the pinhole camera (same class)."""


class PinholeValues:
    """Mixin for results that hold a :class:`Pinhole` as ``camera``: its values under the names
    the paper and the documents use (``fx``, ``mu`` px and ratio, ``cx``, ``cy``, ``width``,
    ``height`` px)."""

    camera: Pinhole

    @property
    def fx(self) -> float:
        return self.camera.fx

    @property
    def mu(self) -> float:
        return self.camera.mu

    @property
    def cx(self) -> float:
        return self.camera.cx

    @property
    def cy(self) -> float:
        return self.camera.cy

    @property
    def width(self) -> int:
        return self.camera.width

    @property
    def height(self) -> int:
        return self.camera.height
