"""What an eye-to-hand cell (#28: the camera static, the board on the flange) writes: dataset.json
says ``setup`` (schema 4, so older code refuses the file instead of taking the images for a
wrist camera's), calibration.json says it and keeps base -> camera and flange -> board with
their sigmas (schema 2), and the hand-eye export writes them as the eye-on-base setup."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from selfcal.camera import Pinhole
from selfcal.export.handeye import from_mounts, to_easy_handeye_yaml, to_tf_yaml
from selfcal.io.board_calibration import (
    BoardCalibrationResult,
    Mount,
    read_board_calibration,
    write_board_calibration,
)
from selfcal.io.dataset_info import DatasetError, DatasetInfo, read_dataset_info, write_dataset_info
from selfcal.io.target_toml import load_target, target_document
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.transforms import pose_from_vec
from tests.unit.test_io import dataset_info

BOARD = target_document(load_target("models/targets/charuco.toml"))


def test_dataset_json_says_eye_to_hand(tmp_path):
    info = dataclasses.replace(dataset_info(), board=BOARD, setup="eye-to-hand")
    path = write_dataset_info(tmp_path / "dataset.json", info)
    doc = json.loads(path.read_text())
    assert doc["schema_version"] == 4 and doc["setup"] == "eye-to-hand"
    back = read_dataset_info(path)
    assert back.setup == "eye-to-hand" and back.eye_to_hand
    del doc["setup"]  # without the key: the cameras on the flange
    path.write_text(json.dumps(doc))
    assert read_dataset_info(path).setup == "eye-in-hand"
    doc["setup"] = "eye-on-base"
    path.write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match="setup"):
        read_dataset_info(path)


def test_an_eye_to_hand_dataset_needs_a_board():
    with pytest.raises(DatasetError, match="board"):
        dataclasses.replace(dataset_info(), board=None, setup="eye-to-hand")
    assert isinstance(dataclasses.replace(dataset_info(), board=BOARD, setup="eye-to-hand"),
                      DatasetInfo)  # fmt: skip


MOUNTS = (
    Mount("base -> camera", "base", "camera", pose_from_vec(np.r_[0.1, -0.2, 0.3, 0.5, -0.4, 0.9]),
          np.radians([0.01, 0.02, 0.03]), np.array([0.3, 0.2, 0.4]) / 1000),
    Mount("flange -> board", "flange", "board", pose_from_vec(np.r_[3.1, 0.0, 0.01, -0.1, 0.09, 0.05]),
          np.radians([0.02, 0.02, 0.003]), np.array([0.01, 0.01, 0.06]) / 1000),
)  # fmt: skip


def test_calibration_json_keeps_the_setup_and_the_mounts(tmp_path):
    robot = load_robot("ur5e")
    cam = Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480)
    cal = BoardCalibrationResult(
        robot_model=robot.name, target=BOARD, camera_names=("left",), cameras=(cam,),
        camera_std=({},), model=nominal_mcpc(robot), nominal_model=nominal_mcpc(robot),
        reprojection_rms_px=0.1, frames=8, frames_used=8, setup="eye-to-hand", mounts=MOUNTS,
    )  # fmt: skip
    path = write_board_calibration(tmp_path / "calibration.json", cal)
    doc = json.loads(path.read_text())
    assert doc["schema_version"] == 2 and doc["setup"] == "eye-to-hand"
    assert "first camera" in doc["world_frame"] and "board" in doc["mcpc"]["tool"]
    back = read_board_calibration(path)
    assert back.eye_to_hand
    for a, b in zip(back.mounts, MOUNTS, strict=True):
        assert (a.what, a.parent, a.child) == (b.what, b.parent, b.child)
        np.testing.assert_allclose(a.T, b.T, atol=1e-15)
        np.testing.assert_allclose(a.sigma_rotation_rad, b.sigma_rotation_rad, rtol=1e-12)
        np.testing.assert_allclose(a.sigma_xyz_m, b.sigma_xyz_m, rtol=1e-12)


def test_the_export_is_the_eye_on_base_setup():
    ex = from_mounts(MOUNTS, "calibration.json")
    assert ex.setup == "eye-to-hand"
    he = to_easy_handeye_yaml(ex)
    assert "eye_on_hand: false" in he and 'board_mount: "flange -> board"' in he
    tf = to_tf_yaml(ex)
    assert "parent: base_link" in tf and "child: camera_optical_frame" in tf
    assert "parent: tool0" in tf and "child: board" in tf


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_an_accuracy_block_in_joint_spans_is_schema_3(tmp_path, setup):
    """A block whose distances are in ``joint_spans_si`` (a revolute joint's range capped at one
    turn) is written as schema 3, so code that reads 2 at most, and would measure the distances
    in the full ranges, refuses it with "upgrade" instead of flagging the wrong postures."""
    robot = load_robot("ur5e")
    cam = Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480)
    cal = BoardCalibrationResult(
        robot_model=robot.name, target=BOARD, camera_names=("left",), cameras=(cam,),
        camera_std=({},), model=nominal_mcpc(robot), nominal_model=nominal_mcpc(robot),
        reprojection_rms_px=0.1, frames=8, frames_used=8, setup=setup,
        mounts=MOUNTS if setup == "eye-to-hand" else (),
        accuracy={"joint_spans_si": [2 * np.pi] * robot.n},
    )  # fmt: skip
    path = write_board_calibration(tmp_path / "calibration.json", cal)
    assert json.loads(path.read_text())["schema_version"] == 3
    assert read_board_calibration(path).accuracy["joint_spans_si"] == [2 * np.pi] * robot.n
    old = dataclasses.replace(cal, accuracy={"joint_limits_si": [[-1.0, 1.0]] * robot.n})
    doc = json.loads(write_board_calibration(tmp_path / "old.json", old).read_text())
    assert doc["schema_version"] == (2 if setup == "eye-to-hand" else 1)
