"""``selfcal calibrate`` from 1000 to 10,000 postures: CPU seconds and peak memory per posture,
side by side with a git ref (issue 32: linear to 10,000 postures, at most 0.3 MB per posture).

For each size (``--sizes``, default 1000, 3000 and 10,000) an analytic dataset of the default
scenario (``[trajectory] poses``, no rendering) is acquired once by this checkout (``--keep DIR``
keeps them there and reuses them), and ``selfcal calibrate --quiet`` runs on a copy of it as a
process of its own, from the launcher of :mod:`selfcal.benchmarks.child` (its user and system
CPU seconds and its peak resident set), by this tree and, with ``--against REF``, at the same
time by REF's (a temporary worktree with its own environment:
:func:`selfcal.benchmarks.speed.against.ref_tree`). The two processes run side by side, so both
see the machine of that minute; on a shared machine their CPU seconds compare them, their wall
times do not. ``--rounds`` repeats every size (median).

The goals, judged for each tree (:data:`LINEAR_SLACK`, :data:`MB_PER_POSTURE`): "linear" is the
CPU seconds at the largest size over those at the smallest at most 1.2 times the size ratio
(10,000 / 1000: at most x12); the memory per posture is the peak's growth from the smallest to
the largest size per posture added (the definition of ``speed.measure --memory``).

``--write-docs`` writes the table into docs/performance.md between the ``benchmark_speed_large``
markers, stamped with the code that measured it (:func:`selfcal.benchmarks.doc_blocks.code_version`;
a checkout with uncommitted code is refused).

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.speed.large [--against REF] [--sizes N ...]
[--rounds R] [--keep DIR] [--write-docs]`` (minutes: ~100 CPU s and ~2.5 GB a tree at 10,000).
"""

from __future__ import annotations

import datetime
import os
import shlex
import shutil
import statistics
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path

from selfcal.benchmarks.child import ChildUsage, child_usage
from selfcal.benchmarks.doc_blocks import ROOT, code_version, write_block
from selfcal.benchmarks.speed.against import compile_tree, ref_tree
from selfcal.benchmarks.usage import benchmark_parser

__all__ = [
    "LINEAR_SLACK",
    "MB_PER_POSTURE",
    "SIZES",
    "Growth",
    "dataset",
    "growth",
    "main",
    "table",
]

SIZES = (1000, 3000, 10000)
"""The posture counts measured by default (issue 32: linear to 10,000)."""
LINEAR_SLACK = 1.2
""""Linear": the CPU seconds grow at most this many times the postures (10,000 / 1000: x12)."""
MB_PER_POSTURE = 0.3
"""Issue 32's memory goal: the peak grows at most this many MB per posture."""
BLOCK = "benchmark_speed_large"


def dataset(n: int, root: Path) -> tuple[Path, bool]:
    """The analytic dataset of the default scenario with ``n`` postures in ``root``
    (``analytic{n}``), acquired unless it is there already; and whether it was."""
    out = root / f"analytic{n}"
    if (out / "dataset.json").is_file():
        return out, True
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire

    s = load_scenario(None, {"trajectory": {"poses": n}, "noise": {"render": False}})
    run_acquire(s, out, quiet=True)
    return out, False


def _script(python: Path) -> list[str]:
    """The ``selfcal`` console script beside ``python`` (else the CLI module)."""
    script = python.parent / "selfcal"
    return [str(script)] if script.is_file() else [str(python), "-m", "selfcal.cli.main"]


def _calibrate(python: Path, data: Path, work: Path) -> ChildUsage:
    """``selfcal calibrate --quiet`` of ``python``'s tree on a copy of ``data`` in ``work``."""
    copy = work / data.name
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(data, copy)
    err = work / f"{data.name}.stderr"
    u = child_usage([*_script(python), "calibrate", "--quiet", str(copy)], stderr=err)
    if u.code != 0:
        raise SystemExit(f"{python}: selfcal calibrate {copy} exited {u.code}: {err.read_text()}")
    shutil.rmtree(copy, ignore_errors=True)
    return u


@dataclass(frozen=True)
class Growth:
    """One tree's figures: ``cpu``, ``user``, ``system`` (s), ``peak`` (MB) per size (the
    medians over the rounds)."""

    sizes: tuple[int, ...]
    cpu: tuple[float, ...]
    user: tuple[float, ...]
    system: tuple[float, ...]
    peak: tuple[float, ...]

    def cpu_ratio(self, i: int) -> float:
        """CPU seconds at ``sizes[i]`` over those at the smallest size."""
        return self.cpu[i] / self.cpu[0]

    def slope(self, i: int) -> float:
        """:meth:`cpu_ratio` over the size ratio (1.0: linear)."""
        return self.cpu_ratio(i) / (self.sizes[i] / self.sizes[0])

    def mb_per_posture(self) -> float:
        """The peak's growth from the smallest to the largest size per posture added (MB)."""
        return (self.peak[-1] - self.peak[0]) / (self.sizes[-1] - self.sizes[0])

    def linear(self) -> bool:
        """CPU at the largest size <= :data:`LINEAR_SLACK` times the size ratio."""
        return self.slope(len(self.sizes) - 1) <= LINEAR_SLACK


def growth(sizes: list[int], runs: list[list[ChildUsage]]) -> Growth:
    """A tree's :class:`Growth` from its runs (one list of rounds per size)."""

    def med(f) -> tuple[float, ...]:
        return tuple(statistics.median(f(u) for u in rs) for rs in runs)

    return Growth(tuple(sizes), med(lambda u: u.cpu), med(lambda u: u.user),
                  med(lambda u: u.system), med(lambda u: u.peak_mb))  # fmt: skip


def _verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def table(this: Growth, ref: Growth | None, label: str, head: str) -> str:
    """The Markdown block: ``head`` (when, how, load), a row per size, the growth and the
    goals, for this tree and ``ref`` (None: this tree alone)."""
    both = ref is not None
    trees = [("this tree", this)] + ([(label, ref)] if ref is not None else [])
    cols = " | ".join(f"{n}: CPU s (user + system) | {n}: peak MB" for n, _ in trees)
    lines = [head, "", f"| postures | {cols} |{' CPU this / ' + label + ' |' if both else ''}",
             "|---|" + "---|---|" * len(trees) + ("---|" if both else "")]  # fmt: skip
    for i, n in enumerate(this.sizes):
        cells = " | ".join(
            f"{g.cpu[i]:.1f} ({g.user[i]:.1f} + {g.system[i]:.1f}) | {g.peak[i]:.0f}"
            for _, g in trees
        )
        ratio = f" {this.cpu[i] / ref.cpu[i]:.2f} |" if ref is not None else ""
        lines.append(f"| {n} | {cells} |{ratio}")
    last = len(this.sizes) - 1
    a, b = this.sizes[0], this.sizes[last]
    names = " | ".join(n for n, _ in trees)
    lines += ["", f"| growth | {names} |", "|---|" + "---|" * len(trees)]
    for i in range(1, len(this.sizes)):
        n = this.sizes[i]
        lines.append(
            f"| CPU {n} / {a} postures (x{n / a:g}); slope: that over x{n / a:g} | "
            + " | ".join(f"x{g.cpu_ratio(i):.2f}; {g.slope(i):.2f}" for _, g in trees)
            + " |"
        )
    lines.append(f"| peak memory per posture, {a} -> {b} (MB) | "
                 + " | ".join(f"{g.mb_per_posture():.3f}" for _, g in trees) + " |")  # fmt: skip
    lines += [
        "",
        f"| goal (issue 32) | test | {names} |",
        "|---|---|" + "---|" * len(trees),
        f"| `calibrate` linear to {b} postures | CPU {b} / {a} <= x{LINEAR_SLACK * b / a:g} "
        f"(slope <= {LINEAR_SLACK:g}) | "
        + " | ".join(f"x{g.cpu_ratio(last):.2f}: {_verdict(g.linear())}" for _, g in trees)
        + " |",
        f"| peak memory per posture | growth {a} -> {b} <= {MB_PER_POSTURE:g} MB | "
        + " | ".join(
            f"{g.mb_per_posture():.3f} MB: {_verdict(g.mb_per_posture() <= MB_PER_POSTURE)}"
            for _, g in trees
        )
        + " |",
    ]
    return "\n".join(lines)


def _load() -> float:
    return os.getloadavg()[0]


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES),
                    help="posture counts (at least two; default 1000 3000 10000)")  # fmt: skip
    ap.add_argument("--against", metavar="REF",
                    help="also git REF (HEAD~1: the previous commit) in a temporary worktree, "
                    "each of its runs side by side with this tree's")  # fmt: skip
    ap.add_argument("--rounds", type=int, default=1, help="runs of every size (median)")
    ap.add_argument("--keep", metavar="DIR", type=Path,
                    help="keep the datasets in DIR (analyticN) and reuse those there")  # fmt: skip
    ap.add_argument("--write-docs", action="store_true",
                    help=f"write docs/performance.md's {BLOCK} block")  # fmt: skip
    argv = sys.argv[1:] if argv is None else argv
    args = ap.parse_args(argv)
    sizes = sorted(set(args.sizes))
    if len(sizes) < 2 or args.rounds < 1:
        ap.error("--sizes needs at least two posture counts and --rounds at least 1")
    code = code_version()
    if args.write_docs and (code is None or code.endswith("+changes")):
        raise SystemExit(f"--write-docs: the checkout's code is {code}; commit it first")
    compile_tree(ROOT)
    loads = [_load()]
    with tempfile.TemporaryDirectory(prefix="selfcal-large-") as d:
        root = args.keep or Path(d)
        root.mkdir(parents=True, exist_ok=True)
        data = []
        for n in sizes:
            path, kept = dataset(n, root)
            print(f"{n} postures: {path} ({'kept' if kept else 'acquired'})", flush=True)
            data.append(path)
        this_runs: list[list[ChildUsage]] = [[] for _ in sizes]
        ref_runs: list[list[ChildUsage]] = [[] for _ in sizes]
        with ref_tree(args.against) if args.against else nullcontext() as found:
            for r in range(args.rounds):
                for i, n in enumerate(sizes):
                    jobs = [(Path(sys.executable), this_runs[i], Path(d) / "this")]
                    if found is not None:
                        jobs.append((Path(found[1]), ref_runs[i], Path(d) / "ref"))
                    for _, _, w in jobs:
                        w.mkdir(exist_ok=True)
                    with ThreadPoolExecutor(len(jobs)) as pool:
                        got = list(pool.map(_calibrate, [j[0] for j in jobs], [data[i]] * len(jobs),
                                            [j[2] for j in jobs]))  # fmt: skip
                    loads.append(_load())
                    for (_, runs, _), u in zip(jobs, got, strict=True):
                        runs.append(u)
                    print(f"round {r + 1}, {n} postures: " + "; ".join(
                        f"{'this' if k == 0 else args.against} CPU {u.cpu:.1f} s (sys "
                        f"{u.system:.1f}), peak {u.peak_mb:.0f} MB" for k, u in enumerate(got)
                    ), flush=True)  # fmt: skip
            label = "" if found is None else f"{args.against} ({found[2]})"
    this = growth(sizes, this_runs)
    ref = growth(sizes, ref_runs) if args.against else None
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    how = (f"each row one `selfcal calibrate --quiet` process per tree{', ' if ref else ''}"
           f"{'the two trees side by side' if ref else ''}; the median of {args.rounds} "
           f"round{'s' if args.rounds > 1 else ''}")  # fmt: skip
    command = shlex.join(["uv", "run", "python", "-m", "selfcal.benchmarks.speed.large", *argv])
    head = (f"Measured {when} by the code at {code} with `nice -n 10 {command}` "
            f"({os.cpu_count()} CPUs; analytic datasets of the default scenario; {how}; "
            f"1-minute load average {min(loads):.1f}-{max(loads):.1f}; 1 BLAS thread).")  # fmt: skip
    text = table(this, ref, label, head)
    print(text)
    if args.write_docs:
        write_block(ROOT / "docs" / "performance.md", text, BLOCK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
