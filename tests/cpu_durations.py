"""Where a test run's CPU goes: ``uv run pytest --cpu-durations DIR`` writes each test phase's
CPU seconds to ``DIR/<worker>-<pid>.jsonl`` (this process's ``process_time`` plus the child
processes it reaped meanwhile), and ``uv run python tests/cpu_durations.py DIR`` sums them by
module and by test.

pytest's ``--durations`` are wall seconds, which the load of a shared machine inflates several
times over (the default tier: 1094 wall against 249 CPU s summed over its tests, load 6-8); CPU
seconds rank the same tests under load as idle, so a change's gain can be measured on a busy
machine. A test module's total counts: forty tests of one second cost as much as one of forty.
Loaded by tests/conftest.py (``pytest_plugins``)."""

from __future__ import annotations

import argparse
import json
import os
import resource
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

PHASES = ("setup", "call", "teardown")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--cpu-durations",
        metavar="DIR",
        help="write each test phase's CPU seconds to DIR/*.jsonl "
        "(summed by `uv run python tests/cpu_durations.py DIR`)",
    )


def _cpu_s() -> float:
    """This process's CPU seconds and those of its reaped children."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


_out: dict[str, object] = {}


def _record(item: pytest.Item, phase: str, cpu_s: float, wall_s: float) -> None:
    folder = item.config.getoption("--cpu-durations")
    if "file" not in _out:
        Path(folder).mkdir(parents=True, exist_ok=True)
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        _out["file"] = open(Path(folder) / f"{worker}-{os.getpid()}.jsonl", "a")  # noqa: SIM115
    f = _out["file"]
    assert hasattr(f, "write")
    line = {"id": item.nodeid, "phase": phase, "cpu_s": cpu_s, "wall_s": wall_s}
    f.write(json.dumps(line) + "\n")
    f.flush()


def _measured(item: pytest.Item, phase: str) -> Iterator[None]:
    if not item.config.getoption("--cpu-durations"):
        yield
        return
    cpu0, wall0 = _cpu_s(), time.perf_counter()
    yield
    _record(item, phase, _cpu_s() - cpu0, time.perf_counter() - wall0)


def pytest_unconfigure(config: pytest.Config) -> None:
    """The process's file closed (open at exit, Python warned "unclosed file" in a ``-n 0``
    run)."""
    f = _out.pop("file", None)
    if f is not None and hasattr(f, "close"):
        f.close()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Iterator[None]:
    yield from _measured(item, "setup")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    yield from _measured(item, "call")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item: pytest.Item) -> Iterator[None]:
    yield from _measured(item, "teardown")


def summary(folder: Path, top: int = 40) -> str:
    """The run in ``folder``: total CPU and wall seconds, by phase, the ``top`` modules by CPU
    seconds (with their test counts) and the ``top`` test phases."""
    rows = [
        json.loads(line)
        for f in sorted(folder.glob("*.jsonl"))
        for line in f.read_text().splitlines()
    ]
    if not rows:
        raise SystemExit(f"{folder}: no *.jsonl; run pytest --cpu-durations {folder} first")
    by_phase, modules, tests, wall = Counter(), Counter(), Counter(), Counter()
    count: Counter[str] = Counter()
    for r in rows:
        module = r["id"].split("::")[0]
        by_phase[r["phase"]] += r["cpu_s"]
        modules[module] += r["cpu_s"]
        wall[module] += r["wall_s"]
        count[module] += r["phase"] == "call"
        tests[f"{r['id']} [{r['phase']}]"] += r["cpu_s"]
    lines = [
        f"{sum(count.values())} tests: {sum(by_phase.values()):.1f} CPU s "
        f"({', '.join(f'{p} {by_phase[p]:.1f}' for p in PHASES)}), "
        f"{sum(wall.values()):.1f} wall s",
        f"modules by CPU s (CPU s, wall s, tests), top {top}:",
        *(f"{c:7.1f} {wall[m]:7.1f} {count[m]:4d}  {m}" for m, c in modules.most_common(top)),
        f"test phases by CPU s, top {top}:",
        *(f"{c:7.2f}  {t}" for t, c in tests.most_common(top)),
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path, help="the --cpu-durations folder of one run")
    ap.add_argument("--top", type=int, default=40, help="how many modules and test phases")
    args = ap.parse_args()
    print(summary(args.folder, args.top))
