"""The report's figures drawn beside the rest of a run, in a forked worker process (issue 17).

Matplotlib costs ``selfcal run`` about 0.5 s to import and 0.5-0.7 s to draw the three figures,
all Python code under the GIL (threads would not help). :class:`FigurePool` forks one worker
early in a run: ``selfcal run`` forks it before it imports the acquisition and the calibration
(:func:`selfcal.pipeline.run.run_figure_pool`), so the worker imports matplotlib and loads the
fonts on the other core while the parent imports, and not during the acquisition, which keeps
both cores busy. The figures the report asks for at once (:meth:`FigurePool.draw_all`) are
drawn side by side: the worker draws the first and forks, matplotlib loaded, one process for
each other figure (issue 32: the run waited 0.85 s for three figures drawn one after another).
The figures are the same files as when drawn in the process (``tests/unit/test_figure_pool.py``).

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
from typing import TYPE_CHECKING, Any

from selfcal.plots.job_figures import FIGURES, write_figure

if TYPE_CHECKING:
    from selfcal.config.scenario import Scenario

__all__ = [
    "FigurePool",
    "PendingFigure",
    "draw_figure",
    "draw_figures",
    "fork_available",
    "run_figure_pool",
]

Builder = Callable[..., Any]
"""A module-level function returning a matplotlib Figure (``selfcal.plots.job_figures``)."""

Job = tuple[Builder, tuple, "str | Path", str]
"""One figure to draw: ``(builder, args, root, name)`` as :func:`draw_figure` takes them."""


def draw_figure(builder: Builder, args: tuple, root: str | Path, name: str) -> Path:
    """``write_figure(builder(*args), root, name)``: the figure ``root/figures/name``."""
    return write_figure(builder(*args), root, name)


def draw_figures(jobs: list[Job]) -> list[Path]:
    """:func:`draw_figure` of every job, side by side on a multi-core machine: the first here,
    each other in a process forked from this one (the pool's worker has matplotlib loaded, so a
    fork starts drawing at once; only where this process has a single thread, else one after
    another here). A job whose process failed is drawn here again, so that its exception is
    raised here; each file is written atomically, a failed process leaves none."""
    forked: dict[int, int] = {}  # job index -> pid
    if (len(jobs) > 1 and (os.cpu_count() or 1) > 1 and fork_available()
            and threading.active_count() == 1):  # fmt: skip
        sys.stdout.flush()
        sys.stderr.flush()
        me = os.getpid()
        for k in range(1, len(jobs)):
            pid = os.fork()
            if pid == 0:  # the child: one figure, then leave without running any cleanup
                code = 1
                try:
                    _die_with_parent(me)
                    draw_figure(*jobs[k])
                    code = 0
                finally:
                    os._exit(code)
            forked[k] = pid
    paths: dict[int, Path] = {}
    try:
        for k in range(len(jobs)):
            if k not in forked:
                paths[k] = draw_figure(*jobs[k])
    finally:  # every child reaped, also when a figure here failed
        codes = {k: os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) for k, pid in forked.items()}
    for k, code in codes.items():
        root, name = jobs[k][2], jobs[k][3]
        paths[k] = Path(root) / FIGURES / name if code == 0 else draw_figure(*jobs[k])
    return [paths[k] for k in range(len(jobs))]


def _warm_up(parent: int) -> None:
    """Worker start: ignore Ctrl-C (the parent handles it), end with the ``parent`` process
    (its pid, taken before the fork), import matplotlib's Agg canvas and the figures' module,
    and draw :func:`_first_figure`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)
    _skip_set_docstrings()
    import selfcal.plots.job_figures  # noqa: F401 - unpickles the figures' data

    _first_figure()


def _first_figure() -> None:
    """A small figure with the parts of the report's figures (:mod:`selfcal.plots.job_figures`)
    whose first drawing in a process costs more than the next: the fonts at their sizes (tick
    labels, 8 pt legend and rotated names, titles), the log axis' locators and formatter, bars,
    a histogram, a legend beside the axes, the fixed layout and a PNG encoded (the encoder
    loads at the first), written nowhere. Drawn in the worker while the run starts,
    before the figures are asked for: each drawer it forks for them paid these again, at the
    end of the run. The files are the same (``tests/unit/test_figure_pool.py``)."""
    from selfcal.plots.plotting import (
        figure_png,
        legend_outside,
        log_y,
        new_figure,
        stack_layout,
    )

    fig = new_figure(2.0, 2.0)
    ax = fig.subplots(1, 1)
    ax.bar([1.0], [1.0], 0.3, color="0.55", label="0.1")
    ax.plot([0.0, 1.0], [1.0, 2.0], "s", ms=4, label="a")
    ax.hist([0.1, 0.2], bins=[0.0, 0.5], histtype="stepfilled", alpha=0.25)
    log_y(ax)
    ax.set_xticks([0.0, 1.0], ["lx0", "ly1"], rotation=90, fontsize=8)
    ax.set(xlabel="x (mm)", ylabel="y (px)")
    ax.set_title("(a)", y=1.0)
    ax.grid(alpha=0.3, which="both")
    legend_outside(ax)
    fig.suptitle("0.1", y=0.99, va="top")
    stack_layout(fig)
    figure_png(fig)


def _skip_set_docstrings() -> None:
    """In the worker, before matplotlib's artists load: every ``Artist`` subclass writes the
    docstring of its ``set()`` when it is defined (``matplotlib.artist.kwdoc``, the property
    table ``help()`` shows), 0.12 of the 0.6 s CPU that loading matplotlib and the font took
    the worker (2 loaded cores). The worker only draws and never shows a docstring: here
    ``kwdoc`` writes none. ``set()`` itself, its signature and every drawing are unchanged (the
    same files: ``tests/unit/test_figure_pool.py``). Artists already loaded (a test process
    that forks the worker) keep theirs; without ``kwdoc`` (another matplotlib) nothing
    changes."""
    try:
        import matplotlib.artist as artist  # loads no artist subclass yet
    except ImportError:  # pragma: no cover - matplotlib is a dependency
        return
    if callable(getattr(artist, "kwdoc", None)):
        artist.kwdoc = _no_kwdoc


def _no_kwdoc(artist: object) -> str:
    """``matplotlib.artist.kwdoc`` in the figure worker: no property table."""
    return ""


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
    """A figure :meth:`FigurePool.draw` or :meth:`FigurePool.draw_all` was asked for;
    :meth:`wait` gives its path. ``index``: its place in the paths of a batch's ``future``
    (:func:`draw_figures`), None when the future gives this figure's path alone."""

    builder: Builder
    args: tuple
    root: str | Path
    name: str
    future: Future[Any]
    index: int | None = None

    def wait(self) -> Path:
        """The figure's path once written; re-raises the drawing's exception, and draws the
        figure in this process if the worker died."""
        try:
            done = self.future.result()
        except BrokenProcessPool:
            return draw_figure(self.builder, self.args, self.root, self.name)
        return done if self.index is None else done[self.index]


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

    def draw_all(self, jobs: list[Job]) -> list[PendingFigure]:
        """:meth:`draw` of every job, drawn side by side in the worker and processes it forks
        (:func:`draw_figures`); without a worker here and now, one after another. An error in
        one figure is raised by each figure's :meth:`PendingFigure.wait` (all or none)."""
        if self._pool is not None:
            try:
                fut = self._pool.submit(draw_figures, list(jobs))
                return [PendingFigure(*job, future=fut, index=k) for k, job in enumerate(jobs)]
            except BrokenProcessPool:
                self._pool.shutdown(wait=False)
                self._pool = None
        return [self.draw(*job) for job in jobs]

    def close(self) -> None:
        """Wait for the figures asked for and stop the worker (idempotent)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> FigurePool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_figure_pool(s: Scenario, figures: bool = True) -> FigurePool:
    """The pool :func:`selfcal.pipeline.run.run_all` draws the report's figures in: a worker
    for a simulated run of the field route (its report draws three figures), else none (the
    other routes draw in the process). The worker forks now: call it before any thread or GL
    context exists, and early (``selfcal run`` calls it before it imports the acquisition and
    the calibration, 0.7 s on one core, so the worker loads matplotlib on the other)."""
    return FigurePool(enabled=figures and s.robot.backend == "sim" and not s.target.board)
