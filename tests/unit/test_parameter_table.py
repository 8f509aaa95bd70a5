"""The parameter table of the reports (selfcal.kinematics.accuracy.parameter_table): angles in one branch."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.kinematics.accuracy import parameter_table, wrap_deg
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc, param_names
from selfcal.robot.definition import load_robot


@pytest.mark.parametrize(
    ("d", "wrapped"),
    [(0.0, 0.0), (180.0, 180.0), (-180.0, 180.0), (359.99, -0.01), (-190.0, 170.0)],
)
def test_wrap_deg_is_half_open_at_minus_180(d: float, wrapped: float) -> None:
    assert wrap_deg(d) == pytest.approx(wrapped, abs=1e-9)


def test_an_angle_a_turn_away_shows_in_the_nominals_branch() -> None:
    nominal = nominal_mcpc(load_robot("er4u-paper"))
    idx = minimal_indices(nominal.joint_types)
    names = param_names(idx)
    flat = nominal.params.reshape(-1).copy()
    # the estimate a turn away (and 0.01 deg off), as a fit that crossed +-180 reports it
    moved = {"alpha0": -2 * np.pi + np.radians(0.01), "gamma5": 2 * np.pi - np.radians(0.02)}
    for name, step in moved.items():
        flat[idx[names.index(name)]] += step
    truth = nominal.with_params(nominal.params.copy())
    rows = {
        r["name"]: r
        for r in parameter_table(
            nominal.with_params(flat.reshape(nominal.params.shape)), {}, truth, nominal
        )
    }
    assert rows["alpha0"]["estimate"] - rows["alpha0"]["nominal"] == pytest.approx(0.01, abs=1e-9)
    assert rows["gamma5"]["estimate"] - rows["gamma5"]["nominal"] == pytest.approx(-0.02, abs=1e-9)
    assert rows["gamma5"]["truth"] == pytest.approx(rows["gamma5"]["nominal"], abs=1e-12)


def test_a_bound_above_the_achieved_error_is_explained() -> None:
    from selfcal.pipeline.report_fit import bound_markdown

    below = bound_markdown(0.022, 0.010)
    assert "0.022 mm" in below and "The achieved 0.010 mm is below it" in below
    assert "below it" not in bound_markdown(0.022, 0.030)
    assert bound_markdown(None, 0.01) == "No Cramér-Rao bound was computed for this calibration."


def test_the_tools_other_euler_triple_shows_in_the_nominals_branch() -> None:
    """#32: alpha5 90.07 -> -90.10 and gamma5 -0.78 -> 179.83 read as two 180-degree errors; they
    are the same rotation written as (a + 180, 180 - b, c + 180)."""
    from selfcal.kinematics.mcpc import shape_matrices

    nominal = nominal_mcpc(load_robot("er4u-paper"))
    p = nominal.params.copy()
    a, b, c = p[-1, :3] + np.radians([0.03, -0.02, 0.6])  # the fit: a small change ...
    p[-1, :3] = [a + np.pi, np.pi - b, c - np.pi]  # ... written on the other branch
    est = nominal.with_params(p)
    rows = {r["name"]: r for r in parameter_table(est, {}, None, nominal)}
    diff = {k: rows[k]["estimate"] - rows[k]["nominal"] for k in ("alpha5", "beta5", "gamma5")}
    assert diff == pytest.approx({"alpha5": 0.03, "beta5": -0.02, "gamma5": 0.6}, abs=1e-9)
    assert np.allclose(shape_matrices(p[-1]), shape_matrices(np.radians(
        [rows["alpha5"]["estimate"], rows["beta5"]["estimate"], rows["gamma5"]["estimate"], 0, 0, 0]
    ) + np.r_[0, 0, 0, p[-1, 3:]]), atol=1e-12)  # fmt: skip
