"""``selfcal import --bag``: a ROS bag (:mod:`selfcal.ros.rosbag`) as a dataset folder.

Two streaming passes over the bag, so memory does not grow with it:

1. the joint topic (``sensor_msgs/JointState``, names matched to the robot's chain, other joints
   ignored), each camera's ``camera_info`` (the image topic's sibling; a calibrated one becomes
   the camera's initial camera in dataset.json) and ``/tf_static`` / ``/tf`` (a hand-eye hint:
   :mod:`selfcal.ros.bag_tf`), kept compactly;
2. the image topics: an image taken at rest (:mod:`selfcal.ros.bag_rest`) is decoded and staged as a
   PNG at once, any other is only counted (one warning line).

Then the cameras' images are paired into frames (one rest, one image of each camera), the joints
interpolated at the first camera's stamp (header stamps; the recording time for a zero one), and :func:`selfcal.importing.dataset.import_dataset` checks
and writes the dataset exactly as for image files and a joints file. ``dataset.json`` records the
bag, its format, the topics and the rest rule (``scenario.import``), ``sources.csv`` each image's
``BAG#TOPIC@STAMP_NS``.
"""

from __future__ import annotations

import os
import shutil
import warnings
from array import array
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from selfcal.camera.registry import MODELS, ROS_D_NAMES, ROS_MODEL_OF
from selfcal.errors import SelfCalWarning
from selfcal.importing.dataset import DEFAULT_MODEL, CameraImages, ImportError_, import_dataset
from selfcal.io.dataset_info import DatasetInfo
from selfcal.io.outlock import removed_on_failure
from selfcal.robot.definition import load_robot
from selfcal.robot.urdf import urdf_chain
from selfcal.ros.bag_rest import GAP, MOVING, OUTSIDE, JointTrack, RestRule, pair_frames, thin_rests
from selfcal.ros.bag_stage import (
    MovingImagesWarning,
    name_frames,
    secs,
    stage_images,
    warn_skipped,
)
from selfcal.ros.bag_tf import TF_TOPICS, TF_TYPE, TfTree
from selfcal.ros.rosbag import (
    IMAGE_TYPES,
    INFO_TYPE,
    JOINT_TYPE,
    BagError,
    BagReader,
    CameraInfo,
)

__all__ = [
    "Chain",
    "ImageTopic",
    "CameraInfoWarning",
    "MovingImagesWarning",
    "initial_values",
    "import_bag",
    "read_joint_track",
    "MODEL_OF",
]

MODEL_OF = {r: m for r, m in ROS_MODEL_OF.items() if m in MODELS}
"""The camera model of a calibrated CameraInfo's ``distortion_model`` (the registry's, for the
models a dataset takes: :data:`selfcal.camera.MODELS`)."""
D_NAMES = ROS_D_NAMES
"""The OpenCV names of a CameraInfo's ``D``, by ``distortion_model``."""
_STAGE = ".bag-staging"


class CameraInfoWarning(SelfCalWarning):
    """A calibrated CameraInfo that cannot initialise the camera (another image size)."""


@contextmanager
def _staging(stage: Path) -> Iterator[None]:
    """Remove the staging folder ``stage`` when the block ends, however it ends."""
    try:
        yield
    finally:
        if stage.exists():
            shutil.rmtree(stage)


@dataclass(frozen=True)
class ImageTopic:
    """One ``--image-topic NAME=TOPIC``: the camera's name and its image topic."""

    name: str
    topic: str

    @classmethod
    def parse(cls, spec: str, default_name: str = "cam0") -> ImageTopic:
        """``NAME=/topic`` (or a bare ``/topic`` for a camera called ``default_name``)."""
        name, sep, topic = spec.partition("=")
        if not sep:
            name, topic = default_name, spec
        name, topic = name.strip(), topic.strip()
        if not name or not all(ch.isalnum() or ch in "-_" for ch in name) or not topic:
            raise ImportError_(f"--image-topic {spec!r}",
                               fix="give NAME=/topic, the name of letters, digits, - or _: "
                               "--image-topic cam0=/camera/image_raw")  # fmt: skip
        return cls(name, topic)

    @property
    def info_topic(self) -> str:
        """The sibling ``camera_info`` topic (``/ns/image_raw`` -> ``/ns/camera_info``;
        ``/ns/image_raw/compressed`` -> ``/ns/camera_info``)."""
        parts = self.topic.rstrip("/").split("/")
        if parts[-1] == "compressed":
            parts = parts[:-1]
        return "/".join(parts[:-1] + ["camera_info"])


def read_joint_track(
    reader: BagReader, topic: str, chain: Chain, cams: Sequence[ImageTopic] = (),
    tf: TfTree | None = None,
) -> tuple[JointTrack, dict[str, CameraInfo | None]]:  # fmt: skip
    """One pass over the joint topic and the cameras' ``camera_info`` topics: the joint readings
    in the order of the robot's ``chain`` (matched by name; messages naming none of the chain's
    joints, e.g. a gripper's, are ignored) and each camera's first calibrated CameraInfo (None
    when its topic is absent or uncalibrated: K all zeros). ``tf``: fed the bag's ``/tf_static``
    and ``/tf`` messages in the same pass.

    Raises:
        BagError: the topic is missing or not a JointState (lists the bag's topics), or its
            messages lack chain joints (lists both sets of names).
    """
    reader.require(topic, (JOINT_TYPE,), "--joint-topic")
    infos = {c.info_topic: c.name for c in cams if reader.topics.get(c.info_topic) == INFO_TYPE}
    found: dict[str, CameraInfo | None] = {c.name: None for c in cams}
    ts, qs = array("q"), array("d")  # compact: 8 bytes a number however long the recording
    seen: set[str] = set()
    bad = False
    tf_topics = [t for t in TF_TOPICS if tf is not None and reader.topics.get(t) == TF_TYPE]
    for t, _m, msg, stamp in reader.timed([topic, *infos, *tf_topics]):
        if t in tf_topics:
            assert tf is not None
            tf.add(msg, static=t == "/tf_static")
            continue
        if t != topic:
            info = CameraInfo.from_msg(msg)
            if found[infos[t]] is None and info.calibrated:
                found[infos[t]] = info
            continue
        if bad:
            continue
        names = list(msg.name)
        seen.update(names)
        idx = {n: k for k, n in enumerate(names)}
        have = [n in idx for n in chain.joint_names]
        if not any(have):
            continue  # another joint group on the same topic (e.g. the gripper)
        pos = np.asarray(msg.position, float)
        if not all(have) or len(pos) != len(names):
            seen, bad = set(names), True
            continue
        ts.append(stamp)
        qs.extend(pos[[idx[n] for n in chain.joint_names]])
    if ts and not bad:
        q = np.frombuffer(qs, float).reshape(len(ts), len(chain.joint_names))
        return JointTrack(np.frombuffer(ts, np.int64), q, chain.joint_types), found
    missing = [n for n in chain.joint_names if n not in seen]
    raise BagError(
        f"{reader.label}: topic {topic}: JointState names {sorted(seen) or 'no joint'}, but robot "
        f"{chain.name}'s chain is {list(chain.joint_names)} (missing: {missing or 'positions'})",
        fix="give the --robot whose URDF/TOML names the joints the driver publishes, or the "
        "--joint-topic of the arm's joints",
    )


@dataclass(frozen=True)
class Chain:
    """The robot's joints as the bag must name them: robot name, joint names and types."""

    name: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]

    @classmethod
    def of(cls, robot: str, base_link: str | None, tool_link: str | None) -> Chain:
        """The chain of ``--robot`` (a model name, robot TOML or URDF, with a URDF's links)."""
        if Path(robot).suffix == ".urdf" and (base_link or tool_link):
            ch = urdf_chain(Path(robot), base_link=base_link, tool_link=tool_link)
            return cls(Path(robot).stem, tuple(ch.joint_names), tuple(ch.joint_types))
        rob = load_robot(robot)
        return cls(rob.name, tuple(rob.joint_names), tuple(rob.joint_types))


def _model(
    infos: dict[str, CameraInfo | None], given: str | Mapping[str, str] | None, bag: str
) -> str | dict[str, str]:
    """The camera model: given, else the calibrated CameraInfos' (one for all), else opencv;
    ``given`` by camera name: the cameras it leaves out by their CameraInfos."""
    if isinstance(given, Mapping):
        rest = {n: i for n, i in infos.items() if n not in given}
        one = _model(rest, None, bag)
        assert isinstance(one, str)
        return {**dict.fromkeys(rest, one), **given}
    if given is not None:
        return given
    models = {n: MODEL_OF.get(i.distortion_model) for n, i in infos.items() if i is not None}
    unknown = [n for n, m in models.items() if m is None]
    if unknown or len(set(models.values())) > 1:
        raise ImportError_(
            f"{bag}: camera_info distortion models "
            f"{ {n: i.distortion_model for n, i in infos.items() if i is not None} }",
            fix="give --camera-model (opencv, fisheye or pinhole) for all cameras",
        )
    return next(iter(models.values()), None) or DEFAULT_MODEL


def initial_values(info: CameraInfo, model: str) -> dict[str, float]:
    """The camera a calibrated CameraInfo describes, by OpenCV's names (px): ``fx``, ``fy``,
    ``cx``, ``cy`` (and ``skew`` when K[0, 1] is not 0) from K and, when ``model`` is the one of its ``distortion_model``
    (:data:`MODEL_OF`), the lens coefficients from D (a pinhole, or another lens, takes K only)."""
    K = info.K
    out = {"fx": K[0], "fy": K[4], "cx": K[2], "cy": K[5]}
    if K[1] != 0.0:  # K[0, 1]: a skewed camera's
        out["skew"] = K[1]
    if MODEL_OF.get(info.distortion_model) == model:
        out.update(zip(D_NAMES[info.distortion_model], info.D))
    return {k: float(v) for k, v in out.items()}


def _initial(infos: dict[str, CameraInfo | None], cams: Sequence[ImageTopic],
             model: str | Mapping[str, str], files: dict[str, list[Path]],
             where: str) -> dict[str, dict] | None:  # fmt: skip
    """dataset.json's initial camera of every camera with a calibrated CameraInfo of its images'
    size (another size: a :class:`CameraInfoWarning`, and no initial camera)."""
    out: dict[str, dict] = {}
    for c in cams:
        info = infos[c.name]
        if info is None:
            continue
        img = cv2.imread(str(files[c.name][0]), cv2.IMREAD_UNCHANGED)
        assert img is not None  # staged by this import
        size = (int(img.shape[1]), int(img.shape[0]))
        if size != (info.width, info.height) or info.K[0] <= 0 or info.K[4] <= 0:
            warnings.warn(
                f"{where}: topic {c.info_topic}: the camera_info describes a {info.width}x"
                f"{info.height} px camera (fx {info.K[0]:g}, fy {info.K[4]:g}) but the images on "
                f"{c.topic} are {size[0]}x{size[1]} px: not used as the initial camera",
                CameraInfoWarning,
                stacklevel=3,
            )
            continue
        out[c.name] = {"source": "camera_info", "where": f"{where}#{c.info_topic}",
                       "values": initial_values(info, model if isinstance(model, str)
                                                 else model[c.name])}  # fmt: skip
    return out or None


def import_bag(
    bag: str | Path | Sequence[str | Path],
    image_topics: Sequence[ImageTopic],
    joint_topic: str,
    robot: str,
    target: str | Path,
    out: str | Path,
    *,
    rule: RestRule | None = None,
    per_rest: int | None = 1,
    base_link: str | None = None,
    tool_link: str | None = None,
    camera_model: str | Mapping[str, str] | None = None,
    free: Sequence[str] | Mapping[str, Sequence[str]] | None = None,
) -> DatasetInfo:
    """Import the bag ``bag`` (a path, or the paths of a split ROS 1 recording read as one bag:
    :class:`selfcal.ros.rosbag.BagReader`) as the dataset folder ``out`` (module docstring); returns its
    ``dataset.json`` content. ``robot``, ``target``, ``base_link``, ``tool_link``, ``free``: as
    :func:`selfcal.importing.dataset.import_dataset`; ``camera_model`` None (or a camera it does not
    name): from the calibrated CameraInfos (plumb_bob / rational_polynomial -> opencv,
    equidistant -> fisheye), else opencv.
    ``rule``: the rest test (default :class:`selfcal.ros.bag_rest.RestRule`). ``per_rest``: keep at most this many frames of each rest (default 1, its middle frame: a frame is one posture, and calibrate refuses two frames of one posture as copies; None: all).

    Raises:
        selfcal.ros.rosbag.BagError: a missing topic, chain joints missing from the JointState, no
            joint message near an image, an unsupported image encoding, no image at rest (each
            names the bag, the topic and the fix); the errors of ``import_dataset``.
    """
    bags = [Path(bag)] if isinstance(bag, (str, Path)) else [Path(b) for b in bag]
    out = Path(out)
    rule = RestRule() if rule is None else rule
    names = [c.name for c in image_topics]
    if not image_topics or len(set(names)) != len(names):
        raise ImportError_(f"camera names {names}", fix="give each --image-topic a distinct NAME=")
    if (out / "dataset.json").exists():
        raise ImportError_(f"{out} already holds a dataset", fix="choose another --out folder")
    if Path(robot).suffix in (".toml", ".urdf") and not Path(robot).is_file():
        raise ImportError_(f"--robot {robot}: no such file",
                           fix="give a model name, a robot TOML or a URDF file")  # fmt: skip
    chain = Chain.of(robot, base_link, tool_link)
    stage = out / _STAGE
    with removed_on_failure(out), _staging(stage):
        with BagReader(bags) as reader:
            where = reader.label
            for c in image_topics:
                reader.require(c.topic, IMAGE_TYPES, "--image-topic")
            tf = TfTree()
            track, infos = read_joint_track(reader, joint_topic, chain, image_topics, tf)
            model = _model(infos, camera_model, where)
            if stage.exists():
                shutil.rmtree(stage)
            staged, counts, total, span, frame_ids = stage_images(
                reader, {c.name: c.topic for c in image_topics}, track, rule, joint_topic, stage)  # fmt: skip
            fmt = reader.format
        topics = ", ".join(c.topic for c in image_topics)
        at_rest = sum(len(s.files) for s in staged.values())
        if total and counts[OUTSIDE] == total:
            raise BagError(
                f"{where}: the {total} images on {topics} ({secs(span[0])} to {secs(span[1])}) lie "
                f"outside the joint messages on {joint_topic} ({secs(int(track.t[0]))} to "
                f"{secs(int(track.t[-1]))})",
                fix="stamp images and joints by one clock (check use_sim_time and the camera "
                "driver's time source), and record the joints for as long as the camera",
            )
        if at_rest == 0:
            raise BagError(
                f"{where}: none of the {total} images on {topics} was taken at rest ({counts[MOVING]}"
                f" while moving, {counts[GAP]} at a pause of {joint_topic}, {counts[OUTSIDE]} "
                f"outside its recording; rest test: {rule.describe()})",
                fix="record stop-and-go motion that rests at least 1 s at every posture "
                "(docs/ros.md), or loosen --rest-speed / shorten --rest-window",
            )
        frames = pair_frames({n: staged[n].stamps for n in names}, names, track, rule)
        frames = thin_rests(frames, staged[names[0]].stamps, track, rule, per_rest)
        warn_skipped(where, rule, counts, total, at_rest, frames, len(names))
        files = name_frames(staged, names, frames, stage)
        n = len(chain.joint_names)
        q = np.array([track.at(staged[names[0]].stamps[f[0]]) for f in frames]).reshape(-1, n)
        joints = stage / "joints.csv"
        lines = ["image," + ",".join(f"j{j + 1}" for j in range(n))]
        lines += [
            f"{k:06d}.png," + ",".join(repr(float(v)) for v in row) for k, row in enumerate(q)
        ]
        joints.write_text("\n".join(lines) + "\n")
        labels = {files[n][k]: f"{staged[n].bags[f[j]].resolve()}#{c.topic}@{staged[n].stamps[f[j]]}"
                  for j, (n, c) in enumerate(zip(names, image_topics))
                  for k, f in enumerate(frames)}  # fmt: skip
        source = {
            "bag": str(bags[0].resolve()) if len(bags) == 1 else [str(b.resolve()) for b in bags],
            "format": fmt, "joint_topic": joint_topic,
            "image_topics": {c.name: c.topic for c in image_topics},
            "joint_names": list(chain.joint_names), "rest": rule.to_json(),
            "camera_info": {n: None if i is None else i.to_json() for n, i in infos.items()},
            "images": {"total": total, "at_rest": at_rest, "frames": len(frames), **counts},
            "target": str(target),
            "tf": tf.hint(frame_ids) if tf.messages else None,
        }  # fmt: skip
        cams = [CameraImages(n, c.topic, tuple(files[n])) for n, c in zip(names, image_topics)]
        initial = _initial(infos, image_topics, model, files, where) if frames else None
        info = import_dataset(robot, cams, joints, "rad", target, out, base_link=base_link,
                              tool_link=tool_link, link=True, trust_units=True,
                              camera_model=model, free=free, source=source, labels=labels,
                              initial=initial)  # fmt: skip
        for link in (out / "frames").iterdir():
            if link.is_symlink():
                os.replace(link.resolve(), link)  # the staged file becomes the frame
        return info
