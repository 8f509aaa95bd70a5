"""The default scenario, rendered, reproduces the golden calibration and report."""

from __future__ import annotations

import json

import pytest

from selfcal.config.scenario import load_scenario
from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

pytestmark = pytest.mark.render


@pytest.mark.slow
def test_default_scenario_rendered_matches_golden(tmp_path, golden):
    run_acquire(load_scenario(), tmp_path, quiet=True)
    run_calibrate(tmp_path, quiet=True)
    run_report(tmp_path, quiet=True)
    golden("rendered/calibration.json", json.loads((tmp_path / "calibration.json").read_text()))
    golden("rendered/report.json", json.loads((tmp_path / "report.json").read_text()))
