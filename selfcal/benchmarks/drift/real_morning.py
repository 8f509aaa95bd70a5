"""Benchmark: a morning check at a real calibration's own postures, on re-noised frames (#29).

The real sets have no posture recorded twice, so a new image at a calibration posture is stood
in for by the calibration's own frame with new corner noise added to its detections (a proxy,
not a new exposure: the frame's own noise stays in it, so the pixels differ from the frame's
by the added noise alone). Per draw ``--views`` frames are drawn without repetition, their
detections moved by Gaussian noise of ``--noise-px`` per coordinate (default the file's white
noise, ``accuracy.view_jitter.white_px``, or the bounds' corner noise), and checked two ways:
as new views (the check before :mod:`selfcal.calibration.drift.paired`: the same posture's
misfit and the fit's residual counted as new) and each against its frame (the check now: the
difference holds the added noise alone, whose variance is half what the check assumes for two
exposures, so this side is conservative by construction; ``--noise-px`` at ``sqrt(2)`` times
the white noise makes it exact). Reported: the share of draws that say "changed" (alpha 0.01)
and the directed test that fired most often.

Run: ``uv run python -m selfcal.benchmarks.drift.real_morning CAL [--draws 100] [--views 5]
[--noise-px S]`` (CAL the folder of ``selfcal calibrate``, with its dataset; e.g. the real tier's
Nachi calibrations, docs/real-data.md).
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.drift.images import (
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    image_drift_check,
    view_noise,
)
from selfcal.calibration.drift.paired import pair_views
from selfcal.io.board_calibration import read_board_calibration
from selfcal.threads import limit_threads

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Run the proxy (module docstring) and print its line."""
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("calibration", type=Path, help="the folder of selfcal calibrate")
    ap.add_argument("--draws", type=int, default=100)
    ap.add_argument("--views", type=int, default=5)
    ap.add_argument("--noise-px", type=float, default=None)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    limit_threads(1)
    cal = read_board_calibration(path := a.calibration / "calibration.json")
    mine = held_out_views(cal, a.calibration, cameras=(cal.camera_names[0],))
    em = calibration_error_model(cal, str(path))
    C, noise = estimate_covariance(cal, em), view_noise(cal, str(path))
    s = noise.pixel_sigma_px if a.noise_px is None else a.noise_px
    frames = [(f, X, uv) for _, f, _, _, X, uv in mine.views]
    rng = np.random.default_rng(a.seed)
    changed = {"new": 0, "paired": 0}
    fired: dict[str, Counter] = {"new": Counter(), "paired": Counter()}
    for _ in range(a.draws):
        picked = rng.choice(len(frames), size=a.views, replace=False)
        new = [(f, X, uv + rng.normal(scale=s, size=uv.shape))
               for f, X, uv in (frames[i] for i in picked)]  # fmt: skip
        vj = calibration_views(cal, em, mine.q, new, where=str(path))
        paired = pair_views(vj, new, mine.q, frames, mine.q, em=em, camera=cal.cameras[0],
                            eye_to_hand=cal.eye_to_hand, pixel_sigma_px=noise.pixel_sigma_px,
                            joint_sigma_rad=noise.joint_sigma_rad)  # fmt: skip
        for way, views in (("new", vj), ("paired", paired)):
            res = image_drift_check(C, views, eye_to_hand=cal.eye_to_hand)
            changed[way] += res.changed
            if res.changed:
                fired[way][res.best] += 1
    print(
        f"{path}: {a.draws} draws of {a.views} of its {len(frames)} frames with "
        f"{s:.3f} px of new corner noise (white {noise.pixel_sigma_px:.3f} px): 'changed' as "
        f"new views {100 * changed['new'] / a.draws:.1f} % (best change "
        f"{dict(fired['new'].most_common(3))}), each against its frame "
        f"{100 * changed['paired'] / a.draws:.1f} % ({dict(fired['paired'].most_common(3))})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
