"""Export of the estimated camera (selfcal.export.camera, ``selfcal export --format
opencv|camera_info``): the OpenCV YAML read back with cv2.FileStorage, the camera_info YAML with
a YAML reader (as camera_calibration_parsers reads it), the same projection through OpenCV; the
format chosen by --format alone, whatever the file's suffix."""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from selfcal.camera import BrownConrady, Fisheye, Pinhole
from selfcal.cli.deploy import register
from selfcal.export.camera import to_camera_info_yaml, to_opencv_yaml
from selfcal.io.calibration import read_calibration, write_calibration
from selfcal.io.calibration_blocks import CameraIntrinsics

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "analytic" / "calibration.json"

CAMERAS = {
    "pinhole": Pinhole(801.25, 0.995, 331.5, 231.25, 640, 480),
    "plumb_bob": BrownConrady(801.25, 0.995, 331.5, 231.25, 640, 480,
                              coeffs=(-0.25, 0.1, 1e-3, -5e-4, 0.01, 0, 0, 0)),
    "rational_polynomial": BrownConrady(801.25, 0.995, 331.5, 231.25, 640, 480,
                                        coeffs=(-0.25, 0.1, 1e-3, -5e-4, 0.01, 0.02, 0, 0.001)),
    "equidistant": Fisheye(401.5, 1.0, 331.5, 231.25, 640, 480,
                           coeffs=(0.05, -0.02, 0.003, -0.001)),
}  # fmt: skip


def _read(text: str) -> cv2.FileStorage:
    fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    assert fs.isOpened()
    return fs


def _data(fs: cv2.FileStorage, key: str) -> np.ndarray:
    node = fs.getNode(key)
    rows, cols = int(node.getNode("rows").real()), int(node.getNode("cols").real())
    d = node.getNode("data")
    return np.array([d.at(i).real() for i in range(d.size())]).reshape(rows, cols)


def _opencv_projection(model: str, K: np.ndarray, D: np.ndarray, X: np.ndarray) -> np.ndarray:
    z = np.zeros(3)
    if model == "equidistant" or model == "fisheye":
        return cv2.fisheye.projectPoints(X.reshape(-1, 1, 3), z, z, K, D)[0].reshape(-1, 2)
    return cv2.projectPoints(X, z, z, K, D)[0].reshape(-1, 2)


def _check_same_projection(cam, got: np.ndarray) -> None:
    """A round trip loses nothing: OpenCV projects like the model, within the rounding of
    tests/unit/test_camera_lens.py (1.5 eps of |uv| + |c| + f measured; 3x that here)."""
    uv = cam.project(X)
    scale = np.abs(uv) + np.abs([cam.cx, cam.cy]) + [cam.fx, cam.fy]
    assert np.all(np.abs(got - uv) <= 4.5 * np.finfo(float).eps * scale)


X = np.c_[np.random.default_rng(0).uniform(-0.35, 0.35, (20, 2)), np.ones(20)] * 0.7


@pytest.mark.parametrize("kind", CAMERAS)
def test_opencv_yaml_reads_back_and_projects_the_same(kind):
    cam = CAMERAS[kind]
    fs = _read(to_opencv_yaml(cam))
    K, D = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat()
    assert (fs.getNode("image_width").real(), fs.getNode("image_height").real()) == (640, 480)
    np.testing.assert_array_equal(K, cam.K)
    assert D.shape == (1, {"pinhole": 5, "plumb_bob": 5, "rational_polynomial": 8,
                           "equidistant": 4}[kind])  # fmt: skip
    assert fs.getNode("distortion_model").string() == kind.replace("pinhole", "plumb_bob")
    _check_same_projection(cam, _opencv_projection(kind, K, D, X))


@pytest.mark.parametrize("kind", CAMERAS)
def test_camera_info_yaml_reads_back(kind):
    """ROS camera_calibration's convention: K, D, R = I and P = [K' | 0] with K' the rectified
    camera matrix (every pixel of the rectified image valid; K itself without distortion)."""
    cam = CAMERAS[kind]
    doc = yaml.safe_load(to_camera_info_yaml(cam, "left"))

    def mat(key: str) -> np.ndarray:
        m = doc[key]
        return np.array(m["data"], float).reshape(m["rows"], m["cols"])

    assert doc["camera_name"] == "left"
    assert (doc["image_width"], doc["image_height"]) == (640, 480)
    model = doc["distortion_model"]
    assert model == kind.replace("pinhole", "plumb_bob")
    K, D = mat("camera_matrix"), mat("distortion_coefficients")
    np.testing.assert_array_equal(K, cam.K)
    np.testing.assert_array_equal(mat("rectification_matrix"), np.eye(3))
    P = mat("projection_matrix")
    np.testing.assert_array_equal(P[:, 3], np.zeros(3))
    if kind == "pinhole":
        np.testing.assert_array_equal(P[:, :3], cam.K)
    else:  # every pixel of the rectified image is valid
        W, H = cam.width, cam.height
        corners = np.array([[0, 0, 1], [W - 1, 0, 1], [0, H - 1, 1], [W - 1, H - 1, 1.0]])
        rays = corners @ np.linalg.inv(P[:, :3]).T
        src = cam.project(rays)
        assert np.all(src > -1.0) and np.all(src < [W, H]), src
        assert not np.allclose(P[:, :3], cam.K)
    _check_same_projection(cam, _opencv_projection(model, K, D, X))


def _parser():
    p = argparse.ArgumentParser(prog="selfcal")
    register(p.add_subparsers(dest="command", required=True))
    return p


@pytest.mark.parametrize("fmt, suffix", [("opencv", "yaml"), ("camera_info", "yml")])
def test_cli_exports_the_calibrated_camera(tmp_path, capsys, fmt, suffix):
    """--format alone chooses the format: OpenCV YAML into a .yaml file and camera_info into a
    .yml file (each suffix the other format's usual one), said in words on stderr."""
    doc = json.loads(GOLDEN.read_text())
    shutil.copy(GOLDEN, tmp_path / "calibration.json")
    lens = CAMERAS["plumb_bob"]
    res = read_calibration(tmp_path)
    write_calibration(tmp_path / "calibration.json",
                      dataclasses.replace(res, intrinsics=CameraIntrinsics.of(lens, {})))  # fmt: skip
    out = tmp_path / f"cam.{suffix}"
    args = _parser().parse_args(["export", str(tmp_path), "--format", fmt, "--out", str(out)])
    assert args.func(args) == 0
    std = capsys.readouterr()
    info = json.loads(std.out)
    words = {"opencv": "OpenCV YAML for cv2.FileStorage", "camera_info": "ROS camera_info YAML"}
    assert info["format"] == fmt and info["out"] == str(out) and info["camera_model"] == "opencv"
    assert words[fmt] in info["written"] and f"wrote {out}: " in std.err
    assert words[fmt] in std.err
    if fmt == "opencv":
        fs = _read(out.read_text())  # kept: its nodes live as long as the storage
        K = fs.getNode("camera_matrix").mat()
    else:
        m = yaml.safe_load(out.read_text())["camera_matrix"]
        K = np.array(m["data"]).reshape(3, 3)
    np.testing.assert_array_equal(K, lens.K)
    assert doc["intrinsics"]["fx"] != lens.fx  # the file's camera, not the golden one
    args = _parser().parse_args(["export", str(tmp_path), "--out", str(out)])
    from selfcal.cli.main import CliError

    with pytest.raises(CliError, match="give --format: the format is never taken from"):
        args.func(args)  # the suffix names no format
    toml = tmp_path / "robot.toml"
    toml.write_text("x = 1\n")
    args = _parser().parse_args(["export", str(toml), "--format", fmt, "--out", str(out)])
    with pytest.raises(CliError, match="needs a calibration.json"):
        args.func(args)


def test_cli_exports_each_camera_of_a_field_rig_with_its_own_intrinsics(tmp_path, capsys):
    """A field calibration whose cameras have their own intrinsics (#12): --camera picks one,
    the default is the first; an unknown name is an error listing the cameras."""
    from selfcal.cli.main import CliError
    from selfcal.io.calibration_blocks import RigCamera

    res = read_calibration(GOLDEN)
    left, right = CAMERAS["plumb_bob"], CAMERAS["pinhole"]
    cams = (RigCamera("left", CameraIntrinsics.of(left, {})),
            RigCamera("right", CameraIntrinsics.of(right, {})))  # fmt: skip
    write_calibration(tmp_path / "calibration.json",
                      dataclasses.replace(res, intrinsics=cams[0].intrinsics, cameras=cams))  # fmt: skip
    for name, cam in ((None, left), ("right", right)):
        out = tmp_path / f"{name}.yml"
        argv = ["export", str(tmp_path), "--format", "opencv", "--out", str(out)] + (
            ["--camera", name] if name else []
        )
        args = _parser().parse_args(argv)
        assert args.func(args) == 0
        capsys.readouterr()
        fs = _read(out.read_text())  # kept: its nodes live as long as the storage
        np.testing.assert_array_equal(fs.getNode("camera_matrix").mat(), cam.K)
    args = _parser().parse_args(["export", str(tmp_path), "--format", "opencv", "--out",
                                 str(tmp_path / "x.yml"), "--camera", "middle"])  # fmt: skip
    with pytest.raises(CliError, match="calibrates the cameras left, right"):
        args.func(args)
    for extra, name in (([], "camera"), (["--camera", "right"], "right"),
                        (["--camera", "right", "--camera-name", "wrist"], "wrist")):  # fmt: skip
        out = tmp_path / "info.yaml"
        args = _parser().parse_args(["export", str(tmp_path), "--format", "camera_info",
                                     "--out", str(out), *extra])  # fmt: skip
        assert args.func(args) == 0
        assert f"camera_name: {name}\n" in out.read_text()  # the camera exported, by default
