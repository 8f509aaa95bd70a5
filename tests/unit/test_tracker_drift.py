"""The drift check's test (selfcal.calibration.tracker.drift, issue #29)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.tracker.drift import drift_check
from selfcal.errors import InputError
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.robot.definition import load_robot


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    cols = minimal_indices(model.joint_types)
    rng = np.random.default_rng(0)
    A = rng.normal(size=(cols.size, cols.size)) * 2e-5
    em = ToolErrorModel(model, np.eye(4), cols, A @ A.T, 3e-5)
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (5, robot.n))
    return em, q


def test_residuals_drawn_from_the_prediction_alarm_at_alpha(setup):
    """Residuals with exactly the covariance the check assumes (the parameters' error shared by
    the rows, model error and noise per row) are called changed in about 1 % of draws."""
    em, q = setup
    rng = np.random.default_rng(1)
    p = em.tool_positions(q)
    Jp = em.jacobian(q)[:, :3]
    L = np.linalg.cholesky(em.covariance)
    sd = np.hypot(em.model_error_m, 1e-4)
    n = 800
    changed = 0
    for _ in range(n):
        dtheta = L @ rng.normal(size=L.shape[0])
        xyz = p + Jp @ dtheta + rng.normal(0.0, sd, p.shape)
        changed += drift_check(em, q, xyz, 1e-4).changed
    assert 0.0025 < changed / n < 0.025


def test_a_grown_model_error_is_expected_at_each_rows_distance(setup):
    """A model error that grows from the calibration postures (growth.py) enters each new row at
    its own distance: far rows expect more, a row at a calibration posture only the level."""
    import dataclasses

    em, q = setup
    span = np.full(em.model.n, 2 * np.pi)
    grown = dataclasses.replace(em, reach_postures=q[:2], reach_span=span, reach_distance=0.05,
                                reach_floor=0.5)  # fmt: skip
    xyz = em.tool_positions(q)
    flat, far = drift_check(em, q, xyz, 1e-4), drift_check(grown, q, xyz, 1e-4)
    factor = grown.model_error_factor(q)
    assert factor[:2] == pytest.approx([0.5, 0.5]) and np.all(factor[2:] > 1)
    Jp = em.jacobian(q)[:, :3].reshape(15, -1)
    want = np.trace(Jp @ em.covariance @ Jp.T) / 5 + 3 * np.mean(
        em.model_error_m**2 * factor + 1e-8
    )
    assert far.expected_rms_mm == pytest.approx(np.sqrt(want) * 1e3)
    assert far.expected_rms_mm > flat.expected_rms_mm


def test_a_shift_is_changed_and_bad_rows_are_refused(setup):
    em, q = setup
    xyz = em.tool_positions(q) + np.array([1e-3, 0.0, 0.0])
    res = drift_check(em, q, xyz, 1e-4)
    assert res.changed and res.p_value < 1e-6
    assert res.mean_mm == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
    assert "changed by" in res.line()
    with pytest.raises(InputError, match="one measured position per joint row"):
        drift_check(em, q, xyz[:3], 1e-4)


def test_a_tail_that_underflows_prints_as_a_bound_not_p_zero():
    # Before: a chi-square tail that underflowed printed "p = 0 < 0.01", an impossible certainty.
    from selfcal.calibration.drift.p_value import p_text
    from selfcal.calibration.tracker.drift import DriftCheck

    assert p_text(0.0) == "p < 1e-15" and p_text(3e-16) == "p < 1e-15"
    assert p_text(0.0023) == "p = 0.0023" and p_text(1e-15) == "p = 1e-15"
    # two digits printed 0.995 - 1 as "p = 1" (a new user's unchanged check, session 28)
    assert p_text(0.985) == "p = 0.98" and p_text(0.996) == "p > 0.99" == p_text(1.0)
    # a Bonferroni bound just below 1 printed "p > 0.99" where one of its 11 tests had 0.09
    bound = p_text(11 * 0.0905, 0.0905, 11)
    assert bound == "p > 0.99 (Bonferroni's bound: 11 tests times their smallest p, 0.09)", bound
    assert p_text(0.996, 0.995, 1) == "p > 0.99"  # its one test's own p: no bound
    assert p_text(0.5, 0.1, 5) == "p = 0.5"
    check = DriftCheck(rows=5, statistic=900.0, dof=15, p_value=0.0, changed=True, rms_mm=2.0,
                       expected_rms_mm=0.1, change_mm=1.9, mean_mm=np.zeros(3), alpha=0.01)  # fmt: skip
    assert "p < 1e-15 < 0.01" in check.line() and "p = 0" not in check.line()
