"""The marker-field forecast against an analytic Monte Carlo of the same plan (issue #30, "the
error the plan predicts is within 0.7 - 1.4x the achieved"): on the analytic path, white corner
noise of the forecast's level, the field route's tool-point error over draws is what the
forecast says. The rendered draws err 2 - 10 times less than their forecast
(docs/plan.md, "What the rendered draws gain over the forecast"); this test says that the
forecast and its setup are the field route's when the corners are as it models them, so the
gap lies in the rendered corners' errors, not in the forecast."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.slow

DRAWS = 6


def test_the_forecast_is_the_analytic_draws_rms(tmp_path):
    """The KR 6's rendered cell's plan of 12 (clear views), drawn on the analytic path at the
    0.1 px it is forecast for, six arms and noise draws: the RMS of the draws' tool-point
    errors over the forecast was 1.13 (12 draws 0.98, the median 0.95 of the forecast). The
    draws' squared error is about chi2 of 6 x 3.6 degrees of freedom (the bound's
    Satterthwaite degrees, ``dof_tip``), whose 90 % interval of the RMS is 0.74 - 1.24 of its
    expectation: 0.6 - 1.4 holds the forecast to that, and a forecast off 2 - 10 times, as it
    is against the rendered draws, fails."""
    from selfcal.benchmarks.plan.field_compare import field_sets
    from selfcal.studies.montecarlo.run import draw_one

    sets = field_sets(tmp_path, robot_name="kr6-r900", pixel_sigma_px=0.1, render=True)
    path, q, forecast = sets["plan 12"]
    tips = []
    for seed in range(1, DRAWS + 1):
        row = draw_one({"config": str(path), "poses": len(q), "pixel_sigma": 0.1, "seed": seed,
                        "traj_seed": 1, "perturb_seed": seed, "dither": True,
                        "joints_deg": q.tolist(), "fair_nominal": False})  # fmt: skip
        assert row["status"] == "ok", row["status"]
        tips.append(row["joint_tip_rms_mm"])
    ratio = float(np.sqrt(np.mean(np.square(tips)))) / (forecast * 1000)
    assert 0.6 < ratio < 1.4, (ratio, tips, forecast)
