"""The default scenario on the analytic path reproduces the golden calibration and report."""

from __future__ import annotations

import json

from scenarios.config import load_scenario
from scenarios.pipeline import run_acquire, run_calibrate, run_report


def test_default_scenario_analytic_matches_golden(tmp_path, golden):
    s = load_scenario(overrides={"noise": {"render": False}})
    run_acquire(s, tmp_path, quiet=True)
    run_calibrate(tmp_path, quiet=True)
    run_report(tmp_path, quiet=True)
    golden("analytic/calibration.json", json.loads((tmp_path / "calibration.json").read_text()))
    golden("analytic/report.json", json.loads((tmp_path / "report.json").read_text()))
