"""Cameras with a lens: the pinhole with OpenCV's Brown-Conrady or fisheye (Kannala-Brandt) map.

Each model is the chain ``X_cam -> perspective -> lens -> Pinhole.pixels`` (see
:mod:`selfcal.camera.model`); the Jacobians follow by the chain rule from the three links'.
Parameters, in order: the pinhole's ``fx`` (px), ``mu = fy / fx``, ``cx``, ``cy``, ``skew`` (px),
then the lens coefficients by OpenCV's names and in OpenCV's order:

- :class:`BrownConrady` (model name ``"opencv"``): ``k1, k2, p1, p2, k3, k4, k5, k6``
  (``k4 .. k6`` the rational model's denominator; zero and held by default);
- :class:`Fisheye` (model name ``"fisheye"``): ``k1, k2, k3, k4``.

By default the pinhole's ``fx`` and ``mu`` are free and the lens is held (at its values): a
configuration frees what it wants to estimate, e.g. ``free = ("fx", "mu", "cx", "cy", "k1",
"k2", "p1", "p2")``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from selfcal.camera.lens import (
    LensMap,
    brown_conrady,
    brown_conrady_points,
    kannala_brandt,
    undistort,
)
from selfcal.camera.model import perspective, perspective_jacobian
from selfcal.camera.pinhole import Pinhole
from selfcal.errors import InputError

__all__ = ["LensCamera", "BrownConrady", "Fisheye"]


@dataclass(frozen=True)
class LensCamera(Pinhole):
    """A pinhole (``fx``, ``mu``, ``cx``, ``cy`` px, image ``width`` x ``height`` px; its
    :meth:`~selfcal.camera.pinhole.Pinhole.pixels` is the last link) with the lens coefficients
    ``coeffs`` (in ``lens_names`` order; default all zero) and the ``free`` parameter names."""

    lens_names: ClassVar[tuple[str, ...]]

    coeffs: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        c = tuple(float(v) for v in self.coeffs) or (0.0,) * len(self.lens_names)
        if len(c) != len(self.lens_names):
            raise InputError(
                f"{type(self).__name__} has {len(self.lens_names)} lens coefficients "
                f"{self.lens_names}, got {len(c)}"
            )
        object.__setattr__(self, "coeffs", c)
        object.__setattr__(self, "free", tuple(self.free))
        self._check_free()
        object.__setattr__(self, "free", tuple(n for n in self.names if n in self.free))

    @staticmethod
    def lens(xn: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The lens map (:data:`selfcal.camera.lens.LensMap`)."""
        raise NotImplementedError

    @classmethod
    def from_pinhole(
        cls, pinhole: Pinhole, coeffs: tuple[float, ...] = (), free: tuple[str, ...] | None = None
    ) -> LensCamera:
        """``pinhole`` with the lens ``coeffs`` (default: none, all zero) and ``free`` (default:
        the pinhole's)."""
        return cls(
            pinhole.fx, pinhole.mu, pinhole.cx, pinhole.cy, pinhole.width, pinhole.height,
            pinhole.free if free is None else tuple(free), tuple(coeffs), skew=pinhole.skew,
        )  # fmt: skip

    @property
    def pinhole(self) -> Pinhole:  # the lens-free camera
        """The pixel map (its ``free``: the pinhole parameters among this model's)."""
        free = tuple(n for n in self.free if n in Pinhole.names)
        return Pinhole(self.fx, self.mu, self.cx, self.cy, self.width, self.height, free,
                       skew=self.skew)  # fmt: skip

    def coefficient(self, name: str) -> float:
        """The lens coefficient ``name`` (e.g. ``"k1"``)."""
        return self.coeffs[self.lens_names.index(name)]

    # ------------------------------------------------------------ the CameraModel interface
    def values(self) -> np.ndarray:
        return np.array([self.fx, self.mu, self.cx, self.cy, self.skew, *self.coeffs], dtype=float)

    def with_values(self, values: np.ndarray):
        v = [float(x) for x in np.asarray(values, dtype=float).reshape(len(self.names))]
        return dataclasses.replace(self, fx=v[0], mu=v[1], cx=v[2], cy=v[3], skew=v[4],
                                   coeffs=tuple(v[5:]))  # fmt: skip

    def project_jacobians(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xn, J_persp = perspective_jacobian(X_cam)
        xd, J_lens, J_coeffs = self.lens(xn, np.asarray(self.coeffs))
        uv, J_pix, J_pin = self.pinhole.pixels_jacobians(xd)
        J_params = np.concatenate([J_pin, J_pix @ J_coeffs], axis=-1)
        return uv, J_pix @ J_lens @ J_persp, J_params

    def unproject_normalised(self, uv: np.ndarray) -> np.ndarray:
        return undistort(self.pinhole.normalised(uv), self.lens, np.asarray(self.coeffs))

    def project(self, X_cam: np.ndarray) -> np.ndarray:
        # the chain of project_jacobians without the derivatives (the same numbers)
        return self.pixels(self.distort_normalised(perspective(X_cam)))

    def distort_normalised(self, xn: np.ndarray) -> np.ndarray:
        """The lens map alone: distorted normalised coordinates (..., 2) of ``xn`` (..., 2)."""
        return self.lens(xn, np.asarray(self.coeffs))[0]


@dataclass(frozen=True)
class BrownConrady(LensCamera):
    """OpenCV's default camera model: pinhole + radial-tangential (rational) distortion."""

    names = ("fx", "mu", "cx", "cy", "skew", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
    lens_names = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
    model_name = "opencv"
    lens: ClassVar[LensMap] = staticmethod(brown_conrady)  # type: ignore[assignment]

    def distort_normalised(self, xn: np.ndarray) -> np.ndarray:
        return brown_conrady_points(xn, np.asarray(self.coeffs))

    @property
    def dist_coeffs(self) -> np.ndarray:
        """OpenCV's ``distCoeffs``: (5,) ``k1, k2, p1, p2, k3`` or (8,) with the rational terms
        when any of ``k4 .. k6`` is nonzero."""
        c = np.asarray(self.coeffs)
        return c if np.any(c[5:] != 0.0) else c[:5]


@dataclass(frozen=True)
class Fisheye(LensCamera):
    """OpenCV's fisheye camera model (``cv2.fisheye``; its skew ``alpha`` is ``skew / fx``)."""

    names = ("fx", "mu", "cx", "cy", "skew", "k1", "k2", "k3", "k4")
    lens_names = ("k1", "k2", "k3", "k4")
    model_name = "fisheye"
    lens: ClassVar[LensMap] = staticmethod(kannala_brandt)  # type: ignore[assignment]

    @property
    def dist_coeffs(self) -> np.ndarray:
        """``cv2.fisheye``'s ``D``: (4,) ``k1 .. k4``."""
        return np.asarray(self.coeffs)
