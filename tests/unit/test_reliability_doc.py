"""docs/reliability.md (issue #15): every test its table names exists, and the count at the top is
the number of rows."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "reliability.md"
ROW = re.compile(r"^\| .* \| `(?P<file>tests/[\w/]+\.py)::(?P<test>test_\w+)` \|$")


def test_every_row_names_a_test_that_exists_and_the_count_is_right():
    lines = DOC.read_text().splitlines()
    table = [line for line in lines if line.startswith("| ") and not line.startswith("| bad input")]
    rows = [ROW.match(line) for line in table]
    assert all(rows), [line for line, m in zip(table, rows) if not m]
    for m in rows:
        src = (REPO / m["file"]).read_text()
        assert re.search(rf"^(?:    )?def {m['test']}\(", src, re.M), m.group(0)
    count = int(re.search(r"\*\*(\d+) bad inputs and faults", DOC.read_text())[1])
    assert count == len(rows) >= 60
