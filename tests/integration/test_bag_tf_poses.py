"""``selfcal import --bag BAG --tf-parent base_link --tf-child tool0 --setup ...`` (#28 item 2): the
flange poses from a bag's /tf instead of joints. A stop-and-go recording of the synthetic lab
(tests/integration/synthetic_board.py): /tf_static world -> base_link and link6 -> tool0, /tf
base_link -> link6 at 50 Hz moving between rests; the camera at 5 Hz. The imported dataset holds
one frame per rest with the pose /tf gives there (the true flange pose to 1e-9 m), each image
named by bag, topic and stamp; and the hand-eye calibrates from it as from a pose file."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp
from synthetic_board import TARGET_TOML, make_lab, postures, render

from selfcal.cli.main import main
from selfcal.kinematics.forward import fk_tool
from selfcal.ros.bag_rest import NS
from selfcal.ros.bag_stage import MovingImagesWarning
from selfcal.transforms import inv_pose, make_pose

pytest.importorskip("rosbags")

X_FLANGE_CAM = make_pose(Rotation.from_euler("xyz", [2.0, -3.0, 91.0], degrees=True).as_matrix(),
                         [0.012, -0.034, 0.061])  # fmt: skip
S_LINK6_TOOL0 = make_pose(Rotation.from_euler("z", 30.0, degrees=True).as_matrix(), [0, 0, 0.02])
REST_S, MOVE_S, TF_HZ, CAM_HZ = 1.0, 0.6, 50, 5


def _record(bag: Path, n: int) -> np.ndarray:
    """The bag of ``n`` rests; returns the true base -> tool0 poses (n, 4, 4)."""
    from selfcal.ros.rosbag import BagWriter

    lab = make_lab(0)
    q = postures(lab, n, seed=3)
    rng = np.random.default_rng(0)
    views = [render(lab, qk, rng) for qk in q]
    T_base_tool0 = fk_tool(lab.true_model, q) @ inv_pose(X_FLANGE_CAM)
    link6 = T_base_tool0 @ inv_pose(S_LINK6_TOOL0)
    period = REST_S + MOVE_S
    t0 = 10 * NS

    def pose(t: int) -> tuple[np.ndarray, int | None]:
        s = (t - t0) / NS
        k = min(max(int(s // period), 0), n - 1)
        into = s - k * period
        if into <= REST_S or k == n - 1:  # before t0 too: at the first rest
            return link6[k], k
        u = (into - REST_S) / MOVE_S
        R = Slerp([0, 1], Rotation.from_matrix(link6[k : k + 2, :3, :3]))([u]).as_matrix()[0]
        return make_pose(R, (1 - u) * link6[k, :3, 3] + u * link6[k + 1, :3, 3]), None

    end = t0 + int(n * period * NS)
    with BagWriter(bag, "ros2") as w:
        w.tf("/tf_static", t0, [("world", "base_link", np.eye(4)),
                                ("link6", "tool0", S_LINK6_TOOL0)])  # fmt: skip
        cam_t = list(range(t0, end, NS // CAM_HZ))
        ci = 0
        for t in range(t0 - NS // 5, end + NS // 5, NS // TF_HZ):
            while ci < len(cam_t) and cam_t[ci] <= t:
                _, k = pose(cam_t[ci])
                w.image("/camera/image_raw", cam_t[ci], "camera",
                        views[k] if k is not None else views[0] // 2)  # fmt: skip
                ci += 1
            w.tf("/tf", t, [("base_link", "link6", pose(t)[0])])
    return T_base_tool0


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    root = tmp_path_factory.mktemp("tfbag")
    (root / "board.toml").write_text(TARGET_TOML)
    truth = _record(root / "rec", 6)
    return root, truth


def _import(root: Path, out: Path, *extra: str) -> int:
    return main(["import", "--bag", str(root / "rec"), "--image-topic", "cam0=/camera/image_raw",
                 "--tf-parent", "base_link", "--tf-child", "tool0", "--setup", "eye-in-hand",
                 "--target", str(root / "board.toml"), "--out", str(out), *extra])  # fmt: skip


def _poses(ds: Path) -> np.ndarray:
    with open(ds / "poses.csv") as f:
        rows = list(csv.DictReader(f))
    p = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows]) / 1e3
    R = Rotation.from_quat([[float(r[k]) for k in ("qx", "qy", "qz", "qw")] for r in rows])
    return make_pose(R.as_matrix(), p)


@pytest.mark.slow
def test_one_frame_per_rest_with_the_pose_tf_gives_there(recording, tmp_path, capsys):
    root, truth = recording
    with pytest.warns(MovingImagesWarning, match="42 of 48 images skipped"):
        assert _import(root, tmp_path / "ds", "--camera-model", "opencv") == 0
    assert "imported 6 frames (eye-in-hand, flange poses base_link -> tool0 from /tf)" in (
        capsys.readouterr().out
    )
    T = _poses(tmp_path / "ds")
    assert np.abs(T[:, :3, 3] - truth[:, :3, 3]).max() < 1e-9
    assert np.abs(T[:, :3, :3] - truth[:, :3, :3]).max() < 1e-9
    doc = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    src = doc["provenance"]["import"]
    assert src["tf"]["parent"] == "base_link" and src["tf"]["child"] == "tool0"
    assert src["images"]["frames"] == 6 and src["images"]["moving"] > 0
    sources = (tmp_path / "ds" / "sources.csv").read_text().splitlines()[1:]
    assert len(sources) == 6 and all("#/camera/image_raw@" in s for s in sources)


def _refused(root: Path, tmp_path: Path, capsys, extra: list, message: str) -> None:
    argv = ["import", "--bag", str(root / "rec"), "--image-topic", "cam0=/camera/image_raw",
            "--tf-parent", "base_link", "--tf-child", "tool0", "--setup", "eye-in-hand",
            "--target", str(root / "board.toml"), "--out", str(tmp_path / "ds")]  # fmt: skip
    if extra[0] in argv:  # replace the option's value, or drop the option
        k = argv.index(extra[0])
        argv[k : k + 2] = [] if extra[1] is None else extra
    else:
        argv += extra
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "ds").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--tf-child", "flange"], "--tf-child 'flange' is not a frame of /tf or /tf_static"),
        (["--tf-parent", "link6"], "never changes on /tf"),
    ],
)
def test_frame_pairs_tf_cannot_give_are_named(recording, tmp_path, capsys, extra, message):
    _refused(recording[0], tmp_path, capsys, extra, message)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--setup", None], "--tf-child needs --setup"),
        (["--robot", "ur5e"], "need no robot model"),
        (["--rotation", "kuka-abc"], "--pose-units and --rotation describe a --poses file"),
        (["--bag", None], "--tf-parent and --tf-child read the flange poses of a --bag"),
    ],
)
def test_options_that_do_not_go_with_tf_poses_are_named(tmp_path, capsys, extra, message):
    _refused(tmp_path, tmp_path, capsys, extra, message)  # refused before any bag is read


@pytest.mark.slow
def test_the_hand_eye_calibrates_from_the_tf_poses(recording, tmp_path, capsys):
    root, _ = recording
    ds = tmp_path / "ds"
    with pytest.warns(MovingImagesWarning, match="42 of 48 images skipped"):
        assert _import(root, ds, "--camera-model", "opencv") == 0
    assert main(["calibrate", str(ds), "--quiet"]) == 0
    he = json.loads((ds / "calibration.json").read_text())["hand_eye"]
    assert he["transform"] == "flange -> camera"
    X = np.asarray(he["matrix"])
    err_mm = np.abs(X[:3, 3] - X_FLANGE_CAM[:3, 3]) * 1e3  # measured: 0.01, 0.11, 0.06 mm
    assert (err_mm <= 3 * np.asarray(he["sigma_xyz_mm"])).all(), err_mm
    turn = Rotation.from_matrix(X[:3, :3] @ X_FLANGE_CAM[:3, :3].T).magnitude()
    assert np.degrees(turn) <= 3 * np.linalg.norm(he["sigma_rotation_deg"]), np.degrees(turn)
