"""The posture-distance bins of the board accuracy benchmark's points
(selfcal.benchmarks.board.accuracy_binned): every point in the bin of its distance, the bins'
statistics of their own points, bad edges refused."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy_binned import binned, table
from selfcal.errors import UsageError


def _points(d: list[float], true: list[float], bound: list[float], flag: list[float]) -> np.ndarray:
    """(9, m) a draw's region rows (predicted 95 %, covariance alone, predicted RMS, true,
    three orientation rows, not-measured flag, distance) with the predicted RMS half the
    bound."""
    m = len(d)
    b = np.array(bound, float)
    return np.stack([b, b, b / 2, np.array(true, float), *np.zeros((3, m)),
                     np.array(flag, float), np.array(d, float)])  # fmt: skip


def test_each_point_counts_in_the_bin_of_its_distance():
    a = _points([0.0, 0.04, 0.05, 0.31], [0.3, 0.4, 2.0, 1.0], [1.0, 1.0, 1.0, 3.0], [0, 0, 1, 1])
    b = _points([0.12, 0.9], [0.6, 4.0], [1.0, 1.0], [0, 1])
    bins = binned([a, b], (0.0, 0.05, 0.2, 0.5, np.inf))
    assert [(x["low"], x["points"]) for x in bins] == [(0.0, 2), (0.05, 2), (0.2, 1), (0.5, 1)]
    first, second = bins[0], bins[1]
    assert first["true_rms_mm"] == pytest.approx(np.sqrt((0.3**2 + 0.4**2) / 2))
    assert first["predicted_rms_mm"] == pytest.approx(0.5) and first["coverage"] == 1.0
    assert first["median_distance"] == pytest.approx(0.02) and first["not_measured_share"] == 0
    # the point at the edge 0.05 goes up; its true 2.0 mm beyond the 1.0 mm bound
    assert second["coverage"] == 0.5 and second["not_measured_share"] == 0.5
    assert bins[-1]["coverage"] == 0.0 and bins[-1]["not_measured_share"] == 1.0
    text = table("row", bins, [0.1, np.inf, 0.3])
    assert "| 0.5- | 1 |" in text and "folds' reach (median over the draws): 0.200" in text


def test_bad_edges_are_refused():
    a = _points([0.1], [0.1], [1.0], [0])
    for edges in ((0.1,), (0.0, 0.2, 0.1)):
        with pytest.raises(UsageError, match="increasing"):
            binned([a], edges)
