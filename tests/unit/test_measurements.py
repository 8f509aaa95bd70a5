"""The README states exactly what was measured.

- The times (the test suite, the first and a later `selfcal run`) are the ones the commands printed,
  recorded in docs/measurements.toml by `python -m selfcal.benchmarks.speed.times` (not timed here).
- Every accuracy figure of the "Accuracy and speed" table names its path (analytic or rendered)
  and a test that exists and asserts it; every timing figure names the benchmark that measures it.
"""

from __future__ import annotations

import re
from pathlib import Path

from selfcal.tomlfile import read_toml

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def _readme() -> str:
    return " ".join(README.read_text().split())


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f} min"


def stated_times(m: dict) -> list[str]:
    """The sentences of the README that carry the measured times, from the measurement file."""
    t, r = m["tests"], m["first_run"]
    return [
        f"`uv run pytest` ran {t['passed'] + t['failed']} tests"
        + (f" ({t['failed']} failed)" if t["failed"] else "")
        + f" in {_minutes(t['seconds'])} ({_minutes(t['cpu_seconds'])} of CPU; {t['cpus']} cores, "
        f"load average {t['load_1min_before']} before the run; {t['date']})",
        f"the first `uv run selfcal run` took {r['first_wall_s']:.0f} s from start to exit, "
        f"{r['first_printed_total_s']:.1f} s of it as the run prints it",
        f"a later one {r['second_wall_s']:.0f} s ({r['second_printed_total_s']:.1f} s printed; "
        f"{r['cpus']} cores, load average {r['load_1min_before']}; {r['date']})",
        f"total {r['first_printed_total_s']:.1f} s; details in runs/paper/report.md",
    ]


def test_readme_times_are_the_measured_ones():
    m = read_toml(ROOT / "docs" / "measurements.toml")
    text = _readme()
    missing = [s for s in stated_times(m) if s not in text]
    assert missing == []


def _accuracy_rows() -> list[list[str]]:
    text = README.read_text()
    section = text[text.index("## Accuracy and speed") :]
    section = section[: section.index("Where the time of a rendered run goes")]  # the first table
    rows = [r for r in section.splitlines() if r.startswith("| ") and not r.startswith("| what")]
    return [[c.strip() for c in re.split(r"(?<!\\)\|", r)[1:-1]] for r in rows]


def _test_exists(ref: str) -> bool:
    path, name = ref.split("::")
    f = ROOT / path
    return f.is_file() and re.search(rf"^def {re.escape(name)}\(", f.read_text(), re.M) is not None


def test_accuracy_figures_name_their_path_and_an_existing_test():
    rows = _accuracy_rows()
    assert len(rows) >= 7
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
