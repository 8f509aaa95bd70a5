"""The report's figures drawn in a forked worker (selfcal/plots/figure_pool.py) are the same files as
drawn in the process, its errors reach the caller, and a dead worker loses no figure."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest

from selfcal.plots.figure_pool import FigurePool, fork_available
from selfcal.plots.job_figures import tool_tip_figure
from selfcal.plots.plotting import new_figure

ERRORS = np.random.default_rng(3).normal(size=(2, 12, 3))


def _small(k: int):
    """A figure a tenth of tool_tip_figure's drawing time (0.06 against 0.37 s), where which
    figure does not matter: a line through the data point ``k``."""
    fig = new_figure(2.0, 2.0)
    fig.add_subplot().plot([0.0, 1.0], [0.0, float(k)])
    return fig


@pytest.fixture(scope="module", autouse=True)
def _matplotlib_loaded() -> None:
    """matplotlib imported and its font loaded once in this process: each worker a test forks
    inherits them, where it paid the import again (0.5 s idle, 2 s on 2 loaded cores)."""
    _small(0).canvas.draw()


def _broken(_: int) -> None:
    raise ValueError("no data for this figure")


def _fails_in_a_forked_drawer(parent: int):
    if os.getppid() != parent:  # not the worker (the test's child): a drawer the worker forked
        raise RuntimeError("this drawer fails")
    return _small(1)


def _dies_in_worker(parent: int):
    if os.getpid() != parent:
        os._exit(3)  # the worker dies as if killed
    return tool_tip_figure(ERRORS[0], ERRORS[1])


@pytest.mark.slow  # over 2 s on 2 cores: the default tier keeps to ~90 s
@pytest.mark.skipif(not fork_available(), reason="no fork on this platform")
def test_the_worker_draws_the_same_file_as_the_process(tmp_path):
    with FigurePool() as pool:
        assert pool.forked
        forked = pool.draw(tool_tip_figure, (ERRORS[0], ERRORS[1]), tmp_path / "a", "t.png")
        assert forked.wait() == tmp_path / "a" / "figures" / "t.png"
    here = FigurePool(enabled=False).draw(tool_tip_figure, (ERRORS[0], ERRORS[1]),
                                          tmp_path / "b", "t.png")  # fmt: skip
    assert here.future.done()  # drawn at once, in this process
    assert forked.wait().read_bytes() == here.wait().read_bytes()


@pytest.mark.slow  # over 2 s on 2 cores
@pytest.mark.skipif(not fork_available(), reason="no fork on this platform")
def test_figures_drawn_side_by_side_are_the_files_drawn_one_by_one(tmp_path):
    """draw_all: the worker draws the first figure and forks a drawer for each other (#32)."""
    jobs = [(tool_tip_figure, (ERRORS[0], ERRORS[k]), tmp_path / "a", f"t{k}.png") for k in (0, 1)]
    with FigurePool() as pool:
        side = [f.wait() for f in pool.draw_all(jobs)]
    assert side == [tmp_path / "a" / "figures" / f"t{k}.png" for k in (0, 1)]
    alone = [f.wait() for f in FigurePool(enabled=False).draw_all([(*j[:2], tmp_path / "b", j[3])
                                                                     for j in jobs])]  # fmt: skip
    assert [p.read_bytes() for p in side] == [p.read_bytes() for p in alone]
    assert side[0].read_bytes() != side[1].read_bytes()  # each job drew its own data


@pytest.mark.skipif(not fork_available(), reason="no fork on this platform")
def test_a_figure_whose_drawer_failed_is_drawn_again_by_the_worker(tmp_path):
    with FigurePool() as pool:
        figs = pool.draw_all([(_small, (0,), tmp_path, "a.png"),
                              (_fails_in_a_forked_drawer, (os.getpid(),), tmp_path, "b.png")])  # fmt: skip
        assert [f.wait().name for f in figs] == ["a.png", "b.png"]
    assert (tmp_path / "figures" / "b.png").stat().st_size > 1000


@pytest.mark.parametrize("enabled", [True, False])
def test_an_error_in_one_of_several_figures_reaches_the_caller(tmp_path, enabled):
    with FigurePool(enabled) as pool:
        figs = pool.draw_all([(_small, (0,), tmp_path, "t.png"),
                              (_broken, (1,), tmp_path, "x.png")])  # fmt: skip
        with pytest.raises(ValueError, match="no data for this figure"):
            figs[1].wait()
    assert not (tmp_path / "figures" / "x.png").exists()


@pytest.mark.parametrize("enabled", [True, False])
def test_an_error_in_a_figure_reaches_the_caller(tmp_path, enabled):
    with FigurePool(enabled) as pool:
        fig = pool.draw(_broken, (1,), tmp_path, "x.png")
        with pytest.raises(ValueError, match="no data for this figure"):
            fig.wait()
    assert not (tmp_path / "figures" / "x.png").exists()


@pytest.mark.slow
@pytest.mark.skipif(not fork_available(), reason="no fork on this platform")
def test_a_dead_worker_loses_no_figure(tmp_path):
    with FigurePool() as pool:
        fig = pool.draw(_dies_in_worker, (os.getpid(),), tmp_path, "t.png")
        path = fig.wait()  # drawn here after the worker died
        assert path.is_file() and path.stat().st_size > 1000
        later = pool.draw(tool_tip_figure, (ERRORS[0], ERRORS[1]), tmp_path, "u.png")
        assert later.wait().is_file()  # and the figures after it are drawn here too


def test_the_worker_writes_no_set_docstrings_and_set_still_works():
    """The worker's matplotlib (selfcal.plots.figure_pool._skip_set_docstrings, before its
    artists load) writes no property table into ``set()``'s docstring, the import CPU it
    saves; ``set()`` and its signature are as before. In a new process: this one has its
    artists loaded."""
    code = (
        "import inspect\n"
        "from selfcal.plots.figure_pool import _skip_set_docstrings\n"
        "_skip_set_docstrings()\n"
        "from matplotlib.lines import Line2D\n"
        "line = Line2D([0.0], [0.0])\n"
        "line.set(color='r', linewidth=3.0)\n"
        "assert (line.get_color(), line.get_linewidth()) == ('r', 3.0)\n"
        "assert 'linewidth' in inspect.signature(Line2D.set).parameters\n"
        "assert 'drawstyle' not in Line2D.set.__doc__, Line2D.set.__doc__\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_the_worker_ends_with_a_killed_parent():
    """An idle worker of a parent killed before it closed the pool ends too (it held the
    parent's stdout open: a `| tee` would wait forever)."""
    code = (
        "import os, signal\n"
        "from selfcal.plots.figure_pool import FigurePool\n"
        "pool = FigurePool()\n"
        "print(*pool._pool._processes, flush=True)\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    pids = [int(p) for p in out.stdout.split()]
    assert pids, out.stderr
    deadline = time.monotonic() + 10.0
    alive = pids
    while alive and time.monotonic() < deadline:
        time.sleep(0.1)
        alive = [p for p in pids if _running(p)]
    assert not alive, f"worker(s) {alive} outlived the killed parent"


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie waiting for its reaper has ended
        return f.read().split(") ")[-1][0] != "Z"
