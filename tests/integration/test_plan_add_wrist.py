"""`selfcal plan --add 5` on a dataset whose postures move only the wrist (the Nachi groups'
kind), simulated end to end (selfcal/benchmarks/plan/add.py): the dataset is calibrated, the 5
postures are planned from its calibration.json, the dataset's postures and the added ones are
acquired again with the same simulated truth and calibrated. Three truths (the benchmark runs
more; docs/plan.md quotes it)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.plan.add import wrist_only_row


@pytest.mark.slow
def test_adding_five_postures_to_a_wrist_only_dataset(tmp_path):
    rows = [wrist_only_row(tmp_path / f"truth{s}", s, 5) for s in (1, 2, 3)]
    predicted = [r["predicted_before_mm"] / r["predicted_after_mm"] for r in rows]
    achieved = [r["achieved_before_mm"] / r["achieved_after_mm"] for r in rows]
    assert min(predicted) >= 2.0  # measured 3.34 - 4.92 (the benchmark's truths 1 - 3)
    # measured 1.66 (0.95 - 2.94) since the selection, its forecast and the draws the swaps
    # judge by do not count a fold leaving out most frames (session 28; 2.51, 0.80 - 4.72
    # before): these three truths fall less, the block's 30 a median of 2.92 (session 30; its
    # first 15 2.83 as in session 29, its first 12 2.89, 3.20 before), 2 times or more in 22 of
    # them, docs/plan.md benchmark_plan_add_5. Truths 1 and 3 (session 29): their achieved 1.151 and 1.251 mm lie
    # between their plans' forecast draws' median and 90th percentile (plan.json
    # forecast_draws.after: 0.956 and 1.70, 0.936 and 1.49 mm), one realisation each; with every
    # fold counted again on this code (counted_folds patched) the plans were forecast to err more
    # (draws' medians 1.245, 1.387) and achieved 1.087 and 0.786 mm: three truths cannot tell the
    # rules apart
    assert np.median(achieved) >= 1.5
    # the added postures let the selection identify parameters the wrist alone could not
    # (counted beyond the placement, as plan --add counts them: the wrist alone keeps none)
    assert all(r["kept_before"] == 0 for r in rows)
    assert np.median([r["kept_after"] for r in rows]) > 0
