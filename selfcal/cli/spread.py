"""``selfcal calibrate --spread N [--seed S] [--jobs J]``: the board calibration's run-to-run
spread over refits of resampled arm configurations (issue #29;
:mod:`selfcal.calibration.board.bootstrap`, run by :mod:`selfcal.pipeline.board_spread`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

from selfcal.console.common import CliError

if TYPE_CHECKING:
    from selfcal.console.progress import TaskCounts
    from selfcal.pipeline.board_spread import BootstrapRun

__all__ = ["add_spread_args", "bootstrap_option"]


def add_spread_args(sp: argparse.ArgumentParser) -> None:
    """``selfcal calibrate``'s ``--spread``, ``--seed`` and ``--jobs``."""
    sp.add_argument(
        "--spread",
        type=int,
        default=0,
        metavar="N",
        help="a board dataset: also the tool point's run-to-run spread over N refits, each of "
        "the arm configurations resampled with replacement (a bootstrap; N fits more, e.g. 20) "
        "with the model selection held (every refit fits the calibration's chosen kinematic "
        "parameters): the estimation spread of the chosen model over resampled configurations, "
        "mm over the workspace's regions in calibration.json accuracy.bootstrap_spread beside "
        "the folds' jackknife, DIR/figures/spread.png (1.2-1.6x the predicted RMS error on 15 "
        "configurations, 1.1-1.3x on 30: docs/tool-accuracy.md)",
    )
    sp.add_argument("--seed", type=int, default=0,
                    help="with --spread: the resamples' seed (default 0; the same seed gives "
                    "the same spread, whatever the order of the dataset's frames)")  # fmt: skip
    sp.add_argument("--jobs", type=int, default=None, metavar="J",
                    help="with --spread: worker processes for the refits (default: the cores "
                    "this process may use, at most N; 1 = in this process)")  # fmt: skip


def bootstrap_option(args: argparse.Namespace) -> BootstrapRun | None:
    """The bootstrap ``args`` ask for (None without ``--spread``), its refits on ``--jobs``
    worker processes.

    Raises:
        CliError: ``--spread`` below 2 (but 0), ``--jobs`` below 1, or ``--seed`` / ``--jobs``
            without ``--spread``.
    """
    n = int(getattr(args, "spread", 0) or 0)
    seed, jobs = getattr(args, "seed", 0), getattr(args, "jobs", None)
    if n == 0:
        if seed != 0 or jobs is not None:
            raise CliError("--seed and --jobs apply to --spread N", fix="add --spread 20, say")
        return None
    if n < 2:
        raise CliError(f"--spread {n}: a spread needs at least 2 refits", fix="e.g. --spread 20")
    if jobs is not None and jobs < 1:
        raise CliError(f"--jobs {jobs}: give at least 1 worker process")
    from selfcal.pipeline.board_spread import BootstrapRun
    from selfcal.threads import helper_threads

    workers = helper_threads(n) if jobs is None else jobs
    return BootstrapRun(n, seed, _pool_runner(workers))


def _pool_runner(jobs: int) -> Callable[..., Iterable[tuple[int, dict]]]:
    """A :data:`selfcal.pipeline.board_spread.Runner` on ``jobs`` worker processes
    (:func:`selfcal.studies.parallel.run_tasks`; a task that raised counts as a failed refit
    with its reason)."""

    def run(fn: Callable[[dict], dict], items: list[dict],
            counts: TaskCounts) -> Iterable[tuple[int, dict]]:  # fmt: skip
        from selfcal.studies.parallel import run_tasks

        def error_row(_item: dict, exc: BaseException) -> dict:
            return {"failed": f"{type(exc).__name__}: {exc}"}

        return run_tasks(fn, items, jobs=jobs, error_row=error_row, counts=counts)

    return run
