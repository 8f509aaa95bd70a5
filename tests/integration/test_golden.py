"""The default scenario on the analytic path reproduces the golden calibration and report."""

from __future__ import annotations

import json

from selfcal.io.calibration import read_calibration
from selfcal.io.jsonfile import dumps


def test_default_scenario_analytic_matches_golden(default_analytic, golden):
    out, result, said, _ = default_analytic  # acquired, calibrated (not quiet) and reported
    # the line names what the default (one-step) method fits: the 26 MCPC parameters of the
    # 5-joint chain less the 6 of the world frame's gauge (not the two-stage "rank 26/26")
    assert "20 kinematic parameters fitted (6 fixed by the world frame's gauge)" in said, said
    # and both models' prediction of the calibration images, the calibrated and the fair nominal
    assert result.nominal is not None
    rms = result.nominal.calibration_images_rms_px
    assert (f"(from the joint readings {rms['calibrated']:.3f} px, the fair nominal "
            f"{rms['nominal']:.3f} px)") in said, said  # fmt: skip
    assert rms["calibrated"] < 1.0 < 4.0 < rms["nominal"] < 5.0  # measured 0.698 and 4.377
    text = (out / "calibration.json").read_text()
    golden("analytic/calibration.json", json.loads(text))
    golden("analytic/report.json", json.loads((out / "report.json").read_text()))
    # the file is the result, and reading it back gives the same text
    assert text == dumps(result.to_json()) == dumps(read_calibration(out).to_json())
    assert result.dataset.skipped_images == () and result.bounds is not None
