"""A rig of N cameras rigidly mounted together (N = 2 today: the wrist stereo pair).

Frames: camera ``c``'s extrinsics are ``T_first_cam[c]``, its pose in the first camera's frame
(OpenCV camera frames, m); ``T_first_cam[0]`` is the identity. With ``T_world_first`` the pose of
the first camera, camera ``c`` sits at ``T_world_first @ T_first_cam[c]``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from selfcal.camera.model import CameraModel
from selfcal.camera.visibility import Visibility
from selfcal.errors import InputError
from selfcal.transforms import inv_pose

__all__ = ["Rig", "STEREO_NAMES"]

STEREO_NAMES = ("left", "right")


@dataclass(frozen=True)
class Rig:
    """``cameras`` (N models), their extrinsics ``T_first_cam`` (N, 4, 4) and ``names`` (N).

    Raises ``ValueError`` when the counts disagree, a transform is not 4x4 or the first
    extrinsic is not the identity.
    """

    cameras: tuple[CameraModel, ...]
    T_first_cam: np.ndarray
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        T = np.asarray(self.T_first_cam, dtype=float).copy()
        names = tuple(self.names)
        if not cams or T.shape != (len(cams), 4, 4) or len(names) != len(cams):
            raise InputError(
                f"a rig needs N >= 1 cameras with N extrinsics (N, 4, 4) and N names; got "
                f"{len(cams)} cameras, extrinsics {T.shape}, names {names}"
            )
        if not np.allclose(T[0], np.eye(4), atol=1e-12):
            raise InputError("the first camera's extrinsic T_first_cam[0] must be the identity")
        T.setflags(write=False)
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "T_first_cam", T)
        object.__setattr__(self, "names", names)

    @classmethod
    def stereo(
        cls, left: CameraModel, T_left_right: np.ndarray, right: CameraModel | None = None
    ) -> Rig:
        """The stereo pair: ``left`` first, ``right`` (default: the same model as ``left``) at
        ``T_left_right`` (its pose in the left camera frame, m)."""
        T = np.stack([np.eye(4), np.asarray(T_left_right, dtype=float)])
        return cls((left, left if right is None else right), T, STEREO_NAMES)

    @property
    def n_cameras(self) -> int:
        """N."""
        return len(self.cameras)

    def T_world_cams(self, T_world_first: np.ndarray) -> np.ndarray:
        """Poses (..., N, 4, 4) of every camera for first-camera poses ``T_world_first``
        (..., 4, 4)."""
        return np.asarray(T_world_first, dtype=float)[..., None, :, :] @ self.T_first_cam

    def T_cams_world(self, T_first_world: np.ndarray) -> np.ndarray:
        """Inverse poses (..., N, 4, 4) of every camera (world -> camera ``c``) for
        ``T_first_world`` (..., 4, 4) of the first camera."""
        return inv_pose(self.T_first_cam) @ np.asarray(T_first_world, dtype=float)[..., None, :, :]

    def _per_camera(
        self, T_world_first: np.ndarray, fn: Callable[[CameraModel, np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """``fn(camera, T_world_cam (m, 4, 4))`` of every camera, stacked on axis 1."""
        T = self.T_world_cams(T_world_first)
        return np.stack([fn(cam, T[:, c]) for c, cam in enumerate(self.cameras)], axis=1)

    def visible_points(
        self,
        rule: Visibility,
        T_world_first: np.ndarray,
        X_world: np.ndarray,
        normals_world: np.ndarray | None = None,
    ) -> np.ndarray:
        """(m, N, k) bool: :meth:`Visibility.points` of every camera at first-camera poses
        ``T_world_first`` (m, 4, 4)."""
        return self._per_camera(
            T_world_first, lambda cam, T: rule.points(cam, T, X_world, normals_world)
        )

    def visible_markers(
        self,
        rule: Visibility,
        T_world_first: np.ndarray,
        corners_world: np.ndarray,
        normals_world: np.ndarray,
    ) -> np.ndarray:
        """(m, N, K) bool: :meth:`Visibility.markers` of every camera at first-camera poses
        ``T_world_first`` (m, 4, 4)."""
        return self._per_camera(
            T_world_first, lambda cam, T: rule.markers(cam, T, corners_world, normals_world)
        )
