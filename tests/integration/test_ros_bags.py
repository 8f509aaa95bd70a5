"""ROS bags in and out (docs/ros.md): `selfcal export DATASET --bag` and `selfcal import --bag` in
the three formats, round trip against the dataset they came from.

The dataset is the synthetic lab of tests/integration/synthetic_board.py (KR 6 R900, one 800x600
camera with a lens, an 11x8 chessboard) with 8 postures, imported from its PNGs and joints file.
Measured: the round trip gives bit-identical pixels, joints.csv equal to the last printed digit
(0 rad difference) and, with BLAS and OpenCV on one thread, the same board calibration to the bit
(0 difference; on several threads the reductions' order alone moves the estimates by up to 2e-8
relative, hence one thread).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from synthetic_board import CAMERA, TARGET_TOML, make_lab, write_lab_data
from threadpoolctl import threadpool_limits

from selfcal.calibration.board.dataset import calibrate_board_dataset
from selfcal.camera import BrownConrady, Pinhole, opencv_values
from selfcal.cli.main import main
from selfcal.export.camera import rectified_matrix
from selfcal.importing.dataset import CameraImages, import_dataset
from selfcal.io.board_calibration import write_board_calibration
from selfcal.io.dataset import Dataset
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.chain import chain_frames
from selfcal.robot.definition import load_robot
from selfcal.robot.urdf import urdf_chain
from selfcal.ros.rosbag import BagReader, CameraInfo, bag_format
from selfcal.transforms import inv_pose, make_pose

pytest.importorskip("rosbags")

ROBOT = "kr6-r900"


def _calibrate(root: Path):
    """The board calibration of ``root`` on one thread (deterministic to the bit)."""
    n = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with threadpool_limits(1):
            return calibrate_board_dataset(root)
    finally:
        cv2.setNumThreads(n)


@pytest.fixture(scope="module")
def lab(shared):
    """The lab's 8 rendered images imported as a dataset and its board calibration, made once
    per test run (shared in tests/conftest.py): (folder, calibration). Copy the dataset to
    change it."""

    def build(root: Path):
        ci, cj = write_lab_data(make_lab(seed=0), root / "cal", 8, seed=1)
        (root / "board.toml").write_text(TARGET_TOML)
        import_dataset(ROBOT, [CameraImages.parse(f"cam0={ci}/*.png")], cj, "rad",
                       root / "board.toml", root / "ds")  # fmt: skip
        cal = _calibrate(root / "ds")
        write_board_calibration(root / "ds" / "calibration.json", cal)
        return root, cal

    return shared("ros-bags-lab", build)


def _import(root: Path, bag: Path, out: Path, *extra: str) -> int:
    return main(["import", "--bag", str(bag), "--image-topic", "cam0=/cam0/image_raw",
                 "--robot", ROBOT, "--target", str(root / "board.toml"), "--out", str(out),
                 *extra])  # fmt: skip


@pytest.mark.slow  # a few seconds on 2 cores: the default tier keeps to ~90 s
@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap", "mcap-file"])
def test_round_trip(lab, tmp_path, fmt, capsys):
    root, cal = lab
    name = {"ros1": "ds.bag", "mcap-file": "ds.mcap"}.get(fmt, "ds_bag")
    bag = tmp_path / name
    fmt, bare = fmt.removesuffix("-file"), fmt.endswith("-file")
    given = [] if bare else ["--format", fmt]  # OUT.mcap alone says mcap
    assert main(["export", str(root / "ds"), "--bag", str(bag), *given]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 8
    assert bag_format(bag) == fmt
    # OUT.mcap is one bare file (no folder, nothing left beside it); other mcap OUT a folder
    assert bag.is_file() == (bare or fmt == "ros1")
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    src = bag
    if fmt == "mcap" and not bare:  # the bare .mcap file inside the folder reads as well
        (src,) = bag.glob("*.mcap")
        assert bag_format(src) == "mcap"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every image of an exported bag is at rest
        assert _import(root, src, tmp_path / "re") == 0
    a, b = Dataset.open(root / "ds"), Dataset.open(tmp_path / "re")
    assert b.info.cameras == ("cam0",) and len(b.indices) == 8
    for (_, _, pa), (_, _, pb) in zip(a.image_paths(), b.image_paths(), strict=True):
        ia, ib = (
            cv2.imread(str(pa), cv2.IMREAD_UNCHANGED),
            cv2.imread(str(pb), cv2.IMREAD_UNCHANGED),
        )
        assert ia.dtype == ib.dtype and np.array_equal(ia, ib)
    dq = np.abs(np.radians(a.joints_deg) - np.radians(b.joints_deg)).max()
    assert dq <= 1e-9  # measured 0 (the same printed digits)
    # the calibrated camera of the dataset travelled as camera_info and chose the model
    rec = b.info.provenance["import"]
    assert rec["format"] == fmt and rec["image_topics"] == {"cam0": "/cam0/image_raw"}
    assert rec["camera_info"]["cam0"]["distortion_model"] == "plumb_bob"
    np.testing.assert_allclose(
        rec["camera_info"]["cam0"]["K"], cal.cameras[0].K.ravel(), rtol=1e-15
    )
    assert b.info.camera_model == "opencv" and b.info.camera_free == a.info.camera_free
    stamps = [r.split("@")[1] for r in (tmp_path / "re" / "sources.csv").read_text().split()[1:]]
    assert len(stamps) == 8 and all(s.isdigit() for s in stamps)
    got = _calibrate(tmp_path / "re")
    va, vb = cal.cameras[0].values(), got.cameras[0].values()
    np.testing.assert_allclose(vb, va, rtol=1e-9, atol=0)  # measured: identical
    np.testing.assert_allclose(got.model.params, cal.model.params, rtol=1e-9, atol=0)
    assert got.reprojection_rms_px == pytest.approx(cal.reprojection_rms_px, rel=1e-9)


def _through_camera_info(root: Path, cal, camera, tmp_path: Path, name: str):
    """The lab's dataset exported with ``camera`` in its camera_info, imported again and
    calibrated: (the dataset, the calibration, the warnings' messages)."""
    ds = tmp_path / f"{name}_ds"
    shutil.copytree(root / "ds", ds)
    write_board_calibration(ds / "calibration.json", dataclasses.replace(cal, cameras=(camera,)))
    assert main(["export", str(ds), "--bag", str(tmp_path / f"{name}.bag")]) == 0
    assert _import(root, tmp_path / f"{name}.bag", tmp_path / name) == 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = _calibrate(tmp_path / name)
    return Dataset.open(tmp_path / name), got, [str(w.message) for w in caught]


@pytest.mark.slow  # a few seconds on 2 cores: the default tier keeps to ~90 s
def test_camera_info_initialises_the_camera(lab, tmp_path, capsys):
    """A calibrated camera_info starts the board calibration (dataset.json records it as the
    camera's initial camera): with the true camera the result is the same as from OpenCV's own
    start; a poor one (fx 25 % off, principal point 40 px off, the lens' signs flipped) does
    not make it worse."""
    root, cal = lab
    truth = np.asarray(CAMERA.values())
    ds, good, notes = _through_camera_info(root, cal, CAMERA, tmp_path, "true")
    init = ds.info.initial_of("cam0")
    assert init is not None and init["source"] == "camera_info"
    assert init["where"].endswith("true.bag#/cam0/camera_info")
    want = opencv_values(CAMERA)
    assert init["values"] == pytest.approx({k: want[k] for k in init["values"]}, rel=1e-15)
    assert not [n for n in notes if "initial camera" in n]  # its start was taken
    base = cal.cameras[0].values()  # the calibration of the images' import: OpenCV's start
    err_base = np.abs(base - truth)[:8]
    err_good = np.abs(good.cameras[0].values() - truth)[:8]
    print("true camera_info: error", err_good, "own start", err_base)
    assert (err_good <= err_base * (1 + 1e-6) + 1e-12).all()
    assert good.reprojection_rms_px <= cal.reprojection_rms_px * (1 + 1e-9)
    poor = BrownConrady.from_pinhole(
        Pinhole(1250.0, 0.97, CAMERA.cx + 40, CAMERA.cy - 30, CAMERA.width, CAMERA.height),
        (0.2, -0.1, 0.01, 0.01, 0.0, 0.0, 0.0, 0.0), CAMERA.free,
    )  # fmt: skip
    _, bad, notes = _through_camera_info(root, cal, poor, tmp_path, "poor")
    # measured: OpenCV's calibration converges from the poor start too (it is kept: no
    # warning), to the same estimate within 5e-12 px
    assert not [n for n in notes if "initial camera" in n]
    assert bad.reprojection_rms_px <= cal.reprojection_rms_px * (1 + 1e-9)
    np.testing.assert_allclose(bad.cameras[0].values(), base, rtol=1e-9, atol=1e-12)
    # the kinematics converge from the two starts to the same point within 1.3e-11 m/rad
    # measured (3.5e-8 relative on a 3e-3 parameter): compared absolutely
    np.testing.assert_allclose(bad.model.params, cal.model.params, rtol=0, atol=4e-11)


@pytest.mark.slow  # a few seconds on 2 cores: the default tier keeps to ~90 s
def test_uncalibrated_camera_info_is_ignored(lab, tmp_path):
    root, _ = lab
    shutil.copytree(root / "ds", tmp_path / "ds", ignore=shutil.ignore_patterns("calibration.json"))
    assert main(["export", str(tmp_path / "ds"), "--bag", str(tmp_path / "u.bag")]) == 0
    with BagReader(tmp_path / "u.bag") as r:
        (info, *_) = [CameraInfo.from_msg(m) for _, _, m in r.messages(["/cam0/camera_info"])]
    assert not any(info.K) and not info.calibrated
    assert _import(root, tmp_path / "u.bag", tmp_path / "u") == 0
    ds = Dataset.open(tmp_path / "u")
    assert ds.info.camera_initial is None and ds.info.provenance["import"]["camera_info"] == {
        "cam0": None
    }
    assert "initial" not in json.loads((tmp_path / "u" / "dataset.json").read_text())["cameras"][0]


@pytest.mark.slow  # the lab's 8 images, their board calibration and a bag: over 2 s on 2 cores
def test_exported_bag_content(lab, tmp_path):
    """Images at their stamps with camera_info, joint_states at the image stamps and a smooth
    100 Hz motion between them, the nominal URDF; nothing of truth."""
    root, cal = lab
    bag = tmp_path / "x.bag"
    assert main(["export", str(root / "ds"), "--bag", str(bag)]) == 0
    ds = Dataset.open(root / "ds")
    with BagReader(bag) as r:
        assert r.topics == {"/robot_description": "std_msgs/msg/String",
                            "/joint_states": "sensor_msgs/msg/JointState",
                            "/cam0/image_raw": "sensor_msgs/msg/Image",
                            "/cam0/camera_info": "sensor_msgs/msg/CameraInfo",
                            "/tf_static": "tf2_msgs/msg/TFMessage",
                            "/tf": "tf2_msgs/msg/TFMessage"}  # fmt: skip
        frame_ids = {m.header.frame_id for _, _, m in r.messages(["/cam0/image_raw",
                                                                 "/cam0/camera_info"])}  # fmt: skip
        (static,) = [_edges(m) for _, _, m in r.messages(["/tf_static"])]
        moving = [(stamp, _edges(m)) for _, _, m, stamp in r.timed(["/tf"])]
        urdf = next(m.data for _, _, m in r.messages(["/robot_description"]))
        imgs = [(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)
                for _, _, m in r.messages(["/cam0/image_raw"])]  # fmt: skip
        infos = [CameraInfo.from_msg(m) for _, _, m in r.messages(["/cam0/camera_info"])]
        P = [np.reshape(m.P if hasattr(m, "P") else m.p, (3, 4))
             for _, _, m in r.messages(["/cam0/camera_info"])]  # fmt: skip
        js = [(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, list(m.name),
               np.array(m.position)) for _, _, m in r.messages(["/joint_states"])]  # fmt: skip
    assert "<robot" in urdf and "_calibrated" not in urdf and 'name="a1"' in urdf
    # the images are in the URDF's camera frame (they said cam0; then cam_left, though the one
    # camera is no left one), on the CALIBRATED chain
    assert frame_ids == {"camera_optical_frame"} and '<link name="camera_optical_frame"' in urdf
    assert set(static) == {("link6", "tool_tip"), ("link6", "camera_optical_frame")}
    by_stamp = dict(moving)
    cams = []
    for s in imgs:
        T = np.eye(4)
        for k in range(6):
            T = T @ by_stamp[s][("base_link" if k == 0 else f"link{k}", f"link{k + 1}")]
        cams.append(T @ static[("link6", "camera_optical_frame")])
    F = fk_tool(cal.model, np.radians(ds.joints_deg))  # the calibration's camera poses
    for k in range(1, 8):  # the same motions (the world frames differ)
        np.testing.assert_allclose(inv_pose(cams[0]) @ cams[k], inv_pose(F[0]) @ F[k], atol=1e-9)
    assert len(imgs) == 8 and len(infos) == 8
    np.testing.assert_allclose(infos[0].K, cal.cameras[0].K.ravel())
    # camera_calibration's P = [K' | 0], K' the rectified camera matrix, as the camera_info export
    np.testing.assert_array_equal(P[0], np.c_[rectified_matrix(cal.cameras[0]), np.zeros(3)])
    assert not np.allclose(P[0][:, :3], cal.cameras[0].K)  # the lab's lens distorts
    t = np.array([s for s, _, _ in js])
    q = np.array([p for _, _, p in js])
    assert all(n == ["a1", "a2", "a3", "a4", "a5", "a6"] for _, n, _ in js)
    assert np.isin(imgs, t).all() and (np.diff(t) > 0).all()
    assert np.diff(t).max() == 10_000_000  # 100 Hz, plus the image stamps
    for k, s in enumerate(imgs):
        np.testing.assert_array_equal(q[t == s][0], np.radians(ds.joints_deg[k]))
    # smooth: the steps between readings change gradually (minimum-jerk moves, no jumps)
    step = np.abs(np.diff(q, axis=0)).max(axis=1)
    span = np.abs(np.diff(np.radians(ds.joints_deg), axis=0)).max()
    assert step.max() < 0.03 * span  # measured 0.019 (1.875 x the mean speed over 1 s at 100 Hz)
    # the NOMINAL robot: its base -> tool tip motion between postures equals the robot file's
    (tmp_path / "r.urdf").write_text(urdf)
    ch = urdf_chain(tmp_path / "r.urdf", base_link="base_link", tool_link="tool_tip")
    robot = load_robot(ROBOT)
    qs = robot.home + np.random.default_rng(0).uniform(-0.5, 0.5, (5, robot.n))
    A = chain_frames(ch.chain, ch.joint_types, qs)[:, -1]
    B = chain_frames(robot.chain, robot.joint_types, qs)[:, -1]
    for k in range(1, 5):
        np.testing.assert_allclose(inv_pose(A[0]) @ A[k], inv_pose(B[0]) @ B[k], atol=1e-12)


def _edges(msg) -> dict:
    """A TFMessage as ``{(parent, child): T_parent_child}``."""
    from scipy.spatial.transform import Rotation

    out = {}
    for tr in msg.transforms:
        t, r = tr.transform.translation, tr.transform.rotation
        R = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
        out[(tr.header.frame_id, tr.child_frame_id)] = make_pose(R, [t.x, t.y, t.z])
    return out


def test_cli_refuses_mixed_options(tmp_path, capsys):
    root = tmp_path  # refused from the arguments alone: no dataset is read
    code = main(["export", str(root / "ds"), "--bag", str(tmp_path / "a.bag"), "--out", "x.urdf"])
    assert code == 2 and "give one" in capsys.readouterr().err
    code = main(["export", str(root / "ds"), "--format", "mcap", "--out", str(tmp_path / "x")])
    assert code == 2 and "give --bag OUT instead of --out" in capsys.readouterr().err
    code = main(["export", str(root / "ds"), "--bag", str(tmp_path / "b"), "--format", "urdf"])
    assert code == 2 and "use one of ros1, ros2, mcap" in capsys.readouterr().err
    code = _import(root, tmp_path / "a.bag", tmp_path / "o", "--images", "x/*.png")
    assert code == 2 and "--bag replaces --images and --joints" in capsys.readouterr().err
    code = main(["run", "scenarios/ur5e.toml", "--out", str(tmp_path / "r"), "--bag",
                 str(tmp_path / "r.bag")])  # fmt: skip
    assert code == 2 and "render = false" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_analytic_dataset_has_no_images_for_a_bag(tmp_path, capsys):
    assert main(["acquire", "scenarios/ur5e.toml", "--out", str(tmp_path / "d"), "--quiet"]) == 0
    assert main(["export", str(tmp_path / "d"), "--bag", str(tmp_path / "d.bag")]) == 2
    err = capsys.readouterr().err
    assert "holds detections (the analytic path)" in err and "render = true" in err
    assert not (tmp_path / "d.bag").exists()


@pytest.mark.slow
@pytest.mark.render
def test_run_writes_its_bag(tmp_path, capsys):
    """`selfcal run --bag`: the rendered stereo run's images and joint readings as a ROS 2 bag."""
    out, bag = tmp_path / "run", tmp_path / "run_bag"
    assert main(["run", "scenarios/paper.toml", "--out", str(out), "--bag", str(bag),
                 "--quiet"]) == 0  # fmt: skip
    ds = Dataset.open(out)
    with BagReader(bag) as r:
        assert bag_format(bag) == "ros2"
        assert {"/left/image_raw", "/right/image_raw", "/joint_states"} <= set(r.topics)
        imgs = [m for _, _, m in r.messages(["/left/image_raw"])]
    assert len(imgs) == len(ds.indices)
    first = cv2.imread(str(ds.frame_paths(int(ds.indices[0]))[0]), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(np.asarray(imgs[0].data).reshape(first.shape), first)
