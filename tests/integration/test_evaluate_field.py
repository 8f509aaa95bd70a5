"""`selfcal evaluate` for the ArUco field: the calibrated marker corners (calibration.json
`scene`) and the stereo rig predict a held-out dataset of the same robot and field from its joint
readings alone (analytic path, default scenario, 0.5 px corner noise; held-out postures from
another trajectory seed). Measured: held-out RMS nominal 12.87 px, calibrated 0.751 px (the noise
floor is sqrt(2) * 0.5 = 0.71 px)."""

from __future__ import annotations

import json

from calib.io.calibration import read_calibration
from scenarios.cli import main
from scenarios.config import load_scenario
from scenarios.pipeline import run_acquire


def test_field_calibration_predicts_a_held_out_dataset(tmp_path, capsys):
    cal, held = tmp_path / "cal", tmp_path / "held"
    run_acquire(load_scenario(overrides={"noise": {"render": False}}), cal, quiet=True)
    s = load_scenario(overrides={"noise": {"render": False, "seed": 9},
                                 "trajectory": {"poses": 8, "seed": 7}})  # fmt: skip
    run_acquire(s, held, quiet=True)
    assert main(["calibrate", str(cal), "--quiet"]) == 0
    res = read_calibration(cal)
    assert res.scene is not None and len(res.scene.point_ids) > 40
    capsys.readouterr()
    assert main(["evaluate", str(cal), str(held)]) == 0
    assert "calibrated" in capsys.readouterr().out
    ev = json.loads((held / "evaluation.json").read_text())
    rms = ev["reprojection_rms_px"]
    assert rms["calibrated"] < 1.0 and rms["nominal"] > 5.0
    assert {i["image"][5:] for i in ev["images"]} == {"left", "right"}
