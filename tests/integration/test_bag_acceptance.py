"""A ROS 2 bag as a stranger's lab records it, through ``selfcal import --bag`` and
``selfcal calibrate`` (the acceptance run of session 5).

Written with rosbags directly: a ROS 2 sqlite3 bag, stop-and-go over 8 postures of the synthetic
lab (tests/integration/synthetic_board.py; rests of 1.2 s, cosine moves of 1 s), JointState at
100 Hz with the names shuffled in every message plus a gripper joint, and a camera streaming
``CompressedImage`` PNGs at 5 Hz the whole time: every image carries its own sensor noise
(1 gray level), as a real camera's do, so the images of one rest differ slightly.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from synthetic_board import TARGET_TOML, make_lab, postures, render

from selfcal.cli.main import main
from selfcal.io.board_calibration import read_board_calibration

pytest.importorskip("rosbags")
from rosbags.rosbag2 import Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

pytestmark = pytest.mark.slow

NS = 1_000_000_000
CHAIN = ["a1", "a2", "a3", "a4", "a5", "a6"]
REST, MOVE = 1.2, 1.0


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("bag")
    lab = make_lab(seed=0)
    rests = postures(lab, 8, seed=1)
    rng = np.random.default_rng(4)
    pictures = [render(lab, q, rng) for q in rests]
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    t0 = 50 * NS
    a = t0 + (np.arange(len(rests)) * (REST + MOVE) * NS).astype(np.int64)
    b = a + int(REST * NS)

    def at(t: int) -> tuple[np.ndarray, int, bool]:
        k = int(np.clip(np.searchsorted(a, t, side="right") - 1, 0, len(rests) - 1))
        if t <= b[k] or k == len(rests) - 1:
            return rests[k], k, True
        s = (1 - np.cos(np.pi * min((t - b[k]) / (MOVE * NS), 1.0))) / 2
        return rests[k] + (rests[k + 1] - rests[k]) * s, k, False

    def header(t: int):
        stamp = T["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=t % NS)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id="cam")

    msgs = []
    end = int(b[-1]) + NS // 2
    for t in range(t0 - NS // 2, end, NS // 100):
        q, _, _ = at(t)
        order = rng.permutation(7)
        names, pos = CHAIN + ["gripper_finger"], np.r_[q, 0.01]
        msg = T["sensor_msgs/msg/JointState"](
            header=header(t), name=[names[i] for i in order], position=pos[order],
            velocity=np.zeros(0), effort=np.zeros(0))  # fmt: skip
        msgs.append((t, "/joint_states", "sensor_msgs/msg/JointState", msg))
    for t in range(t0 + NS // 10, end, NS // 5):
        _, k, rest = at(t)
        img = np.clip(pictures[k] + rng.normal(0, 1.0, pictures[k].shape), 0, 255)
        img = img.astype(np.uint8) if rest else cv2.GaussianBlur(pictures[k], (0, 0), 3)
        data = np.frombuffer(cv2.imencode(".png", img)[1].tobytes(), np.uint8)
        msg = T["sensor_msgs/msg/CompressedImage"](header=header(t), format="png", data=data)
        msgs.append((t + NS // 500, "/cam/image_raw/compressed",
                     "sensor_msgs/msg/CompressedImage", msg))  # fmt: skip
    with Writer(root / "lab", version=8) as w:
        conns = {}
        for t, topic, kind, msg in sorted(msgs, key=lambda m: m[0]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, kind, typestore=ts)
            w.write(conns[topic], int(t), ts.serialize_cdr(msg, kind))
    (root / "board.toml").write_text(TARGET_TOML)
    return root / "lab", root / "board.toml"


def _import(bag: Path, target: Path, out: Path, *extra: str) -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the moving images' count
        return main(["import", "--bag", str(bag), "--image-topic",
                     "cam0=/cam/image_raw/compressed", "--robot", "kr6-r900", "--target",
                     str(target), "--out", str(out), *extra])  # fmt: skip


def test_one_frame_per_rest_imports_and_calibrates(recording, tmp_path, capsys):
    bag, target = recording
    out = tmp_path / "ds"
    assert _import(bag, target, out, "--per-rest", "1") == 0
    err = capsys.readouterr().err.splitlines()
    # the last line names what was written (before: "done ..., nothing written")
    assert err[-1].startswith(f"selfcal: wrote {out}"), err[-1]
    assert main(["calibrate", str(out), "--quiet"]) == 0
    cal = read_board_calibration(out)
    assert cal.frames_used == 8
    assert cal.reprojection_rms_px < 0.3  # measured 0.117 px


def test_the_default_import_of_a_bag_calibrates(recording, tmp_path):
    """The import keeps one frame per rest by default (its middle image): with every image at
    rest, calibrate refused two images of one rest as copies (same joint readings, corners
    0.008 px apart)."""
    bag, target = recording
    out = tmp_path / "ds"
    assert _import(bag, target, out) == 0
    assert main(["calibrate", str(out), "--quiet"]) == 0
