"""The hand-eye export (selfcal.export.handeye, ``selfcal export --format tf|easy_handeye|matrix``):
a pose dataset's calibration of known poses read back from each format as ROS and easy_handeye
read it (the static_transform_publisher arguments, the launch XML, easy_handeye's keys), the
quaternion and Euler angles recomposed; a chain with joints gives flange -> camera and
base -> board with the sigmas carried to first order."""

from __future__ import annotations

import argparse
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation
from test_handeye import BOARD, CAMERA, _features, _scene

from selfcal.calibration.handeye.calibrate import calibrate_hand_eye, chain_motions
from selfcal.calibration.handeye.calibration_file import handeye_document
from selfcal.calibration.handeye.eiv import EXACT
from selfcal.cli.deploy import register
from selfcal.export.handeye import from_chain
from selfcal.io.jsonfile import write_json_atomic
from selfcal.kinematics.alignment import regauge
from selfcal.kinematics.mcpc import chain_transforms, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.transforms import make_pose

FRAMES = ("base_link", "tool0", "camera_optical_frame", "board")


@pytest.fixture(scope="module", params=["eye-in-hand", "eye-to-hand"])
def calibrated(request, tmp_path_factory):
    """A noise-free pose dataset's calibration.json and its truth ``X``, ``B``."""
    setup = request.param
    X, B, F = _scene(setup, 10, seed=21)
    feats = _features(X, B, chain_motions(setup, F), 0.0, 1)
    cal = calibrate_hand_eye(BOARD, feats, F, setup, 1280, 960, free=CAMERA.free, pose_noise=EXACT)
    root = tmp_path_factory.mktemp(setup)
    write_json_atomic(root / "calibration.json", handeye_document(cal, str(root)))
    return root, setup, X, B


def _export(root, fmt: str, capsys, *extra: str) -> tuple[dict, dict, str]:
    p = argparse.ArgumentParser(prog="selfcal")
    register(p.add_subparsers(dest="command", required=True))
    out = root / f"{fmt}.txt"  # the suffix chooses nothing
    args = p.parse_args(["export", str(root), "--format", fmt, "--out", str(out), *extra])
    assert args.func(args) == 0
    std = capsys.readouterr()
    return yaml.safe_load(out.read_text()), json.loads(std.out), std.err


def _ros2_args(text: str) -> tuple[np.ndarray, str, str]:
    """The transform, parent and child of ROS 2 static_transform_publisher arguments."""
    a = text.split()
    kv = {a[i].lstrip("-"): a[i + 1] for i in range(0, len(a), 2)}
    q = [float(kv[k]) for k in ("qx", "qy", "qz", "qw")]
    T = make_pose(Rotation.from_quat(q).as_matrix(), [float(kv[k]) for k in "xyz"])
    return T, kv["frame-id"], kv["child-frame-id"]


def _ros1_args(text: str) -> tuple[np.ndarray, str, str]:
    a = text.split()
    v = [float(x) for x in a[:7]]
    return make_pose(Rotation.from_quat(v[3:]).as_matrix(), v[:3]), a[7], a[8]


def _truth(setup, X, B):
    """The hand-eye and the board mount with their ROS frames."""
    if setup == "eye-in-hand":
        return [(X, "tool0", "camera_optical_frame"), (B, "base_link", "board")]
    return [(X, "base_link", "camera_optical_frame"), (B, "tool0", "board")]


def test_tf_publishes_the_calibrated_transforms(calibrated, capsys):
    root, setup, X, B = calibrated
    doc, info, err = _export(root, "tf", capsys)
    cal = json.loads((root / "calibration.json").read_text())
    assert info["format"] == "tf" and "ROS static transforms" in err
    assert doc["setup"] == setup and len(doc["transforms"]) == 2
    launch2 = ET.fromstring(doc["launch_ros2_xml"]).findall("node")
    launch1 = ET.fromstring(doc["launch_ros1"]).findall("node")
    for k, ((T_true, parent, child), t, key) in enumerate(
        zip(_truth(setup, X, B), doc["transforms"], ("hand_eye", "board_mount"), strict=True)
    ):
        for T, p, c in (_ros2_args(t["ros2"].split("static_transform_publisher")[1]),
                        _ros1_args(t["ros1"].split("static_transform_publisher")[1]),
                        _ros2_args(launch2[k].get("args")), _ros1_args(launch1[k].get("args"))):  # fmt: skip
            assert (p, c) == (parent, child) == (t["parent"], t["child"])
            np.testing.assert_allclose(T, T_true, atol=1e-6)  # noise-free: the truth
            np.testing.assert_allclose(T, cal[key]["matrix"], atol=1e-12)
        np.testing.assert_allclose(t["sigma_xyz_mm"], cal[key]["sigma_xyz_mm"], rtol=1e-15)
        assert t["what"] == cal[key]["transform"]


def test_easy_handeye_reads_the_hand_eye(calibrated, capsys):
    root, setup, X, B = calibrated
    doc, _, err = _export(root, "easy_handeye", capsys, "--frames", ",".join(FRAMES))
    par, tr = doc["parameters"], doc["transformation"]
    # the keys easy_handeye's HandeyeCalibrationParameters(**parameters) takes
    assert set(par) == {"namespace", "move_group_namespace", "move_group", "eye_on_hand",
                        "robot_base_frame", "robot_effector_frame", "tracking_base_frame",
                        "tracking_marker_frame"}  # fmt: skip
    assert par["eye_on_hand"] is (setup == "eye-in-hand")
    assert (par["robot_base_frame"], par["robot_effector_frame"]) == FRAMES[:2]
    assert par["tracking_base_frame"] == "camera_optical_frame"
    T = make_pose(Rotation.from_quat([tr[k] for k in ("qx", "qy", "qz", "qw")]).as_matrix(),
                  [tr[k] for k in "xyz"])  # fmt: skip
    np.testing.assert_allclose(T, X, atol=1e-6)  # effector (or base) -> tracking base frame
    assert "easy_handeye" in err


def test_matrix_quaternion_and_euler_agree(calibrated, capsys):
    root, setup, X, B = calibrated
    doc, _, _ = _export(root, "matrix", capsys)
    for (T_true, parent, _), t in zip(_truth(setup, X, B), doc["transforms"], strict=True):
        T = np.array(t["matrix"])
        np.testing.assert_allclose(T, T_true, atol=1e-6)
        np.testing.assert_allclose(np.array(t["translation_mm"]) / 1000.0, T[:3, 3], atol=1e-15)
        R_q = Rotation.from_quat(t["quaternion_xyzw"]).as_matrix()
        r, p, y = np.radians(t["euler_rpy_deg"])
        Rz, Ry, Rx = (Rotation.from_rotvec(a * np.eye(3)[i]).as_matrix()
                      for a, i in ((y, 2), (p, 1), (r, 0)))  # fmt: skip
        np.testing.assert_allclose(R_q, T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(Rz @ Ry @ Rx, T[:3, :3], atol=1e-12)
        assert t["parent"] == parent and t["quaternion_xyzw"][3] >= 0


def test_robot_formats_of_a_pose_calibration_are_refused(calibrated, capsys):
    from selfcal.console.common import CliError

    root = calibrated[0]
    with pytest.raises(CliError, match="identified no kinematics"):
        _export(root, "urdf", capsys)
    with pytest.raises(CliError, match="four frame names"):
        _export(root, "tf", capsys, "--frames", "a,b")
    doc, info, _ = _export(root, "camera_info", capsys)  # its camera exports
    assert info["camera_model"] == "opencv" and doc["camera_matrix"]["rows"] == 3


def test_a_chain_with_joints_gives_flange_camera_and_base_board():
    """A board calibration's chain (world = the board, tool = the camera) built from the nominal
    robot placed at a known board pose: flange -> camera is the robot's camera mount, base ->
    board the placement; a 1 mm sigma of lz_n alone is 1 mm along the camera mount's last axis."""
    robot = load_robot("er4u-paper")
    cam = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    T_board_base = make_pose(Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), [0.4, 0.1, -0.2])
    G = chain_transforms(cam)
    model = regauge([T_board_base @ G[0], *G[1:]], cam.joint_types, cam.joint_offsets)
    n = model.n
    ex = from_chain(model, robot, {f"lz{n}": 1e-3}, "synthetic", board=True)
    he, bm = ex.transforms
    np.testing.assert_allclose(he.T, robot.T_flange_cam, atol=1e-12)
    np.testing.assert_allclose(bm.T, np.linalg.inv(T_board_base), atol=1e-12)
    assert (he.parent, he.child, bm.parent, bm.child) == ("flange", "camera", "base", "board")
    assert bm.sigma_xyz_m is None and he.sigma_xyz_m is not None
    assert np.linalg.norm(he.sigma_xyz_m) == pytest.approx(1e-3, rel=1e-5)
    assert np.all(he.sigma_rotation_rad < 1e-9)
    assert from_chain(model, robot, {}, "synthetic", board=False).transforms[0].sigma_xyz_m is None


def test_a_chain_without_a_base_frame_gives_flange_camera_alone():
    """A board calibration of a chain whose joint 1 is prismatic (an arm on a track) has no base
    frame rebuilt on axes 1 and 2: flange -> camera is exported alone, the note says why (it
    raised and `selfcal export --format tf` exited 1)."""
    from selfcal.robot.definition import models_dir

    robot = load_robot(str(models_dir().parent / "tests" / "data" / "virtual_chain_xyz.urdf"))
    T_flange_cam = make_pose(Rotation.from_rotvec([0.2, 0.1, -0.3]).as_matrix(), [0.01, 0.0, 0.05])
    cam = nominal_mcpc(robot).with_tool(T_flange_cam)
    T_board_base = make_pose(Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), [0.4, 0.1, -0.2])
    G = chain_transforms(cam)
    model = regauge([T_board_base @ G[0], *G[1:]], cam.joint_types, cam.joint_offsets)
    ex = from_chain(model, robot, {}, "synthetic", board=True)
    (he,) = ex.transforms
    np.testing.assert_allclose(he.T, T_flange_cam, atol=1e-9)
    assert "no base -> board" in ex.note and "joints 1 and 2 must be revolute" in ex.note
