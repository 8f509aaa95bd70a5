"""`selfcal import --bag` on bags written with rosbags directly (not through the project's export),
as a lab's recording looks: stop-and-go motion, joint stamps with jitter, the driver's joint order
shuffled in every message plus a gripper joint, a camera streaming while the arm moves; and every
bad input, each an error naming the bag, the topic and the fix.

The arm rests at postures of the synthetic lab (tests/integration/synthetic_board.py) and moves
between them on a cosine profile. Every image at rest over the whole window around it (0.5 s by
default) must be kept with its joints within 1e-6 rad (measured 2.3e-7 rad: the readings carry
1e-7 rad noise), and every image taken while moving skipped. An image at rest within half a window
of a move is kept when the move's first milliseconds stay below the speed threshold.
"""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from synthetic_board import TARGET_TOML, make_lab, postures, render

from selfcal.cli.main import main
from selfcal.errors import InputError
from selfcal.io.dataset import Dataset
from selfcal.ros.bag_import import MovingImagesWarning
from selfcal.ros.rosbag import BagReader

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

ROBOT = "kr6-r900"
CHAIN = ["a1", "a2", "a3", "a4", "a5", "a6"]
NS = 1_000_000_000
REST_S, MOVE_S, WINDOW_S = 1.6, 1.2, 0.5


class RawBag:
    """A bag written with rosbags alone: ROS 1 (``.bag``) or ROS 2 (a folder, sqlite3 or mcap)."""

    def __init__(self, path: Path, kind: str = "ros1") -> None:
        self.ros1 = kind == "ros1"
        self.ts = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        if self.ros1:
            self.w = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
            self.w = Writer2(path, version=8, storage_plugin=plugin)
        self.w.open()
        self.conns: dict[str, object] = {}
        self.T = self.ts.types

    def header(self, t: int):
        stamp = self.T["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=t % NS)
        extra = {"seq": 0} if self.ros1 else {}
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id="cam", **extra)

    def put(self, topic: str, msgtype: str, t: int, msg) -> None:
        if topic not in self.conns:
            self.conns[topic] = self.w.add_connection(topic, msgtype, typestore=self.ts)
        ser = self.ts.serialize_ros1 if self.ros1 else self.ts.serialize_cdr
        self.w.write(self.conns[topic], t, ser(msg, msgtype))

    def joints(self, topic: str, t: int, names: list[str], q, stamp: int | None = None) -> None:
        msg = self.T["sensor_msgs/msg/JointState"](
            header=self.header(t if stamp is None else stamp), name=names, position=np.asarray(q, float),
            velocity=np.zeros(0), effort=np.zeros(0))  # fmt: skip
        self.put(topic, "sensor_msgs/msg/JointState", t, msg)

    def image(self, topic: str, t: int, img: np.ndarray, encoding: str = "mono8") -> None:
        h, w = img.shape[:2]
        msg = self.T["sensor_msgs/msg/Image"](
            header=self.header(t), height=h, width=w, encoding=encoding, is_bigendian=0,
            step=img.nbytes // h, data=np.frombuffer(img.tobytes(), np.uint8))  # fmt: skip
        self.put(topic, "sensor_msgs/msg/Image", t, msg)

    def compressed(self, topic: str, t: int, img: np.ndarray, fmt: str = "png") -> None:
        data = np.frombuffer(cv2.imencode(f".{fmt}", img)[1].tobytes(), np.uint8)
        msg = self.T["sensor_msgs/msg/CompressedImage"](header=self.header(t), format=fmt,
                                                        data=data)  # fmt: skip
        self.put(topic, "sensor_msgs/msg/CompressedImage", t, msg)

    def close(self) -> None:
        self.w.close()


def stop_and_go(rests: np.ndarray, t0: int):
    """The motion: rest k over [a_k, b_k], a cosine move to rest k + 1; returns a, b (ns), q(t)
    (rad) and the rests' true extent lo, hi (the first starts, the last ends, at rest)."""
    a = t0 + np.arange(len(rests)) * int((REST_S + MOVE_S) * NS)
    b = a + int(REST_S * NS)
    lo, hi = a.copy(), b.copy()
    lo[0], hi[-1] = t0 - 100 * NS, hi[-1] + 100 * NS  # at rest before the first and after the last

    def q(t: int) -> np.ndarray:
        k = int(np.clip(np.searchsorted(a, t, side="right") - 1, 0, len(rests) - 1))
        if t <= b[k] or k == len(rests) - 1:
            return rests[k]
        s = (1 - np.cos(np.pi * min((t - b[k]) / (MOVE_S * NS), 1.0))) / 2
        return rests[k] + (rests[k + 1] - rests[k]) * s

    return a, b, q, lo, hi


def write_joints(bag: RawBag, q, start: int, end: int, rng, rate_hz=200.0, jitter_s=1.5e-3,
                 topic="/joint_states", names=CHAIN) -> None:  # fmt: skip
    """JointState at ``rate_hz`` with stamp jitter, names shuffled in every message plus a
    gripper joint, readings with 1e-7 rad noise."""
    period = int(NS / rate_hz)
    for t in range(start, end, period):
        ts = t + int(rng.uniform(-jitter_s, jitter_s) * NS)
        vals = dict(zip(CHAIN, q(ts) + rng.normal(0, 1e-7, 6), strict=True))
        vals["gripper_finger_joint"] = 0.02
        order = [n for n in names if n in vals] + ["gripper_finger_joint"]
        rng.shuffle(order)
        bag.joints(topic, ts, order, [vals[n] for n in order])


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    root = tmp_path_factory.mktemp("rosimport")
    world = make_lab(seed=0)
    rests = postures(world, 7, seed=3)
    rng = np.random.default_rng(5)
    pictures = [render(world, q, rng) for q in rests]
    (root / "board.toml").write_text(TARGET_TOML)
    return root, rests, pictures


def _import(bag: Path, out: Path, root: Path, *topics: str, extra=()) -> int:
    args = ["import", "--bag", str(bag), "--robot", ROBOT, "--target", str(root / "board.toml"),
            "--out", str(out), "--joint-topic", "/joint_states", *extra]  # fmt: skip
    for t in topics:
        args += ["--image-topic", t]
    return main(args)


def _stamps(out: Path) -> dict[str, list[int]]:
    rows = list(csv.DictReader((out / "sources.csv").read_text().splitlines()))
    got: dict[str, list[int]] = {}
    for r in rows:
        got.setdefault(r["camera"], []).append(int(r["source"].rsplit("@", 1)[1]))
    return got


def test_stop_and_go_recording(lab, tmp_path):
    root, rests, pictures = lab
    rng = np.random.default_rng(11)
    t0 = 100 * NS
    a, b, q, lo, hi = stop_and_go(rests, t0)
    bag = RawBag(tmp_path / "lab.bag")
    write_joints(bag, q, t0 - NS // 2, int(b[-1]) + NS // 2, rng)
    cam = t0 + int(0.037 * NS) + np.arange(int((b[-1] - t0) / NS * 5)) * (NS // 5)  # 5 Hz
    rest_of = [int(np.searchsorted(a, t, side="right") - 1) for t in cam]
    moving = np.array([t > b[k] for t, k in zip(cam, rest_of, strict=True)])
    h = int(WINDOW_S / 2 * NS)
    full = np.array([lo[k] + h <= t <= hi[k] - h for t, k in zip(cam, rest_of, strict=True)])
    for t, k, mv in zip(cam, rest_of, moving, strict=True):
        # a moving image is never decoded by the import: any content does (the last rest's)
        bag.image("/camera/image_raw", int(t), pictures[k] if not mv else pictures[k] // 2)
    bag.close()
    out = tmp_path / "ds"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert _import(tmp_path / "lab.bag", out, root, "cam0=/camera/image_raw",
                       extra=["--per-rest", "all"]) == 0  # fmt: skip
    lines = [str(w.message) for w in caught if issubclass(w.category, MovingImagesWarning)]
    kept = _stamps(out)["cam0"]
    assert len(lines) == 1 and f"{len(cam) - len(kept)} of {len(cam)} images skipped" in lines[0]
    assert set(cam[full].tolist()) <= set(kept)  # every image at rest over the whole window
    assert not set(cam[moving].tolist()) & set(kept)  # no image taken while moving
    assert moving.sum() > 30 and full.sum() > 25 and (~moving & ~full).sum() > 5
    # the rest images within half a window of a move: kept while the move's first
    # milliseconds stay below the speed threshold (measured 6 of 18)
    assert len(kept) < full.sum() + (~moving & ~full).sum()
    ds = Dataset.open(out)
    rest_at = dict(zip(cam.tolist(), rest_of, strict=True))
    want = np.array([rests[rest_at[t]] for t in kept])
    err = np.abs(np.radians(ds.joints_deg) - want).max()
    assert err < 1e-6  # measured 2.3e-7 rad (the readings' 1e-7 rad noise, interpolated)
    rec = ds.info.provenance["import"]
    assert rec["bag"].endswith("lab.bag") and rec["format"] == "ros1" and rec["tf"] is None
    assert rec["joint_names"] == CHAIN and rec["images"]["moving"] == len(cam) - len(kept)
    # frames are pixel for pixel the recorded images
    img = cv2.imread(str(ds.frame_paths(int(ds.indices[0]))[0]), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(img, pictures[rest_at[kept[0]]])


class SplitBag(RawBag):
    """A ROS 1 recording split like ``rosbag record --split``: message k goes to the file whose
    time span holds its recording time (``cuts``: the first stamp of every file but the first)."""

    def __init__(self, paths: list[Path], cuts: list[int]) -> None:
        self.parts = [RawBag(p) for p in paths]
        self.cuts, self.ros1, self.ts, self.T = cuts, True, self.parts[0].ts, self.parts[0].T

    def put(self, topic: str, msgtype: str, t: int, msg) -> None:
        self.parts[int(np.searchsorted(self.cuts, t, side="right"))].put(topic, msgtype, t, msg)

    def close(self) -> None:
        for p in self.parts:
            p.close()


def _recording(bag: RawBag, rests, pictures, t0: int) -> None:
    """A stop-and-go recording of ``rests`` with a 5 Hz camera (deterministic)."""
    rng = np.random.default_rng(21)
    a, b, q, _, _ = stop_and_go(rests, t0)
    write_joints(bag, q, t0 - NS // 2, int(b[-1]) + NS // 2, rng)
    for t in t0 + int(0.037 * NS) + np.arange(int((b[-1] - t0) / NS * 5)) * (NS // 5):
        k = int(np.searchsorted(a, t, side="right") - 1)
        bag.image("/camera/image_raw", int(t), pictures[k] if t <= b[k] else pictures[k] // 2)
    bag.close()


@pytest.mark.slow  # three imports of 8 images each: over 2 s on 2 cores
def test_split_recording_reads_as_one_bag(lab, tmp_path):
    """`rosbag record --split` files (rec_0.bag, rec_1.bag, rec_2.bag; cut in the middle of
    rests and of moves) import as the same dataset as the recording in one file, given as a
    glob or as repeated --bag in any order; sources.csv names the file of every image."""
    root, rests, pictures = lab
    rests, pictures, t0 = rests[:4], pictures[:4], 100 * NS
    _recording(RawBag(tmp_path / "whole.bag"), rests, pictures, t0)
    cuts = [t0 + int(2.0 * NS), t0 + int(6.5 * NS)]  # inside rest 0; inside the move 2 -> 3
    parts = [tmp_path / f"rec_{k}.bag" for k in range(3)]
    _recording(SplitBag(parts, cuts), rests, pictures, t0)
    with BagReader(parts) as r:  # every file holds part of the recording
        assert r.label.endswith("rec_2.bag (3 files)")
        files = {f.name for *_, f in r.timed_in(["/camera/image_raw", "/joint_states"])}
    assert files == {p.name for p in parts}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MovingImagesWarning)
        assert _import(tmp_path / "whole.bag", tmp_path / "one", root, "cam0=/camera/image_raw",
                       extra=["--per-rest", "2"]) == 0  # fmt: skip
        assert _import(tmp_path / "rec_*.bag", tmp_path / "glob", root, "cam0=/camera/image_raw",
                       extra=["--per-rest", "2"]) == 0  # fmt: skip
        args = ["--per-rest", "2", "--bag", str(parts[2]), "--bag", str(parts[0])]
        assert _import(parts[1], tmp_path / "any", root, "cam0=/camera/image_raw", extra=args) == 0
    one = Dataset.open(tmp_path / "one")
    assert len(one.indices) == 8
    for name in ("glob", "any"):
        ds = Dataset.open(tmp_path / name)
        assert _stamps(tmp_path / name) == _stamps(tmp_path / "one")
        np.testing.assert_array_equal(ds.joints_deg, one.joints_deg)
        for (_, _, pa), (_, _, pb) in zip(one.image_paths(), ds.image_paths(), strict=True):
            assert np.array_equal(cv2.imread(str(pa), cv2.IMREAD_UNCHANGED),
                                  cv2.imread(str(pb), cv2.IMREAD_UNCHANGED))  # fmt: skip
        rec = ds.info.provenance["import"]
        assert sorted(Path(b).name for b in rec["bag"]) == [p.name for p in parts]
    src = [
        r["source"]
        for r in csv.DictReader((tmp_path / "glob" / "sources.csv").read_text().splitlines())
    ]
    assert {Path(s.split("#")[0]).name for s in src} == {"rec_0.bag", "rec_1.bag", "rec_2.bag"}


def _tf(bag: RawBag, topic: str, t: int, edges) -> None:
    """A TFMessage of ``edges``: (parent, child, xyz m, quaternion xyzw)."""
    T = bag.T
    trs = [T["geometry_msgs/msg/TransformStamped"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=t // NS,
                                        nanosec=t % NS), frame_id=parent),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=r[0], y=r[1], z=r[2], w=r[3])))
        for parent, child, p, r in edges]  # fmt: skip
    bag.put(topic, "tf2_msgs/msg/TFMessage", t, T["tf2_msgs/msg/TFMessage"](transforms=trs))


def test_tf_records_where_the_camera_is_attached(lab, tmp_path):
    """/tf_static (tool0 -> camera_link -> cam, the images' frame_id) and /tf (the arm's links
    moving, world -> base_link constant): the import records the camera rigidly on tool0 with the
    composed transform, a hint in dataset.json's provenance; a bag without tf records none."""
    from scipy.spatial.transform import Rotation

    root, rests, pictures = lab
    bag = RawBag(tmp_path / "tf", "ros2")
    t0 = 100 * NS
    q_a = Rotation.from_euler("z", 90, degrees=True).as_quat()
    q_b = Rotation.from_euler("xyz", [-90, 0, -90], degrees=True).as_quat()
    _tf(bag, "/tf_static", t0 - NS, [("tool0", "camera_link", (0.01, 0.02, 0.05), q_a),
                                     ("camera_link", "cam", (0.0, 0.0, 0.0), q_b)])  # fmt: skip
    for k in range(40):  # the arm's links move; the base stands still on /tf
        t = t0 - NS + k * NS // 4
        turn = Rotation.from_euler("z", 3 * k, degrees=True).as_quat()
        _tf(bag, "/tf", t, [("world", "base_link", (0.0, 0.0, 0.0), (0, 0, 0, 1)),
                            ("base_link", "link1", (0, 0, 0.3), turn),
                            ("link1", "tool0", (0.4, 0, 0), turn)])  # fmt: skip
    _recording(bag, rests[:4], pictures[:4], t0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MovingImagesWarning)
        assert _import(tmp_path / "tf", tmp_path / "ds", root, "cam0=/camera/image_raw",
                       extra=["--per-rest", "2"]) == 0  # fmt: skip
    hint = Dataset.open(tmp_path / "ds").info.provenance["import"]["tf"]["cam0"]
    assert hint["frame"] == "cam" and hint["rigidly_on"] == "tool0"
    assert hint["path"] == ["cam", "camera_link", "tool0"]
    R = Rotation.from_quat(q_a).as_matrix() @ Rotation.from_quat(q_b).as_matrix()
    np.testing.assert_allclose(np.array(hint["T_parent_camera"])[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(np.array(hint["T_parent_camera"])[:3, 3], [0.01, 0.02, 0.05],
                               atol=1e-12)  # fmt: skip
    assert Dataset.open(tmp_path / "ds").info.initial_of("cam0") is None  # no camera_info


def test_split_recording_errors(lab, tmp_path, capsys):
    root = lab[0]
    code = _import(tmp_path / "none_*.bag", tmp_path / "o", root, "cam0=/camera/image_raw")
    assert code == 2 and "--bag " in (err := capsys.readouterr().err)
    assert "no file matches the pattern" in err
    _small_bag(tmp_path / "s.bag")
    b2 = RawBag(tmp_path / "r2", "ros2")
    b2.joints("/joint_states", 10 * NS, CHAIN, np.zeros(6))
    b2.close()
    code = _import(tmp_path / "s.bag", tmp_path / "o", root, "cam0=/cam/image_raw",
                   extra=["--bag", str(tmp_path / "r2")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "only the files of a split ROS 1 recording are read as one bag" in err
    assert "s.bag (ros1)" in err and "r2 (ros2)" in err


@pytest.mark.slow  # 5 s: two cameras' detections and geometry checks
def test_two_cameras_raw_and_compressed(lab, tmp_path):
    """A frame is one rest with an image of every camera: cam0 raw rgb8 at 5 Hz, cam1 png
    CompressedImage at 3 Hz, in a ROS 2 mcap bag."""
    root, rests, pictures = lab
    rests, pictures = rests[:3], pictures[:3]
    rng = np.random.default_rng(12)
    t0 = 50 * NS
    a, b, q, lo, hi = stop_and_go(rests, t0)
    bag = RawBag(tmp_path / "two", "mcap")
    write_joints(bag, q, t0 - NS // 2, int(b[-1]) + NS // 2, rng)
    h = int(WINDOW_S / 2 * NS)
    full, at_rest = [], []  # per camera and rest: images at rest over the whole window; at all
    for name, hz, off in (("cam0", 5, 0.011), ("cam1", 3, 0.05)):
        stamps = t0 + int(off * NS) + np.arange(int((b[-1] - t0) / NS * hz)) * (NS // hz)
        n_full, n_rest = np.zeros(len(rests), int), np.zeros(len(rests), int)
        for t in stamps:
            k = int(np.searchsorted(a, t, side="right") - 1)
            img = pictures[k]
            if name == "cam0":
                bag.image("/cam0/image_raw", int(t), np.dstack([img] * 3), "rgb8")
            else:
                bag.compressed("/cam1/image_raw/compressed", int(t), img)
            n_full[k] += lo[k] + h <= t <= hi[k] - h
            n_rest[k] += t <= hi[k]
        full.append(n_full)
        at_rest.append(n_rest)
    bag.close()
    out = tmp_path / "ds"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MovingImagesWarning)
        assert _import(tmp_path / "two", out, root, "cam0=/cam0/image_raw",
                       "cam1=/cam1/image_raw/compressed", extra=["--per-rest", "all"]) == 0  # fmt: skip
    got = _stamps(out)
    rest = [int(np.searchsorted(a, t, side="right") - 1) for t in got["cam0"]]
    assert rest == [int(np.searchsorted(a, t, side="right") - 1) for t in got["cam1"]]
    assert all(t <= hi[k] for c in got.values() for t, k in zip(c, rest, strict=True))
    per_rest = np.bincount(rest, minlength=len(rests))
    assert (per_rest >= np.minimum(*full)).all() and (per_rest <= np.minimum(*at_rest)).all()
    ds = Dataset.open(out)
    assert ds.info.cameras == ("cam0", "cam1")
    p0, p1 = ds.frame_paths(int(ds.indices[0]))
    assert cv2.imread(str(p0), cv2.IMREAD_UNCHANGED).shape == (600, 800, 3)  # rgb8 -> colour PNG
    assert np.array_equal(cv2.imread(str(p1), cv2.IMREAD_UNCHANGED), pictures[rest[0]])
    # --per-rest 2: two frames of each rest
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MovingImagesWarning)
        assert _import(tmp_path / "two", tmp_path / "ds2", root, "cam0=/cam0/image_raw",
                       "cam1=/cam1/image_raw/compressed",
                       extra=["--per-rest", "2", "--camera-model", "cam1=pinhole"]) == 0  # fmt: skip
    info = Dataset.open(tmp_path / "ds2").info  # the per-camera choice passed through
    assert info.model_of("cam0")[0] == "opencv" and info.model_of("cam1")[0] == "pinhole"
    got = _stamps(tmp_path / "ds2")["cam0"]
    assert (
        np.bincount([int(np.searchsorted(a, t, side="right") - 1) for t in got]).tolist() == [2] * 3
    )


# --- bad input: each error names the bag, the topic and the fix ---------------------------------


def _small_bag(path: Path, *, names=CHAIN, pause=None, encoding="mono8", moving=False, clock=0,
               zero_stamps=False):  # fmt: skip
    """Two rests of 2 s with images at 4 Hz (64x48, no board: these errors come first)."""
    rests = np.array([np.zeros(6), np.full(6, 0.2)])
    t0 = 10 * NS
    a, b, q, lo, hi = stop_and_go(rests, t0)
    if moving:

        def q(t):  # noqa: E306 - always moving
            return np.full(6, 0.3 * (t - t0) / NS)

    bag = RawBag(path)
    rng = np.random.default_rng(1)
    period = NS // 100
    for t in range(t0, int(b[-1]), period):
        if pause and pause[0] <= t < pause[1]:
            continue
        bag.joints("/joint_states", t, list(names), q(t)[: len(names)], 0 if zero_stamps else None)
    bag.joints("/gripper/joint_states", t0, ["gripper_finger_joint"], [0.0])
    img = rng.integers(0, 255, (48, 64), np.uint8)
    for t in range(t0 + NS // 3 + clock, int(b[-1]) - NS // 3 + clock, NS // 4):
        bag.image("/cam/image_raw", t, img if encoding != "bayer_rggb8" else img, encoding)
    bag.close()
    return t0


def _error(bag: Path, tmp_path: Path, root: Path, capsys, topic="cam0=/cam/image_raw", extra=()):
    assert _import(bag, tmp_path / "out", root, topic, extra=extra) == 2
    assert not (tmp_path / "out").exists()  # nothing half-written
    err = capsys.readouterr().err
    assert str(bag) in err and " -- " in err  # the fix after the message
    return err


def test_a_camera_option_for_a_camera_the_bag_import_lacks(tmp_path, capsys):
    assert _import(tmp_path / "none.bag", tmp_path / "out", tmp_path, "cam0=/cam/image_raw",
                   extra=["--free", "cam9=fx,mu"]) == 2  # fmt: skip
    assert "--free names camera(s) cam9, but the --image-topic cameras are cam0" in (
        capsys.readouterr().err
    )


def test_missing_topic_lists_the_bags_topics(lab, tmp_path, capsys):
    root = lab[0]
    _small_bag(tmp_path / "s.bag")
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys, "cam0=/camera/image_raw")
    assert "topic /camera/image_raw is not in the bag" in err
    assert "image topics: /cam/image_raw; joint topics: /gripper/joint_states, /joint_states" in err
    assert "give --image-topic one of the topics listed" in err
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys, extra=["--joint-topic", "/js"])
    assert "topic /js is not in the bag" in err and "--joint-topic" in err


def test_chain_joints_missing(lab, tmp_path, capsys):
    root = lab[0]
    _small_bag(tmp_path / "s.bag", names=CHAIN[:5])
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys)
    assert "topic /joint_states" in err and "missing: ['a6']" in err
    assert "['a1', 'a2', 'a3', 'a4', 'a5']" in err and str(CHAIN) in err and "--robot" in err


def test_no_joint_message_within_the_window(lab, tmp_path, capsys):
    root = lab[0]
    t0 = 10 * NS
    _small_bag(tmp_path / "s.bag", pause=(t0 + NS // 2, t0 + 3 * NS // 2))
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys)
    assert "no message on /joint_states within +-0.25 s of the image at" in err
    assert "on /cam/image_raw" in err and "pause from 10.490 s to 11.500 s" in err
    assert "record the joint topic without pauses" in err


def test_unsupported_encoding(lab, tmp_path, capsys):
    root = lab[0]
    _small_bag(tmp_path / "s.bag", encoding="bayer_rggb8")
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys)
    assert "topic /cam/image_raw: image encoding 'bayer_rggb8' is not supported" in err
    assert "mono8, mono16, rgb8 or bgr8" in err


def test_no_image_at_rest(lab, tmp_path, capsys):
    root = lab[0]
    _small_bag(tmp_path / "s.bag", moving=True)
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys)
    assert "none of the" in err and "images on /cam/image_raw was taken at rest" in err
    assert "while moving" in err and "record stop-and-go motion" in err


def test_images_and_joints_on_two_clocks(lab, tmp_path, capsys):
    root = lab[0]
    _small_bag(tmp_path / "s.bag", clock=1000 * NS)
    err = _error(tmp_path / "s.bag", tmp_path, root, capsys)
    assert (
        "the 15 images on /cam/image_raw (1010.333 s to 1013.833 s) lie outside the joint " in err
    )
    assert "messages on /joint_states (10.000 s to 14.390 s)" in err and "one clock" in err


def test_zero_header_stamps_are_taken_at_their_recording_time(lab, tmp_path, capsys):
    root = lab[0]
    _small_bag(tmp_path / "s.bag", zero_stamps=True)
    with BagReader(tmp_path / "s.bag") as r:
        got = [(m.header.stamp.sec, s) for _, _, m, s in r.timed(["/joint_states"])]
    assert got[:2] == [(0, 10 * NS), (0, 10 * NS + NS // 100)]
    # the joints cover the images: the import gets as far as looking for the board in them
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # 6 images taken while moving; no board in any image
        assert _import(tmp_path / "s.bag", tmp_path / "o", root, "cam0=/cam/image_raw") == 2
    err = capsys.readouterr().err
    assert "is found in none of the 2 frames" in err  # one frame per rest (the default), 2 rests


def test_not_a_bag(tmp_path):
    from selfcal.ros.rosbag import bag_format

    (tmp_path / "x.bag").write_text("hello")
    with pytest.raises(InputError, match="not a ROS bag"):
        bag_format(tmp_path / "x.bag")
    (tmp_path / "d").mkdir()
    with pytest.raises(InputError, match="without metadata.yaml"):
        bag_format(tmp_path / "d")
