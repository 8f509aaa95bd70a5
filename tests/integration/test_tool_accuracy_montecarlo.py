"""Monte Carlo of the predicted tool-point accuracy (slow; the benchmark
selfcal/benchmarks/tracker/accuracy.py runs 30 draws on three robots and three noise levels)."""

from __future__ import annotations

import pytest

from selfcal.benchmarks.tracker.accuracy import run


@pytest.mark.slow
def test_the_predicted_bound_covers_the_true_error_over_draws():
    """ER-4u, 0.1 mm, 10 draws: a model that fits is covered at ~95 % of the workspace points
    with the predicted RMS near the true one (the benchmark: 94.1 %, 1.03 over 30 draws); a
    compliance the chain cannot express is covered thanks to the model error."""
    rows = run(10, robots=("er4u-paper",), noise_mm=(0.1,))
    got = {(r["model"], r["region"]): r for r in rows}
    fits = got[("fits", "workspace")]
    assert 0.88 < fits["coverage"] < 0.99 and 0.8 < fits["ratio"] < 1.25
    bent = got[("compliance", "inside")]
    assert bent["coverage"] > 0.85 and bent["coverage_covariance"] < bent["coverage"] - 0.1
    assert 0.7 < bent["ratio"] < 1.4


@pytest.mark.slow
def test_a_turn_of_a_joint_is_not_a_distance():
    """UR5e, 0.1 mm, 10 draws of the compliance: its joints turn +-360 deg, and its model error
    does not grow over the workspace; counted from the calibration postures with a revolute
    joint's turns wrapped, the bound covers it at 96.9 % over the workspace (predicted / true
    RMS 1.16); measured across the turns (before) it over-covered, 99.1 % (1.28)."""
    rows = run(10, robots=("ur5e",), noise_mm=(0.1,), models=("compliance",))
    ws = next(r for r in rows if r["region"] == "workspace")
    assert 0.90 <= ws["coverage"] <= 0.98 and 0.7 < ws["ratio"] < 1.25
