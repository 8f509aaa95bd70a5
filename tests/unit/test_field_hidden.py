"""The rendered check of partly hidden markers groups a marker by the hidden line of sight
nearest its black square (selfcal/benchmarks/plan/field_hidden.py, docs/plan.md "A marker
field")."""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.plan.field_hidden import GROUPS, _group


def test_a_marker_is_grouped_by_its_hidden_point_nearest_the_square():
    reach = np.array([-0.5, 0.0, 0.25, 0.5, 0.75, 1.0])  # inside, the edge, the quiet zone
    cases = {(): "clear", (5,): "outer half of the quiet zone", (4, 5): "outer half of the quiet zone",
             (3, 5): "its second quarter", (2,): "its first quarter", (1, 4): "the square crossed",
             (0,): "the square crossed"}  # fmt: skip
    for hidden_at, words in cases.items():
        hidden = np.zeros(len(reach), bool)
        hidden[list(hidden_at)] = True
        assert GROUPS[_group(hidden, reach)] == words, hidden_at
