"""`selfcal export --format camera_info` of a board calibration names the camera it exports:
on the photoneo set the command said "camera cam0" and a bag of the same dataset publishes
/cam0/camera_info, but the file's camera_name read "camera" (new user's trip, session 26)."""

from __future__ import annotations

import argparse

import yaml

from selfcal.camera import Pinhole
from selfcal.cli.deploy import register
from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="selfcal")
    register(p.add_subparsers(dest="command", required=True))
    return p


def test_a_board_calibration_s_camera_info_is_named_as_its_camera(tmp_path, capsys):
    robot = load_robot("ur5e")
    cams = (
        Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480),
        Pinhole(810.0, 1.0, 320.0, 240.0, 640, 480),
    )
    res = BoardCalibrationResult(
        robot_model=robot.name, target={"type": "chessboard"}, camera_names=("cam0", "cam1"),
        cameras=cams, camera_std=({}, {}), model=nominal_mcpc(robot),
        nominal_model=nominal_mcpc(robot), reprojection_rms_px=0.1, frames=8, frames_used=8,
    )  # fmt: skip
    write_board_calibration(tmp_path / "calibration.json", res)
    for extra, name, fx in (([], "cam0", 800.0), (["--camera", "cam1"], "cam1", 810.0),
                            (["--camera-name", "wrist"], "wrist", 800.0)):  # fmt: skip
        out = tmp_path / "info.yaml"
        args = _parser().parse_args(["export", str(tmp_path), "--format", "camera_info",
                                     "--out", str(out), *extra])  # fmt: skip
        assert args.func(args) == 0
        err = capsys.readouterr().err
        info = yaml.safe_load(out.read_text())
        assert info["camera_name"] == name and info["camera_matrix"]["data"][0] == fx
        if name != "wrist":
            assert f"camera {name} (pinhole model)" in err  # the message names the same camera
