"""`selfcal plan --add 5` on a tracker calibration whose rows move only the wrist, simulated
through the commands (selfcal/benchmarks/plan/tracker_add.py): `selfcal identify` calibrates the
rows, the 5 postures are planned from its calibration.json, measured with the same simulated
truth and identified again with the dataset's rows. One truth (the benchmark runs more;
docs/plan.md quotes it)."""

from __future__ import annotations

import pytest

from selfcal.benchmarks.plan.tracker_add import tracker_add_row


@pytest.mark.slow
def test_adding_five_postures_to_a_wrist_only_tracker_calibration(tmp_path):
    r = tracker_add_row(tmp_path / "truth1", 1, 5)
    predicted = r["predicted_before_mm"] / r["predicted_after_mm"]
    achieved = r["achieved_before_mm"] / r["achieved_after_mm"]
    assert predicted >= 4.4  # measured 13.2 (3.006 -> 0.228 mm); issue #30 asks 2
    assert achieved >= 2.5  # measured 7.4 (2.727 -> 0.368 mm)
    # and the calibration after beats its fair nominal of the same rows (measured 4.8 times:
    # 1.779 against 0.368 mm); before it did not (2.688 against 2.727 mm)
    assert r["fair_nominal_after_mm"] >= 1.6 * r["achieved_after_mm"]
    # which the plan predicted: the fair nominal's prediction after 1.823 mm (achieved 0.98
    # times it), before 3.509 mm (0.77 times)
    for when in ("before", "after"):
        ratio = r[f"fair_nominal_{when}_mm"] / r[f"fair_predicted_{when}_mm"]
        assert 0.33 <= ratio <= 3.0
    assert "NOT predicted to beat it" in r["line"].split("\nafter, ")[0]
    # the wrist alone identifies 15 of the UR5e's 30; the added postures move the arm's joints
    assert r["kept_before"] == 15 and r["kept_after"] >= 25
    assert r["plan"]["kind"] == "tracker-add" and r["plan"]["count"] == 5
