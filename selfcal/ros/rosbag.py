"""ROS bags: read and write the messages of a calibration through ``rosbags`` (pure Python, no ROS
installation; the optional extra ``scorbot-selfcal[ros]``).

Formats, recognised from the path's content (:func:`bag_format`), never declared:

- ``ros1``: a ROS 1 ``.bag`` file;
- ``ros2``: a ROS 2 bag folder (``metadata.yaml``) with sqlite3 storage;
- ``mcap``: a ROS 2 bag folder with mcap storage, or a bare ``.mcap`` file.

Messages (ROS 2 type names, which ``rosbags`` uses for ROS 1 too): ``sensor_msgs/msg/Image`` and
``CompressedImage`` (decoded by :func:`decode_image`: numpy for raw, OpenCV for jpeg/png),
``CameraInfo`` (:class:`CameraInfo`), ``JointState`` and ``std_msgs/msg/String``. Stamps are
integer nanoseconds (the header stamp, ``sec * 1e9 + nanosec``). Reading streams: one message at a
time is deserialised, so memory does not grow with the bag.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar

import cv2
import numpy as np

from selfcal.choices import BAG_FORMATS
from selfcal.errors import InputError
from selfcal.ros.bag_rest import NS

__all__ = [
    "BagError",
    "BagReader",
    "BagWriter",
    "CameraInfo",
    "COMPRESSED_TYPE",
    "RAW_TYPE",
    "FORMATS",
    "IMAGE_TYPES",
    "INFO_TYPE",
    "JOINT_TYPE",
    "STRING_TYPE",
    "ENCODINGS",
    "bag_format",
    "decode_image",
    "stamp_ns",
]

FORMATS = BAG_FORMATS
"""Bag formats: ROS 1 ``.bag``, ROS 2 folder with sqlite3 storage, ROS 2 mcap (folder or file)."""
RAW_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (RAW_TYPE, COMPRESSED_TYPE)
INFO_TYPE = "sensor_msgs/msg/CameraInfo"
JOINT_TYPE = "sensor_msgs/msg/JointState"
TF_MSG = "tf2_msgs/msg/TFMessage"
STRING_TYPE = "std_msgs/msg/String"
ENCODINGS = ("mono8", "mono16", "rgb8", "bgr8")
"""Raw image encodings read (and ``CompressedImage`` in jpeg or png)."""
INSTALL_FIX = "install the ROS extra: pip install 'scorbot-selfcal[ros]' (or uv sync --extra ros)"
_MAGIC_ROS1 = b"#ROSBAG V2.0"
_MAGIC_MCAP = b"\x89MCAP0\r\n"
_MAGIC_SQLITE = b"SQLite format 3\x00"


class BagError(InputError):
    """A bag that cannot be read or does not hold what is asked (names the bag, topic and fix)."""


def _rosbags() -> Any:
    """The ``rosbags`` package (an optional dependency; its absence is a clear error)."""
    try:
        import rosbags.highlevel  # optional heavy import: only bag users need it
        import rosbags.rosbag1
        import rosbags.rosbag2
        import rosbags.typesys
    except ImportError:  # pragma: no cover - the dev environment has it
        raise InputError("reading or writing ROS bags needs the rosbags package",
                         fix=INSTALL_FIX) from None  # fmt: skip
    return rosbags


def _magic(path: Path) -> bytes:
    with open(path, "rb") as fh:
        return fh.read(16)


def bag_format(path: str | Path) -> str:
    """The format of the bag at ``path`` (:data:`FORMATS`), from its content.

    Raises:
        BagError: no such path, or not a bag of a known format (the message says what was found).
    """
    p = Path(path)
    if p.is_dir():
        meta = p / "metadata.yaml"
        if not meta.is_file():
            raise BagError(f"{p}: a folder without metadata.yaml is no ROS 2 bag",
                           fix="give the bag folder `ros2 bag record` wrote, a .bag or a .mcap "
                           "file")  # fmt: skip
        text = meta.read_text(errors="replace")
        return "mcap" if "storage_identifier: mcap" in text else "ros2"
    if not p.is_file():
        raise BagError(f"{p}: no such bag", fix="give a .bag file, a ROS 2 bag folder or a .mcap")
    head = _magic(p)
    if head.startswith(_MAGIC_ROS1):
        return "ros1"
    if head.startswith(_MAGIC_MCAP):
        return "mcap"
    if head.startswith(_MAGIC_SQLITE):
        raise BagError(f"{p}: a ROS 2 sqlite3 file alone",
                       fix=f"give the bag folder that holds it and its metadata.yaml "
                       f"({p.parent})")  # fmt: skip
    raise BagError(f"{p}: not a ROS bag (starts with {head[:12]!r})",
                   fix="give a ROS 1 .bag, a ROS 2 bag folder or a .mcap file")  # fmt: skip


@dataclass(frozen=True)
class CameraInfo:
    """A ``sensor_msgs/CameraInfo``: image size (px), distortion model and coefficients, K, and
    the rectified camera matrix K' of ``P = [K' | 0]`` (empty: K)."""

    width: int
    height: int
    distortion_model: str
    D: tuple[float, ...]
    K: tuple[float, ...]
    K_rectified: tuple[float, ...] = ()

    @property
    def calibrated(self) -> bool:
        """Whether it carries a calibration (an uncalibrated camera publishes K all zeros)."""
        return any(k != 0.0 for k in self.K)

    def to_json(self) -> dict:
        return {"width": self.width, "height": self.height,
                "distortion_model": self.distortion_model, "D": list(self.D), "K": list(self.K)}  # fmt: skip

    @classmethod
    def from_msg(cls, msg: Any) -> CameraInfo:
        D = getattr(msg, "d", None)
        K = getattr(msg, "k", None)
        D = msg.D if D is None else D
        K = msg.K if K is None else K
        return cls(int(msg.width), int(msg.height), str(msg.distortion_model),
                   tuple(float(v) for v in D), tuple(float(v) for v in K))  # fmt: skip


def stamp_ns(msg: Any) -> int:
    """A message's header stamp in integer nanoseconds."""
    t = msg.header.stamp
    return int(t.sec) * NS + int(t.nanosec)


def decode_image(msg: Any, msgtype: str, where: str) -> np.ndarray:
    """The pixels of an ``Image`` or ``CompressedImage`` message: (H, W) uint8 or uint16 for mono,
    (H, W, 3) uint8 in OpenCV's BGR order for colour. ``where`` names the bag and topic in errors.

    Raises:
        BagError: an encoding outside :data:`ENCODINGS` (or a compressed format other than jpeg
            or png), or data that do not fit the declared size.
    """
    if msgtype == COMPRESSED_TYPE:
        fmt = str(msg.format).lower()
        if ("jpeg" not in fmt and "jpg" not in fmt and "png" not in fmt) or "depth" in fmt:
            raise BagError(f"{where}: compressed image format {msg.format!r} is not supported",
                           fix="record jpeg or png CompressedImage, or raw mono8, mono16, rgb8 or "
                           "bgr8 Image messages")  # fmt: skip
        img = cv2.imdecode(np.asarray(msg.data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise BagError(f"{where}: a {msg.format!r} image that OpenCV cannot decode",
                           fix="check the camera driver's compression settings")  # fmt: skip
        return img
    enc = str(msg.encoding)
    if enc not in ENCODINGS:
        raise BagError(f"{where}: image encoding {enc!r} is not supported",
                       fix="record the camera as mono8, mono16, rgb8 or bgr8 (e.g. the "
                       "image_proc output, not a Bayer or YUV stream), or as jpeg/png "
                       "CompressedImage")  # fmt: skip
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, np.uint8)
    if data.size < h * step:
        raise BagError(f"{where}: {data.size} bytes for a {w}x{h} {enc} image (step {step})",
                       fix="the message is damaged; re-record the topic")  # fmt: skip
    rows = data[: h * step].reshape(h, step)
    if enc == "mono16":
        dt = np.dtype(">u2" if msg.is_bigendian else "<u2")
        return rows[:, : 2 * w].copy().view(dt).astype(np.uint16).reshape(h, w)
    ch = 1 if enc == "mono8" else 3
    img = rows[:, : ch * w].reshape(h, w, ch) if ch == 3 else rows[:, :w]
    if enc == "rgb8":
        return np.ascontiguousarray(img[:, :, ::-1])
    return np.ascontiguousarray(img)


_C = TypeVar("_C", bound="_Closing")


class _Closing:
    """A context manager that calls ``close()`` on exit."""

    def close(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class BagReader(_Closing):
    """A bag opened for streaming reads (a context manager): one bag, or the files of one ROS 1
    recording split by ``rosbag record --split`` (``name_0.bag``, ``name_1.bag``, ...) read as
    one bag, their messages merged in time order.

    ``topics``: topic -> message type of every topic in the bag; ``path``: the (first) bag;
    ``paths``: all of them; ``label``: how messages name the bag (its path, or the first and last
    file of a split recording and their count).
    """

    def __init__(self, path: str | Path | Sequence[str | Path]) -> None:
        many = [path] if isinstance(path, (str, Path)) else list(path)
        if not many:
            raise BagError("no bag given", fix="give --bag PATH (repeat it for the files of a "
                           "split recording)")  # fmt: skip
        self.paths = tuple(dict.fromkeys(Path(p) for p in many))
        self.path = self.paths[0]
        self.label = (str(self.path) if len(self.paths) == 1 else
                      f"{self.paths[0]} ... {self.paths[-1].name} ({len(self.paths)} files)")  # fmt: skip
        formats = {p: bag_format(p) for p in self.paths}
        self.format = formats[self.path]
        rb = _rosbags()
        for p, fmt in formats.items():
            if fmt == "ros1" and p.suffix != ".bag":
                raise BagError(f"{p}: a ROS 1 bag without the .bag suffix",
                               fix=f"rename it to {p.with_suffix('.bag').name}")  # fmt: skip
        if len(self.paths) > 1 and set(formats.values()) != {"ros1"}:
            kinds = ", ".join(f"{p.name} ({f})" for p, f in formats.items())
            raise BagError(f"several bags given ({kinds}): only the files of a split ROS 1 "
                           "recording are read as one bag",
                           fix="give one ROS 2 bag folder (it holds all its split files) or "
                           "one .mcap, or only the .bag files of one recording")  # fmt: skip
        try:
            self._reader = rb.highlevel.AnyReader(list(self.paths))
            self._reader.open()
        except Exception as exc:  # rosbags' reader errors have no common root
            raise BagError(f"{self.label}: cannot open the {self.format} bag ({exc})",
                           fix="check that the recording finished (a ROS 2 bag folder needs "
                           "its metadata.yaml; `ros2 bag reindex` rebuilds it; a ROS 1 bag "
                           "`rosbag reindex`)") from None  # fmt: skip
        self.topics: dict[str, str] = {c.topic: c.msgtype for c in self._reader.connections}

    def close(self) -> None:
        """Close the bag."""
        self._reader.close()

    def of_type(self, *msgtypes: str) -> list[str]:
        """The bag's topics of these message types (sorted)."""
        return sorted(t for t, m in self.topics.items() if m in msgtypes)

    def require(self, topic: str, msgtypes: Sequence[str], option: str) -> str:
        """The message type of ``topic``, which must be one of ``msgtypes``.

        Raises:
            BagError: the topic is not in the bag or has another type; the message lists the
                bag's image and joint topics, the fix names ``option``.
        """
        have = (f"image topics: {', '.join(self.of_type(*IMAGE_TYPES)) or 'none'}; joint topics: "
                f"{', '.join(self.of_type(JOINT_TYPE)) or 'none'}")  # fmt: skip
        if topic not in self.topics:
            raise BagError(f"{self.label}: topic {topic} is not in the bag ({have})",
                           fix=f"give {option} one of the topics listed")  # fmt: skip
        if self.topics[topic] not in msgtypes:
            raise BagError(f"{self.label}: topic {topic} holds {self.topics[topic]}, not "
                           f"{' or '.join(msgtypes)} ({have})",
                           fix=f"give {option} one of the topics listed")  # fmt: skip
        return self.topics[topic]

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[str, str, Any]]:
        """``(topic, msgtype, message)`` of ``topics`` in the bag's time order, deserialised one
        at a time."""
        for topic, msgtype, msg, _t in self.timed(topics):
            yield topic, msgtype, msg

    def timed(self, topics: Sequence[str]) -> Iterator[tuple[str, str, Any, int]]:
        """As :meth:`messages`, with each message's stamp (ns): its header stamp, or the time
        it was recorded when it has no header or a zero stamp (some drivers publish those)."""
        for topic, msgtype, msg, stamp, _file in self.timed_in(topics):
            yield topic, msgtype, msg, stamp

    def timed_in(self, topics: Sequence[str]) -> Iterator[tuple[str, str, Any, int, Path]]:
        """As :meth:`timed`, with the bag file each message was read from (one of
        :attr:`paths`; the bag folder for ROS 2)."""
        conns = [c for c in self._reader.connections if c.topic in set(topics)]
        if not conns:
            return
        for conn, t, raw in self._reader.messages(connections=conns):
            try:
                msg = self._reader.deserialize(raw, conn.msgtype)
            except Exception as exc:  # rosbags' serde errors have no common root
                raise BagError(f"{self.label}: topic {conn.topic}: a message that cannot be "
                               f"decoded ({exc})", fix="re-record the topic") from None  # fmt: skip
            stamp = stamp_ns(msg) if hasattr(msg, "header") else 0
            owner = getattr(getattr(conn, "owner", None), "path", None)
            yield conn.topic, conn.msgtype, msg, stamp or int(t), Path(owner or self.path)


class BagWriter(_Closing):
    """A new bag of ``fmt`` (:data:`FORMATS`) at ``path`` (a ``.bag`` file for ros1, a folder for
    ros2, a bare ``.mcap`` file for mcap when ``path`` ends in ``.mcap``, else an mcap bag
    folder); a context manager. Topics are added on first use."""

    def __init__(self, path: str | Path, fmt: str) -> None:
        if fmt not in FORMATS:
            raise BagError(f"bag format {fmt!r}", fix=f"use one of {', '.join(FORMATS)}")
        self.path, self.format = Path(path), fmt
        if self.path.exists():
            raise BagError(f"{self.path} exists already", fix="choose a new --bag path")
        rb = _rosbags()
        ts = rb.typesys
        self._ros1 = fmt == "ros1"
        store = ts.Stores.ROS1_NOETIC if self._ros1 else ts.Stores.ROS2_HUMBLE
        self._ts = ts.get_typestore(store)
        if TF_MSG not in self._ts.types:  # ROS 1 Noetic's store lacks tf2_msgs: its definition
            self._ts.register(ts.get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", TF_MSG))  # fmt: skip
        # a bare .mcap: rosbags writes a bag folder; its one .mcap file is moved out on close
        self._bare = fmt == "mcap" and self.path.suffix == ".mcap"
        self._folder = self.path.with_name(f".{self.path.name}.part") if self._bare else self.path
        if self._bare and self._folder.exists():
            shutil.rmtree(self._folder)  # left by an interrupted export
        if self._ros1:
            self._w = rb.rosbag1.Writer(self.path)
        else:
            plugin = rb.rosbag2.StoragePlugin
            self._w = rb.rosbag2.Writer(self._folder, version=8, storage_plugin=(
                plugin.MCAP if fmt == "mcap" else plugin.SQLITE3))  # fmt: skip
        self._w.open()
        self._conns: dict[str, Any] = {}
        self._T = self._ts.types

    def close(self) -> None:
        """Finish the bag (its index and metadata; a bare ``.mcap`` keeps its summary and
        drops the folder's metadata.yaml)."""
        self._w.close()
        if self._bare:
            (data,) = self._folder.glob("*.mcap")
            os.replace(data, self.path)
            shutil.rmtree(self._folder)

    def _header(self, stamp: int, frame_id: str) -> Any:
        t = self._T["builtin_interfaces/msg/Time"](sec=stamp // NS,
                                                  nanosec=stamp % NS)  # fmt: skip
        if self._ros1:
            return self._T["std_msgs/msg/Header"](seq=0, stamp=t, frame_id=frame_id)
        return self._T["std_msgs/msg/Header"](stamp=t, frame_id=frame_id)

    def _write(self, topic: str, msgtype: str, stamp: int, msg: Any) -> None:
        if topic not in self._conns:
            self._conns[topic] = self._w.add_connection(topic, msgtype, typestore=self._ts)
        data = (self._ts.serialize_ros1(msg, msgtype) if self._ros1
                else self._ts.serialize_cdr(msg, msgtype))  # fmt: skip
        self._w.write(self._conns[topic], stamp, data)

    def image(self, topic: str, stamp: int, frame_id: str, img: np.ndarray) -> None:
        """A raw ``Image`` at ``stamp`` (ns): mono8 / mono16 for (H, W) uint8 / uint16, bgr8 for
        (H, W, 3) uint8 (OpenCV's channel order)."""
        img = np.ascontiguousarray(img)
        if img.ndim == 2:
            enc = "mono16" if img.dtype == np.uint16 else "mono8"
        elif img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8:
            enc = "bgr8"
        else:
            raise BagError(f"an image of shape {img.shape} and type {img.dtype}",
                           fix="give gray (8 or 16 bit) or 8-bit BGR images")  # fmt: skip
        le = img.astype(img.dtype.newbyteorder("<"), copy=False)
        h, w = img.shape[:2]
        msg = self._T[RAW_TYPE](header=self._header(stamp, frame_id), height=h, width=w,
                                encoding=enc, is_bigendian=0, step=le.nbytes // h,
                                data=np.frombuffer(le.tobytes(), np.uint8))  # fmt: skip
        self._write(topic, RAW_TYPE, stamp, msg)

    def camera_info(self, topic: str, stamp: int, frame_id: str, info: CameraInfo) -> None:
        """A ``CameraInfo`` at ``stamp`` (ns); R = identity (a monocular camera), P = [K' | 0]
        with K' ``info.K_rectified`` (ROS camera_calibration's convention), K when empty."""
        K = np.asarray(info.K, float)
        P = np.zeros(12)
        P.reshape(3, 4)[:, :3] = np.asarray(info.K_rectified or info.K, float).reshape(3, 3)
        roi = self._T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0,
                                                          width=0, do_rectify=False)  # fmt: skip
        arrays = {"d": np.asarray(info.D, float), "k": K, "r": np.eye(3).ravel(), "p": P}
        if self._ros1:
            arrays = {k.upper(): v for k, v in arrays.items()}
        msg = self._T[INFO_TYPE](header=self._header(stamp, frame_id), height=info.height,
                                 width=info.width, distortion_model=info.distortion_model,
                                 binning_x=0, binning_y=0, roi=roi, **arrays)  # fmt: skip
        self._write(topic, INFO_TYPE, stamp, msg)

    def joint_state(self, topic: str, stamp: int, names: Sequence[str], q: np.ndarray) -> None:
        """A ``JointState`` at ``stamp`` (ns): ``names`` and positions ``q`` (rad / m)."""
        empty = np.zeros(0)
        msg = self._T[JOINT_TYPE](header=self._header(stamp, ""), name=list(names),
                                  position=np.asarray(q, float), velocity=empty, effort=empty)  # fmt: skip
        self._write(topic, JOINT_TYPE, stamp, msg)

    def tf(self, topic: str, stamp: int, edges: Sequence[tuple[str, str, np.ndarray]]) -> None:
        """A ``tf2_msgs/TFMessage`` at ``stamp`` (ns) of ``edges``: ``(parent, child,
        T_parent_child)`` (4, 4), metres."""
        from scipy.spatial.transform import Rotation

        T = self._T
        trs = []
        for parent, child, M in edges:
            x, y, z, w = Rotation.from_matrix(np.asarray(M, float)[:3, :3]).as_quat()
            p = np.asarray(M, float)[:3, 3]
            trs.append(T["geometry_msgs/msg/TransformStamped"](
                header=self._header(stamp, parent), child_frame_id=child,
                transform=T["geometry_msgs/msg/Transform"](
                    translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
                    rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w))))  # fmt: skip
        self._write(topic, TF_MSG, stamp, T[TF_MSG](transforms=trs))

    def string(self, topic: str, stamp: int, text: str) -> None:
        """A ``std_msgs/String`` at ``stamp`` (ns)."""
        self._write(topic, STRING_TYPE, stamp, self._T[STRING_TYPE](data=text))
