"""``selfcal calibrate --spread N`` of a board dataset: the bootstrap refits run, counted on a
progress bar, and gathered into ``calibration.json``'s ``accuracy.bootstrap_spread``
(:mod:`selfcal.calibration.board.bootstrap`), beside the jackknife's ``accuracy.spread``.

The refits run on whatever ``runner`` the command gives (:class:`BootstrapRun`: the command
passes :func:`selfcal.studies.parallel.run_tasks` on ``--jobs`` worker processes, which sits
above this layer); each result is counted as it arrives.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.bootstrap import (
    KEY,
    bootstrap_spread,
    canonical_frames,
    refit_row,
    resamples,
)
from selfcal.calibration.board.dataset import BoardDatasetCalibration
from selfcal.calibration.spread import Spread
from selfcal.console.progress import Progress, TaskCounts
from selfcal.errors import InputError

__all__ = [
    "BootstrapRun",
    "Runner",
    "bootstrap_items",
    "run_bootstrap",
    "serial_runner",
    "with_bootstrap",
]

Runner = Callable[[Callable[[dict], dict], list[dict], TaskCounts], Iterable[tuple[int, dict]]]
"""``runner(fn, items, counts)``: ``(index, fn(items[index]))`` of every item as they finish
(a task that raised gives ``{"failed": reason}``), ``counts`` kept up to date."""


def serial_runner(fn: Callable[[dict], dict], items: list[dict],
                  counts: TaskCounts) -> Iterable[tuple[int, dict]]:  # fmt: skip
    """A :data:`Runner` in this process, one item after the other (a bug in a task raises)."""
    for i, item in enumerate(items):
        counts.running = 1
        row = fn(item)
        counts.running = 0
        yield i, row


@dataclass(frozen=True)
class BootstrapRun:
    """The bootstrap a command asks for: ``count`` resamples drawn with ``seed``, refitted by
    ``runner`` (default in this process); ``held``: every refit fits the calibration's chosen
    kinematic parameters (the default), False: each runs its own parameter selection (a
    benchmark's comparison, ``selfcal.benchmarks.board.spread --selection free``)."""

    count: int
    seed: int = 0
    runner: Runner = serial_runner
    held: bool = True


def bootstrap_items(cal: BoardDatasetCalibration, run: BootstrapRun) -> tuple[list[dict], int]:
    """The refits' tasks (:func:`selfcal.calibration.board.bootstrap.refit_row`'s items) of the
    bootstrap ``run`` of the board calibration ``cal`` (the detailed result of
    :func:`selfcal.calibration.board.dataset.calibrate_board_dataset_detailed`, with its
    accuracy block) and its number of arm configurations: the frames its fit used, resampled
    by configuration, each refit to fit the calibration's chosen kinematic parameters (the
    model selection held, as the jackknife's fold fits; ``run.held`` False: to select its own).

    Raises:
        InputError: fewer than 2 resamples, a calibration of a rig of cameras (its refit is not
            written yet), or one without the predicted accuracy's sample (no bounds).
    """
    if run.count < 2:
        raise InputError(f"--spread {run.count}: a spread needs at least 2 resamples",
                         fix="e.g. --spread 20")  # fmt: skip
    if cal.inputs is None:
        raise InputError("--spread N refits one camera's images; this dataset has a rig of "
                         f"{len(cal.features)} cameras",
                         fix="leave out --spread: accuracy.spread holds the jackknife over the folds")  # fmt: skip
    if cal.spread_points is None:
        raise InputError("--spread N: the calibration has no predicted accuracy (no bounds: "
                         f"{cal.result.bounds_error}), so no workspace to spread over",
                         fix="leave out --spread")  # fmt: skip
    used = np.asarray(cal.fit.used, dtype=bool)
    inputs = cal.inputs
    index = np.flatnonzero(used)
    groups = canonical_frames(inputs.q[index], [inputs.features[i] for i in index],
                              inputs.nominal.joint_types)  # fmt: skip
    picks = [index[p] for p in resamples(groups, run.count, run.seed)]
    keep = None if cal.fit.selection is None or not run.held else cal.fit.selection.identified
    items = [{"inputs": inputs, "pick": p, "points": cal.spread_points, "keep": keep}
             for p in picks]  # fmt: skip
    return items, len(groups)


def run_bootstrap(
    cal: BoardDatasetCalibration, run: BootstrapRun, *, quiet: bool = False
) -> Spread:
    """The bootstrap spread of the board calibration ``cal`` over ``run.count`` resamples of its
    arm configurations (:func:`bootstrap_items`), refitted by ``run.runner``; a progress bar on
    a terminal unless ``quiet``.

    Raises:
        InputError: as :func:`bootstrap_items`.
    """
    items, configurations = bootstrap_items(cal, run)
    counts = TaskCounts(len(items))
    outcomes: list[dict] = [{"failed": "no result (the worker pool stopped)"}] * len(items)
    progress = Progress("bootstrap", enabled=not quiet, counts=counts)
    progress.start(len(items))
    try:
        for i, row in run.runner(refit_row, items, counts):
            outcomes[i] = row
            counts.finish(failed="tips" not in row)
            progress.advance()
    finally:
        progress.finish()
    chosen = None if cal.fit.selection is None else cal.fit.selection.identified
    return bootstrap_spread(outcomes, seed=run.seed, configurations=configurations,
                            chosen=chosen, held=run.held)  # fmt: skip


def with_bootstrap(accuracy: dict, spread: Spread) -> dict:
    """``accuracy`` (the block) with the bootstrap's block under :data:`KEY`."""
    return {**accuracy, KEY: spread.to_json()}
