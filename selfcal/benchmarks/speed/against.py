"""The speed benchmark (:mod:`selfcal.benchmarks.speed.measure`) side by side with a git ref, and issue
32's speed goals met or not.

``python -m selfcal.benchmarks.speed.measure --against REF`` measures this checkout and the commit
``REF`` (a commit, branch or tag; ``HEAD~1`` is the previous commit) in turn, part by part
(:mod:`selfcal.benchmarks.speed.pairs`: ``--rounds`` rounds, each part of the benchmark by one
tree and at once by the other, the first alternating), so that a drifting machine moves both
columns alike. REF runs in a temporary worktree (``git worktree add --detach``) with its own
environment (``uv sync --locked --compile-bytecode``). Every part of either tree is a process of
its own running the same copy of this checkout's ``speed.py`` (``--part P --json FILE``) with
that tree's interpreter, so that both columns come from the same measuring code and differ only
in the code measured. Both trees' ``selfcal/`` are compiled first (:func:`compile_tree`), as
``pip install`` leaves a wheel: where ``PYTHONDONTWRITEBYTECODE`` is set every process would
compile them again (``uv sync --compile-bytecode`` compiles the dependencies, not the editable
project). The worktree is removed at the end.

Prints one row per figure (each tree's median over the rounds, the ratio this / REF balanced over
the order in the pairs, :attr:`~selfcal.benchmarks.speed.pairs.Paired.ratio`, each order's median
and the range) and one row per goal of issue 32 (:data:`GOALS`): met or not met,
for each column.
"""

from __future__ import annotations

import compileall
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from selfcal.benchmarks.doc_blocks import ROOT
from selfcal.benchmarks.speed.pairs import Paired, interleave, median_figures, named, paired

__all__ = [
    "GOALS",
    "Goal",
    "compile_tree",
    "measure_against",
    "ref_tree",
    "part_argv",
    "named",
    "comparison",
]

_DROPPED = {"--against": 1, "--json": 1, "--write-docs": 0, "--write-readme": 0, "--check": 0,
            "--with-pybotics": 0, "--pybotics-n": 1, "--part": 1, "--rounds": 1,
            "--run-repeat": 1, "--memory": 0, "--skip-run": 0}  # fmt: skip
"""Options of this run not passed to a part's (value count): a part measures the same figures
as the whole run, without the pybotics comparison, without writing anything, and each
``selfcal run`` once (the rounds are its repeats); which parts run is the caller's choice."""


@dataclass(frozen=True)
class Goal:
    """One of issue 32's speed goals: ``value`` of the figures (None: not measured) at most
    ``limit`` ``unit``."""

    what: str
    unit: str
    limit: float
    value: Callable[[dict], float | None]


def _run(fig: dict) -> float | None:
    return fig["run"][0] if "run" in fig else None


def _run_loaded(fig: dict) -> float | None:
    return fig["run_loaded"][0] / fig["run"][0] if "run_loaded" in fig else None


def _calibrate_300(fig: dict) -> float | None:
    return next((r["wall"] for r in fig.get("calibrate", []) if r["poses"] == 300), None)


def _memory(fig: dict) -> float | None:
    return fig["memory"]["mb_per_posture"] if "memory" in fig else None


GOALS = (
    Goal("`selfcal run` default scenario, on an idle 2-core machine", "s", 2.8, _run),
    Goal("`selfcal run` beside one CPU-bound process, over the quiet run", "x", 1.5, _run_loaded),
    Goal("`calibrate` at 300 postures (analytic, in-process)", "s", 2.0, _calibrate_300),
    Goal("`selfcal calibrate`'s peak memory per posture", "MB", 0.3, _memory),
)
"""Issue 32's speed goals."""


def compile_tree(root: Path, python: str = sys.executable) -> None:
    """Compile ``root/selfcal`` into its ``__pycache__`` with ``python`` (its own version's
    bytecode)."""
    if python == sys.executable:
        compileall.compile_dir(str(root / "selfcal"), quiet=1)
        return
    subprocess.run([python, "-m", "compileall", "-q", str(root / "selfcal")], check=True,
                   stdout=subprocess.DEVNULL)  # fmt: skip


def part_argv(argv: list[str], part: str, out: Path) -> list[str]:
    """This run's options as a part's run takes them (:data:`_DROPPED` left out, ``--opt v``
    or ``--opt=v``): ``--part part --json out`` and one ``selfcal run`` a round."""
    kept: list[str] = []
    skip = 0
    for a in argv:
        if skip:
            skip -= 1
            continue
        name = a.split("=", 1)[0]
        if name in _DROPPED:
            skip = 0 if "=" in a else _DROPPED[name]
            continue
        kept.append(a)
    return [*kept, "--run-repeat", "1", "--part", part, "--json", str(out)]


def _clean_env() -> dict[str, str]:
    """This environment less what points uv and Python at this checkout's environment."""
    drop = ("VIRTUAL_ENV", "UV_PROJECT_ENVIRONMENT", "PYTHONPATH", "PYTHONHOME")
    return {k: v for k, v in os.environ.items() if k not in drop}


@contextmanager
def ref_tree(ref: str) -> Iterator[tuple[Path, str, str]]:
    """``(tree, python, commit)``: git ``ref`` checked out in a temporary worktree with its own
    environment and its ``selfcal/`` compiled, its interpreter and its short commit; the
    worktree is removed on leaving."""
    if shutil.which("uv") is None:
        raise SystemExit("--against needs uv on PATH (it makes REF's environment)")
    git = ["git", "-C", str(ROOT)]
    found = subprocess.run([*git, "rev-parse", "--verify", "--short", f"{ref}^{{commit}}"],
                           capture_output=True, text=True)  # fmt: skip
    if found.returncode != 0:
        raise SystemExit(f"--against {ref}: not a commit of {ROOT} ({found.stderr.strip()})")
    commit = found.stdout.strip()
    with tempfile.TemporaryDirectory(prefix="selfcal-against-") as d:
        tree = Path(d) / "tree"
        subprocess.run([*git, "worktree", "add", "--detach", "--quiet", str(tree), commit],
                       check=True)  # fmt: skip
        try:
            print(f"--against {ref}: {commit} in {tree}; uv sync --locked --compile-bytecode")
            subprocess.run(["uv", "sync", "--locked", "--compile-bytecode", "--quiet"], cwd=tree,
                           env=_clean_env(), check=True)  # fmt: skip
            python = str(tree / ".venv" / "bin" / "python")
            compile_tree(tree, python)
            yield tree, python, commit
        finally:
            subprocess.run([*git, "worktree", "remove", "--force", str(tree)], check=False)


def measure_against(
    ref: str, argv: list[str], parts: list[str], rounds: int
) -> tuple[str, dict, dict, dict[str, Paired]]:
    """This tree and git ``ref`` measured in turn, part by part
    (:func:`selfcal.benchmarks.speed.pairs.interleave`): REF's label (the ref, with its commit
    when the ref is not one), each tree's medians over the rounds
    (:func:`selfcal.benchmarks.speed.pairs.median_figures`) and every figure paired
    (:func:`selfcal.benchmarks.speed.pairs.paired`). Each part is a process of its own running
    one copy of this checkout's ``speed.py`` (``argv``: this run's options,
    :func:`part_argv`) with the tree's interpreter, in the tree."""
    with tempfile.TemporaryDirectory(prefix="selfcal-parts-") as d, ref_tree(ref) as found:
        tree, python, commit = found
        script = Path(d) / "speed.py"  # alone in its folder: nothing beside it shadows a module
        shutil.copy(Path(__file__).with_name("measure.py"), script)
        where = {"this": (ROOT, sys.executable, os.environ.copy()),
                 "ref": (tree, python, _clean_env())}  # fmt: skip

        def measure(which: str, part: str, k: int) -> dict:
            root, py, env = where[which]
            out = Path(d) / f"{which}-{part}-{k}.json"
            print(f"round {k + 1}/{rounds}, {part}: {'this tree' if which == 'this' else ref}")
            subprocess.run([py, str(script), *part_argv(argv, part, out)], cwd=root, env=env,
                           check=True)  # fmt: skip
            return json.loads(out.read_text())

        got = interleave(parts, rounds, measure)
    label = ref if commit.startswith(ref) or ref.startswith(commit) else f"{ref} ({commit})"
    pairs = paired(got["this"], got["ref"])
    return label, median_figures(got["this"]), median_figures(got["ref"]), pairs


def _cell(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.3g}" if abs(v) < 10 else f"{v:.1f}"


def _verdict(goal: Goal, v: float | None) -> str:
    if v is None:
        return "not measured"
    return f"{_cell(v)} {goal.unit}: {'met' if v <= goal.limit else 'NOT met'}"


def _ratio(r: float | None) -> str:
    return "n/a" if r is None else f"{r:.3f}"


def _load_range(fig: dict) -> str:
    v = fig.get("load", [])
    return f"{min(v):.1f}-{max(v):.1f}" if v else "n/a"


def comparison(
    fig: dict, ref: dict | None = None, label: str = "", pairs: dict[str, Paired] | None = None
) -> str:
    """The goals table of ``fig`` (this tree) and, with ``ref`` and ``pairs``
    (:func:`measure_against`, REF named ``label``), every figure side by side: each tree's
    median over the rounds, the ratio this / REF balanced over the order in the pairs
    (:attr:`Paired.ratio`), each order's median and the range."""
    lines = []
    if ref is not None and pairs is not None:
        n = fig.get("rounds", 1)
        lines += [
            f"This tree against {label}, interleaved: {n} rounds, in each every part of the "
            f"benchmark run by one tree and at once by the other (the first alternating round to "
            f"round); each tree's median over the rounds, and this / {label}: the geometric "
            f"mean of the median ratio of the rounds where this tree went first and of those "
            f"where {label} did (a factor the order puts on every pair cancels), each order's "
            f"median and the range of the {n} rounds' ratios (1-minute load average over the "
            f"parts: this tree {_load_range(fig)}, {label} {_load_range(ref)}):",
            "",
            f"| what | this tree | {label} | this / {label}, paired | this first; "
            f"{label} first (range) |",
            "|---|---|---|---|---|",
        ]
        for k, p in pairs.items():
            a, b = p.by_order
            orders = (f"{_ratio(a)}; {_ratio(b)} ({min(p.ratios):.2f}-{max(p.ratios):.2f})"
                      if p.ratios else "n/a")  # fmt: skip
            lines.append(
                f"| {k} | {_cell(p.this)} | {_cell(p.ref)} | {_ratio(p.ratio)} | {orders} |"
            )
        lines.append("")
    both = ref is not None
    head = f"| goal (issue 32) | at most | this tree |{f' {label} |' if both else ''}"
    lines += [head, "|---|---|---|" + ("---|" if both else "")]
    for g in GOALS:
        row = f"| {g.what} | {g.limit:g} {g.unit} | {_verdict(g, g.value(fig))} |"
        if ref is not None:
            row += f" {_verdict(g, g.value(ref))} |"
        lines.append(row)
    if max(fig.get("load", [0.0])) > 0.5:
        lines += ["", "(the machine was not idle: a time goal is judged on an idle machine)"]
    return "\n".join(lines)
