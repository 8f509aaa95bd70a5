"""A command's own exit code, wall time and peak memory, measured from a small launcher process.

Linux carries a process's resident set at ``fork`` into its child's ``ru_maxrss`` across
``exec``: a command started straight from a benchmark that has grown to hundreds of MB (its
in-process calibrations, a bag it wrote) would report at least the benchmark's size. A small
launcher process forks and execs the command instead, so the floor is the launcher's ~10 MB;
it also times the command from its fork to its exit (the launcher's own start-up left out).
The speed benchmark (:mod:`selfcal.benchmarks.speed.measure`) and the bag import benchmark
(:mod:`selfcal.benchmarks.timing.ros`) measure their commands with it.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ChildUsage", "child_usage", "run_child"]

# argv[1]: the stderr file ("" for none); argv[2:]: the command. Prints "code peak-kB wall-s
# user-s sys-s".
_LAUNCHER = (
    "import os, sys, time\n"
    "t = time.perf_counter()\n"
    "pid = os.fork()\n"
    "if pid == 0:\n"
    "    fd = os.open(os.devnull, os.O_WRONLY); os.dup2(fd, 1)\n"
    "    if sys.argv[1]:\n"
    "        fd = os.open(sys.argv[1], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)\n"
    "    os.dup2(fd, 2)\n"
    "    os.execvp(sys.argv[2], sys.argv[2:])\n"
    "_, status, usage = os.wait4(pid, 0)\n"
    "print(os.waitstatus_to_exitcode(status), usage.ru_maxrss, time.perf_counter() - t,\n"
    "      usage.ru_utime, usage.ru_stime)\n"
)


@dataclass(frozen=True)
class ChildUsage:
    """What :func:`child_usage` measured of a command: its exit ``code``, ``wall`` s from its
    fork to its exit, its ``peak_mb`` resident set (MB) and its ``user`` and ``system`` CPU
    seconds (its own and its waited-for children's)."""

    code: int
    wall: float
    peak_mb: float
    user: float
    system: float

    @property
    def cpu(self) -> float:
        """User + system CPU seconds."""
        return self.user + self.system


def child_usage(argv: list[str], *, stderr: Path | None = None) -> ChildUsage:
    """The command ``argv`` run from the launcher (module docstring), its standard output
    thrown away and its standard error written to ``stderr`` (thrown away when None)."""
    done = subprocess.run([sys.executable, "-c", _LAUNCHER, "" if stderr is None else str(stderr),
                           *argv], check=True, capture_output=True, text=True)  # fmt: skip
    code, kb, wall, user, system = done.stdout.split()
    return ChildUsage(int(code), float(wall), int(kb) / 1024, float(user), float(system))


def run_child(argv: list[str], *, stderr: Path | None = None) -> tuple[int, float, float]:
    """``(exit code, wall time s, peak resident set MB)`` of the command ``argv`` (Linux
    ``ru_maxrss``; :func:`child_usage`), its standard output thrown away and its standard error
    written to ``stderr`` (thrown away when None)."""
    u = child_usage(argv, stderr=stderr)
    return u.code, u.wall, u.peak_mb
