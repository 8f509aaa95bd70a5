"""What `selfcal plan --add` forecasts over and with (selfcal/calibration/board/plan/add_ground.py):
the workspace the dataset covers when the robot file has no planning window, and the deviation
sized so that the forecast's fair-nominal folds match the misfit the calibration's folds
measured."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.add import DatasetPlan
from selfcal.calibration.board.plan.add_ground import dataset_workspace, sized_deviation
from selfcal.calibration.board.plan.ground import PlanOptions, workspace_sample
from selfcal.calibration.board.plan.information import (
    board_model,
    frame_information,
    prediction_information,
)
from selfcal.calibration.board.plan.predict import linear_estimator
from selfcal.calibration.board.plan.selection import selection_folds
from selfcal.kinematics.tool_error import EDGE_FRACTION

NONE = np.zeros(0, np.int64)


def _dataset(setup, q) -> DatasetPlan:
    ids = setup.board.layout()[0]
    return DatasetPlan(setup, np.asarray(q, float), (ids,) * len(q), NONE, NONE)


def test_without_a_planning_window_the_workspace_is_the_datasets_region(ur5e_wrist_plan):
    setup, plan = ur5e_wrist_plan
    r = setup.robot
    q = plan.q + np.radians([120.0, 0, 0, 0, 0, 0])  # the dataset away from home's window
    no_window = dataclasses.replace(setup, robot=dataclasses.replace(r, planning_window=False))
    ws = dataset_workspace(_dataset(no_window, q), 30, seed=2)
    band = EDGE_FRACTION * (r.limits[:, 1] - r.limits[:, 0])
    lo = np.maximum(q.min(axis=0) - band, r.limits[:, 0])
    hi = np.minimum(q.max(axis=0) + band, r.limits[:, 1])
    assert ws.source == "dataset region" and len(ws.q) == 30
    assert np.all((ws.q >= lo) & (ws.q <= hi))
    # it spans the region, not a corner of it: every joint's draws cover most of its window
    assert np.all(np.ptp(ws.q, axis=0) > 0.7 * (hi - lo))
    # the old workspace (the planning window around home) lies mostly outside the region
    home = workspace_sample(setup, 30, seed=2)
    assert np.mean(np.all((home >= lo) & (home <= hi), axis=1)) < 0.5
    # a robot file with a planning window keeps it
    kept = dataset_workspace(_dataset(setup, q), 30, seed=2)
    assert kept.source == "planning window" and np.array_equal(kept.q, home)


def _measured_folds(setup, q, truth: Deviation, sigma: float, rng, draws: int):
    """``draws`` simulated calibrations' fair-nominal folds (px), to first order: each an arm
    drawn uniformly within ``truth`` (the placement exact) and corner noise ``sigma``; each
    fold's fit on the other folds' frames (camera and placement) predicts the fold's features.
    Returns the nominal's label and the folds' RMS (draws, folds)."""
    model = board_model(setup)
    folds = selection_folds(model, q)
    F = frame_information(setup, q, sigma)
    A = prediction_information(setup, q, sigma)
    n_cam, n_feat = setup.camera.n_free, len(setup.board.layout()[0])
    half = np.sqrt(3.0 * truth.variance(model.joint_types))  # 0 for the placement
    fits = []
    for f in range(len(folds.labels)):
        out = folds.out(f)
        F_tr = F[~out].sum(axis=0)
        w, V = np.linalg.eigh(F_tr)
        fits.append(
            (
                *linear_estimator(F_tr, n_cam, folds.directions[f][0]),
                V * np.sqrt(np.clip(w, 0.0, None)),
                A[out].sum(axis=0),
                n_feat * out.sum(),
            )
        )
    rms = np.zeros((draws, len(fits)))
    for i in range(draws):
        d = np.concatenate([np.zeros(n_cam), rng.uniform(-1.0, 1.0, half.size) * half])
        for f, (C, R, L, A_out, n) in enumerate(fits):
            e = -R @ d + C @ (L @ rng.standard_normal(len(L)))  # noise ~ N(0, F_tr)
            noise = sigma**2 * rng.chisquare(2 * n) / n  # the fold's own corners, per feature
            rms[i, f] = np.sqrt(noise + sigma**2 * e @ A_out @ e / n)
    return folds.candidates[0].label, rms


@pytest.mark.parametrize("scale", [0.3, 1.0])
def test_the_sized_deviation_tracks_the_folds_measured_misfit(ur5e_wrist_plan, scale):
    setup, plan = ur5e_wrist_plan
    truth = Deviation(1e-3 * scale, np.radians(0.5) * scale)
    opts = PlanOptions()  # the default deviation, 0.5 px
    rng = np.random.default_rng(7)
    got = []
    label, draws = _measured_folds(setup, plan.q, truth, 0.5, rng, 5)
    for measured in draws:  # five simulated arms of the set deviation, one calibration each
        sel = {"candidates": [{"label": label, "fold_rms_px": measured.tolist()}]}
        sized = sized_deviation(_dataset(setup, plan.q), sel, opts)
        assert sized.source == "sized" and sized.forecast_px == pytest.approx(
            float(np.sqrt(np.mean(measured**2))), rel=1e-9)  # fmt: skip
        got.append(sized.scale)
    assert len(set(np.round(got, 9))) == 5  # each arm's own misfit, not a constant
    # measured: median 0.72 (scale 1) and 0.68 (0.3) times the set scale over these 5 arms,
    # 0.88 over 20 (the module docstring); the default deviation is 1 and 3.3 times them
    assert np.median(got) == pytest.approx(scale, rel=0.5)


def test_one_configuration_keeps_the_default_and_says_why(ur5e_wrist_plan):
    setup, plan = ur5e_wrist_plan
    sel = {"candidates": [{"label": "nominal (placement + camera)", "fold_rms_px": [1.2]}]}
    sized = sized_deviation(_dataset(setup, plan.q), sel, PlanOptions())
    assert sized.source == "default" and sized.scale == 1.0
    assert "no cross-validation" in sized.words
