"""The large-size speed benchmark's figures and verdicts (selfcal/benchmarks/speed/large.py)."""

from __future__ import annotations

import sys

import pytest

from selfcal.benchmarks.child import ChildUsage, child_usage
from selfcal.benchmarks.speed.large import growth, table


def _runs(cpu: list[float], peak: list[float]) -> list[list[ChildUsage]]:
    return [[ChildUsage(0, 2 * c, p, 0.9 * c, 0.1 * c)] for c, p in zip(cpu, peak, strict=True)]


def test_linear_growth_and_memory_per_posture_are_met() -> None:
    g = growth([1000, 3000, 10000], _runs([8.0, 25.0, 90.0], [350.0, 780.0, 2500.0]))
    assert g.cpu_ratio(2) == pytest.approx(90 / 8)
    assert g.slope(1) == pytest.approx(25 / 8 / 3)
    assert g.mb_per_posture() == pytest.approx(2150 / 9000)
    assert g.linear()
    text = table(g, None, "", "head")
    assert "x11.25: met" in text and "0.239 MB: met" in text


def test_super_linear_growth_and_a_large_memory_growth_are_not_met() -> None:
    this = growth([1000, 10000], _runs([8.0, 100.0], [350.0, 3500.0]))
    ref = growth([1000, 10000], _runs([8.0, 90.0], [350.0, 2500.0]))
    assert not this.linear() and ref.linear()
    text = table(this, ref, "main (abc1234)", "head")
    assert "x12.50: NOT met" in text and "0.350 MB: NOT met" in text
    assert "x11.25: met" in text
    assert "| 10000 | 100.0 (90.0 + 10.0) | 3500 | 90.0 (81.0 + 9.0) | 2500 | 1.11 |" in text


def test_the_median_of_the_rounds_is_taken() -> None:
    runs = [[ChildUsage(0, 1, m, c, 0.0) for c, m in ((1.0, 10), (3.0, 30), (2.0, 20))],
            [ChildUsage(0, 1, 50, 20.0, 0.0)]]  # fmt: skip
    g = growth([10, 100], runs)
    assert g.cpu == (2.0, 20.0) and g.peak == (20, 50)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ru_maxrss in kB")
def test_a_child_s_cpu_seconds_are_its_own() -> None:
    spin = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass"
    u = child_usage([sys.executable, "-c", spin])
    assert u.code == 0
    assert 0.3 <= u.cpu < 3.0  # the spin and the interpreter's start, not the parent's
