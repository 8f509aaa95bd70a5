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
    vector) pairs or more (measured 100 %). The benchmark's 30 draws gave 1.04 and 94.7 % (93.8 %
    before the held share's bound took the folds' noise):
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


def test_no_model_error_is_counted_where_the_arm_fits_and_its_held_deviation_is_large():
    """Seed 5 of the benchmark's 12-posture draws: the arm fits (its model's kind), the
    selection held directions, and the arm's one draw of its deviation along them gave the folds
    1.22 times what the prior's mean gives: counted as a 0.049 mm model error (2.9 noise
    standard errors) before the count took the draw's scatter about that mean
    (selfcal/calibration/board/held_null.py counted_excess: one share of that draw explains
    every fold); none now."""
    row = draw((ARM7, 0.5, "fits", 5, 12))
    assert row["status"] == "ok", row["status"]
    assert row["model_error_mm"] == 0.0, row["model_error_mm"]
