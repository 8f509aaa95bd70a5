"""The speed benchmark's two trees measured in turn, part by part (``speed --against REF``).

A shared machine's speed drifts (other tenants: +-20 % within an hour), so two trees measured
one after the other differ by the drift as much as by their code (session 25: 0.955 side by
side, 1.08 one after the other, the same hour). Here every part of the benchmark
(:data:`selfcal.benchmarks.speed.measure.PARTS`) is measured once by each tree, then the next part,
for ``rounds`` rounds; within
a round the tree that goes first alternates (:func:`schedule`), so neither is always the one
that runs after the other's warm caches. Each figure is reported as each tree's median over the
rounds and the ratio this / REF of the round-by-round pairs (:func:`paired`): a pair is
measured seconds apart, so the drift between the pairs cancels in each ratio. A run's place in
its pair can matter too (the second after the first's warm caches, or on a machine the first
has heated): the ratio is the geometric mean of the two orders' medians (:attr:`Paired.ratio`),
in which a factor the order puts on every pair cancels, as it does not in the median of an odd
number of rounds (the review of session 26: 9 rounds, identical trees, the second 2 % slower:
0.980).

Pure bookkeeping: what is run and how is :mod:`selfcal.benchmarks.speed.against`.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from selfcal.errors import InternalError, UsageError

__all__ = [
    "TREES",
    "Paired",
    "interleave",
    "merge_parts",
    "median_figures",
    "named",
    "paired",
    "schedule",
]

TREES = ("this", "ref")
"""The two trees: this checkout and REF."""


def schedule(parts: Sequence[str], rounds: int) -> list[tuple[int, str, str]]:
    """``(round, part, tree)`` in the order they run: in each round every part by one tree and
    at once by the other, this tree first in even rounds, REF first in odd ones."""
    if rounds < 1:
        raise UsageError(f"rounds must be at least 1, got {rounds}")
    order = []
    for k in range(rounds):
        first, second = TREES if k % 2 == 0 else TREES[::-1]
        for part in parts:
            order += [(k, part, first), (k, part, second)]
    return order


def merge_parts(fragments: Sequence[dict]) -> dict:
    """One round's figures of one tree from its parts' figures (disjoint keys but ``load``,
    whose readings are joined in order)."""
    fig: dict = {"load": []}
    for f in fragments:
        for key, value in f.items():
            if key == "load":
                fig["load"] += list(value)
            elif key in fig:
                raise InternalError(f"two parts both measured {key!r}")
            else:
                fig[key] = value
    return fig


def interleave(
    parts: Sequence[str], rounds: int, measure: Callable[[str, str, int], dict]
) -> dict[str, list[dict]]:
    """Each tree's figures round by round: ``measure(tree, part, round)`` (a part's figures)
    called in :func:`schedule`'s order, merged per round (:func:`merge_parts`)."""
    got: dict[tuple[str, int], list[dict]] = {}
    for k, part, tree in schedule(parts, rounds):
        got.setdefault((tree, k), []).append(measure(tree, part, k))
    return {t: [merge_parts(got[(t, k)]) for k in range(rounds)] for t in TREES}


def _median(values: list, path: str) -> object:
    """The median of one figure (``path``, e.g. ``calibrate[0].used``) over the rounds, keeping
    its shape (a list or dict of numbers figure by figure); a text or an integer (a count:
    poses, unknowns) is kept when every round has the same, and refused otherwise."""
    first = values[0]
    if isinstance(first, bool | str | int) or first is None:  # a count, a name: the same
        if any(v != first for v in values):
            raise InternalError(
                f"the figure {path} differs between the rounds: {values}: the rounds did "
                "different work (a count or a name is not a time to take the median of); "
                "measure that part again (--part) and look at the round that differs"
            )
        return first
    if isinstance(first, float):
        return statistics.median(values)
    if isinstance(first, dict):
        return {key: _median([v[key] for v in values], f"{path}.{key}") for key in first}
    return [_median([v[i] for v in values], f"{path}[{i}]") for i in range(len(first))]


def median_figures(rounds: Sequence[dict]) -> dict:
    """One tree's figures over its rounds: every figure's median (the same shape as one
    round's, so the tables read it as one measurement); ``load`` is every reading, in order,
    and ``rounds`` their number."""
    keys = [k for k in rounds[0] if k != "load"]
    fig = {k: _median([r[k] for r in rounds], k) for k in keys}
    fig["load"] = [v for r in rounds for v in r.get("load", [])]
    fig["rounds"] = len(rounds)
    return fig


def named(fig: dict) -> dict[str, float]:
    """The figures of one measurement by name (seconds unless the name says otherwise)."""
    out = {
        "`selfcal --help` (process, median)": fig["help"][0],
        "`selfcal fk --joints ...` (process, median)": fig["fk"][0],
    }
    if "run" in fig:
        out["`selfcal run` default scenario (process)"] = fig["run"][0]
        out["same, CPU"] = fig["run"][1]
    if "run_loaded" in fig:
        out["same, beside a CPU-bound process"] = fig["run_loaded"][0]
    for r in fig.get("calibrate", []):
        out[f"`calibrate`, analytic, {r['poses']} poses (in-process)"] = r["wall"]
    for r in fig.get("calibrate", []):
        out[f"acquisition, analytic, {r['poses']} poses"] = r["acquire"]
        if "acquire_cpu" in r:  # a figures file of an older speed.py has none
            out[f"same, {r['poses']} poses, CPU"] = r["acquire_cpu"]
    if "ba" in fig:
        out[f"bundle adjustment, {fig['ba']['poses']} poses, engine"] = fig["ba"]["engine"]
    if "memory" in fig:
        m = fig["memory"]
        for n, mb in zip(m["poses"], m["peak_mb"], strict=True):
            out[f"`selfcal calibrate` peak memory, {n} poses (MB)"] = mb
    return out


@dataclass(frozen=True)
class Paired:
    """One figure of both trees over the rounds: each tree's median, and the round-by-round
    ratios this / REF (a round's two measurements taken one right after the other), with
    whether this tree went first in that round (:func:`schedule`: the even rounds)."""

    this: float | None
    ref: float | None
    ratios: tuple[float, ...]
    this_first: tuple[bool, ...] = ()

    @property
    def by_order(self) -> tuple[float | None, float | None]:
        """The median ratio of the rounds where this tree went first, and of those where REF
        did (None: no such round)."""
        first = [r for r, f in zip(self.ratios, self.this_first, strict=True) if f]
        second = [r for r, f in zip(self.ratios, self.this_first, strict=True) if not f]
        return (statistics.median(first) if first else None,
                statistics.median(second) if second else None)  # fmt: skip

    @property
    def ratio(self) -> float | None:
        """This / REF: the geometric mean of :attr:`by_order`'s two medians, so that a factor
        a run's place in its pair puts on every ratio cancels (the median of all the ratios
        when only one order was measured; None: no round measured both)."""
        if not self.ratios:
            return None
        a, b = self.by_order if len(self.this_first) == len(self.ratios) else (None, None)
        if a is None or b is None:
            return statistics.median(self.ratios)
        return math.sqrt(a * b)


def paired(this: Sequence[dict], ref: Sequence[dict]) -> dict[str, Paired]:
    """Every figure (:func:`named`) of two trees measured round by round (the same number of
    rounds, :func:`interleave`: this tree first in the even rounds): the medians and the ratios
    of the pairs."""
    if len(this) != len(ref):
        raise UsageError(f"{len(this)} rounds of this tree against {len(ref)} of REF")
    a, b = [named(f) for f in this], [named(f) for f in ref]
    out = {}
    for key in dict.fromkeys([k for r in a + b for k in r]):
        xs = [r[key] for r in a if key in r]
        ys = [r[key] for r in b if key in r]
        both = [(x[key] / y[key], k % 2 == 0) for k, (x, y) in enumerate(zip(a, b, strict=True))
                if key in x and key in y and y[key]]  # fmt: skip
        out[key] = Paired(
            statistics.median(xs) if xs else None,
            statistics.median(ys) if ys else None,
            tuple(r for r, _ in both),
            tuple(f for _, f in both),
        )
    return out
