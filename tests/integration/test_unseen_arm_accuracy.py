"""The predicted tool-point accuracy on an arm the project's benchmarks do not draw (issue #29):
the 7-joint test arm (tests/data/arm7.toml) on the analytic mono-charuco scenario with 12
calibration postures, as a new user's planned run had (34 minimal parameters, every fold fit
on 9-10 configurations). A report of that user's read 'calibrated 0.025 mm RMS' against 'tool
point within 0.275 mm (95 %)', 11x apart, where the prediction of its own point was 1.23x its
true error: this holds the prediction itself to the issue's target over seeded draws
(selfcal/benchmarks/board/accuracy_draw.py, the benchmark's own draw)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy_draw import draw

ARM7 = str(Path(__file__).resolve().parents[1] / "data" / "arm7.toml")

pytestmark = pytest.mark.slow  # 8 board calibrations with their folds: ~40 s loaded


def test_the_prediction_holds_on_the_seven_joint_arm_with_few_postures():
    """8 draws (seeds 1-8), 0.5 px, 12 postures: inside the calibrated region the pooled
    predicted RMS over the pooled true RMS of the flange (board frame, unaligned) lies within
    the issue's 0.7-1.4 (measured 1.03), and the 95 % bounds cover 85 % of the (draw, joint
    vector) pairs or more (measured 100 %). The benchmark's 30 draws gave 1.04 and 93.8 %:
    ``uv run python -m selfcal.benchmarks.board.accuracy --robots tests/data/arm7.toml
    --models fits --draws 30 --jobs 1 --poses 12 --noise-px 0.5``."""
    rows = [draw((ARM7, 0.5, "fits", seed, 12)) for seed in range(1, 9)]
    assert all(r["status"] == "ok" for r in rows), [r["status"] for r in rows]
    a = np.concatenate([r["inside"] for r in rows], axis=1)  # rows: draw()'s docstring
    ratio = np.sqrt(np.mean(a[2] ** 2)) / np.sqrt(np.mean(a[3] ** 2))
    cover = float(np.mean(a[3] <= a[0]))
    print(f"predicted / true RMS {ratio:.3f}, coverage {cover:.3f}")
    assert 0.7 < ratio < 1.4, ratio
    assert cover >= 0.85, cover
