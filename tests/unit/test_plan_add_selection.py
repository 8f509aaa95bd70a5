"""The benchmark's question to the selection (selfcal/benchmarks/plan/add_selection.py): the
one-standard-error rule on the same folds with the fold holding most frames not counted."""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.plan.add_selection import majority_fold_left_out
from selfcal.calibration.board.param_selection import Candidate, one_se_rule


def _cands(rms: list[list[float]]) -> list[Candidate]:
    out = []
    for i, r in enumerate(rms):
        c = Candidate(f"c{i}", (), np.array([], int), np.array([], int))
        c.fold_rms_px = tuple(r)
        c.cv_px = float(np.exp(np.mean(np.log(r))))
        out.append(c)
    return out


# truth 7 of the eye-to-hand --add 5 table (calibration.json's fold RMS, px): the 23 and the 30
# predict 4 folds better than the nominal, the dataset's fold (12 frames, its training part the
# 5 added views) far worse
RMS = [[1.55, 1.26, 0.957, 1.309, 2.125], [1.229, 1.958, 1.258, 1.351, 2.054],
       [0.943, 0.889, 0.784, 2.533, 1.259], [0.899, 0.805, 0.725, 8.002, 1.413]]  # fmt: skip
FOLDS = np.repeat([0, 1, 2, 3, 4], [2, 1, 1, 12, 1])


def test_the_majority_fold_not_counted_changes_the_choice():
    assert one_se_rule(_cands(RMS))[0] == 0  # all folds: the nominal within one standard error
    chosen, out = majority_fold_left_out(_cands(RMS), FOLDS)
    assert (chosen, out) == (2, 3)  # the 23 within one standard error of the 30 on the 4 others


def test_without_a_majority_fold_it_is_the_rule():
    balanced = np.repeat([0, 1, 2, 3, 4], [4, 4, 4, 4, 4])
    assert majority_fold_left_out(_cands(RMS), balanced) == (one_se_rule(_cands(RMS))[0], None)


def test_too_few_folds_left_count_every_fold():
    rms = [r[:3] for r in RMS]
    folds = np.repeat([0, 1, 2], [2, 2, 12])  # two would remain: not left out
    assert majority_fold_left_out(_cands(rms), folds) == (one_se_rule(_cands(rms))[0], None)
