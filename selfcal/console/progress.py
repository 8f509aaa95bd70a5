"""Progress on the command line: the one mechanism for every step that can take more than a
couple of seconds (render, detect, the calibration stages, homing and moving the robot,
acquisition, studies and Monte Carlo).

- :class:`Progress` -- a counted stage (``start(total)``, ``advance(note=...)``, ``finish()``):
  a bar with done/total, elapsed time and time left on stderr when it is a terminal, drawn by
  `rich <https://rich.readthedocs.io>`_ (``rich.progress``; imported when a bar is first drawn,
  never when the command line is parsed); elsewhere one line at the end of a stage that took
  over a second. Notes (a finished study run, say) are printed as lines above the bar.
  ``step(label)`` is a stage of one piece (a calibration stage, homing): a ``rich`` spinner with
  ``label ...`` while it runs, then ``label: <result> (1.2 s)``.
- :class:`TaskCounts` -- the state of a batch of tasks on worker processes (done / total,
  running, failed, time left); a :class:`Progress` of a batch shows it.

Off with ``enabled=False`` (``-q``). Progress writes to stderr only, so stdout keeps the results.
The bar is redrawn when a piece is done (no drawing thread: a stage an error ends leaves no
display running over the error message).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:  # rich: imported when a bar is drawn (_start_bar)
    from rich.progress import Progress as RichProgress
    from rich.progress import TaskID

__all__ = ["Progress", "Step", "TaskCounts", "format_seconds"]

CLEAR = "\r\033[K"
"""Carriage return and erase-to-end-of-line: a bar is redrawn in place."""


def format_seconds(s: float) -> str:
    """``"42 s"``, ``"3 min 05 s"``: a duration for people."""
    if s < 60:
        return f"{s:.0f} s"
    m, sec = divmod(int(round(s)), 60)
    return f"{m} min {sec:02d} s"


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


class Step:
    """A running :meth:`Progress.step`: :meth:`result` sets the text shown when it ends (e.g.
    the stage's cost)."""

    def __init__(self) -> None:
        self.text = "done"

    def result(self, text: str) -> None:
        """What the step achieved, e.g. ``"reprojection RMS 0.41 px"``."""
        self.text = text


class Progress:
    """Progress of one stage: ``start(total)``, ``advance()``, ``finish()``; or ``step(label)``.

    Draws a ``rich`` bar on a terminal; elsewhere prints one line at the end of stages that took
    over a second. ``counts``: the batch's :class:`TaskCounts` (its running and failed tasks and
    its time left are shown).
    """

    def __init__(
        self,
        label: str,
        stream: TextIO | None = None,
        enabled: bool = True,
        counts: TaskCounts | None = None,
    ) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.counts = counts
        self.total = 0
        self.done = 0
        self.t0 = time.perf_counter()
        self.start_done = 0
        # the rich.progress.Progress of a counted stage on a terminal
        self._bar: RichProgress | None = None
        self._task: TaskID | None = None

    # ----------------------------------------------------------------- counted stages
    def start(self, total: int, done: int = 0) -> None:
        """A stage of ``total`` pieces, ``done`` of them already (a resumed acquisition)."""
        self.total, self.done, self.t0 = total, done, time.perf_counter()
        self.start_done = done
        if self.tty and total > 0:
            self._start_bar()
        self._draw()

    def advance(self, k: int = 1, note: str | None = None) -> None:
        """``k`` more pieces done; ``note``: a line to print above the bar (or alone)."""
        self.done += k
        if note is not None and self.enabled:
            if self._bar is not None:
                self._bar.console.print(f"  {note}", markup=False, highlight=False)
            else:
                if self.tty:
                    self.stream.write(CLEAR)
                prefix = "" if self.tty or self.counts is None else f"[{self.counts.line()}] "
                self.stream.write(f"  {prefix}{note}\n")
        self._draw()

    def seconds_left(self) -> float | None:
        """Time left (s) from the pace so far in this stage; None before the first piece."""
        if self.counts is not None:
            return self.counts.seconds_left()
        new = self.done - self.start_done
        if new <= 0:
            return None
        return (time.perf_counter() - self.t0) / new * (self.total - self.done)

    def state(self) -> str:
        """The text beside the bar: elapsed time, the batch's running and failed tasks, the time
        left, e.g. ``"3.1 s, 2 running, 0 failed, ~12 s left"``."""
        dt = time.perf_counter() - self.t0
        left = self.seconds_left()
        eta = "" if left is None or self.done >= self.total else f", ~{format_seconds(left)} left"
        extra = ""
        if self.counts is not None:
            extra = f", {self.counts.running} running, {self.counts.failed} failed"
        return f"{dt:5.1f} s{extra}{eta}"

    def _start_bar(self) -> None:
        """The ``rich`` bar of this stage on ``self.stream`` (rich imported here, not when the
        command line is parsed). Redrawn on every :meth:`advance` (no refresh thread), the
        cursor left visible."""
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, TextColumn
        from rich.progress import Progress as RichProgress

        console = Console(file=self.stream, force_terminal=True, highlight=False)
        bar = RichProgress(
            TextColumn("{task.description:<12}"),
            BarColumn(bar_width=30, complete_style="cyan", finished_style="green"),
            MofNCompleteColumn(),
            TextColumn("{task.fields[state]}"),
            console=console,
            auto_refresh=False,
            redirect_stdout=False,
            redirect_stderr=False,
        )
        self._task = bar.add_task(
            self.label, total=self.total, completed=self.done, state=self.state()
        )
        bar.start()
        console.show_cursor(True)
        self._bar = bar

    def _draw(self) -> None:
        if self._bar is None or self._task is None:
            return
        self._bar.update(self._task, completed=self.done, state=self.state(), refresh=True)

    def finish(self) -> None:
        """End the stage: the final bar on a terminal; elsewhere one line if it took > 1 s."""
        dt = time.perf_counter() - self.t0
        if self._bar is not None:
            self._draw()
            self._bar.stop()
            self._bar = None
        elif self.enabled and not self.tty and dt > 1.0:
            self.stream.write(f"{self.label}: {self.done}/{self.total} in {dt:.1f} s\n")
        self.stream.flush()

    # ----------------------------------------------------------------- one-piece steps
    @contextmanager
    def step(self, label: str) -> Iterator[Step]:
        """A stage of one piece (a calibration stage, homing the robot): a ``rich`` spinner and
        ``label ...`` on a terminal while it runs, then ``label: <result> (t s)``; elsewhere that
        line alone when it took over a second."""
        st = Step()
        t0 = time.perf_counter()
        status = None
        if self.tty:
            from rich.console import Console

            console = Console(file=self.stream, force_terminal=True, highlight=False)
            status = console.status(f"{label} ...")
            status.start()
        ok = False
        try:
            yield st
            ok = True
        finally:
            dt = time.perf_counter() - t0
            text = st.text if ok else "failed"
            if status is not None:
                status.stop()
                self.stream.write(f"{label}: {text} ({dt:.1f} s)\n")
            elif self.enabled and dt > 1.0:
                self.stream.write(f"{label}: {text} ({dt:.1f} s)\n")
            self.stream.flush()
