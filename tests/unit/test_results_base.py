"""The shared base of the kinematic estimators' results (selfcal.kinematics.parameter_estimates.ParameterEstimates)."""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.parameter_estimates import ParameterEstimates


def estimates() -> ParameterEstimates:
    return ParameterEstimates(
        names=("alpha0", "lx0", "gamma5"),
        values=np.array([np.radians(90.0), 0.25, 0.0]),
        std=np.array([np.radians(0.01), 1e-4, np.nan]),
        estimated=np.array([True, True, False]),
        held_reason={"gamma5": "explicit"},
        covariance=np.diag([np.radians(0.01) ** 2, 1e-8]),
        rank=2,
        n_params=3,
    )


def test_held_and_identifiable_split_the_names_by_the_mask() -> None:
    est = estimates()
    assert est.identifiable == ("alpha0", "lx0")
    assert est.held == ("gamma5",)
    assert [r[3] for r in est.rows()] == [True, True, False]
    assert [r[4] for r in est.rows()] == [None, None, "explicit"]


def test_table_prints_angles_in_deg_lengths_in_mm_and_why_a_parameter_is_held() -> None:
    lines = estimates().table([True, False, True])
    assert lines == [
        " alpha0     90.00000 +-   0.01000 deg",
        "    lx0    250.00000 +-   0.10000 mm",
        " gamma5      0.00000 +-       nan deg  held: explicit",
    ]
