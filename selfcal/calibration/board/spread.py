"""Run-to-run spread of a board calibration: the jackknife over its cross-validation folds
(issue #29).

Would the same images, taken again at other postures of the same kind, give the same tool point?
The board route already refits its chosen candidate without each fold of arm configurations
(:mod:`selfcal.calibration.board.param_selection`, the folds :mod:`selfcal.calibration.board.folds`):
those ``k`` fits are a delete-a-group jackknife. At a joint vector with the fold fits' tool points
``t_i`` (the flange, in the chain's world frame: the board frame, eye-to-hand the first camera's)
the jackknife variance of the calibration's tool point is

    var = (k - 1) / k * sum_i |t_i - t_mean|^2

(the squared spread summed over the three coordinates, as the tracker's bootstrap spread,
:mod:`selfcal.calibration.tracker.spread`); the spread is its square root (mm), kept per region
of the workspace sample and at the calibration postures as the largest and the median value
(:class:`selfcal.calibration.spread.Spread`, ``accuracy.spread``). It costs no fit beyond the
cross-validation's.

The folds are symmetric in it, and the configurations are numbered by their joints before they
are dealt into the folds (:func:`selfcal.calibration.board.folds.configurations`), so the order
of the dataset's frames does not change it (tests/integration/test_board_analytic.py shuffles
them through ``selfcal calibrate``). What it cannot see: a model error every fold shares; with
few folds (``k - 1`` degrees of freedom) the spread is itself uncertain (about +-35 % at 5
folds, 1 standard deviation); a fold whose training frames could not determine some parameters
held them at the fair nominal's value (``held_folds``): its fit differs in kind, and the spread
then over-states. And the jackknife's
variance is biased upward (Efron and Stein) when a fold holds a large share of the information,
few configurations for many parameters: for a linear least-squares fit with 15 configurations
of 2 rows in 5 folds it over-states the variance 1.08 times on average with one parameter, 1.25
with four and 1.55 with eight, 1.04-1.05 with 150 rows or 60 configurations for four
(:mod:`selfcal.benchmarks.board.jackknife_bias`); a board fit has tens of parameters.

Every fold enters it, also one that leaves out more than half of the frames and so does not
count in the selection or the accuracy side (:func:`selfcal.calibration.board.folds.counted_folds`):
the jackknife is a variance over the groups, each replicate leaving one out, and a replicate
dropped from the sum takes its group's part of the variance with it (the group is then in every
replicate left: the spread would hold it fixed and under-state). Such a fold's fit on the
minority lies far out instead, and the spread over-states (the bias above at its largest); the
unequal groups' delete-m jackknife, which weighs a fold by the frames it keeps over those it
leaves out, is not used.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.board.param_selection import Selection
from selfcal.calibration.spread import JACKKNIFE, Spread, SpreadPoints, region_spread
from selfcal.kinematics.accuracy import tool_tips

__all__ = ["WHAT", "jackknife_spread"]

WHAT = (
    "delete-a-fold jackknife over the cross-validation folds' fits of the chosen "
    "candidate: sqrt((k - 1) / k * sum |t_i - t_mean|^2) of the folds' tool points t_i, per "
    "joint vector (mm)"
)


def jackknife_spread(selection: Selection, points: SpreadPoints) -> Spread | None:
    """The jackknife spread of the board calibration whose parameter selection is ``selection``
    (module docstring) at ``points`` (the workspace sample's regions and the calibration
    postures, the tool point); the block's ``held_folds`` counts the folds whose fit held
    parameters at the fair nominal. None without folds or with fewer than two fitted."""
    if selection.fold_of is None:
        return None
    cand = selection.candidates[selection.chosen]
    fits = [fit for _, (fit, _, _) in sorted(cand.fold_fits.items())]
    k = len(fits)
    if k < 2:
        return None
    squared = {}
    for name, q in points.qs.items():
        t = np.stack([tool_tips(fit.model, q, points.T_tool_point) for fit in fits])  # (k, m, 3)
        squared[name] = (k - 1) / k * np.sum((t - t.mean(axis=0)) ** 2, axis=(0, 2))
    held = sum(1 for f in cand.fold_fits if cand.fold_held.get(f))
    return Spread(k, selection.folds - k, region_spread(squared), WHAT, JACKKNIFE,
                  {"held_folds": held})  # fmt: skip
