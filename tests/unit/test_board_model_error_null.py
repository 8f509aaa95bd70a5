"""When the board route counts a model error (selfcal/calibration/board/held_prior.py, issue #29):
the arm is one draw of its deviation prior, so what the held parameters add to the folds'
held-out pixels scatters about the prior's mean, and an arm that fits must not be read as a
model error when its draw lies above that mean (a 7-joint arm's 12 postures: 1.22 times the
mean, counted at 2.9 noise standard errors; 2 of 30 fitting draws had a model error)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.held_prior import (
    counted_excess,
    held_excess_variance,
    held_share,
    null_variance,
)

K, ROWS, SIGMA = 6, 40, 1.0  # minimal parameters, pixel rows per frame, px
FOLDS, FRAMES = 5, 2  # folds, held-out frames per fold
HALF_WIDTH = np.r_[1.0, 0.3, 0.3, 0.1, 0.1, 0.1]  # the prior: uniform within +-HALF_WIDTH


def _design(seed: int) -> list[np.ndarray]:
    """Per held-out frame its pixels per unit deviation ``L`` (ROWS, K): one held direction
    (the first parameter's) moves the pixels most, as a 7-joint arm's few postures hold."""
    rng = np.random.default_rng(seed)
    return [rng.normal(0.0, 1.0, (ROWS, K)) * np.r_[1.0, 0.2, 0.2, 0.1, 0.1, 0.1]
            for _ in range(FOLDS * FRAMES)]  # fmt: skip


def _calibrations(L: list[np.ndarray], rng: np.random.Generator, count: int,
                  model_error_px: float = 0.0) -> tuple[list[dict], np.ndarray]:  # fmt: skip
    """``count`` calibrations' held-out frames (the keys of held_out_errors the count reads):
    each with the arm's one deviation drawn from the uniform prior, the pixel noise, and a
    model error moving each pixel row by ``model_error_px`` (px) in a random direction; and the
    prior's variance."""
    var = HALF_WIDTH**2 / 3.0
    Ls = np.array(L)  # (frames, ROWS, K)
    delta = rng.uniform(-HALF_WIDTH, HALF_WIDTH, (count, K))
    r = rng.normal(0.0, np.hypot(SIGMA, model_error_px), (count, len(L), ROWS))
    r += np.einsum("frk,ck->cfr", Ls, delta)
    px2 = np.sum(r**2, axis=2)
    same = {
        "px2_expected": np.full(len(L), ROWS * SIGMA**2),
        "px2_var": np.full(len(L), 2.0 * ROWS * SIGMA**4),
        "px2_held": np.sum(Ls**2 * var, axis=(1, 2)),
        "held_gram": np.einsum("frk,frj->fkj", Ls, Ls),
        "held_cross": SIGMA**2 * np.sum(Ls**2, axis=1),
    }
    return [same | {"px2": p} for p in px2], var


def _counted(h: dict, var: np.ndarray, prior: bool = True) -> bool:
    """Whether the count finds a model error (the folds' share first, as model_error does);
    ``prior`` False: the null without the deviation's scatter (the count before the fix)."""
    per_fold = [slice(f * FRAMES, (f + 1) * FRAMES) for f in range(FOLDS)]
    share = held_share(np.array([np.sum(h["px2"][s] - h["px2_expected"][s]) for s in per_fold]),
                       np.array([np.sum(h["px2_held"][s]) for s in per_fold]),
                       np.array([np.sum(h["px2_expected"][s]) for s in per_fold]),
                       np.array([np.sum(h["px2_var"][s]) for s in per_fold]))  # fmt: skip
    if prior:
        return counted_excess(h, share, var) > 0
    extra = np.sum(h["px2"] - h["px2_expected"]) - share.point * np.sum(h["px2_held"])
    return bool(extra > Z_MODEL_ERROR * np.sqrt(null_variance(h, share, None)))


def test_the_held_excess_variance_is_the_scatter_of_one_deviations_excess():
    """``2 tr((M D)^2)`` against 40000 Gaussian draws of the deviation (within 4 %); the prior's
    uniform draws of the same variance scatter less (the count is on the safe side)."""
    L = _design(0)
    M = np.sum([Li.T @ Li for Li in L], axis=0)
    var = HALF_WIDTH**2 / 3.0
    rng = np.random.default_rng(1)
    g = rng.normal(0.0, np.sqrt(var), (40000, K))
    u = rng.uniform(-HALF_WIDTH, HALF_WIDTH, (40000, K))
    q_gauss = np.einsum("ij,jk,ik->i", g, M, g)
    q_unif = np.einsum("ij,jk,ik->i", u, M, u)
    v = held_excess_variance(M, var)
    assert np.var(q_gauss) == pytest.approx(v, rel=0.04)
    assert np.var(q_unif) < 0.8 * v
    assert np.mean(q_unif) == pytest.approx(np.trace(M * var), rel=0.02)  # px2_held's mean


@pytest.mark.parametrize(
    ("scale", "low", "high", "before"), [(1.0, 0.0, 0.035, 0.2), (0.01, 0.01, 0.04, 0.0)]
)
def test_an_arm_that_fits_is_counted_a_model_error_at_the_stated_rate_only(scale, low, high,
                                                                           before):  # fmt: skip
    """1000 calibrations of an arm that fits, its one deviation drawn from the prior: where the
    held directions move the pixels (their mean excess 4.9 noise standard errors, ``scale`` 1)
    a model error is counted in at most 3.5 % (measured 0 of 1000: the uniform draw's scatter is
    bounded, the count takes a Gaussian's), where the count without the deviation's scatter
    counted one in five or more (32 %: every draw above the prior's mean by two noise standard
    errors); where they add little (``scale`` 0.01) near the rate Z_MODEL_ERROR = 2 states,
    about 2.3 % (measured 3.0 %, the summed chi-square's right tail a little heavier than the
    normal's; 1-4 %), as before. A model error
    moving every pixel row by 1.5 px (its excess 6.5 times the deviation's mean) is counted in
    95 % of them or more (100 %; 1 px: 47 %)."""
    L = [scale * Li for Li in _design(0)]
    rng = np.random.default_rng(2)
    draws, var = _calibrations(L, rng, 1000)
    rate = np.mean([_counted(h, var) for h in draws])
    old = np.mean([_counted(h, var, prior=False) for h in draws])
    print(f"counted on a fitting arm: {rate:.4f} (without the deviation's scatter {old:.4f})")
    assert low <= rate <= high, rate
    assert old >= before, old
    misfit, var = _calibrations(L, rng, 200, model_error_px=1.5)
    power = np.mean([_counted(h, var) for h in misfit])
    assert power >= 0.95, power
