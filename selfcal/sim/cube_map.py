"""A ray model's image from a cube map: six perspective renders from one centre, resampled.

MuJoCo renders pinholes. A camera past 180 deg (:class:`selfcal.camera.DoubleSphere`) is
rendered as six square pinhole images from its centre, one per face of a cube around its optical
axis (:func:`add_cube_cameras`; each :data:`FACE_FOV_DEG` wide, so the face a ray is read from
keeps a margin of pixels around it), and its image is resampled from them (:class:`CubeMapRemap`):
every output pixel's ray (the model's ``unproject``) is read from the face whose axis is nearest
to it (bilinear, ``cv2.remap`` over the faces side by side); a pixel no ray reaches is black.
The headlight's diffuse part differs between the faces' viewpoints: :func:`even_headlight` makes
it ambient only, so a surface is equally bright in every face and the seams do not show.
"""

from __future__ import annotations

import cv2
import mujoco
import numpy as np

from selfcal.camera import CameraModel, Pinhole
from selfcal.sim.mj_camera import add_camera
from selfcal.transforms import make_pose

__all__ = ["FACE_FOV_DEG", "CubeMapRemap", "add_cube_cameras", "even_headlight", "face_pinhole"]

FACE_FOV_DEG = 100.0
"""Field of view of each face's pinhole across its side (deg): 10 deg beyond the cube's 90."""


def _face_rotations() -> np.ndarray:
    """(6, 3, 3) ``R_cam_face`` of the faces +z, -z, +x, -x, +y, -y (OpenCV frames: each face's
    z axis along its cube axis)."""
    out = []
    for a in np.vstack([np.eye(3)[[2]], -np.eye(3)[[2]], np.eye(3)[[0]], -np.eye(3)[[0]],
                        np.eye(3)[[1]], -np.eye(3)[[1]]]):  # fmt: skip
        ref = np.array([0.0, 0.0, 1.0]) if abs(a[1]) > 0.5 else np.array([0.0, 1.0, 0.0])
        x = np.cross(ref, a)
        x /= np.linalg.norm(x)
        out.append(np.stack([x, np.cross(a, x), a], axis=1))
    return np.stack(out)


FACES = _face_rotations()


def face_pinhole(face_px: int) -> Pinhole:
    """The pinhole of every face: ``face_px`` square, :data:`FACE_FOV_DEG` wide, centred."""
    f = (face_px / 2.0) / np.tan(np.radians(FACE_FOV_DEG) / 2.0)
    c = (face_px - 1) / 2.0
    return Pinhole(f, 1.0, c, c, int(face_px), int(face_px))


def add_cube_cameras(
    body: mujoco.MjsBody, prefix: str, face_px: int, T_body_cam: np.ndarray
) -> tuple[str, ...]:
    """Add the six face cameras of the ray-model camera at ``T_body_cam`` (OpenCV camera ->
    ``body``'s frame, m) to ``body`` of an ``MjSpec``, named ``<prefix>_0`` .. ``<prefix>_5`` (the
    order of :class:`CubeMapRemap`'s faces); returns their names."""
    names = tuple(f"{prefix}_{k}" for k in range(len(FACES)))
    pin = face_pinhole(face_px)
    T = np.asarray(T_body_cam, dtype=float)
    for name, R in zip(names, FACES, strict=True):
        add_camera(body, name, pin, T @ make_pose(R, np.zeros(3)))
    return names


def even_headlight(spec: mujoco.MjSpec) -> None:
    """Make the headlight ambient only (its diffuse part moved into the ambient): a surface is
    equally bright from the six faces' viewpoints (module docstring)."""
    hl = spec.visual.headlight
    hl.ambient = [a + d for a, d in zip(hl.ambient, hl.diffuse, strict=True)]
    hl.diffuse = [0.0, 0.0, 0.0]


class CubeMapRemap:
    """The image of ``camera`` (its size) resampled from the six ``face_px`` square face images
    of :func:`add_cube_cameras` (module docstring)."""

    def __init__(self, camera: CameraModel, face_px: int) -> None:
        self.camera = camera
        self.face = face_pinhole(face_px)
        u, v = np.meshgrid(
            np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float)
        )
        ray = camera.unproject(np.stack([u, v], axis=-1))  # (H, W, 3), NaN where none
        along = np.einsum("hwi,fi->hwf", np.nan_to_num(ray), FACES[:, :, 2])
        k = np.argmax(along, axis=-1)
        r_face = np.einsum("hwji,hwj->hwi", FACES[k], ray)  # R_cam_face^T ray
        uv = self.face.pixels(r_face[..., :2] / r_face[..., 2:3])
        ok = np.all(np.isfinite(ray), axis=-1)
        self._map_x = np.where(ok, uv[..., 0] + k * face_px, -1.0).astype(np.float32)
        self._map_y = np.where(ok, uv[..., 1], -1.0).astype(np.float32)

    def image(self, faces: list[np.ndarray]) -> np.ndarray:
        """The camera's image (H, W[, C], the faces' dtype) from the six face images in
        :func:`add_cube_cameras`' order."""
        return cv2.remap(np.hstack(faces), self._map_x, self._map_y, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT)  # fmt: skip
