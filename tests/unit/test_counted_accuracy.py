"""The accuracy side reads the folds the selection counts (issue #30): a fold that leaves out more
than half of the frames (selfcal/calibration/board/folds.py counted_folds) is no part of the
model error and the held share (fold_fits.fold_bounds), nor of the cross-validated held-out RMS
(accuracy.cross_validated_reprojection); the jackknife keeps every fold (spread.py says why)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from selfcal.calibration.board import accuracy, fold_fits
from selfcal.calibration.board.folds import counted_folds
from selfcal.calibration.board.param_selection import Candidate, Selection
from selfcal.calibration.board.spread import jackknife_spread
from selfcal.calibration.spread import SpreadPoints

# five folds, the fourth leaving out 12 of 17 frames (the eye-to-hand --add 5 calibrations' kind)
FOLDS = np.repeat([0, 1, 2, 3, 4], [2, 1, 1, 12, 1])


def _selection(fold_of: np.ndarray, fitted: tuple[int, ...] = (0, 1, 2, 3, 4)) -> Selection:
    """A selection of two candidates (nominal, chosen) whose folds ``fitted`` have a fit (a
    stand-in: its model's ``tag`` is the fold)."""
    cands = []
    for label in ("nominal", "chosen"):
        c = Candidate(label, (), np.zeros(0, np.int64), np.zeros(0, np.int64))
        c.fold_fits = {f: (SimpleNamespace(model=SimpleNamespace(tag=f), cameras=None),
                           np.zeros(0, np.int64), np.zeros(0, np.int64)) for f in fitted}  # fmt: skip
        cands.append(c)
    counted = tuple(counted_folds(fold_of).tolist())
    n = len(np.unique(fold_of[fold_of >= 0]))
    return Selection(cands, 1, (), {}, n, n, "rule", [], fold_of, counted)


def test_the_selection_says_which_folds_count():
    sel = _selection(FOLDS)
    assert [sel.counts(f) for f in range(5)] == [True, True, True, False, True]
    assert sel.folds_counting == 4
    # a frame without the board (-1) is in no fold; labels, not positions, are asked
    sel = _selection(np.array([-1, 0, 0, 2, 2, 2, 2]))
    assert sel.counts(0) and not sel.counts(2) and (sel.folds, sel.folds_counting) == (2, 1)
    every = _selection(np.repeat([0, 1, 2], [3, 3, 3]))
    assert all(every.counts(f) for f in range(3)) and every.folds_counting == 3
    none = Selection([], 0, (), {}, 1, 0, "no cross-validation")
    assert none.counts(0) and none.folds_counting == 0


def test_the_model_error_reads_the_folds_that_count(monkeypatch):
    """fold_bounds (the model error's and the held share's folds) skips the fold leaving out
    the majority: its fit on 5 of 17 frames stands for a smaller experiment."""
    seen = []

    def bounds(board, cameras, model, q, feats, sigma, **kw):
        seen.append(len(q))
        return "cr"

    monkeypatch.setattr(fold_fits, "board_cramer_rao", bounds)
    monkeypatch.setattr(fold_fits, "standard_gauge", lambda model, offsets: model)
    obs = SimpleNamespace(used=np.ones(17, bool), q=np.zeros((17, 6)), features=[None] * 17,
                          rig_features=(), board=None, joint_sigma=None, rig=None,
                          eye_to_hand=False)  # fmt: skip
    got = list(fold_fits.fold_bounds(obs, _selection(FOLDS), np.zeros(6), np.eye(4), 0.5))
    assert [fit.model.tag for _, fit, _ in got] == [0, 1, 2, 4]
    assert [int(out.sum()) for out, _, _ in got] == [2, 1, 1, 1]
    assert seen == [15, 16, 16, 16]  # every training part the rest of the frames


def _errors(fold_of: np.ndarray):
    """A stand-in for the held-out errors: fold f's frames err f + 1 px (and mm)."""

    def errors(obs, fit, frames):
        e = np.full(int(frames.sum()), fit.model.tag + 1.0)
        return e, e

    return errors


def test_the_held_out_rms_pools_the_folds_that_count(monkeypatch):
    monkeypatch.setattr(accuracy, "_errors_px_mm", _errors(FOLDS))
    cv = accuracy.cross_validated_reprojection(None, _selection(FOLDS))  # type: ignore[arg-type]
    assert cv is not None and cv["folds"] == 5 and cv["folds_counting"] == 4
    assert "folds_counted" not in cv  # the selection's key, a flag per fold: not this int
    e = np.repeat([1.0, 2.0, 3.0, 5.0], [2, 1, 1, 1])  # fold 3 (4 px, 12 frames) left out
    for key in ("calibrated", "nominal"):
        assert cv[key]["corners"] == 5
        assert cv[key]["reprojection_rms_px"] == pytest.approx(np.sqrt(np.mean(e**2)))
    assert "that count" in cv["what"]
    # the fold that does not count may fail: the block stands; a counted one may not
    cv = accuracy.cross_validated_reprojection(None, _selection(FOLDS, (0, 1, 2, 4)))  # type: ignore[arg-type]
    assert cv is not None and cv["calibrated"]["corners"] == 5
    cv = accuracy.cross_validated_reprojection(None, _selection(FOLDS, (0, 1, 3, 4)))  # type: ignore[arg-type]
    assert cv is not None and cv["calibrated"] is None and cv["nominal"] is None
    # every fold counting: every fold pooled, no folds_counting
    even = np.repeat([0, 1, 2, 3, 4], [2, 2, 2, 2, 2])
    monkeypatch.setattr(accuracy, "_errors_px_mm", _errors(even))
    cv = accuracy.cross_validated_reprojection(None, _selection(even))  # type: ignore[arg-type]
    assert cv is not None and "folds_counting" not in cv and cv["calibrated"]["corners"] == 10


def test_the_jackknife_keeps_every_fold(monkeypatch):
    """The jackknife is a variance over all the groups (spread.py): the fold that does not count
    stays in it, its tool point beside the others'."""
    from selfcal.calibration.board import spread

    monkeypatch.setattr(spread, "tool_tips",
                        lambda model, q, T: np.full((len(q), 3), float(model.tag)))  # fmt: skip
    points = SpreadPoints({"inside": np.zeros((3, 6))}, np.eye(4))
    got = jackknife_spread(_selection(FOLDS), points)
    assert got is not None and got.resamplings == 5
    t = np.arange(5.0)
    assert got.regions["inside"]["spread_mm_rms"] == pytest.approx(
        1e3 * np.sqrt(4 / 5 * 3 * np.sum((t - t.mean()) ** 2)))  # fmt: skip
