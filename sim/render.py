"""Offscreen stereo rendering of the MuJoCo scene (EGL, classic OpenGL renderer).

One GL context, one ``MjrContext`` and one ``MjvScene`` serve both cameras: the scene geometry is
built once per pair (``mjv_updateScene`` for the left camera) and only the camera is swapped for
the right one (``mjv_updateCamera``), which halves the CPU-side scene update. Images are uint8
RGB (H, W, 3) with row 0 at the top, in the pixel convention of ``sim.mj_camera``.

Timing (``scenarios/benchmark_render.py``, 640x480, 2 CPU cores shared with other jobs, Mesa
llvmpipe via EGL, default LP_NUM_THREADS = 2): about 20-35 ms per stereo pair with 4x MSAA
(llvmpipe grants at most 4 samples; 8 or 16 fall back to 4) and 9-16 ms without MSAA. Almost all
of it is llvmpipe rasterisation + the multisample resolve, which ``mjr_readPixels`` waits for;
``mjv_updateScene`` takes 0.04 ms and the vertical flip 0.1 ms. Sensor noise (``image_sigma``)
costs another 5-13 ms per image (Gaussian draws). MSAA smooths only polygon silhouettes: marker
corners are texture edges, filtered by (mipmapped, bilinear) texture sampling, and their detected
positions were identical with 0 and 4 samples, so ``offsamples=0`` in
``sim.scene.configure_visual`` is a legitimate 2-3x speed-up when silhouettes do not matter.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.mj_camera import camera_id

__all__ = ["StereoRenderer"]


class StereoRenderer:
    """Render the stereo pair seen by two (or more) named cameras of ``model``.

    ``width`` x ``height`` must match the cameras' intrinsics (``sim.mj_camera.add_camera``) and
    fit the model's offscreen buffer (``visual/global offwidth/offheight``). Multisample
    anti-aliasing uses ``model.vis.quality.offsamples`` samples.

    Raises ``ValueError`` for a size mismatch and ``KeyError`` for an unknown camera.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        camera_names: tuple[str, ...] = ("cam_left", "cam_right"),
        max_geom: int = 2000,
    ) -> None:
        self._gl = None
        self._ctx = None
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(
                f"image {width}x{height} exceeds the offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}; "
                "build the spec with sim.scene.configure_visual(spec, width, height)"
            )
        self.model = model
        self.width, self.height = int(width), int(height)
        self.camera_names = tuple(camera_names)
        self._cams = []
        for name in self.camera_names:
            cid = camera_id(model, name)
            res = tuple(int(v) for v in model.cam_resolution[cid])
            if res != (self.width, self.height):
                raise ValueError(
                    f"camera {name!r} was built for {res[0]}x{res[1]} pixels, renderer is "
                    f"{self.width}x{self.height}: the intrinsics would not hold"
                )
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            cam.fixedcamid = cid
            self._cams.append(cam)
        self._opt = mujoco.MjvOption()
        self._scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        self._gl = mujoco.GLContext(self.width, self.height)
        self._gl.make_current()
        self._ctx = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._buf = np.empty((self.height, self.width, 3), dtype=np.uint8)

    @property
    def samples(self) -> int:
        """Multisample count actually granted by the GL driver (0: no anti-aliasing)."""
        return int(self._ctx.offSamples) if self._ctx is not None else 0

    def _render_one(self) -> np.ndarray:
        mujoco.mjr_render(self._rect, self._scene, self._ctx)
        mujoco.mjr_readPixels(self._buf, None, self._rect, self._ctx)
        return np.flipud(self._buf).copy()  # GL rows start at the bottom

    def render_all(
        self, data: mujoco.MjData, image_sigma: float = 0.0, rng: np.random.Generator | None = None
    ) -> list[np.ndarray]:
        """One uint8 RGB image (H, W, 3) per camera, in ``camera_names`` order.

        ``data`` must hold up-to-date kinematics (``mj_kinematics``/``mj_forward``).
        ``image_sigma`` > 0 adds i.i.d. Gaussian noise of that standard deviation (grey levels,
        0-255 scale) to every channel, then rounds and clips; ``rng`` makes it reproducible.
        """
        if self._ctx is None:
            raise RuntimeError("StereoRenderer is closed")
        if image_sigma < 0:
            raise ValueError(f"image_sigma must be >= 0, got {image_sigma}")
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
            out.append(self._render_one())
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
            raise ValueError(
                f"render() needs exactly two cameras, this renderer has {len(self._cams)}; "
                "use render_all()"
            )
        left, right = self.render_all(data, image_sigma, rng)
        return left, right

    def close(self) -> None:
        """Free the GL resources (idempotent)."""
        if self._ctx is not None:
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


def _add_noise(img: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    noisy = rng.standard_normal(size=img.shape, dtype=np.float32)
    noisy *= np.float32(sigma)
    noisy += img
    np.rint(noisy, out=noisy)
    return np.clip(noisy, 0, 255).astype(np.uint8)
