"""The report's figures drawn beside the rest of a run, in a forked worker process (issue 17).

Matplotlib costs ``selfcal run`` about 0.5 s to import and 0.7 s to draw the three figures, all
on the one core the run's Python code holds (threads would not help: drawing is Python code
under the GIL). :class:`FigurePool` forks one worker at the start of a run, before the
acquisition opens its GL context; the worker imports matplotlib and loads the fonts while the
parent acquires and calibrates, then draws each figure the report asks for while the parent
goes on with the report. The figures are the same files as when drawn in the process
(``tests/unit/test_figure_pool.py``).

Where ``fork`` is not the platform's way to start processes (macOS, Windows), or a worker dies,
the figures are drawn in the process as before: the pool only moves work, it never drops it.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from selfcal.plots.job_figures import write_figure

__all__ = ["FigurePool", "PendingFigure", "draw_figure", "fork_available"]

Builder = Callable[..., Any]
"""A module-level function returning a matplotlib Figure (``selfcal.plots.job_figures``)."""


def draw_figure(builder: Builder, args: tuple, root: str | Path, name: str) -> Path:
    """``write_figure(builder(*args), root, name)``: the figure ``root/figures/name``."""
    return write_figure(builder(*args), root, name)


def _warm_up(parent: int) -> None:
    """Worker start: ignore Ctrl-C (the parent handles it), end with the ``parent`` process
    (its pid, taken before the fork), import matplotlib's Agg canvas and load the default font,
    the part of a first figure that does not depend on its data."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)
    from selfcal.plots.plotting import new_figure

    fig = new_figure(1.0, 1.0)
    fig.text(0.5, 0.5, "0.1")
    fig.canvas.draw()


def _die_with_parent(parent: int) -> None:
    """Linux: the kernel ends this worker when the process ``parent`` that forked it dies
    without closing the pool (killed, crashed): an idle worker would otherwise wait forever,
    holding the run's stdout and stderr open (a ``| tee`` or a CI job would not see their end).
    ``parent`` is the pid the parent had before the fork: read in the worker, a parent killed
    before the read would already have left it to pid 1, which never dies."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent died before the call took effect
        os._exit(0)


def fork_available() -> bool:
    """Whether this platform starts processes by fork (Linux): else figures are drawn here."""
    return sys.platform.startswith("linux") and "fork" in mp.get_all_start_methods()


@dataclass
class PendingFigure:
    """A figure :meth:`FigurePool.draw` was asked for; :meth:`wait` gives its path."""

    builder: Builder
    args: tuple
    root: str | Path
    name: str
    future: Future[Path]

    def wait(self) -> Path:
        """The figure's path once written; re-raises the drawing's exception, and draws the
        figure in this process if the worker died."""
        try:
            return self.future.result()
        except BrokenProcessPool:
            return draw_figure(self.builder, self.args, self.root, self.name)


class FigurePool:
    """Draws figures in a forked worker process (``enabled`` and Linux), else in this process.

    Create it before any thread or GL context exists in the process (a fork copies the one
    thread that forks) and close it when done (a context manager). :meth:`draw` returns at once;
    the figure's :meth:`PendingFigure.wait` gives its path."""

    def __init__(self, enabled: bool = True) -> None:
        self._pool: ProcessPoolExecutor | None = None
        # a fork copies the calling thread alone: with others running, one may hold a lock
        if enabled and fork_available() and threading.active_count() == 1:
            sys.stdout.flush()  # a forked child would write the parent's buffered text again
            sys.stderr.flush()
            self._pool = ProcessPoolExecutor(
                max_workers=1,
                mp_context=mp.get_context("fork"),
                initializer=_warm_up,
                initargs=(os.getpid(),),
            )
            self._pool.submit(int)  # forks now, while this process has a single thread

    @property
    def forked(self) -> bool:
        """Whether figures go to a worker process."""
        return self._pool is not None

    def draw(self, builder: Builder, args: tuple, root: str | Path, name: str) -> PendingFigure:
        """Draw ``builder(*args)`` (``args`` picklable) into ``root/figures/name``: in the worker,
        or here and now without one."""
        if self._pool is not None:
            try:
                fut = self._pool.submit(draw_figure, builder, args, root, name)
                return PendingFigure(builder, args, root, name, fut)
            except BrokenProcessPool:
                self._pool.shutdown(wait=False)
                self._pool = None
        done: Future[Path] = Future()
        try:
            done.set_result(draw_figure(builder, args, root, name))
        except Exception as exc:  # noqa: BLE001 - raised again by PendingFigure.wait
            done.set_exception(exc)
        return PendingFigure(builder, args, root, name, done)

    def close(self) -> None:
        """Wait for the figures asked for and stop the worker (idempotent)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> FigurePool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
