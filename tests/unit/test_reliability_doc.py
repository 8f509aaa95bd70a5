"""docs/reliability.md (issue #15): every test its table names exists, and the counts at the top
(inputs tried, clear errors, documented behaviours, silent results, hangs) are the table's.

Run with ``-s`` to print the counts."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "reliability.md"
ROW = re.compile(
    r"^\| (?P<input>.*) \| (?P<outcome>.*) \| `(?P<file>tests/[\w/]+\.py)::(?P<test>test_\w+)` \|$"
)
BEHAVIOUR = "*behaviour:* "
SILENT = re.compile(r"silent|without a word|no warning|exit 0", re.I)
HANG = re.compile(r"\bhangs?\b|never ends|waits forever|no timeout", re.I)


def counts(text: str) -> dict[str, int]:
    """The table's counts: ``inputs`` (rows), ``errors`` (rows not marked *behaviour:*),
    ``behaviours``, ``silent`` and ``hangs`` (rows whose outcome says so)."""
    table = [
        line
        for line in text.splitlines()
        if line.startswith("| ") and not line.startswith("| bad input")
    ]
    rows = [ROW.match(line) for line in table]
    assert all(rows), [line for line, m in zip(table, rows) if not m]
    outcome = [m["outcome"] for m in rows if m]
    behaviours = sum(o.startswith(BEHAVIOUR) for o in outcome)
    return {
        "inputs": len(rows),
        "errors": len(rows) - behaviours,
        "behaviours": behaviours,
        "silent": sum(bool(SILENT.search(o)) for o in outcome),
        "hangs": sum(bool(HANG.search(o)) for o in outcome),
    }


def test_every_row_names_a_test_that_exists_and_the_count_is_right():
    text = DOC.read_text()
    for line in text.splitlines():
        m = ROW.match(line)
        if m:
            src = (REPO / m["file"]).read_text()
            assert re.search(rf"^(?:    )?def {m['test']}\(", src, re.M), m.group(0)
    c = counts(text)
    print(c)
    assert int(re.search(r"\*\*(\d+) bad inputs and faults", text)[1]) == c["inputs"] >= 60
    said = re.search(
        r"\*\*(\d+) inputs tried, (\d+) clear errors, (\d+) documented behaviours,\s+(\d+) silent "
        r"results, (\d+) hangs\*\*",
        text,
    )
    assert said, "the counts sentence is missing"
    assert tuple(int(v) for v in said.groups()) == (
        c["inputs"], c["errors"], c["behaviours"], c["silent"], c["hangs"]
    )  # fmt: skip
    assert c["silent"] == 0 and c["hangs"] == 0


def test_the_counts_see_silent_and_hanging_rows():
    """The counter is not blind: a row documenting a silent result or a hang is counted."""
    t = "tests/unit/test_reliability_doc.py::test_the_counts_see_silent_and_hanging_rows"
    text = (
        f"| a | exit 0 without a word | `{t}` |\n| b | *behaviour:* hangs | `{t}` |\n"
        f"| c | error naming the file | `{t}` |\n"
    )
    assert counts(text) == {"inputs": 3, "errors": 2, "behaviours": 1, "silent": 1, "hangs": 1}
