"""Benchmark: the times the README states, as the commands print them, into
``docs/measurements.toml`` (``tests/unit/test_measurements.py`` holds the README to it).

Usage::

    MUJOCO_GL=egl .venv/bin/python -m selfcal.benchmarks.speed.times tests       # uv run pytest -q
    MUJOCO_GL=egl .venv/bin/python -m selfcal.benchmarks.speed.times first-run   # selfcal run, twice

- ``tests``: the default tier (``pytest -q``): the seconds pytest prints on its last line, the
  CPU seconds (user + system) of pytest and its workers (which a shared machine's load inflates
  far less than the wall seconds) and the numbers of tests passed and failed (the failures are
  printed; a time is a time either way).
- ``first-run``: ``selfcal run`` of the default scenario into a new folder with an empty Python
  bytecode cache (``PYTHONPYCACHEPREFIX`` pointing at a new folder: every module compiled afresh,
  as after an install), then again into another new folder with that cache filled: the total
  each run prints ("total X s": acquisition, calibration, report) and the wall time of each
  command (process start to exit, imports included).

Each records the machine (CPU count, 1-minute load average before the run: the machines are
shared) beside its numbers and leaves the other section of the file as it is.
"""

from __future__ import annotations

import datetime
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.io.atomic import write_text_atomic
from selfcal.tomlfile import read_toml

__all__ = ["measure_tests", "measure_first_run", "MEASUREMENTS"]

ROOT = Path(__file__).resolve().parents[3]
MEASUREMENTS = ROOT / "docs" / "measurements.toml"
_PYTEST_LINE = re.compile(r"(?:(\d+) failed, )?(\d+) passed.* in ([\d.]+)s")
_RUN_TOTAL = re.compile(r"total ([\d.]+) s")


def _machine() -> dict:
    return {
        "cpus": os.cpu_count() or 1,
        "load_1min_before": round(os.getloadavg()[0], 1),
        "date": datetime.date.today().isoformat(),
    }


def measure_tests() -> dict:
    """Run the default tier (``pytest -q``) and return what its last line says."""
    machine = _machine()
    cpu0 = _children_cpu_s()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"],
                          cwd=ROOT, capture_output=True, text=True, check=False)  # fmt: skip
    cpu_s = _children_cpu_s() - cpu0
    last = [ln for ln in done.stdout.splitlines() if _PYTEST_LINE.search(ln)]
    if not last:
        raise SystemExit(f"pytest did not finish (exit {done.returncode}):\n{done.stdout[-3000:]}")
    m = _PYTEST_LINE.search(last[-1])
    assert m is not None
    failed = [ln for ln in done.stdout.splitlines() if ln.startswith("FAILED ")]
    print("\n".join(failed) or "all passed")
    return {"command": "uv run pytest", "passed": int(m.group(2)), "failed": int(m.group(1) or 0),
            "seconds": float(m.group(3)), "cpu_seconds": round(cpu_s, 1), **machine}  # fmt: skip


def _children_cpu_s() -> float:
    """CPU seconds (user + system) of this process's finished children and theirs (pytest's
    xdist workers are its children)."""
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def _run(out: Path, cache: Path) -> tuple[float, float]:
    env = {**os.environ, "PYTHONPYCACHEPREFIX": str(cache)}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "selfcal.cli.main", "run", "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, env=env, check=False)  # fmt: skip
    wall = time.perf_counter() - t0
    m = _RUN_TOTAL.search(done.stdout)
    if done.returncode != 0 or m is None:
        raise SystemExit(f"selfcal run failed (exit {done.returncode}):\n{done.stderr[-3000:]}")
    return float(m.group(1)), wall


def measure_first_run() -> dict:
    """``selfcal run`` with an empty bytecode cache, then with it filled (module docstring)."""
    machine = _machine()
    with tempfile.TemporaryDirectory(prefix="selfcal-first-run-") as tmp:
        first = _run(Path(tmp) / "first", Path(tmp) / "pycache")
        second = _run(Path(tmp) / "second", Path(tmp) / "pycache")
    return {
        "command": "uv run selfcal run",
        "first_printed_total_s": round(first[0], 1),
        "first_wall_s": round(first[1], 1),
        "second_printed_total_s": round(second[0], 1),
        "second_wall_s": round(second[1], 1),
        **machine,
    }


def _toml_value(v: object) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(v)


def write(sections: dict[str, dict], path: Path = MEASUREMENTS) -> Path:
    """Write ``sections`` (flat tables of str, int, float) as ``path``."""
    lines = ["# Written by `python -m selfcal.benchmarks.speed.times tests|first-run`; do not edit.",
             "# The README's stated times are checked against it (tests/unit/test_measurements.py)."]  # fmt: skip
    for name, table in sections.items():
        lines += ["", f"[{name}]"] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return write_text_atomic(path, "\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> None:
    p = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=("tests", "first-run"))
    args = p.parse_args(argv)
    sections = read_toml(MEASUREMENTS) if MEASUREMENTS.is_file() else {}
    if args.what == "tests":
        sections["tests"] = measure_tests()
    else:
        sections["first_run"] = measure_first_run()
    print(f"{args.what}: {sections['tests' if args.what == 'tests' else 'first_run']}")
    print(f"written: {write(sections)}")


if __name__ == "__main__":
    main()
