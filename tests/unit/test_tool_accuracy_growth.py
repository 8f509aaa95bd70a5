"""The probe of the tracker benchmark's model error against the truth
(selfcal.benchmarks.tool_accuracy_growth, issue #29)."""

from __future__ import annotations

import re

from selfcal.benchmarks.tool_accuracy_growth import probe


def test_one_draw_of_the_ur5e_compliance():
    """Draw 0 of the benchmark's UR5e at 0.1 mm with the compliance: a line for the draw (its
    variogram, each region's distance and model errors) and one per region pooled; the true
    model error is the compliance's, about 0.2 mm per coordinate in every region (0.207, 0.216,
    0.194 in this draw), and the prediction's is read from the folds."""
    lines = probe("ur5e", 0.1, 1, "compliance")
    assert len(lines) == 4 and lines[0].startswith("draw  0: c0 ")
    for region, line in zip(("inside", "edge", "workspace"), lines[1:], strict=True):
        got = re.search(rf"{region}: model error per coordinate true ([0-9.]+) mm, predicted "
                        r"([0-9.]+) mm", line)  # fmt: skip
        assert got is not None, line
        true, predicted = float(got[1]), float(got[2])
        assert 0.15 < true < 0.26 and 0.1 < predicted < 0.4
