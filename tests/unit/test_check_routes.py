"""``selfcal check`` names the calibration it refuses by what it is, and what to run instead."""

from __future__ import annotations

import json

from selfcal.calibration.handeye.calibration_file import HANDEYE_FORMAT
from selfcal.cli.main import main


def test_a_hand_eye_calibration_is_refused_by_name_with_what_checks_it(tmp_path, capsys):
    """An eye-to-hand calibration from flange poses (`selfcal import --poses`) is not the marker
    field's: the refusal says which calibration it is and points at `selfcal evaluate`, which
    predicts new images from their flange poses."""
    cal = tmp_path / "cal"
    cal.mkdir()
    (cal / "calibration.json").write_text(json.dumps({"format": HANDEYE_FORMAT}))
    assert main(["check", str(cal), str(tmp_path / "new")]) == 2
    err = capsys.readouterr().err
    assert "field" not in err, err
    assert "hand-eye calibration from flange poses" in err, err
    assert f"selfcal evaluate {cal} NEW_DATASET" in err, err
