"""``selfcal report`` of ``selfcal identify``'s DIR: the predicted tool-point accuracy (#29)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from selfcal.calibration.tracker.accuracy import SAMPLE_COUNT, error_model_from_json
from selfcal.calibration.tracker.calibration_file import read_tracker_calibration
from selfcal.calibration.tracker.cross_validation import cross_validation_line
from selfcal.calibration.tracker.spread import spread_line
from selfcal.cli.main import main
from selfcal.kinematics.tool_error import workspace_sample
from selfcal.plots.plotting import figure_problems
from selfcal.plots.workspace_map import workspace_map_figure
from selfcal.robot.definition import load_robot
from tests.integration.test_tracker_cli import _measurements, _write


@pytest.mark.slow
def test_identify_then_report_says_the_predicted_accuracy(tmp_path, capsys):
    robot = load_robot("er4u-paper")
    _, header, rows = _measurements(tmp_path, robot, m=30)
    keep = np.abs(rows[:, 0]) < 90.0  # joint 1 within +-90 deg: the region is not everything
    meas = _write(tmp_path / "m.csv", header, rows[keep])
    out = tmp_path / "cal"
    argv = ["identify", meas, "--robot", "er4u-paper", "--joint-units", "deg", "--out", str(out),
            "--spread", "20"]  # fmt: skip
    assert main(argv) == 0
    said = capsys.readouterr().out
    doc = json.loads((out / "calibration.json").read_text())
    acc = doc["accuracy"]
    inside, edge = acc["regions"]["inside"], acc["regions"]["edge"]
    line = (f"tool point within {inside['position_95_mm_max']:.3f} mm (95 %) inside the "
            f"calibrated region, {edge['position_95_mm_max']:.3f} mm at its edge")  # fmt: skip
    assert f"predicted: {line}" in said
    assert acc["model_error"]["rows"] == keep.sum() and acc["model_error"]["folds"] == 10
    assert len(acc["regions"]["calibration_postures"]["position_95_mm"]) == keep.sum()
    assert edge["position_95_mm_max"] > inside["position_95_mm_median"]
    spread = acc["spread"]
    assert spread["resamplings"] + spread["failed"] == 20
    assert spread_line(spread) in said
    assert main(["report", str(out)]) == 0
    said = capsys.readouterr().out
    assert said.startswith(f"report: {line};")
    report = json.loads((out / "report.json").read_text())
    assert report["accuracy"]["regions"] == acc["regions"]  # the same numbers, rebuilt
    md = (out / "report.md").read_text()
    assert (out / report["figures"][0]).is_file() and line in md and spread_line(spread) in md
    # the k-fold held-out RMS beside the fair nominal's, printed and in report.md
    cv = cross_validation_line(doc["fit"]["cross_validation"])
    assert cv is not None and cv.startswith("cross-validated over ") and "fair nominal" in cv
    assert f"{line}; {cv};" in said and cv[1:] in md

    cal = read_tracker_calibration(out / "calibration.json")
    em = error_model_from_json(acc, cal.model, cal.T_meas_fit, cal.names, False, "x")
    q = np.array(acc["calibration_postures_si"])
    sample = workspace_sample(q, cal.joint_limits, count=SAMPLE_COUNT)
    assert figure_problems(workspace_map_figure(em, sample, q, line, "tracker frame")) == []
