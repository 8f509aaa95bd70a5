"""The README states exactly what was measured.

- The times (the test suite, the first and a later `selfcal run`) are the ones the commands printed,
  recorded in docs/measurements.toml by `python -m scenarios.benchmark_times` (not timed here).
- Every accuracy figure of the "Accuracy and speed" table names its path (analytic or rendered)
  and a test that exists and asserts it; every timing figure names the benchmark that measures it.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def _readme() -> str:
    return " ".join(README.read_text().split())


def _accuracy_rows() -> list[list[str]]:
    text = README.read_text()
    section = text[text.index("## Accuracy and speed") :]
    section = section[: section.index("Per stage and pose count")]  # the first table
    rows = [r for r in section.splitlines() if r.startswith("| ") and not r.startswith("| what")]
    return [[c.strip() for c in re.split(r"(?<!\\)\|", r)[1:-1]] for r in rows]


def _test_exists(ref: str) -> bool:
    path, name = ref.split("::")
    f = ROOT / path
    return f.is_file() and re.search(rf"^def {re.escape(name)}\(", f.read_text(), re.M) is not None


def test_accuracy_figures_name_their_path_and_an_existing_test():
    rows = _accuracy_rows()
    assert len(rows) >= 8
    bad = []
    for what, _figure, by in rows:
        tests = re.findall(r"`(tests/[\w/]+\.py::\w+)`", by)
        benches = re.findall(r"`python -m (scenarios\.\w+)`", by)
        if not tests and not benches:
            bad.append(f"{what}: names neither a test nor a benchmark")
        bad += [f"{what}: no test {t}" for t in tests if not _test_exists(t)]
        bad += [f"{what}: no script {b}" for b in benches
                if not (ROOT / (b.replace(".", "/") + ".py")).is_file()]  # fmt: skip
        if tests and not re.search(r"\b(analytic|rendered)\b", what):
            bad.append(f"{what}: an accuracy figure must name its path (analytic or rendered)")
    assert bad == []
