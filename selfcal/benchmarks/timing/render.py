"""Benchmark: milliseconds per rendered stereo pair (median of N) with ``selfcal.sim.render.StereoRenderer``.

Scene: the default marker field (``selfcal.sim.markers.make_marker_field()``) and two free-standing
cameras 6 cm apart, 0.35 m above the field looking at it (no robot; the robot's few dozen geoms
add little). Usage::

    MUJOCO_GL=egl .venv/bin/python -m selfcal.benchmarks.timing.render [--n 50] [--samples 4]
        [--width 640 --height 480] [--breakdown]

``LP_NUM_THREADS`` (Mesa llvmpipe rasteriser threads, default = CPU count) must be set in the
environment before the process starts. ``--breakdown`` times the stages separately
(scene update, ``mjr_render``, ``mjr_readPixels``).
"""

from __future__ import annotations

import os
import time

import selfcal.sim  # noqa: F401  (first: selfcal/sim/__init__.py sets the MUJOCO_GL default before mujoco loads)
from selfcal.benchmarks.usage import benchmark_parser

# isort: split
import mujoco
import numpy as np

from selfcal.camera import Intrinsics
from selfcal.sim.markers import make_marker_field
from selfcal.sim.mj_camera import add_camera, look_at_cv
from selfcal.sim.render import StereoRenderer
from selfcal.sim.scene import scene_spec


def build(width: int, height: int, samples: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    field = make_marker_field()
    spec = scene_spec(field, width, height, offsamples=samples)
    intr = Intrinsics.centered(800.0, 1.0, width, height)
    target = np.array([0.47, 0.39, 0.03])
    T = look_at_cv(target + [0.0, -0.2, 0.3], target)
    for name, dx in (("cam_left", -0.03), ("cam_right", 0.03)):
        Tc = T.copy()
        Tc[:3, 3] += dx * T[:3, 0]
        add_camera(spec.worldbody, name, intr, Tc)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def main(argv: list[str] | None = None) -> None:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50, help="timed stereo pairs")
    ap.add_argument("--samples", type=int, default=4, help="MSAA samples (visual/quality)")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--sigma", type=float, default=0.0, help="image noise (grey levels)")
    ap.add_argument("--breakdown", action="store_true", help="time the stages separately")
    args = ap.parse_args(argv)
    model, data = build(args.width, args.height, args.samples)
    rng = np.random.default_rng(0)
    with StereoRenderer(model, args.width, args.height) as r:
        for _ in range(3):  # warm-up (shader compilation, texture upload)
            r.render(data)
        t = []
        for _ in range(args.n):
            t0 = time.perf_counter()
            r.render(data, image_sigma=args.sigma, rng=rng)
            t.append(time.perf_counter() - t0)
        t_ms = 1e3 * np.array(t)
        print(
            f"{args.width}x{args.height} samples={r.samples} (requested {args.samples}) "
            f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', 'unset')} "
            f"cpus={os.cpu_count()}: median {np.median(t_ms):.1f} ms per stereo pair "
            f"(min {t_ms.min():.1f}, p10 {np.percentile(t_ms, 10):.1f}, p90 {np.percentile(t_ms, 90):.1f}, n={args.n})"
        )
        if args.breakdown:
            _breakdown(r, data, args.n)


def _breakdown(r: StereoRenderer, data: mujoco.MjData, n: int) -> None:
    """Per-stage medians for one camera (uses the renderer's internals on purpose)."""
    cam, rect = r._cams[0], r._rects[0]
    buf = np.empty_like(r._bufs[0])
    stages: dict[str, list[float]] = {
        "update_scene": [],
        "mjr_render": [],
        "readPixels": [],
        "flip+copy": [],
    }
    for _ in range(n):
        t0 = time.perf_counter()
        mujoco.mjv_updateScene(
            r.model, data, r._opt, None, cam, mujoco.mjtCatBit.mjCAT_ALL, r._scene
        )
        t1 = time.perf_counter()
        mujoco.mjr_render(rect, r._scene, r._ctx)
        t2 = time.perf_counter()
        mujoco.mjr_readPixels(buf, None, rect, r._ctx)
        t3 = time.perf_counter()
        np.flipud(buf).copy()
        t4 = time.perf_counter()
        for k, dt in zip(stages, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            stages[k].append(1e3 * dt)
    print("  per image: " + ", ".join(f"{k} {np.median(v):.2f} ms" for k, v in stages.items()))


if __name__ == "__main__":
    main()
