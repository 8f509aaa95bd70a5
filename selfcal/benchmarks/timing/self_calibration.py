"""Benchmark of the camera self-calibration (selfcal.calibration.field.self_calibration): initialisation + bundle adjustment.

Synthetic stereo-rig scenes (20 markers, 640x480, fx = 800 px, 60 mm baseline), 0.5 px noise and
1 % gross outliers (20 px), for 10, 30, 100 and 300 robot configurations. Prints a table of the
stage timings and the accuracy of fx. Run: ``.venv/bin/python selfcal/benchmarks/timing/self_calibration.py``.
"""

from __future__ import annotations

import time

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.field.self_calibration import self_calibrate
from selfcal.calibration.field.synthetic import synthetic_stereo_scene


def run(configs: list[int], noise_px: float, outlier_fraction: float, seed: int) -> None:
    head = (
        f"{'configs':>7} {'views':>5} {'obs':>6} {'focal s':>7} {'init s':>6} {'BA s':>6} "
        f"{'total s':>7} {'fx err %':>8} {'fx std':>7} {'rms px':>6} {'outl':>9} {'reg':>7}"
    )
    print(f"noise {noise_px} px, outliers {100 * outlier_fraction:.1f} % x 20 px, seed {seed}")
    print(head)
    print("-" * len(head))
    for m in configs:
        sc = synthetic_stereo_scene(
            m, seed=seed, noise_px=noise_px, outlier_fraction=outlier_fraction
        )
        obs = sc.observations()
        t0 = time.perf_counter()
        res = self_calibrate(
            obs,
            sc.intrinsics.width,
            sc.intrinsics.height,
            scale_markers=sc.scale_markers,
            scale_distance_m=sc.scale_distance_m,
        )
        total = time.perf_counter() - t0
        d = res.diagnostics
        fx_err = 100.0 * (res.fx / sc.intrinsics.fx - 1.0)
        print(
            f"{m:7d} {obs.n_views:5d} {len(obs):6d} {d['t_focal_s']:7.2f} {d['t_init_s']:6.2f} "
            f"{d['t_ba_s']:6.2f} {total:7.2f} {fx_err:8.3f} {res.fx_std:7.3f} "
            f"{res.rms_px:6.3f} {res.n_outliers:4d}/{len(sc.outlier_rows):<4d} "
            f"{int(res.registered.sum()):3d}/{m:<3d}"
        )


def main() -> None:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, nargs="+", default=[10, 30, 100, 300])
    ap.add_argument("--noise-px", type=float, default=0.5)
    ap.add_argument("--outliers", type=float, default=0.01)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    np.set_printoptions(precision=4)
    run(args.configs, args.noise_px, args.outliers, args.seed)


if __name__ == "__main__":
    main()
