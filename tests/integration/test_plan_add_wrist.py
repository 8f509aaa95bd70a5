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
    # measured 2.57 - 4.91 (the benchmark's truths 1 - 3; 3.34 - 4.92 before the greedy choice
    # stopped serving the fold that leaves out the dataset, session 29)
    assert min(predicted) >= 2.0
    # measured 2.16 (0.72 - 2.51; truths 1, 2, 3: 2.16, 0.72, 2.51) since the greedy choice does
    # not serve a fold that does not count (session 29: plan/add.py training_sets); 1.66 (0.95 -
    # 2.94; 2.94, 0.95, 1.66) since the selection, its forecast and the draws the swaps judge
    # by do not count it (session 28); 2.51 (0.80 - 4.72) before. One realisation per truth
    # against the plan's forecast draws (plan.json forecast_draws.after, mm: median, 90th
    # percentile): before the greedy change truth 1 achieved 1.151 (0.956, 1.70), truth 3
    # 1.251 (0.936, 1.49), within the draws; after it truth 1 1.565 (0.885, 1.41), truth 2
    # 1.482 (1.012, 1.77), truth 3 0.826 (1.090, 1.70): no gain or loss shown on three
    # truths. The block's 12 truths (docs/plan.md benchmark_plan_add_5, before the greedy
    # change): a median of 2.89
    assert np.median(achieved) >= 1.5
    # the added postures let the selection identify parameters the wrist alone could not
    assert all(r["kept_before"] == 12 for r in rows)
    assert np.median([r["kept_after"] for r in rows]) > 12
