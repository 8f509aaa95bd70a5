"""The speed benchmark (:mod:`selfcal.benchmarks.speed`) side by side with a git ref, and issue
32's speed goals met or not.

``python -m selfcal.benchmarks.speed --against REF`` measures this checkout, then the commit
``REF`` (a commit, branch or tag; ``HEAD~1`` is the previous commit) the same way: in a
temporary worktree (``git worktree add --detach``) with its own environment (``uv sync --locked
--compile-bytecode``), by this checkout's ``speed.py`` run with REF's interpreter, so that both
columns come from the same measuring code and differ only in the code measured. Both trees'
``selfcal/`` are compiled first (:func:`compile_tree`; ``speed.py`` always compiles its own), as
``pip install`` leaves a wheel: where ``PYTHONDONTWRITEBYTECODE`` is set every process would
compile them again (``uv sync --compile-bytecode`` compiles the dependencies, not the editable
project). The worktree is removed at the end.

Prints one row per figure (this tree, REF, ratio) and one row per goal of issue 32 (:data:`GOALS`):
met or not met, for each column.
"""

from __future__ import annotations

import compileall
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from selfcal.benchmarks.doc_blocks import ROOT

__all__ = ["GOALS", "Goal", "compile_tree", "measure_ref", "ref_argv", "named", "comparison"]

_DROPPED = {"--against": 1, "--json": 1, "--write-docs": 0, "--write-readme": 0, "--check": 0,
            "--with-pybotics": 0, "--pybotics-n": 1}  # fmt: skip
"""Options of this run not passed to REF's (value count): what REF measures is the same set
of figures, without the pybotics comparison and without writing anything."""


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


def ref_argv(argv: list[str]) -> list[str]:
    """This run's options as REF's run takes them: less what :data:`_DROPPED` names (``--opt v``
    or ``--opt=v``), with ``--memory`` (its goal needs it)."""
    out: list[str] = []
    skip = 0
    for a in argv:
        if skip:
            skip -= 1
            continue
        name = a.split("=", 1)[0]
        if name in _DROPPED:
            skip = 0 if "=" in a else _DROPPED[name]
            continue
        out.append(a)
    return out if "--memory" in out else [*out, "--memory"]


def _clean_env() -> dict[str, str]:
    """This environment less what points uv and Python at this checkout's environment."""
    drop = ("VIRTUAL_ENV", "UV_PROJECT_ENVIRONMENT", "PYTHONPATH", "PYTHONHOME")
    return {k: v for k, v in os.environ.items() if k not in drop}


def measure_ref(ref: str, argv: list[str]) -> tuple[dict, str]:
    """The figures of git ``ref`` (and its commit, short): measured by this checkout's
    ``speed.py`` with ``argv`` (:func:`ref_argv`) in a temporary worktree of ``ref`` with its own
    environment; the worktree is removed afterwards."""
    if shutil.which("uv") is None:
        raise SystemExit("--against needs uv on PATH (it makes REF's environment)")
    git = ["git", "-C", str(ROOT)]
    found = subprocess.run([*git, "rev-parse", "--verify", "--short", f"{ref}^{{commit}}"],
                           capture_output=True, text=True)  # fmt: skip
    if found.returncode != 0:
        raise SystemExit(f"--against {ref}: not a commit of {ROOT} ({found.stderr.strip()})")
    commit = found.stdout.strip()
    env = _clean_env()
    with tempfile.TemporaryDirectory(prefix="selfcal-against-") as d:
        tree, out = Path(d) / "tree", Path(d) / "figures.json"
        script = Path(d) / "speed.py"  # alone in its folder: nothing beside it shadows a module
        shutil.copy(Path(__file__).with_name("speed.py"), script)
        subprocess.run([*git, "worktree", "add", "--detach", "--quiet", str(tree), commit],
                       check=True)  # fmt: skip
        try:
            print(f"--against {ref}: {commit} in {tree}; uv sync --locked --compile-bytecode")
            subprocess.run(["uv", "sync", "--locked", "--compile-bytecode", "--quiet"], cwd=tree,
                           env=env, check=True)  # fmt: skip
            python = str(tree / ".venv" / "bin" / "python")
            compile_tree(tree, python)
            subprocess.run([python, str(script), "--json", str(out), *argv], cwd=tree, env=env,
                           check=True)  # fmt: skip
            return json.loads(out.read_text()), commit
        finally:
            subprocess.run([*git, "worktree", "remove", "--force", str(tree)], check=False)


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


def _cell(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.3g}" if abs(v) < 10 else f"{v:.1f}"


def _verdict(goal: Goal, v: float | None) -> str:
    if v is None:
        return "not measured"
    return f"{_cell(v)} {goal.unit}: {'met' if v <= goal.limit else 'NOT met'}"


def comparison(fig: dict, ref: dict | None = None, label: str = "") -> str:
    """The goals table of ``fig`` (this tree) and, with ``ref`` (:func:`measure_ref`, named
    ``label``), every figure side by side with the ratio this / REF."""
    loads = lambda f: ", ".join(f"{v:.1f}" for v in f.get("load", []))  # noqa: E731
    lines = []
    if ref is not None:
        a, b = named(fig), named(ref)
        lines += [
            f"This tree against {label} (1-minute load average during the parts: this tree "
            f"{loads(fig)}; {label} {loads(ref)}):",
            "",
            f"| what | this tree | {label} | this / {label} |",
            "|---|---|---|---|",
        ]
        for k in dict.fromkeys([*a, *b]):
            x, y = a.get(k), b.get(k)
            ratio = f"{x / y:.2f}" if x is not None and y else "n/a"
            lines.append(f"| {k} | {_cell(x)} | {_cell(y)} | {ratio} |")
        lines.append("")
    head = f"| goal (issue 32) | at most | this tree |{f' {label} |' if ref is not None else ''}"
    lines += [head, "|---|---|---|" + ("---|" if ref is not None else "")]
    for g in GOALS:
        row = f"| {g.what} | {g.limit:g} {g.unit} | {_verdict(g, g.value(fig))} |"
        if ref is not None:
            row += f" {_verdict(g, g.value(ref))} |"
        lines.append(row)
    if max(fig.get("load", [0.0])) > 0.5:
        lines += ["", "(the machine was not idle: a time goal is judged on an idle machine)"]
    return "\n".join(lines)
