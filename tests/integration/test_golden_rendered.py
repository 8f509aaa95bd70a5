"""The default scenario, rendered, reproduces the golden calibration and report."""

from __future__ import annotations

import json

import pytest

pytestmark = pytest.mark.render


@pytest.mark.slow
def test_default_scenario_rendered_matches_golden(default_rendered, golden):
    """The files of tests/conftest.py's ``default_rendered`` run (acquire, calibrate, report of
    the default scenario: the rendered pipeline's accuracy test reads the same run)."""
    out, _ = default_rendered
    golden("rendered/calibration.json", json.loads((out / "calibration.json").read_text()))
    golden("rendered/report.json", json.loads((out / "report.json").read_text()))
