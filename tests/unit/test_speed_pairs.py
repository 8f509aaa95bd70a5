"""The speed benchmark's two trees in turn (#32, ``speed --against REF``): the order the parts
run in, one round's parts merged, the medians over the rounds and the round-by-round ratios,
which hold on a machine whose speed drifts where the ratio of the medians does not."""

from __future__ import annotations

import argparse
import statistics

import pytest

from selfcal.benchmarks.speed.measure import PARTS, parts_of
from selfcal.benchmarks.speed.pairs import (
    TREES,
    interleave,
    median_figures,
    merge_parts,
    paired,
    schedule,
)
from selfcal.errors import InternalError, UsageError


def test_each_part_is_run_by_both_trees_one_after_the_other_the_first_alternating():
    order = schedule(["a", "b"], 3)
    assert order == [
        (0, "a", "this"), (0, "a", "ref"), (0, "b", "this"), (0, "b", "ref"),
        (1, "a", "ref"), (1, "a", "this"), (1, "b", "ref"), (1, "b", "this"),
        (2, "a", "this"), (2, "a", "ref"), (2, "b", "this"), (2, "b", "ref"),
    ]  # fmt: skip
    for k in range(3):  # each part of a round: both trees, next to each other
        for part in "ab":
            i = order.index((k, part, "this"))
            j = order.index((k, part, "ref"))
            assert abs(i - j) == 1
    with pytest.raises(UsageError, match="at least 1"):
        schedule(["a"], 0)


def test_the_benchmark_s_parts_are_the_ones_its_options_ask_for():
    args = argparse.Namespace(part=None, skip_run=False, memory=False, against="HEAD~1")
    assert parts_of(args) == list(PARTS)
    args.against, args.skip_run = None, True
    assert parts_of(args) == ["start", "calibrate", "ba"]
    args.part = "run"
    assert parts_of(args) == ["run"]


def test_a_round_s_parts_are_merged_and_a_figure_measured_twice_is_refused():
    fig = merge_parts([{"load": [1.0, 2.0], "help": [0.1, 0.1]}, {"load": [3.0], "run": [3, 4]}])
    assert fig == {"load": [1.0, 2.0, 3.0], "help": [0.1, 0.1], "run": [3, 4]}
    with pytest.raises(InternalError, match="'run'"):
        merge_parts([{"run": [1, 1]}, {"run": [2, 2]}])


def _round(run: float, cal: float, load: float) -> dict:
    return {"load": [load], "help": [0.13, 0.12], "fk": [0.14, 0.14], "run": [run, 1.5 * run],
            "calibrate": [{"poses": 300, "used": 300, "wall": cal, "cpu": cal,
                           "acquire": 0.6}],
            "ba": {"poses": 300, "solver": "schur", "engine": 0.2}}  # fmt: skip


def test_the_rounds_medians_keep_the_figures_shape():
    rounds = [_round(3.0, 1.7, 1.0), _round(2.0, 1.9, 2.0), _round(4.0, 1.8, 3.0)]
    fig = median_figures(rounds)
    assert fig["run"] == [3.0, 4.5]
    assert fig["calibrate"] == [{"poses": 300, "used": 300, "wall": 1.8, "cpu": 1.8,
                                 "acquire": 0.6}]  # fmt: skip
    assert fig["ba"] == {"poses": 300, "solver": "schur", "engine": 0.2}
    assert fig["load"] == [1.0, 2.0, 3.0] and fig["rounds"] == 3
    assert isinstance(fig["calibrate"][0]["poses"], int)  # "300 poses", not "300.0"
    rounds[1]["ba"]["solver"] = "dense"
    with pytest.raises(InternalError, match="differs between the rounds"):
        median_figures(rounds)
    rounds[1]["ba"]["solver"] = "schur"
    rounds[2]["calibrate"][0]["used"] = 299
    with pytest.raises(
        InternalError, match=r"figure calibrate\[0\]\.used differs between the rounds"
    ):
        median_figures(rounds)


def test_the_paired_ratio_holds_on_a_drifting_machine():
    """This tree 5 % faster than REF; the machine's speed drifts by +-20 % from round to round
    and the run that goes second in a pair is 2 % slower. Each pair sees one speed of the
    machine: every pair's ratio is the code's 0.95 and the order's 2 % (either way, the first
    alternating), their median the code's within it. The same runs paired a round apart (as
    when measured minutes apart) spread by the drift."""
    drift = [1.0, 1.2, 0.85, 1.15, 0.8, 1.1, 0.9, 1.2, 0.83]

    def measure(tree: str, part: str, k: int) -> dict:
        second = tree == ("ref" if k % 2 == 0 else "this")
        speed = drift[k] * (1.02 if second else 1.0) * (0.95 if tree == "this" else 1.0)
        return {"load": [0.1], "help": [0.1, 0.1], "fk": [0.1, 0.1], "run": [3.0 * speed] * 2}

    calls = []
    got = interleave(
        ["run"], len(drift), lambda t, p, k: calls.append((k, p, t)) or measure(t, p, k)
    )
    assert calls == schedule(["run"], len(drift))
    assert set(got) == set(TREES) and len(got["this"]) == len(drift)
    p = paired(got["this"], got["ref"])["`selfcal run` default scenario (process)"]
    assert len(p.ratios) == len(drift)
    # the two orders' medians carry the order's 2 % either way; their geometric mean is the
    # code's 0.95 (the median of the 9 ratios was 0.95 / 1.02: 5 of 9 rounds with REF second)
    assert p.by_order == pytest.approx((0.95 / 1.02, 0.95 * 1.02), rel=1e-9)
    assert p.ratio == pytest.approx(0.95, rel=1e-9)
    assert all(0.93 < r < 0.97 for r in p.ratios)  # each pair: the code's 0.95 and the order's 2 %
    assert p.this == pytest.approx(statistics.median(r["run"][0] for r in got["this"]))
    # the same runs, REF's column shifted by one round (measured minutes apart): the drift
    shifted = paired(got["this"][1:], got["ref"][:-1])["`selfcal run` default scenario (process)"]
    assert max(shifted.ratios) / min(shifted.ratios) > 1.3
