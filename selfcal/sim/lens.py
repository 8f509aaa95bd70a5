"""The lens of a simulated camera: MuJoCo renders a pinhole, an exact inverse remap distorts it.

MuJoCo renders pinhole images only. For a camera with a lens (:class:`selfcal.camera.LensCamera`)
the simulator renders the *source* pinhole :func:`source_pinhole` -- the same focal lengths (times
``supersample``), an image large enough to hold every ray the lens camera sees (plus a margin),
its principal point placed accordingly -- and :class:`LensRemap` turns that image into the lens
camera's: for every output pixel ``u`` (OpenCV pixel centres) the ray ``camera.unproject_normalised(u)``
(exact: Newton on the lens map) is projected by the source pinhole, and ``cv2.remap`` samples the
source image there (bilinear). So a scene point ``X`` lands where ``camera.project(X)`` says, up
to interpolation. A plain :class:`selfcal.camera.Pinhole` (principal point anywhere: MuJoCo's own
principal-point offset, :mod:`selfcal.sim.mj_camera`) needs no remap.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from selfcal.camera import LensCamera, Pinhole, entry_of
from selfcal.errors import InputError, UsageError

__all__ = ["source_pinhole", "LensRemap", "needs_remap"]

MARGIN_PX = 3
"""Source pixels kept around the outermost sampled position (bilinear needs one)."""


def needs_remap(camera: Pinhole) -> bool:
    """True for a camera with a lens or a skew (MuJoCo cannot render either directly).

    Raises :class:`UsageError` for a model the simulator does not take (the double sphere: its
    rays do not fit one pinhole image; :mod:`selfcal.sim.cube_map` renders it)."""
    if not entry_of(camera).everywhere:
        raise UsageError(
            f"a {camera.model_name} camera is not one pinhole image with a remap: render it "
            "through a cube map (selfcal.sim.cube_map)"
        )
    return isinstance(camera, LensCamera) or camera.skew != 0.0


def _rays(camera: Pinhole) -> np.ndarray:
    """Normalised coordinates (H, W, 2) of every output pixel centre of ``camera``."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    xn = camera.unproject_normalised(np.stack([u, v], axis=-1))
    if not np.isfinite(xn).all():
        raise InputError(
            f"the lens of {camera} cannot be inverted over the whole image (the distortion "
            "folds over): use smaller coefficients"
        )
    return xn


def source_pinhole(
    camera: Pinhole, supersample: int = 1, rays: np.ndarray | None = None
) -> Pinhole:
    """The pinhole MuJoCo renders for ``camera``: ``camera`` itself without a lens; with one,
    focal lengths ``supersample * (fx, fy)`` and the smallest image (plus ``MARGIN_PX``) holding
    every output pixel's ray (``rays``: those normalised coordinates (H, W, 2) when known)."""
    if not needs_remap(camera):
        return camera
    xn = _rays(camera) if rays is None else rays
    fx, fy = supersample * camera.fx, supersample * camera.fy
    lo = np.array([fx * xn[..., 0].min(), fy * xn[..., 1].min()]) - MARGIN_PX
    hi = np.array([fx * xn[..., 0].max(), fy * xn[..., 1].max()]) + MARGIN_PX
    # integer principal-point offsets keep the source grid aligned with the ray grid's origin
    cx, cy = math.ceil(-lo[0]), math.ceil(-lo[1])
    W, H = cx + math.ceil(hi[0]) + 1, cy + math.ceil(hi[1]) + 1
    return Pinhole(fx, camera.mu, float(cx), float(cy), int(W), int(H))


class LensRemap:
    """The remap from :func:`source_pinhole`'s image to ``camera``'s (see the module
    docstring); ``source`` is that pinhole."""

    def __init__(self, camera: Pinhole, supersample: int = 1) -> None:
        self.camera = camera
        xn = _rays(camera)
        self.source = source_pinhole(camera, supersample, xn)
        uv = self.source.pixels(xn)
        self._map_x = uv[..., 0].astype(np.float32)
        self._map_y = uv[..., 1].astype(np.float32)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """The lens camera's image (H, W[, C]) of the source image (source H, W[, C])."""
        if image.shape[:2] != (self.source.height, self.source.width):
            raise UsageError(
                f"source image {image.shape[1]}x{image.shape[0]} px, expected "
                f"{self.source.width}x{self.source.height}"
            )
        return cv2.remap(
            image, self._map_x, self._map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
