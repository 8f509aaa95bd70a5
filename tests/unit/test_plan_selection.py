"""The forecast of the selection's cross-validation (selfcal/calibration/board/plan_selection.py):
a dataset recorded in one arm configuration is left out whole by one fold, whose fit has only
the added postures of the other folds; with too few of them the large candidates cannot predict
it and the selection keeps fewer parameters than the rank test on every frame accepts."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.plan.add import WRIST_SPAN_DEG, wrist_cell
from selfcal.calibration.board.plan import board_model, frame_information, plan_recording
from selfcal.calibration.board.plan_predict import Deviation, kept_by_rank
from selfcal.calibration.board.plan_selection import forecast_selection
from selfcal.calibration.board.plan_views import feasible

JS = np.full(6, np.radians(0.01))


@pytest.fixture(scope="module")
def cell():
    setup, _, _ = wrist_cell()
    plan = plan_recording(setup, 8, seed=3, candidates=80, workspace=20, joint_sigma=JS)
    rng = np.random.default_rng(1)
    q = np.tile(setup.robot.home, (2000, 1))
    q[:, 3:] += rng.uniform(-1, 1, size=(2000, 3)) * np.radians(WRIST_SPAN_DEG)
    wrist = q[feasible(setup, q)][:4]
    assert len(wrist) == 4
    return setup, wrist, plan.q


def _forecast(setup, q):
    model = board_model(setup)
    F = frame_information(setup, q, 0.5, JS)
    n = np.full(len(q), len(setup.board.layout()[0]))
    var = Deviation().variance(model.joint_types)
    return forecast_selection(model, q, F, n, setup.camera.n_free, var, 0.5)


def test_a_fold_that_trains_on_four_postures_cannot_keep_the_large_sets(cell):
    setup, wrist, added = cell
    q = np.concatenate([wrist, added[:5]])  # 6 configurations in 5 folds: the 5th added
    fc = _forecast(setup, q)  # shares the wrist's fold, which trains on the other 4
    assert fc.folds == 5
    nominal, largest = fc.fold_rms_px[0], fc.fold_rms_px[-1]
    assert largest[0] > 10 * nominal[0]  # 33 px against 1.2 measured
    assert max(largest[1:]) < 1.5 * max(nominal[1:])  # the other folds predict it well
    rank = sum(map(len, kept_by_rank(board_model(setup), q)))
    assert sum(map(len, fc.kept)) < rank  # 16 kept against the rank test's 30


def test_enough_postures_in_that_fold_let_the_large_sets_predict(cell):
    setup, wrist, added = cell
    fc = _forecast(setup, np.concatenate([wrist, added]))  # the wrist's fold trains on 7
    nominal, largest = fc.fold_rms_px[0], fc.fold_rms_px[-1]
    assert largest[0] < nominal[0]  # 0.75 px against 0.92 measured
    assert len(fc.free_idx) > 12  # more than the placement's: 19 measured


def test_one_configuration_is_not_cross_validated(cell):
    setup, wrist, _ = cell
    fc = _forecast(setup, wrist)
    assert fc.folds == 1 and fc.label.startswith("nominal") and len(fc.offset_joints) == 0
