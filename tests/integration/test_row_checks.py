"""The rows of a real study run and a real Monte Carlo draw record the calibration's reliability
checks (issue #15) as ``selfcal calibrate`` reports them: a sound calibration passes them
(``checks = "passed"``, no failures). The failing case is the same field through the fake tasks
of tests/unit/test_seeds_and_checks.py; the checks themselves: tests of selfcal.calibration.field.quality."""

from __future__ import annotations

import pytest

from selfcal.studies.defs import BASE
from selfcal.studies.montecarlo.run import draw_one
from selfcal.studies.runs import run_one


@pytest.mark.slow  # a whole acquisition and calibration each (13-17 s on the loaded machine)
def test_a_study_run_records_passed_checks():
    row = run_one({**BASE, "poses": 12, "seed": 1})
    assert row["status"] == "ok", row["status"]
    assert row["checks"] == "passed" and row["failed_checks"] is None


@pytest.mark.slow
def test_a_monte_carlo_draw_records_passed_checks():
    settings = {"poses": 12, "pixel_sigma": 0.5, "seed": 1, "traj_seed": 1, "perturb_seed": 1}
    row = draw_one({**settings, "dither": True, "plan": "random", "config": None})
    assert row["status"] == "ok", row["status"]
    assert row["checks"] == "passed" and row["failed_checks"] is None
    # the fair nominal's tool-tip error (its chain as fitted beside the calibration, against
    # the same truth): what the calibration is judged against (0.316 against 4.943 mm, the
    # drawn chain 1.579 mm, when written)
    assert 4 * row["joint_tip_rms_mm"] < row["fair_nominal_tip_rms_mm"]
