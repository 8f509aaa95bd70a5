"""A small progress bar for the command line (stderr), silent when not a terminal unless asked;
and :class:`TaskCounts`, the state of a batch of tasks (done / total, running, failed, time left)."""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["Progress", "TaskCounts"]


class Progress:
    """Progress of one stage: ``start(total)``, ``advance()``, ``finish()``.

    Draws a bar on a terminal; elsewhere prints one line at the end of stages that took over a second.
    """

    def __init__(self, label: str, stream: TextIO | None = None, enabled: bool = True) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.total = 0
        self.done = 0
        self.t0 = time.perf_counter()

    def start(self, total: int, done: int = 0) -> None:
        self.total, self.done, self.t0 = total, done, time.perf_counter()
        self._draw()

    def advance(self, k: int = 1) -> None:
        self.done += k
        self._draw()

    def _draw(self) -> None:
        if not self.tty or self.total <= 0:
            return
        width = 30
        fill = int(width * self.done / self.total)
        dt = time.perf_counter() - self.t0
        self.stream.write(
            f"\r{self.label:<12} [{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {dt:5.1f}s"
        )
        self.stream.flush()

    def finish(self) -> None:
        dt = time.perf_counter() - self.t0
        if self.tty:
            self._draw()
            self.stream.write("\n")
        elif self.enabled and dt > 1.0:
            self.stream.write(f"{self.label}: {self.done}/{self.total} in {dt:.1f} s\n")
        self.stream.flush()


class TaskCounts:
    """Counts of a batch of ``total`` tasks run by worker processes (studies, Monte Carlo).

    ``finish(failed=...)`` when a task's result arrives; ``running`` is set by the runner (tasks on
    the workers now). :meth:`line` is the state as text, with the time left estimated from the mean
    wall time per task finished so far in this batch.
    """

    def __init__(self, total: int) -> None:
        self.total = total
        self.done = 0
        self.failed = 0
        self.running = 0
        self.t0 = time.perf_counter()

    def finish(self, failed: bool = False) -> None:
        """One more task finished (``failed``: its result is an error)."""
        self.done += 1
        self.failed += int(failed)

    def seconds_left(self) -> float | None:
        """Estimated wall time until the batch is done (s); None before the first result."""
        if self.done == 0:
            return None
        return (time.perf_counter() - self.t0) / self.done * (self.total - self.done)

    def line(self) -> str:
        """E.g. ``"12/40 done, 2 running, 0 failed, ~31 s left"``."""
        left = self.seconds_left()
        eta = "" if left is None else f", ~{left:.0f} s left"
        return f"{self.done}/{self.total} done, {self.running} running, {self.failed} failed{eta}"
