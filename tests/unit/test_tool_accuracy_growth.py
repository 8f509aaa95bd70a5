"""The probe of the tracker benchmark's model error against the truth
(selfcal.benchmarks.tracker.accuracy_growth, issue #29)."""

from __future__ import annotations

import re

from selfcal.benchmarks.tracker.accuracy_growth import probe


def test_one_draw_of_the_ur5e_compliance():
    """Draw 0 of the benchmark's UR5e at 0.1 mm with the compliance: a line for the draw (its
    variogram, each region's distance and model errors) and one per region pooled; the true
    model error is the compliance's, about 0.2 mm per coordinate in every region (0.207, 0.216,
    0.194 in this draw), and the prediction's is read from the folds; the last line the folds'
    excess per coordinate, which this draw counts as its model error."""
    lines = probe("ur5e", 0.1, 1, "compliance")
    assert len(lines) == 5 and lines[0].startswith("draw  0: c0 ")
    for region, line in zip(("inside", "edge", "workspace"), lines[1:4], strict=True):
        got = re.search(rf"{region}: model error per coordinate true ([0-9.]+) mm, predicted "
                        r"([0-9.]+) mm", line)  # fmt: skip
        assert got is not None, line
        true, predicted = float(got[1]), float(got[2])
        assert 0.15 < true < 0.26 and 0.1 < predicted < 0.4
    excess = re.search(
        r"held-out excess pooled over the draws, per coordinate \+([0-9.]+) mm", lines[4]
    )
    assert excess is not None, lines[4]
    assert 0.1 < float(excess[1]) < 0.4


def test_at_half_a_millimetre_the_held_out_test_cannot_count_the_compliance():
    """Draw 0 at 0.5 mm (the tracker block's UR5e row NOT met inside): its line says why no model
    error is counted: the folds' excess is below two standard errors, which at this noise and
    30 rows means a model error below about 0.35 mm per coordinate (the compliance's is ~0.2)."""
    line = probe("ur5e", 0.5, 1, "compliance")[0]
    got = re.search(r"no growing model error counted \(held-out excess ([-+0-9.]+) standard "
                    r"errors, 2 needed: counted from ([0-9.]+) mm per coordinate\)", line)  # fmt: skip
    assert got is not None, line
    assert float(got[1]) < 2.0 and 0.25 < float(got[2]) < 0.45
