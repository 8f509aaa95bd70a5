"""``selfcal report`` of a pose dataset's calibration (selfcal.pipeline.handeye_report): the hand-eye
and the board mount with sigmas beside the nominal, the fit, the note that no kinematics were
identified, and the held-out check of DIR/evaluation.json with its verdict."""

from __future__ import annotations

import json

import numpy as np
from test_handeye import BOARD, CAMERA, _features, _scene

from selfcal.calibration.handeye.calibrate import calibrate_hand_eye, chain_motions
from selfcal.calibration.handeye.calibration_file import handeye_document
from selfcal.cli.main import main
from selfcal.io.jsonfile import write_json_atomic


def test_report_of_a_pose_calibration(tmp_path, capsys):
    X, B, F = _scene("eye-to-hand", 10, seed=23)
    feats = _features(X, B, chain_motions("eye-to-hand", F), 0.3, 2)
    cal = calibrate_hand_eye(BOARD, feats, F, "eye-to-hand", 1280, 960, free=CAMERA.free,
                             camera="refined")  # fmt: skip
    doc = handeye_document(cal, str(tmp_path))
    write_json_atomic(tmp_path / "calibration.json", doc)

    assert main(["report", str(tmp_path)]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("report (eye-to-hand, flange poses: no kinematics identified): fit ")
    assert (
        f"{cal.calibrated.rms_px:.3f} px RMS calibrated, {cal.nominal.rms_px:.3f} px nominal"
        in line
    )
    assert "evaluation.json is missing" in line and "\n" not in line
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["kind"] == "handeye" and "No kinematics were identified" in rep["kinematics"]
    he, bm = rep["transforms"]
    assert (he["what"], bm["what"]) == ("base -> camera", "flange -> board")
    np.testing.assert_allclose(he["calibrated"]["xyz_mm"], cal.calibrated.X[:3, 3] * 1000)
    np.testing.assert_allclose(he["nominal"]["xyz_mm"], cal.nominal.X[:3, 3] * 1000)
    np.testing.assert_allclose(bm["calibrated"]["sigma_xyz_mm"], cal.calibrated.B_std[3:] * 1000)
    d = np.linalg.norm(cal.calibrated.X[:3, 3] - cal.nominal.X[:3, 3]) * 1000
    assert abs(he["difference_mm"] - d) < 1e-9
    assert rep["camera"]["parameters"]["fx"]["nominal"] == cal.nominal.camera.fx
    md = (tmp_path / "report.md").read_text()
    assert "No kinematics were identified" in md and "| base -> camera |" in md
    assert (
        rep["flange_poses"].startswith("flange poses: ")
        and "left-out images" in rep["flange_poses"]
    )
    assert rep["flange_poses"][1:] in md  # the cross-validation's choice, the first letter capital

    # a held-out evaluation of this calibration, as `selfcal evaluate CAL HELD --out
    # CAL/evaluation.json` writes it, where the calibration predicts worse than the nominal
    ev = {"calibration": str(tmp_path), "dataset": "held", "setup": "eye-to-hand", "frames": 4,
          "corners": 140, "held_out_rms_px": {"nominal": 0.41, "calibrated": 0.43},
          "calibration_better_than_nominal": False}  # fmt: skip
    write_json_atomic(tmp_path / "evaluation.json", ev)
    assert main(["report", str(tmp_path), "-q"]) == 0
    line = capsys.readouterr().out
    assert "held-out reprojection 0.430 px RMS calibrated, 0.410 px nominal over 4 frames" in line
    assert "the calibration is NOT better than the nominal" in line
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["held_out"]["reprojection_rms_px"] == ev["held_out_rms_px"]
    # an answer that holds the camera stage's camera is the nominal, and says so
    doc["camera_choice"] = {"treatment": "held", "cross_validation": {
        "folds": 8, "held_px": 0.41, "refined_px": 0.4106, "margin": 0.01, "chosen": "held"}}  # fmt: skip
    write_json_atomic(tmp_path / "calibration.json", doc)
    assert main(["report", str(tmp_path), "-q"]) == 0
    line = capsys.readouterr().out
    assert "the calibration is the nominal: the camera held at the board calibration's" in line
    assert ("Camera: held at the board calibration's; left-out images predicted from their "
            "poses (8 folds): held 0.410 px, refined 0.411 px (refined only when better by more "
            "than 1 %).") in (tmp_path / "report.md").read_text()  # fmt: skip
    ev["calibration"] = str(tmp_path / "other")  # another calibration's evaluation is not used
    write_json_atomic(tmp_path / "evaluation.json", ev)
    assert main(["report", str(tmp_path), "-q"]) == 0
    assert "is not an evaluation of" in capsys.readouterr().out
    # `selfcal evaluate . HELD` run in CAL records "." and its calibration.json's absolute path,
    # which names it from this working directory too ("." alone named the cwd: not used)
    ev.update(calibration=".", calibration_file=str(tmp_path / "calibration.json"))
    write_json_atomic(tmp_path / "evaluation.json", ev)
    assert main(["report", str(tmp_path), "-q"]) == 0
    line = capsys.readouterr().out
    assert "is not an evaluation of" not in line and "held-out reprojection 0.430 px" in line


def test_held_out_corners_behind_the_camera_and_frames_without_the_board():
    """`selfcal evaluate` of a pose dataset: a corner the calibrated model puts behind the camera
    is a failure, counted apart (it made the RMS NaN: "nan px", exit 0); a frame with fewer
    corners than the board's min_features is left out with a warning."""
    import dataclasses

    import pytest

    from selfcal.calibration.handeye.held_out import HeldOutWarning, held_out_check
    from selfcal.target.base import Features
    from selfcal.transforms import make_pose

    X, B, F = _scene("eye-in-hand", 6, seed=5)
    feats = _features(X, B, chain_motions("eye-in-hand", F), 0.3, 1)
    feats[2] = Features(feats[2].ids[:3], feats[2].uv[:3])
    cal = calibrate_hand_eye(BOARD, feats[:2] + feats[3:], np.delete(F, 2, axis=0), "eye-in-hand",
                             1280, 960, free=CAMERA.free)  # fmt: skip
    models = {"nominal": cal.nominal, "calibrated": cal.calibrated}
    with pytest.warns(HeldOutWarning, match=r"in 1 of 6 held-out frame\(s\), left out: 2"):
        ok = held_out_check(BOARD, feats, F, "eye-in-hand", models, "held")
    assert ok["frames"] == 5 and ok["skipped_frames"] == [2] and not ok["failures"]
    assert ok["behind_camera"] == {"nominal": 0, "calibrated": 0}
    assert 0.2 < ok["held_out_rms_px"]["calibrated"] < 0.6  # the 0.3 px noise per coordinate
    # the camera turned half round about its x-axis: every corner behind it
    flipped = cal.calibrated.X @ make_pose(np.diag([1.0, -1.0, -1.0]), np.zeros(3))
    models["calibrated"] = dataclasses.replace(cal.calibrated, X=flipped)
    with pytest.warns(HeldOutWarning):
        bad = held_out_check(BOARD, feats, F, "eye-in-hand", models, "held")
    assert bad["behind_camera"] == {"nominal": 0, "calibrated": 5 * 35}
    assert bad["held_out_rms_px"]["calibrated"] is None
    assert not bad["calibration_better_than_nominal"]
    assert bad["failures"] and "175 of 175 held-out corners" in bad["failures"][0]
