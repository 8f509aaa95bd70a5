"""`selfcal plan --add` forecasts with the corner noise its dataset's calibration estimated: a new
user's rendered 3-joint dataset fitted to 0.036 px was forecast at the default 0.5 px, whose noise
alone (0.71 px) exceeded the folds' measured misfit (0.39 px), so the arm's deviation was sized to
its floor and the fair nominal predicted at 0.28 mm (measured 1.58 mm)."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from selfcal.camera import Pinhole
from selfcal.cli.plan_add import corner_noise
from selfcal.io.board_calibration import (
    BoardBounds,
    BoardCalibrationResult,
    write_board_calibration,
)
from selfcal.io.calibration_bounds import ToolTipBound
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot


def _calibration(folder, sigma_px: float | None):
    robot = load_robot("ur5e")
    res = BoardCalibrationResult(
        robot_model=robot.name, target={"type": "chessboard"}, camera_names=("left",),
        cameras=(Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480),), camera_std=({},),
        model=nominal_mcpc(robot), nominal_model=nominal_mcpc(robot), reprojection_rms_px=0.05,
        frames=12, frames_used=12,
    )  # fmt: skip
    if sigma_px is not None:
        bounds = BoardBounds(pixel_sigma_px=sigma_px, joint_sigma_deg=None, observations=1056,
                             unknowns=26, tool_tip_rms_mm=ToolTipBound(bound=0.03, validation_poses=12),
                             cameras=(), parameters=())  # fmt: skip
        res = dataclasses.replace(res, bounds=bounds)
    folder.mkdir()
    write_board_calibration(folder / "calibration.json", res)
    return folder


def _args(given: float | None) -> argparse.Namespace:
    """As selfcal plan leaves them: --pixel-sigma's default filled in, whether it was given."""
    return argparse.Namespace(pixel_sigma=0.5 if given is None else given,
                              pixel_sigma_given=given is not None)  # fmt: skip


def test_without_pixel_sigma_the_calibrations_noise_is_used_and_said(tmp_path):
    root = _calibration(tmp_path / "ds", 0.0355)
    args = _args(None)
    got = corner_noise(args, root)
    assert args.pixel_sigma == pytest.approx(0.0355) and got["px"] == pytest.approx(0.0355)
    assert got["source"] == "calibration"
    assert got["words"].startswith("corner noise 0.0355 px, the calibration's")
    assert "bounds.pixel_sigma_px" in got["words"] and "--pixel-sigma overrides" in got["words"]


def test_a_given_pixel_sigma_wins(tmp_path):
    root = _calibration(tmp_path / "ds", 0.0355)
    args = _args(0.2)
    got = corner_noise(args, root)
    assert args.pixel_sigma == 0.2 and got["source"] == "given"
    assert got["words"] == "corner noise 0.2 px, as given"


def test_a_calibration_without_bounds_keeps_the_default_and_says_why(tmp_path):
    root = _calibration(tmp_path / "ds", None)
    args = _args(None)
    got = corner_noise(args, root)
    assert args.pixel_sigma == 0.5 and got["source"] == "default"
    assert "records no corner noise" in got["words"]
