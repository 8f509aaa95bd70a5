"""Issue #29 on the real sets (real tier, ``uv run pytest -m real``): the held-out images'
reprojection RMS the board calibration predicts (the estimate's errors, the model error from its
own cross-validation, the joint and pixel noise) is within 0.67-1.5x the one ``selfcal
evaluate`` measures, as ``uv run python -m selfcal.benchmarks.board_accuracy --real`` reports
it (docs/tool-accuracy.md). What misses today is marked ``xfail(strict=True)`` with its figure.
"""

from __future__ import annotations

import pytest

from selfcal.benchmarks.board_accuracy import REAL_SETS, real_set

pytestmark = pytest.mark.real

LOW, HIGH = 0.67, 1.5  # the band of predicted / measured

XFAIL: dict[str, str] = {}  # photoneo's 1.63x (the pooled model error) is 1.47x since the
# folds count the share of the held parameters' deviation they show, at its upper 95 % bound
# (docs/tool-accuracy.md)


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=[pytest.mark.xfail(strict=True, reason=XFAIL[n])])
        if n in XFAIL
        else n
        for n in REAL_SETS
    ],
)
def test_the_predicted_held_out_error_is_the_measured_one(name, tmp_path):
    r = real_set(name, tmp_path)
    ratio = r["predicted_px"] / r["measured_px"]
    assert LOW <= ratio <= HIGH, (ratio, r)
