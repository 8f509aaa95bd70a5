"""A damaged ``calibration.json`` is refused when read, by every command (#33): the readers
(:mod:`selfcal.io.calibration`, :mod:`selfcal.io.board_calibration`) check that the numbers are
finite, focal lengths positive, poses rigid. Before, ``fx = NaN`` exported ``.Nan`` into an
OpenCV camera matrix and ``fx = -800`` a camera_info, both with exit 0."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from selfcal.camera import Pinhole
from selfcal.cli import main as cli
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "analytic" / "calibration.json"


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _set(doc: dict, path: str, value) -> None:
    *head, last = path.split(".")
    for k in head:
        doc = doc[int(k)] if isinstance(doc, list) else doc[k]
    doc[last] = value


def _reflect(T: list) -> list:
    return (np.array(T) @ np.diag([1.0, 1.0, -1.0, 1.0])).tolist()


def _field(tmp_path: Path, path: str, value) -> Path:
    doc = json.loads(GOLDEN.read_text())
    _set(doc, path, value(doc) if callable(value) else value)
    (tmp_path / "calibration.json").write_text(json.dumps(doc))
    return tmp_path


FIELD_CASES = {
    "intrinsics.fx": float("nan"),
    "intrinsics.fy": -800.0,
    "intrinsics.cx": float("inf"),
    "intrinsics.width": 0,
    "rig.T_left_right_m": lambda d: (np.array(d["rig"]["T_left_right_m"]) * 2).tolist(),
    "hand_eye.T_flange_cam_m": lambda d: _reflect(d["hand_eye"]["T_flange_cam_m"]),
    "camera_poses.T_world_cam_left_m": lambda d: [
        [[float("nan")] * 4] * 4,
        *d["camera_poses"]["T_world_cam_left_m"][1:],
    ],
}


@pytest.mark.parametrize("key", FIELD_CASES)
@pytest.mark.parametrize("fmt", ["opencv", "camera_info"])
def test_a_damaged_field_calibration_is_refused_naming_the_key(capsys, tmp_path, key, fmt):
    ds = _field(tmp_path, key, FIELD_CASES[key])
    code, out, err = run(capsys, "export", ds, "--format", fmt, "--out", tmp_path / "cam.yml")
    assert code == 2 and out == "", err
    assert str(ds / "calibration.json") in err and f"'{key}'" in err
    assert not (tmp_path / "cam.yml").exists()


def test_fy_must_be_mu_fx(capsys, tmp_path):
    """An edited fx with fy and mu left as they were is a damaged file, not another camera."""
    ds = _field(tmp_path, "intrinsics.fx", lambda d: d["intrinsics"]["fx"] * 1.5)
    code, _, err = run(capsys, "export", ds, "--format", "opencv", "--out", tmp_path / "c.yml")
    assert code == 2 and "'intrinsics.fy'" in err and "fy = mu fx" in err


def test_non_utf8_calibration_names_the_file(capsys, tmp_path):
    (tmp_path / "calibration.json").write_bytes(GOLDEN.read_bytes()[:40] + b"\xff\xfe" + b"}")
    code, _, err = run(capsys, "export", tmp_path, "--format", "opencv", "--out", tmp_path / "c")
    assert code == 2 and "not UTF-8" in err and str(tmp_path / "calibration.json") in err


def _board(tmp_path: Path) -> dict:
    robot = load_robot("ur5e")
    cam = Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480)
    res = BoardCalibrationResult(
        robot_model=robot.name, target={"type": "chessboard"}, camera_names=("left", "right"),
        cameras=(cam, cam), camera_std=({}, {}), model=nominal_mcpc(robot),
        nominal_model=nominal_mcpc(robot), reprojection_rms_px=0.1, frames=8, frames_used=8,
        T_first_cam=np.stack([np.eye(4), np.eye(4)]),
    )  # fmt: skip
    return res.to_json()


BOARD_CASES = {
    "cameras.0.parameters.fx": float("nan"),
    "cameras.0.parameters.fy": -800.0,
    "cameras.0.parameters.cy": float("-inf"),
    "cameras.0.resolution": [640, 480, 3],
    "cameras.1.T_first_camera": _reflect(np.eye(4).tolist()),
    "mcpc.params_si": lambda d: [[float("nan")] * 6] * len(d["mcpc"]["params_si"]),
}


@pytest.mark.parametrize("key", BOARD_CASES)
def test_a_damaged_board_calibration_is_refused_naming_the_key(capsys, tmp_path, key):
    doc = _board(tmp_path)
    v = BOARD_CASES[key]
    _set(doc, key, v(doc) if callable(v) else v)
    (tmp_path / "calibration.json").write_text(json.dumps(doc))
    code, out, err = run(capsys, "export", tmp_path, "--format", "camera_info",
                         "--out", tmp_path / "cam.yaml")  # fmt: skip
    assert code == 2 and out == "", err
    assert str(tmp_path / "calibration.json") in err
    assert key.replace(".0.", "[0].").replace(".1.", "[1].").split(".")[-1] in err
    assert not (tmp_path / "cam.yaml").exists()


def test_the_undamaged_board_calibration_exports(capsys, tmp_path):
    """The damaged cases above fail for the damage: the file they start from exports."""
    (tmp_path / "calibration.json").write_text(json.dumps(_board(tmp_path)))
    code, _, err = run(capsys, "export", tmp_path, "--format", "camera_info",
                       "--out", tmp_path / "cam.yaml")  # fmt: skip
    assert code == 0, err


@pytest.mark.parametrize("argv", [["export", "{d}", "--out", "{d}/o.urdf", "--format", "urdf"],
                                  ["export", "{d}", "--out", "{d}/o.toml", "--format", "toml"],
                                  ["fk", "--calibration", "{d}", "--joints", "0,0,0,0,0"]])  # fmt: skip
def test_a_robot_model_no_robot_has_is_named_with_the_file(capsys, tmp_path, argv):
    """#33's leftover: robot_model 'no-such-arm' stopped with the robot lookup's message alone,
    not naming the calibration.json that names it."""
    d = _field(tmp_path, "robot_model", "no-such-arm")
    code, _, err = run(capsys, *[a.format(d=d) for a in argv])
    assert code == 2
    assert f"{d / 'calibration.json'}: robot_model 'no-such-arm' is not a robot" in err
    assert " -- calibrate again with this version, or pass the robot file" in err
