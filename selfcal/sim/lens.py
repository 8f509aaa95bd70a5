"""The lens of a simulated camera: MuJoCo renders a pinhole, an exact inverse remap distorts it.

MuJoCo renders pinhole images only. For a camera with a lens (:class:`selfcal.camera.LensCamera`)
the simulator renders the *source* pinhole :func:`source_pinhole` -- the same focal lengths (times
``supersample``), an image large enough to hold every ray the lens camera sees (plus a margin),
its principal point placed accordingly; sized from the rays of the image's edge pixels alone,
see :func:`source_pinhole` -- and :class:`LensRemap` turns that image into the lens
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

__all__ = ["source_pinhole", "LensRemap", "edge_pixels", "needs_remap"]

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


def _unproject(camera: Pinhole, uv: np.ndarray, where: str) -> np.ndarray:
    """Normalised coordinates (..., 2) of the pixels ``uv`` (..., 2) of ``camera``; raises
    :class:`InputError` when the lens cannot be inverted at one of them (``where``: which)."""
    xn = camera.unproject_normalised(uv)
    if not np.isfinite(xn).all():
        raise InputError(
            f"the lens of {camera} cannot be inverted over {where} (the distortion "
            "folds over): use smaller coefficients"
        )
    return xn


def _rays(camera: Pinhole) -> np.ndarray:
    """Normalised coordinates (H, W, 2) of every output pixel centre of ``camera``."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    return _unproject(camera, np.stack([u, v], axis=-1), "the whole image")


def edge_pixels(width: int, height: int) -> np.ndarray:
    """The pixel centres (N, 2) of an image's outermost rows and columns (px, OpenCV), each
    once: ``N = 2 (width + height) - 4`` (fewer for an image one pixel wide or high)."""
    u, v = np.arange(width, dtype=float), np.arange(height, dtype=float)
    rows = [np.stack([u, np.full(width, y)], axis=-1) for y in sorted({0.0, height - 1.0})]
    inner = v[1:-1]
    cols = [np.stack([np.full(inner.size, x), inner], axis=-1) for x in sorted({0.0, width - 1.0})]
    return np.concatenate(rows + cols)


def source_pinhole(camera: Pinhole, supersample: int = 1) -> Pinhole:
    """The pinhole MuJoCo renders for ``camera``: ``camera`` itself without a lens; with one,
    focal lengths ``supersample * (fx, fy)`` and the smallest image (plus ``MARGIN_PX``) holding
    every output pixel's ray.

    The rays' extent is taken from the image's edge pixels (:func:`edge_pixels`, ``2 (W + H)``
    rays, not ``W H``: ``selfcal export --format mjcf`` of a 2064 x 1544 camera took 2 GB when
    every pixel was inverted). For a lens that does not fold over inside the image the inverse
    lens map is continuous and one-to-one, so it maps the image's edge onto the edge of the
    region of rays, where each coordinate's extremes lie; between two edge pixels an extreme
    can exceed theirs by the edge curve's sag over one pixel, far below ``MARGIN_PX``.
    :class:`LensRemap`, which inverts every pixel, checks that every ray falls inside (a lens
    that folds over inside the image is refused there, not here)."""
    if not needs_remap(camera):
        return camera
    xn = _unproject(camera, edge_pixels(camera.width, camera.height), "the image's edge")
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
        self.source = source_pinhole(camera, supersample)
        uv = self.source.pixels(_rays(camera))
        size = np.array([self.source.width, self.source.height]) - 1.0
        outside = ~np.all((uv >= 0.0) & (uv <= size), axis=-1)
        if outside.any():
            v, u = np.argwhere(outside)[0]
            raise InputError(
                f"the ray of pixel ({u}, {v}) of {camera} falls outside the source image "
                f"{self.source.width}x{self.source.height} px sized from the image's edge: the "
                "lens is not one-to-one over the image (use smaller coefficients)"
            )
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
