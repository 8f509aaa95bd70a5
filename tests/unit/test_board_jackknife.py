"""The board route's jackknife over its fold fits (selfcal.calibration.board.spread): the
(k - 1) / k factor on stub fold fits with a known answer, no calibration needed. The agreement
with the covariance on a real calibration: tests/integration/test_board_analytic.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from selfcal.calibration.board.param_selection import Candidate, Selection
from selfcal.calibration.board.spread import jackknife_spread
from selfcal.calibration.spread import SpreadPoints, spread_line
from selfcal.kinematics.mcpc import MCPCModel


def _shifted(dx: float, dy: float) -> SimpleNamespace:
    """A fold's fit whose one-joint chain differs only by its base translation (m): every tool
    point moves by (dx, dy, 0)."""
    params = np.zeros((2, 6))
    params[0, 3:5] = dx, dy
    params[1, 3] = 0.3  # the tool 0.3 m out along the link
    return SimpleNamespace(model=MCPCModel(params, ("revolute",), np.zeros(1)))


def _selection(shifts: list[tuple[float, float]], folds: int) -> Selection:
    """A selection whose chosen candidate has one fold fit per shift; ``folds`` the folds
    attempted (the rest failed); fold 1 held a parameter."""
    cand = Candidate("stub", (), np.zeros(0, dtype=int), np.zeros(0, dtype=int))
    cand.fold_fits = {f: (_shifted(*s), np.zeros(0), np.zeros(0)) for f, s in enumerate(shifts)}
    cand.fold_held = {1: ("lx0",)}
    return Selection([cand], 0, (), {}, 15, folds, "stub", fold_of=np.zeros(15, dtype=int))


def test_the_jackknife_spread_is_sqrt_k_minus_1_over_k_times_the_sum_of_squares():
    """k = 4 fold fits at +-a along x and +-b along y about their mean: var = 3 / 4 *
    (4 a^2 + 2 b^2) at every joint vector: 1.837 mm. Without the factor it reads 2.121 mm,
    inverted 2.449 mm (both tried: this test fails)."""
    a, b = 0.001, 0.0005  # m
    shifts = [(a, 0.0), (-a, 0.0), (a, b), (-a, -b)]
    q = np.linspace(-1.0, 1.0, 5)[:, None]
    points = SpreadPoints({"inside": q, "edge": q[:2]}, np.eye(4))
    spread = jackknife_spread(_selection(shifts, folds=5), points)
    assert spread is not None
    block = spread.to_json()
    expected_mm = np.sqrt(3 / 4 * (4 * a**2 + 2 * b**2)) * 1e3
    for region in ("inside", "edge"):
        got = block["regions"][region]
        for key in ("spread_mm_max", "spread_mm_median", "spread_mm_rms", "spread_mm_p95"):
            assert got[key] == pytest.approx(expected_mm, rel=1e-9), (region, key)
    assert block["method"] == "jackknife"
    assert block["resamplings"] == 4 and block["failed"] == 1 and block["held_folds"] == 1
    assert "delete-a-fold jackknife over the 4 cross-validation folds" in spread_line(block)


def test_the_jackknife_needs_two_fold_fits():
    points = SpreadPoints({"inside": np.zeros((2, 1))}, np.eye(4))
    assert jackknife_spread(_selection([(0.001, 0.0)], folds=5), points) is None


def test_the_jackknife_of_a_mean_over_equal_folds_is_unbiased_and_of_a_wide_fit_is_not():
    """selfcal.benchmarks.board.jackknife_bias: the expected jackknife variance of a mean (one
    parameter, every row alike) over equal folds is the true variance, exactly (so the (k - 1) /
    k factor is right; dropped it would read 1.25); with eight parameters on 30 rows it is
    biased upward (the benchmark: 1.55 on average)."""
    from selfcal.benchmarks.board.jackknife_bias import expected_ratio
    from selfcal.calibration.board.folds import fold_labels

    fold = fold_labels(np.repeat(np.arange(15), 2))
    x0 = np.ones((3, 1))
    assert expected_ratio(np.ones((30, 1)), fold, x0) == pytest.approx(1.0, rel=1e-12)
    rng = np.random.default_rng(1)
    wide = [expected_ratio(rng.normal(size=(30, 8)), fold, rng.normal(size=(3, 8)))
            for _ in range(20)]  # fmt: skip
    assert 1.3 < np.mean(wide) < 1.9, np.mean(wide)
