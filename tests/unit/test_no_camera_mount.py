"""A robot file without ``[camera_mount]`` (a URDF never has one) makes the calibrated tool tip
the camera's optical frame. Session 25's new-user trip: the photoneo set's calibration (its
robot the Nachi URDF) exported as URDF and solved by ``selfcal ik --calibration`` without a
word, the joints 15 deg (j2) and 87 deg (j6) from the nominal's for the same target, because
the "tool tip" was the camera 167.1 mm and 91.0 deg from the flange. Now ``fk``/``ik
--calibration`` and ``export`` warn, naming the file and the fix."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from types import SimpleNamespace

import pytest

from selfcal.cli.calibration_files import NoCameraMountWarning, calibration_robot

NACHI = (Path(__file__).resolve().parents[1] / "data" / "real" / "nachi-2025-01-17-photoneo"
         / "inputs" / "nachi_mz25.urdf")  # fmt: skip


def _calibration(tmp_path: Path, robot_model: str) -> Path:
    p = tmp_path / "calibration.json"
    p.write_text(json.dumps({"robot_model": robot_model}))
    return p


def test_a_robot_file_without_camera_mount_is_said(tmp_path):
    p = _calibration(tmp_path, str(NACHI))
    with pytest.warns(NoCameraMountWarning) as got:
        robot = calibration_robot(str(tmp_path), "nachi_mz25")
    assert not robot.camera_mount_given
    text = str(got.list[0].message)
    # the URDF's <robot name="nachi_mz25_nominal">, not its file's stem
    assert text.startswith(f"{p}: the robot file of nachi_mz25_nominal gives no [camera_mount]")
    assert "the tool tip here is the calibrated camera's optical frame" in text
    assert "[camera_mount] xyz_mm, x_axis, z_axis" in text and "[urdf] file" in text


def test_a_shipped_model_with_its_mount_is_not(tmp_path):
    _calibration(tmp_path, "ur5e")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert calibration_robot(str(tmp_path), "ur5e").camera_mount_given


def test_the_exported_tool_frame_words_hold_without_a_camera_mount():
    """``export --format urdf``'s JSON ``tool_frame`` (and the URDF's and TOML's comment) said
    "the identified left camera ...; orientation of the nominal flange" for the photoneo set's
    single camera and its Nachi URDF, while the same command warned that the tool tip is the
    camera's optical frame (session 26's new user): the words now say both cases."""
    from selfcal.export.deploy import TOOL_FRAME

    assert "left camera composed" not in TOOL_FRAME  # a single camera has no left
    assert "without [camera_mount]" in TOOL_FRAME
    assert "the calibrated camera's optical frame (z along its view), not the flange" in TOOL_FRAME


def test_an_exported_toml_of_a_users_robot_named_like_a_shipped_one_is_the_users(
    tmp_path, monkeypatch
):
    """A robot loaded from a URDF is named by its <robot name> (session 27); an exported TOML
    then found its robot by that name among the shipped ones first, so a user's URDF named
    "ur5e" with other dimensions read back as the shipped UR5e. The calibration the TOML names
    as its source (its folder's robot file) comes first now."""
    import selfcal.export.robot_toml as robot_toml

    urdf = tmp_path / "my_arm.urdf"
    urdf.write_text(NACHI.read_text().replace('name="nachi_mz25_nominal"', 'name="ur5e"', 1))
    cal = _calibration(tmp_path, str(urdf))
    toml = tmp_path / "exported.toml"
    toml.write_text("# an exported calibration")
    monkeypatch.setattr(robot_toml, "from_toml", lambda text: SimpleNamespace(source=str(cal)))
    with pytest.warns(NoCameraMountWarning):  # the Nachi URDF has none; the shipped UR5e has
        robot = calibration_robot(str(toml), "ur5e")
    assert robot.name == "ur5e" and not robot.camera_mount_given
