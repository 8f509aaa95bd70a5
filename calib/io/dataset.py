"""The dataset folder: what a robot (simulated or real) hands to the calibration.

Layout of ``DIR``::

    dataset.json        robot model, camera resolution, target (dictionary, scale ids, d), the
                        planned trajectory and validation postures (deg), observation kind
    joints.csv          one row per frame taken: index, joint read-back (deg)
    frames/NNNN_left.png, frames/NNNN_right.png    rendered or captured stereo pairs (images path)
    detections.csv      index, camera, marker_id, corner, u_px, v_px (analytic path, no images)
    truth.json          simulation only; never read by the calibration

A frame counts as taken once its row is in ``joints.csv``: images are written first (atomically,
via a temporary file and rename), detections are appended and flushed, and the joints row comes
last. An interrupted acquisition therefore keeps every complete frame, and a resumed one drops any
partial rows of the frame that was being written.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from calib.camera import MODELS
from calib.errors import InputError
from calib.io.jsonfile import (
    SCHEMA_KEY,
    Fields,
    check_header,
    dumps,
    load_json,
    write_json_atomic,
)

__all__ = [
    "DatasetError",
    "DatasetInfo",
    "DatasetWriter",
    "Dataset",
    "Detections",
    "read_dataset_info",
    "write_dataset_info",
    "read_gray",
    "CAMERAS",
    "FORMAT",
    "SCHEMA_VERSION",
]

FORMAT = "scorbot-selfcal-dataset"
SCHEMA_VERSION = 1
"""The newest ``dataset.json`` schema this code reads and the one it writes."""
CAMERAS = ("left", "right")
OBSERVATIONS = ("images", "detections")
_FIX = "give a dataset folder written by `selfcal acquire CONFIG --out DIR`, or re-acquire it"

Detections = dict[tuple[int, str], dict[int, np.ndarray]]
"""(frame index, camera) -> {marker id: (4, 2) corners in px, OpenCV convention}."""


class DatasetError(InputError):
    """A dataset folder that is missing, damaged or inconsistent; the message says how to fix it."""


@dataclass(frozen=True)
class DatasetInfo:
    """Contents of ``dataset.json``."""

    robot_model: str
    resolution: tuple[int, int]
    dictionary: str
    scale_ids: tuple[int, int]
    scale_length_m: float
    observation: str  # "images" or "detections"
    planned_joints_deg: np.ndarray
    validation_joints_deg: np.ndarray
    backend: str = "sim"
    scenario: dict = field(default_factory=dict)
    camera_model: str = "pinhole"
    """The cameras' model by name (:data:`calib.camera.MODELS`)."""
    camera_free: tuple[str, ...] = ("fx", "mu")
    """The camera parameters the calibration estimates (OpenCV names; ``mu = fy / fx``)."""

    def to_json(self) -> dict:
        """The ``dataset.json`` document (the one writer: :func:`write_dataset_info`)."""
        return {
            "format": FORMAT,
            SCHEMA_KEY: SCHEMA_VERSION,
            "robot_model": self.robot_model,
            "backend": self.backend,
            "camera": {
                "resolution": list(self.resolution),
                "model": self.camera_model,
                "free": list(self.camera_free),
            },
            "target": {
                "dictionary": self.dictionary,
                "scale_marker_ids": list(self.scale_ids),
                "scale_length_mm": self.scale_length_m * 1000.0,
            },
            "observation": self.observation,
            "trajectory_joints_deg": np.asarray(self.planned_joints_deg).tolist(),
            "validation_joints_deg": np.asarray(self.validation_joints_deg).tolist(),
            "scenario": self.scenario,
        }

    @classmethod
    def from_json(cls, d: dict, where: str) -> DatasetInfo:
        """Parse a ``dataset.json`` document read from ``where`` (the one reader:
        :func:`read_dataset_info`).

        Raises:
            DatasetError: another format, a newer schema_version, a missing or malformed key
                (the message names ``where`` and the key).
        """
        check_header(d, where, fmt=FORMAT, version=SCHEMA_VERSION, fix=_FIX, error=DatasetError)
        f = Fields(d, where, _FIX, error=DatasetError)
        tgt, cam = f.sub("target"), f.sub("camera")
        resolution = cam.ints("resolution")
        if len(resolution) != 2:
            raise cam.bad("resolution", "[width, height]", list(resolution))
        scale_ids = tgt.ints("scale_marker_ids")
        if len(scale_ids) != 2:
            raise tgt.bad("scale_marker_ids", "two marker ids", list(scale_ids))
        planned = f.array("trajectory_joints_deg", (None, None))
        valid = np.zeros((0,))
        if f.has("validation_joints_deg") and f.raw("validation_joints_deg") != []:
            valid = f.array("validation_joints_deg", (None, planned.shape[1]))
        observation = f.str("observation")
        if observation not in OBSERVATIONS:
            raise f.bad("observation", f"one of {OBSERVATIONS}", observation)
        model = cam.str("model") if cam.has("model") else "pinhole"
        if model not in MODELS:
            raise cam.bad("model", f"one of {tuple(MODELS)}", model)
        free = cam.strs("free") if cam.has("free") else ("fx", "mu")
        if not set(free) <= set(MODELS[model].names) or "fx" not in free:
            raise cam.bad("free", f"names of {MODELS[model].names} including fx", list(free))
        scenario = f.raw("scenario") if f.has("scenario") else {}
        if not isinstance(scenario, dict):
            raise f.bad("scenario", "an object", scenario)
        return cls(
            robot_model=f.str("robot_model"),
            backend=f.str("backend") if f.has("backend") else "sim",
            resolution=(resolution[0], resolution[1]),
            dictionary=tgt.str("dictionary"),
            scale_ids=(scale_ids[0], scale_ids[1]),
            scale_length_m=tgt.float("scale_length_mm") / 1000.0,
            observation=observation,
            planned_joints_deg=planned,
            validation_joints_deg=valid,
            scenario=scenario,
            camera_model=model,
            camera_free=tuple(free),
        )


def read_dataset_info(path: str | Path) -> DatasetInfo:
    """Read ``dataset.json`` at ``path`` (the one reader of that file).

    Raises:
        DatasetError: missing or unreadable file, not JSON, another format, a newer
            schema_version, a missing or malformed key (named).
    """
    doc = load_json(path, fix=_FIX, error=DatasetError)
    return DatasetInfo.from_json(doc, str(path))


def write_dataset_info(path: str | Path, info: DatasetInfo) -> Path:
    """Write ``info`` as ``dataset.json`` at ``path`` (atomically; the one writer)."""
    return write_json_atomic(path, info.to_json())


def _resume_key(info: DatasetInfo) -> str:
    """What must match to resume a dataset: everything but how the hardware is reached (a
    controller may come back on another port, cameras under other device names)."""
    doc = info.to_json()
    scenario = {**doc["scenario"]}
    if isinstance(scenario.get("robot"), dict):
        scenario["robot"] = {k: v for k, v in scenario["robot"].items() if k != "hardware"}
    doc["scenario"] = scenario
    return dumps(doc)


def _write_bytes_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name("." + path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def _encode_png(rgb: np.ndarray) -> bytes:
    img = np.asarray(rgb)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover
        raise DatasetError("could not encode a PNG image")
    return buf.tobytes()


def _read_csv_rows(path: Path) -> list[list[str]]:
    """Rows of a CSV file, header excluded, ignoring a trailing partial line."""
    if not path.is_file():
        return []
    text = path.read_text()
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    rows = list(csv.reader(text.splitlines()))
    return rows[1:]


class DatasetWriter:
    """Writes a dataset frame by frame; ``resume=True`` continues an interrupted one."""

    def __init__(self, root: str | Path, info: DatasetInfo, *, resume: bool = False) -> None:
        self.root = Path(root)
        self.info = info
        meta = self.root / "dataset.json"
        if meta.exists() and not resume:
            raise DatasetError(
                f"{self.root} already holds a dataset; use --resume to continue it or choose "
                "another --out folder"
            )
        if resume and meta.exists():
            if _resume_key(read_dataset_info(meta)) != _resume_key(info):
                raise DatasetError(
                    f"{self.root}: cannot resume: the dataset was acquired with another scenario "
                    "(dataset.json differs); use a new --out folder"
                )
        self.root.mkdir(parents=True, exist_ok=True)
        (self.root / "frames").mkdir(exist_ok=True)
        write_dataset_info(meta, info)
        n = info.planned_joints_deg.shape[1]
        self._joints = self.root / "joints.csv"
        self._dets = self.root / "detections.csv"
        done = [int(r[0]) for r in _read_csv_rows(self._joints) if r]
        self.done: list[int] = done
        self._rewrite(self._joints, ["index"] + [f"q{j + 1}_deg" for j in range(n)], done, 0)
        if info.observation == "detections":
            header = ["index", "camera", "marker_id", "corner", "u_px", "v_px"]
            self._rewrite(self._dets, header, done, 0)

    def _rewrite(self, path: Path, header: list[str], keep: list[int], col: int) -> None:
        """Keep only the complete frames' rows (drops a partially written frame)."""
        rows = [r for r in _read_csv_rows(path) if r and int(r[col]) in set(keep)]
        tmp = path.with_name("." + path.name + ".tmp")
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            w.writerows(rows)
        os.replace(tmp, path)

    @property
    def n_done(self) -> int:
        """Number of complete frames."""
        return len(self.done)

    def add_frame(
        self,
        index: int,
        joints_deg: np.ndarray,
        *,
        left: np.ndarray | None = None,
        right: np.ndarray | None = None,
        detections: dict[str, dict[int, np.ndarray]] | None = None,
    ) -> None:
        """Store frame ``index``: images (images path) or detections (analytic path), then joints."""
        if self.info.observation == "images":
            if left is None or right is None:
                raise DatasetError("an images dataset needs both left and right images per frame")
            for cam, img in (("left", left), ("right", right)):
                _write_bytes_atomic(
                    self.root / "frames" / f"{index:04d}_{cam}.png", _encode_png(img)
                )
        else:
            if detections is None:
                raise DatasetError("a detections dataset needs the detections of each frame")
            with open(self._dets, "a", newline="") as fh:
                w = csv.writer(fh)
                for cam in CAMERAS:
                    for mid, c in sorted(detections.get(cam, {}).items()):
                        for k in range(4):
                            w.writerow([index, cam, mid, k, f"{c[k, 0]:.6f}", f"{c[k, 1]:.6f}"])
                fh.flush()
                os.fsync(fh.fileno())
        with open(self._joints, "a", newline="") as fh:
            csv.writer(fh).writerow([index] + [f"{v:.6f}" for v in np.asarray(joints_deg)])
            fh.flush()
            os.fsync(fh.fileno())
        self.done.append(index)


def _missing(path: Path, index: int) -> DatasetError:
    return DatasetError(
        f"frame {path.name} is missing or unreadable although joints.csv lists frame {index}; the "
        f"dataset is damaged: re-acquire it (or remove frame {index}'s row from joints.csv to "
        "calibrate without it)"
    )


def read_gray(path: Path, index: int) -> np.ndarray:
    """A dataset image as gray uint8; raises DatasetError naming the frame if unreadable."""
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise _missing(path, index)
    return img


@dataclass(frozen=True)
class Dataset:
    """A dataset opened for reading (frames are loaded lazily)."""

    root: Path
    info: DatasetInfo
    indices: np.ndarray
    joints_deg: np.ndarray

    @classmethod
    def open(cls, root: str | Path) -> Dataset:
        """Open ``root``; raises DatasetError if it is not a complete dataset."""
        root = Path(root)
        meta = root / "dataset.json"
        if not meta.is_file():
            raise DatasetError(
                f"{root}: no dataset.json; is this a dataset folder? (create one with "
                "`selfcal acquire CONFIG --out DIR`)"
            )
        info = read_dataset_info(meta)
        rows = _read_csv_rows(root / "joints.csv")
        if not rows:
            raise DatasetError(f"{root}: joints.csv holds no frames; acquire first")
        try:
            idx = np.array([int(r[0]) for r in rows])
            q = np.array([[float(v) for v in r[1:]] for r in rows])
        except (ValueError, IndexError) as exc:
            raise DatasetError(f"{root / 'joints.csv'}: malformed row ({exc})") from exc
        if len(set(idx.tolist())) != len(idx):
            raise DatasetError(f"{root / 'joints.csv'}: duplicate frame indices")
        if q.ndim != 2 or q.shape[1] != info.planned_joints_deg.shape[1]:
            raise DatasetError(f"{root / 'joints.csv'}: rows do not match the robot's joint count")
        return cls(root=root, info=info, indices=idx, joints_deg=q)

    def frame_paths(self, index: int) -> tuple[Path, Path]:
        """Paths of a frame's left and right images."""
        return tuple(self.root / "frames" / f"{index:04d}_{c}.png" for c in CAMERAS)  # type: ignore[return-value]

    def image_paths(self) -> list[tuple[int, str, Path]]:
        """``(index, camera, path)`` of every image; raises DatasetError for a missing frame
        before anything is read."""
        out = []
        for i in self.indices:
            for cam, path in zip(CAMERAS, self.frame_paths(int(i))):
                if not path.is_file():
                    raise _missing(path, int(i))
                out.append((int(i), cam, path))
        return out

    def iter_images(self) -> Iterator[tuple[int, str, np.ndarray]]:
        """Yield ``(index, camera, gray uint8 image)``; raises DatasetError for a missing frame."""
        for i, cam, path in self.image_paths():
            yield i, cam, read_gray(path, i)

    def read_detections(self) -> Detections:
        """Detections of the analytic path from ``detections.csv``."""
        path = self.root / "detections.csv"
        if not path.is_file():
            raise DatasetError(f"{path} is missing; this dataset's observation is 'detections'")
        out: Detections = {}
        keep = set(self.indices.tolist())
        buf: dict[tuple[int, str, int], np.ndarray] = {}
        for r in _read_csv_rows(path):
            try:
                i, cam, mid, k, u, v = (
                    int(r[0]),
                    r[1],
                    int(r[2]),
                    int(r[3]),
                    float(r[4]),
                    float(r[5]),
                )
            except (ValueError, IndexError) as exc:
                raise DatasetError(f"{path}: malformed row {r} ({exc})") from exc
            if i not in keep:
                continue
            buf.setdefault((i, cam, mid), np.full((4, 2), np.nan))[k] = (u, v)
        for (i, cam, mid), c in buf.items():
            if np.isnan(c).any():
                raise DatasetError(f"{path}: marker {mid} in frame {i} ({cam}) lacks corners")
            out.setdefault((i, cam), {})[mid] = c
        return out
