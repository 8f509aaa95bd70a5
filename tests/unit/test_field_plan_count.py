"""The count a field plan advises (selfcal/calibration/field/plan.py ``count_to_match``, issue
#30): the smallest plan whose forecast reaches the random plan of MATCH_RANDOM, found by
bisection over nested plans whose forecast falls with their size."""

from __future__ import annotations

import pytest

from selfcal.calibration.field.plan import MATCH_RANDOM, count_to_match


def _forecasts(calls: list[int], at: dict[int, float | None] | None = None):
    def forecast_of(n: int) -> float | None:
        calls.append(n)
        return (at or {}).get(n, 1.0 / n)  # falls with the count

    return forecast_of


@pytest.mark.parametrize("target_n", [13, 16, 21, MATCH_RANDOM])
def test_the_smallest_count_that_reaches_the_target(target_n):
    calls: list[int] = []
    got = count_to_match(12, _forecasts(calls), 1.0 / target_n)
    assert got == (target_n, pytest.approx(1.0 / target_n))
    assert len(calls) <= 6  # bisection, not every count from 13 to 30


def test_none_when_not_even_the_largest_plan_reaches_it():
    calls: list[int] = []
    assert count_to_match(12, _forecasts(calls), 0.5 / MATCH_RANDOM) is None
    assert calls == [MATCH_RANDOM]


def test_a_plan_without_a_bound_does_not_reach_it():
    """A count whose plan has no bound (None) counts as not reaching the target: the count
    above it is given."""
    calls: list[int] = []
    got = count_to_match(12, _forecasts(calls, {21: None}), 1.0 / 21)
    assert got == (22, pytest.approx(1.0 / 22))
    assert count_to_match(12, _forecasts([], {MATCH_RANDOM: None}), 1.0) is None
