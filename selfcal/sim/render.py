"""Offscreen stereo rendering of the MuJoCo scene (EGL, classic OpenGL renderer).

One GL context, one ``MjrContext`` and one ``MjvScene`` serve both cameras: the scene geometry is
built once per pair (``mjv_updateScene`` for the left camera) and only the camera is swapped for
the right one (``mjv_updateCamera``), which halves the CPU-side scene update. Images are uint8
RGB (H, W, 3) with row 0 at the top, in the pixel convention of ``selfcal.sim.mj_camera``.

Timing (``selfcal/benchmarks/timing/render.py``, 640x480, 2 CPU cores shared with other jobs, Mesa
llvmpipe via EGL, default LP_NUM_THREADS = 2): about 20-35 ms per stereo pair with 4x MSAA
(llvmpipe grants at most 4 samples; 8 or 16 fall back to 4) and 9-16 ms without MSAA. Almost all
of it is llvmpipe rasterisation + the multisample resolve, which ``mjr_readPixels`` waits for;
``mjv_updateScene`` takes 0.04 ms and the vertical flip 0.1 ms. Sensor noise (``image_sigma``)
costs another ~2 ms of CPU per image (the rounded Gaussian drawn as integers through a table,
:func:`noise_field`, where float32 normals took 8-9 ms; ``selfcal.sim.sim_robot.SimRobot`` draws
the next capture's on a worker thread). MSAA smooths only polygon silhouettes: marker
corners are texture edges, filtered by (mipmapped, bilinear) texture sampling, and their detected
positions were identical with 0 and 4 samples, so ``offsamples=0`` in
``selfcal.sim.scene.configure_visual`` is a legitimate 2-3x speed-up when silhouettes do not matter.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import mujoco
import numpy as np

from selfcal.camera import Pinhole
from selfcal.errors import InputError, InternalError, UsageError
from selfcal.sim.lens import LensRemap, needs_remap
from selfcal.sim.mj_camera import camera_id

__all__ = [
    "StereoRenderer",
    "noise_field",
    "apply_noise",
    "rounded_gaussian_pmf",
    "rounded_gaussian_table",
]


class StereoRenderer:
    """Render the stereo pair seen by two (or more) named cameras of ``model``.

    ``width`` x ``height`` (the output images) must match the cameras' intrinsics
    (``selfcal.sim.mj_camera.add_camera``) and the rendered images fit the model's offscreen buffer
    (``visual/global offwidth/offheight``). ``lenses``: the true camera model of each camera
    (``camera_names`` order; None: pinholes as built): a camera with a lens is rendered as its
    source pinhole and remapped (:mod:`selfcal.sim.lens`). Multisample anti-aliasing uses
    ``model.vis.quality.offsamples`` samples.

    Raises ``ValueError`` for a size mismatch and ``KeyError`` for an unknown camera.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        camera_names: tuple[str, ...] = ("cam_left", "cam_right"),
        max_geom: int = 2000,
        lenses: Sequence[Pinhole] | None = None,
    ) -> None:
        self._gl: mujoco.GLContext | None = None
        self._ctx: mujoco.MjrContext | None = None
        self.model = model
        self.width, self.height = int(width), int(height)
        self.camera_names = tuple(camera_names)
        if lenses is not None and len(lenses) != len(self.camera_names):
            raise UsageError(f"{len(lenses)} lenses for {len(self.camera_names)} cameras")
        self._remaps = [
            LensRemap(c) if c is not None and needs_remap(c) else None for c in (lenses or ())
        ] or [None] * len(self.camera_names)
        sizes = [
            (self.width, self.height) if m is None else (m.source.width, m.source.height)
            for m in self._remaps
        ]
        self._cams = []
        for name, size in zip(self.camera_names, sizes, strict=True):
            cid = camera_id(model, name)
            res = tuple(int(v) for v in model.cam_resolution[cid])
            if res != size:
                raise InputError(
                    f"camera {name!r} was built for {res[0]}x{res[1]} pixels, renderer is "
                    f"{size[0]}x{size[1]}: the intrinsics would not hold"
                )
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            cam.fixedcamid = cid
            self._cams.append(cam)
        gw, gh = max(w for w, _ in sizes), max(h for _, h in sizes)
        if gw > model.vis.global_.offwidth or gh > model.vis.global_.offheight:
            raise InputError(
                f"image {gw}x{gh} exceeds the offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}; "
                "build the spec with selfcal.sim.scene.configure_visual(spec, width, height)"
            )
        self._opt = mujoco.MjvOption()
        self._scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._rects = [mujoco.MjrRect(0, 0, w, h) for w, h in sizes]
        self._gl = mujoco.GLContext(gw, gh)
        self._gl.make_current()
        self._ctx = _context(model)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._bufs = [np.empty((h, w, 3), dtype=np.uint8) for w, h in sizes]

    @property
    def samples(self) -> int:
        """Multisample count actually granted by the GL driver (0: no anti-aliasing)."""
        return int(self._ctx.offSamples) if self._ctx is not None else 0

    def _render_one(self, k: int) -> np.ndarray:
        rect, buf, remap = self._rects[k], self._bufs[k], self._remaps[k]
        mujoco.mjr_render(rect, self._scene, self._ctx)
        mujoco.mjr_readPixels(buf, None, rect, self._ctx)
        img = np.flipud(buf)  # GL rows start at the bottom
        return img.copy() if remap is None else remap(np.ascontiguousarray(img))

    def render_all(
        self, data: mujoco.MjData, image_sigma: float = 0.0, rng: np.random.Generator | None = None
    ) -> list[np.ndarray]:
        """One uint8 RGB image (H, W, 3) per camera, in ``camera_names`` order.

        ``data`` must hold up-to-date kinematics (``mj_kinematics``/``mj_forward``).
        ``image_sigma`` > 0 adds i.i.d. Gaussian noise of that standard deviation (grey levels,
        0-255 scale) to every channel, then rounds and clips; ``rng`` makes it reproducible.
        """
        if self._ctx is None or self._gl is None:
            raise InternalError("StereoRenderer is closed")
        if image_sigma < 0:
            raise InputError(f"image_sigma must be >= 0, got {image_sigma}")
        self._gl.make_current()
        out = []
        for k, cam in enumerate(self._cams):
            if k == 0:
                mujoco.mjv_updateScene(
                    self.model, data, self._opt, None, cam, mujoco.mjtCatBit.mjCAT_ALL, self._scene
                )
            else:  # same geometry, different viewpoint (and headlight)
                mujoco.mjv_updateCamera(self.model, data, cam, self._scene)
                mujoco.mjv_makeLights(self.model, data, self._scene)
            out.append(self._render_one(k))
        if image_sigma > 0:
            rng = np.random.default_rng() if rng is None else rng
            out = [_add_noise(img, image_sigma, rng) for img in out]
        return out

    def render(
        self, data: mujoco.MjData, image_sigma: float = 0.0, rng: np.random.Generator | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(left_rgb, right_rgb)`` uint8 (H, W, 3) for the first two cameras; see
        :meth:`render_all` for ``image_sigma`` and ``rng``."""
        if len(self._cams) != 2:
            raise UsageError(
                f"render() needs exactly two cameras, this renderer has {len(self._cams)}; "
                "use render_all()"
            )
        left, right = self.render_all(data, image_sigma, rng)
        return left, right

    def close(self) -> None:
        """Free the GL resources (idempotent)."""
        if self._ctx is not None:
            if self._gl is not None:
                self._gl.make_current()
            self._ctx.free()
            self._ctx = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None

    def __enter__(self) -> StereoRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown: GL may already be gone
            pass


def _context(model: mujoco.MjModel) -> mujoco.MjrContext:
    """The ``MjrContext`` of ``model`` (the GL context current). Without a light that casts a
    shadow (the scenes of ``selfcal.sim.scene`` unless ``shadows``), ``mjr_render`` draws no
    shadow map: the context is made without one (``vis.quality.shadowsize`` 0 while it is made,
    then restored), where MuJoCo allocated a 4096 x 4096 depth texture for it (64 MB; 16,000
    page faults and ~0.05 s CPU of the renderer's start under Mesa llvmpipe). The same
    pixels."""
    quality = model.vis.quality
    size = int(quality.shadowsize)
    if not np.any(model.light_castshadow):
        quality.shadowsize = 0
    try:
        return mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
    finally:
        quality.shadowsize = size


_U64_MAX = np.iinfo(np.uint64).max
_TABLE_BITS = 16
"""The noise table's resolution: one uniform draw of this many bits per pixel and channel."""


@functools.lru_cache(maxsize=8)
def rounded_gaussian_table(sigma: float) -> np.ndarray:
    """The integer noise of std ``sigma`` (grey levels) by uniform draw: an int16 table of
    2**16 entries in which each integer k takes round(2**16 * P(k)) slots (up to one slot, from
    the rounding of the cumulative sums), P(k) the probability that a Gaussian of std ``sigma``
    rounds to k (:func:`rounded_gaussian_pmf`). The table's resolution is 2**-16: every k's
    probability is within 2**-16 of P(k), and a value beyond which the tail's probability is
    below 2**-17 is never drawn (the noise stops about 4.3 ``sigma`` out each side for ``sigma``
    2-64; below ``sigma`` 0.115 it is always 0)."""
    if not sigma > 0:
        raise InputError(f"image noise sigma must be > 0 grey levels, got {sigma}")
    k, pmf = rounded_gaussian_pmf(sigma)
    slots = 1 << _TABLE_BITS
    ends = np.rint(np.cumsum(pmf)[:-1] * slots)  # the first slot after each k's
    table = k[np.searchsorted(ends, np.arange(slots), side="right")].astype(np.int16)
    table.flags.writeable = False
    return table


def rounded_gaussian_pmf(sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``(k, P(k))``: the integers k = -K..K and the probabilities that a Gaussian of std
    ``sigma`` (grey levels) rounds to them, K the first integer beyond 7.5 ``sigma`` (the
    rest, below 1e-13, is left out)."""
    half = int(np.ceil(7.5 * sigma)) + 1
    k = np.arange(-half, half + 1)
    cdf = np.array([0.5 * math.erfc(-(v + 0.5) / (sigma * math.sqrt(2.0))) for v in k])
    return k, np.diff(cdf, prepend=0.0)


def noise_field(shape: tuple[int, ...], sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian sensor noise of std ``sigma`` (grey levels) as int16 of ``shape``, already
    rounded: the image is integer, so rint(img + z) = img + rint(z) (but for ties, of
    probability 0) and the rounded noise is drawn directly, 16 uniform bits per value through
    :func:`rounded_gaussian_table` (its resolution 2**-16 of probability), about 4x less CPU than
    float32 normals. The draws of one image, in the order :meth:`StereoRenderer.render_all`
    takes them from ``rng`` (the same seed, the same fields)."""
    table = rounded_gaussian_table(float(sigma))
    n = math.prod(shape)
    # 4 draws of 16 bits in each full-range 64-bit integer (a 64-bit generator's raw output;
    # a 32-bit one's two outputs, where its raw output would leave the high half 0)
    raw = rng.integers(0, _U64_MAX, size=(n + 3) // 4, dtype=np.uint64, endpoint=True)
    bits = raw.astype("<u8", copy=False).view("<u2")[:n]  # the same on every byte order
    return np.take(table, bits).reshape(shape)


def apply_noise(img: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``img`` (uint8) plus the rounded noise ``z`` (int16 of :func:`noise_field`, consumed),
    clipped to 0-255."""
    z += img
    return np.clip(z, 0, 255, out=z).astype(np.uint8)


def _add_noise(img: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    return apply_noise(img, noise_field(img.shape, sigma, rng))
