"""The exchange that improves a plan's greedy choice (selfcal/calibration/board/plan/greedy.py,
issue #30): it lowers the greedy's criterion where the greedy's first pick leads it astray, never
raises it, ends where no single swap helps, and the plan's prediction is below the greedy
choice's on the UR5e example's cell."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest

from selfcal.calibration.board.plan.greedy import REG, exchange, select_greedy


def _cost(F: np.ndarray, W: np.ndarray, idx) -> float:
    """trace(W (REG I + sum F)^-1), W on every parameter (the greedy's scaling changes only
    the small regularisation)."""
    return float(np.trace(W @ np.linalg.inv(REG * np.eye(len(W)) + F[list(idx)].sum(axis=0))))


def test_exchange_finds_the_pair_the_greedy_misses():
    # the full-rank D lowers the cost most alone, but A and C together beat D with either:
    # the greedy takes D first and then A (1/4 + 1 = 1.25), the best pair is A, C (2/3)
    F = np.array([np.diag(d) for d in ([3.0, 0.0], [0.0, 1.0], [0.0, 3.0], [1.0, 1.0])])
    W = np.eye(2)
    greedy = select_greedy(F, W, 0, 2)
    assert sorted(greedy.tolist()) == [0, 3]
    best = exchange(F, W, 0, greedy)
    assert sorted(best.tolist()) == [0, 2]
    assert _cost(F, W, best) == pytest.approx(2.0 / 3.0, rel=1e-5)
    assert _cost(F, W, greedy) == pytest.approx(1.25, rel=1e-5)


def test_exchange_never_raises_the_cost_and_ends_where_no_swap_helps():
    rng = np.random.default_rng(4)
    p, m, count = 4, 12, 3
    worse = 0
    for _ in range(20):
        A = rng.normal(size=(m, 2, p))
        F = np.einsum("mki,mkj->mij", A, A)  # rank-2 candidates: three are needed
        W = np.diag(rng.uniform(0.5, 2.0, p))
        greedy = select_greedy(F, W, 0, count)
        best = exchange(F, W, 0, greedy)
        assert len(set(best.tolist())) == count
        c = _cost(F, W, best)
        assert c <= _cost(F, W, greedy) * (1 + 1e-12)
        worse += c < _cost(F, W, greedy) * (1 - 1e-6)
        others = np.setdiff1d(np.arange(m), best)
        for k in range(count):  # no single swap lowers it by more than the exchange's gain
            for j in others:
                swapped = best.copy()
                swapped[k] = j
                assert _cost(F, W, swapped) >= c * (1 - 1e-5)
        optimum = min(_cost(F, W, s) for s in combinations(range(m), count))
        assert c <= 1.5 * optimum
    assert worse > 0  # the greedy was improved on some draws (the test can fail)


def test_exchange_keeps_a_choice_no_swap_improves():
    F = np.array([np.diag(d) for d in ([1.0, 0.0], [0.0, 1.0], [0.1, 0.1])])
    W = np.eye(2)
    assert exchange(F, W, 0, np.array([1, 0])).tolist() == [1, 0]
