"""The one-step refinement's re-expression in the reference camera's frame
(:func:`selfcal.estimation.joint_report.express_in_reference`)."""

from __future__ import annotations

import numpy as np

import selfcal.estimation.joint_report as joint_report
from selfcal.estimation.joint_report import express_in_reference
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.robot.definition import load_robot


def test_a_covariance_without_a_finite_entry_is_not_propagated(monkeypatch):
    """The fair nominal's refinement computes no covariance (all NaN): its re-expression is the
    chain alone, the all-NaN covariance it propagated to before, without the central differences
    (two re-expressed chains a free parameter); a finite covariance is propagated as before."""
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    free = minimal_indices(model.joint_types)[6:]
    q_ref = np.full((1, model.n), 0.1)
    calls = []
    express = joint_report.express_in_frame
    monkeypatch.setattr(joint_report, "express_in_frame",
                        lambda *a, **kw: calls.append(1) or express(*a, **kw))  # fmt: skip
    cov = 1e-8 * np.eye(len(free))
    ref, full = express_in_reference(model, free, q_ref, model, cov)
    assert len(calls) == 1 + 2 * len(free) and np.isfinite(full).all()
    calls.clear()
    ref_nan, none = express_in_reference(model, free, q_ref, model, np.full_like(cov, np.nan))
    assert len(calls) == 1
    np.testing.assert_array_equal(ref_nan.params, ref.params)
    assert none.shape == full.shape and np.isnan(none).all()
