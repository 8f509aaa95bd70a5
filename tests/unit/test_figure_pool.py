"""The report's figures drawn in a forked worker (scenarios/figure_pool.py) are the same files as
drawn in the process, its errors reach the caller, and a dead worker loses no figure."""

from __future__ import annotations

import os

import numpy as np
import pytest

from scenarios.figure_pool import FigurePool, fork_available
from scenarios.job_figures import tool_tip_figure

ERRORS = np.random.default_rng(3).normal(size=(2, 12, 3))


def _broken(_: int) -> None:
    raise ValueError("no data for this figure")


def _dies_in_worker(parent: int):
    if os.getpid() != parent:
        os._exit(3)  # the worker dies as if killed
    return tool_tip_figure(ERRORS[0], ERRORS[1])


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


@pytest.mark.parametrize("enabled", [True, False])
def test_an_error_in_a_figure_reaches_the_caller(tmp_path, enabled):
    with FigurePool(enabled) as pool:
        fig = pool.draw(_broken, (1,), tmp_path, "x.png")
        with pytest.raises(ValueError, match="no data for this figure"):
            fig.wait()
    assert not (tmp_path / "figures" / "x.png").exists()


@pytest.mark.skipif(not fork_available(), reason="no fork on this platform")
def test_a_dead_worker_loses_no_figure(tmp_path):
    with FigurePool() as pool:
        fig = pool.draw(_dies_in_worker, (os.getpid(),), tmp_path, "t.png")
        path = fig.wait()  # drawn here after the worker died
        assert path.is_file() and path.stat().st_size > 1000
        later = pool.draw(tool_tip_figure, (ERRORS[0], ERRORS[1]), tmp_path, "u.png")
        assert later.wait().is_file()  # and the figures after it are drawn here too
