"""The camera-model interface: camera-frame points to pixels, its Jacobians, and back to rays.

Frames and units (OpenCV): the camera frame has x right, y down, z forward along the optical axis
(m); pixel coordinates have x right, y down and pixel centres at integers (the top-left pixel's
centre is (0, 0)). *Normalised coordinates* are ``(x / z, y / z)`` of a camera-frame point: the
ray through the pixel at unit depth.

A :class:`CameraModel` is a central ray model (Kalibr's projection x distortion): it projects
camera-frame points to pixels (:meth:`~CameraModel.project`, with the points it projects at
all: :meth:`~CameraModel.valid`, :meth:`~CameraModel.project_valid`), its Jacobians w.r.t. the
point and the parameters (:meth:`~CameraModel.project_jacobians`), and unprojects pixels to unit
rays (:meth:`~CameraModel.unproject`); it owns its visibility test (:meth:`~CameraModel.valid`,
:meth:`~CameraModel.depth`, asked by :class:`selfcal.camera.visibility.Visibility`) and its
initial guesses from images (:meth:`~CameraModel.starts`). The perspective models are the chain
``X_cam -> perspective -> [lens] -> pixels`` with ``z > 0``; :func:`perspective` (and
:func:`perspective_jacobian`) is the first link for all of them. The pinhole
(:class:`selfcal.camera.pinhole.Pinhole`) has no lens term; a distortion model (Brown-Conrady,
Kannala-Brandt) is a class that holds a pinhole and inserts its map between
:func:`perspective` and :meth:`Pinhole.pixels` (chain rule for the Jacobians). A model past 180
deg (:class:`selfcal.camera.double_sphere.DoubleSphere`) replaces the perspective link by its own
map of the 3-D point and overrides the visibility test; the estimation code, which only sees this
interface, does not change.

Parameters carry OpenCV's names (``fx``, ``cx``, ``cy``, later ``k1`` ...; the paper's aspect
ratio ``mu = fy / fx``). ``free`` selects the ones an estimation adjusts; the others stay at their
values. The estimation works with the free parameters only (:meth:`free_values`,
:meth:`with_free_values`, :meth:`project_free`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar, TypeVar

import numpy as np

from selfcal.errors import InputError, UsageError

__all__ = ["CameraModel", "perspective", "perspective_jacobian", "project"]


def perspective(X_cam: np.ndarray) -> np.ndarray:
    """Normalised coordinates ``(x / z, y / z)`` (..., 2) of camera-frame points ``X_cam``
    (..., 3) (m). Points at z = 0 give inf/NaN."""
    X = np.asarray(X_cam, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return X[..., :2] / X[..., 2:3]


def perspective_jacobian(X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`perspective` of ``X_cam`` (..., 3) and its Jacobian w.r.t. the point (..., 2, 3)
    (1/m)."""
    X = np.asarray(X_cam, dtype=float)
    xn = perspective(X)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / X[..., 2]
    J = np.zeros(X.shape[:-1] + (2, 3))
    J[..., 0, 0] = inv_z
    J[..., 0, 2] = -xn[..., 0] * inv_z
    J[..., 1, 1] = inv_z
    J[..., 1, 2] = -xn[..., 1] * inv_z
    return xn, J


C = TypeVar("C", bound="CameraModel")
"""A camera model type: what a method returns for a model of the same class."""


class CameraModel(ABC):
    """A central camera model (see the module docstring).

    Attributes every model has: ``names`` (class attribute: all parameter names in order),
    ``model_name`` (class attribute: a name of :data:`selfcal.camera.registry.REGISTRY`),
    ``free`` (the names an estimation adjusts, a subset of ``names`` in ``names`` order),
    ``width``, ``height`` (image size, px).
    """

    names: ClassVar[tuple[str, ...]]
    model_name: ClassVar[str]
    free: tuple[str, ...]
    width: int
    height: int

    # ------------------------------------------------------------------ what a model provides
    @abstractmethod
    def values(self) -> np.ndarray:
        """All parameter values (len(names),), in ``names`` order (px or unitless)."""

    @abstractmethod
    def with_values(self: C, values: np.ndarray) -> C:
        """The same model with all parameters replaced by ``values`` (len(names),)."""

    @abstractmethod
    def project_jacobians(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixels (..., 2) of camera-frame points ``X_cam`` (..., 3) (m), their Jacobian w.r.t.
        the point (..., 2, 3) (px/m) and w.r.t. every parameter (..., 2, len(names)).

        Points the model does not project (:meth:`valid`) give meaningless values: callers
        check :meth:`valid` (or use :meth:`project_valid`)."""

    @abstractmethod
    def unproject_normalised(self, uv: np.ndarray) -> np.ndarray:
        """Normalised coordinates (..., 2) of pixels ``uv`` (..., 2): the inverse of
        :meth:`project` up to depth (``project([xn, yn, 1] * z) == uv`` for any ``z > 0``);
        NaN for a pixel whose ray does not point forward (z <= 0) or that no ray reaches."""

    def project(self, X_cam: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of camera-frame points ``X_cam`` (..., 3) (m)."""
        return self.project_jacobians(X_cam)[0]

    # ------------------------------------------------------------------ the ray model
    def valid(self, X_cam: np.ndarray) -> np.ndarray:
        """(...,) bool: which camera-frame points ``X_cam`` (..., 3) (m) the model projects (a
        perspective model: ``z > 0``; a model past 180 deg overrides it with its own
        condition). The visibility rule's first test."""
        return np.asarray(X_cam, dtype=float)[..., 2] > 0.0

    def depth(self, X_cam: np.ndarray) -> np.ndarray:
        """(...,) m: the distance the visibility rule's depth range bounds: ``z`` along the
        optical axis for a perspective model; a model past 180 deg overrides it with the
        distance from the camera centre (a point beside or behind the camera has z <= 0)."""
        return np.asarray(X_cam, dtype=float)[..., 2]

    def project_valid(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (..., 2) of camera-frame points ``X_cam`` (..., 3) (m), NaN where the model
        does not project the point, and the (...,) bool mask of those it does (:meth:`valid`
        and a finite pixel)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.array(self.project(X_cam), dtype=float)
        ok = self.valid(X_cam) & np.all(np.isfinite(uv), axis=-1)
        uv[~ok] = np.nan
        return uv, ok

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        """Unit rays (..., 3) in the camera frame of pixels ``uv`` (..., 2): ``project(s ray)
        == uv`` for every ``s > 0``; NaN where no ray reaches the pixel. A perspective model
        normalises ``[xn, yn, 1]`` of :meth:`unproject_normalised`."""
        xn = np.asarray(self.unproject_normalised(uv), dtype=float)
        ray = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], axis=-1)
        return ray / np.linalg.norm(ray, axis=-1, keepdims=True)

    @classmethod
    def starts(cls: type[C], width: int, height: int, free: tuple[str, ...]) -> list[C]:
        """Initial guesses of this model for ``width`` x ``height`` px images (principal point
        at the centre, fields of view from narrow to past 180 deg where the model reaches
        them), for a start from images where OpenCV does not calibrate the model
        (the board calibration refines each and keeps the best, :mod:`selfcal.camera.start`)."""
        raise UsageError(f"camera model {cls.model_name!r} has no start from images")

    # ------------------------------------------------------------------ the free parameters
    def _check_free(self) -> None:
        unknown = [n for n in self.free if n not in self.names]
        if unknown or len(set(self.free)) != len(self.free):
            raise InputError(
                f"free camera parameters {self.free} must be distinct names of {self.names}"
            )

    @property
    def free_index(self) -> np.ndarray:
        """Indices (n_free,) of the free parameters in ``names``."""
        return np.array([self.names.index(n) for n in self.free], dtype=np.int64)

    @property
    def n_free(self) -> int:
        """How many parameters an estimation adjusts."""
        return len(self.free)

    def free_values(self) -> np.ndarray:
        """The free parameters' values (n_free,), in ``free`` order."""
        return self.values()[self.free_index]

    def with_free_values(self: C, free_values: np.ndarray) -> C:
        """The same model with the free parameters set to ``free_values`` (n_free,)."""
        v = self.values()
        v[self.free_index] = np.asarray(free_values, dtype=float).reshape(-1)
        return self.with_values(v)

    def project_free(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`project_jacobians` with the parameter Jacobian restricted to the free
        parameters (..., 2, n_free)."""
        uv, J_point, J_params = self.project_jacobians(X_cam)
        return uv, J_point, J_params[..., self.free_index]

    def in_image(self, uv: np.ndarray, margin_px: float = 0.0) -> np.ndarray:
        """(...,) bool: pixels ``uv`` (..., 2) more than ``margin_px`` inside the image (pixel
        centres 0 .. W - 1 and 0 .. H - 1); NaN is outside."""
        u, v = uv[..., 0], uv[..., 1]
        with np.errstate(invalid="ignore"):
            return (
                (u > margin_px)
                & (u < self.width - 1 - margin_px)
                & (v > margin_px)
                & (v < self.height - 1 - margin_px)
            )


def project(camera: CameraModel, T_cam_world: np.ndarray, X_world: np.ndarray) -> np.ndarray:
    """Pixels (..., 2) of world points ``X_world`` (..., 3) (m) seen by ``camera`` at poses
    ``T_cam_world`` (..., 4, 4) (world -> camera frame; leading axes broadcast).

    Points behind the camera give meaningless values; callers check depth with
    ``(T_cam_world @ X)[2] > 0``."""
    X = np.asarray(X_world, dtype=float)
    T = np.asarray(T_cam_world, dtype=float)
    Xc = np.einsum("...ij,...j->...i", T[..., :3, :3], X) + T[..., :3, 3]
    return camera.project(Xc)
