"""`selfcal export` refuses a board or field calibration whose held-out check in its folder is no
gain."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import pytest

from selfcal.calibration.board.evaluate import Evaluation, write_evaluation
from selfcal.camera import Pinhole
from selfcal.cli.deploy import _refuse_no_gain
from selfcal.console.common import CliError
from selfcal.errors import SelfCalWarning
from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "analytic"


@pytest.fixture
def cal_dir(tmp_path):
    robot = load_robot("ur5e")
    cam = Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480)
    res = BoardCalibrationResult(
        robot_model=robot.name, target={"type": "chessboard"}, camera_names=("left",),
        cameras=(cam,), camera_std=({},), model=nominal_mcpc(robot),
        nominal_model=nominal_mcpc(robot), reprojection_rms_px=0.1, frames=8, frames_used=8,
    )  # fmt: skip
    (tmp_path / "cal").mkdir()
    write_board_calibration(tmp_path / "cal" / "calibration.json", res)
    return tmp_path / "cal"


def _evaluation(cal_dir, calibration: str, calibrated: float, nominal: float) -> None:
    rms = {"calibrated": calibrated, "nominal": nominal}
    write_evaluation(cal_dir / "evaluation.json", Evaluation(rms, (), (), "held-out", calibration))


def test_a_held_out_check_of_no_gain_refuses_the_export(cal_dir):
    """Within SAME_RMS of the nominal is no gain, as `selfcal evaluate` says (a strict `<`
    exported a calibration 1e-8 below the nominal's RMS)."""
    _evaluation(cal_dir, str(cal_dir), 1.0 - 1e-8, 1.0)
    with pytest.raises(CliError, match="is not below the fair nominal's"):
        _refuse_no_gain(str(cal_dir), force=False)
    _evaluation(cal_dir, str(cal_dir / "calibration.json"), 0.5, 1.0)
    _refuse_no_gain(str(cal_dir), force=False)


def test_an_evaluation_of_another_calibration_is_not_used(cal_dir, tmp_path):
    """An evaluation.json in the folder that evaluates another calibration neither refuses nor
    passes this one: it is set aside with a warning."""
    _evaluation(cal_dir, str(tmp_path / "other"), 2.0, 1.0)
    with pytest.warns(SelfCalWarning, match="not used"):
        _refuse_no_gain(str(cal_dir), force=False)
    _evaluation(cal_dir, str(cal_dir), 2.0, 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CliError, match="not exported"):
            _refuse_no_gain(str(cal_dir), force=False)


def test_a_field_calibration_of_no_gain_held_out_is_refused_too(tmp_path):
    """The ArUco field's calibration (the golden one of the default scenario) with a held-out
    check in its folder that is no gain over its fair nominal: refused unless --force, as a
    board's (it was exported whatever its check said)."""
    cal_dir = tmp_path / "field"
    cal_dir.mkdir()
    shutil.copy(GOLDEN / "calibration.json", cal_dir / "calibration.json")
    _evaluation(cal_dir, str(cal_dir), 5.0, 5.0)
    with pytest.raises(CliError, match="is not below the fair nominal's"):
        _refuse_no_gain(str(cal_dir), force=False)
    with pytest.warns(SelfCalWarning, match="exported with --force"):
        _refuse_no_gain(str(cal_dir), force=True)
    _evaluation(cal_dir, str(cal_dir), 0.75, 5.0)
    _refuse_no_gain(str(cal_dir), force=False)


def test_an_evaluation_of_dot_refuses_the_export_from_another_folder(cal_dir, tmp_path,
                                                                     monkeypatch):  # fmt: skip
    """`selfcal evaluate . HELD --out evaluation.json` in the calibration's folder, then `selfcal
    export` from another: the evaluation (no gain) is of this calibration and refuses it (it
    recorded "." alone and was set aside, "evaluates ., not ...", review of session 25)."""
    import numpy as np

    monkeypatch.chdir(cal_dir)
    errs = [{"nominal": np.ones((3, 2)), "calibrated": np.full((3, 2), 2.0)}]
    rows = [{"image": "0000_left.png", "camera": "left", "features": 3}]
    write_evaluation(cal_dir / "evaluation.json", Evaluation.of(rows, errs, (), "held", "."))
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CliError, match="not exported"):
            _refuse_no_gain("cal", force=False)
