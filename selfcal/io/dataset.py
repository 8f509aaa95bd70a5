"""The dataset folder: what a robot (simulated or real) hands to the calibration.

Layout of ``DIR``::

    dataset.json        what the dataset says about itself (robot model, cameras, target, planned
                        postures, observation kind, provenance): :mod:`selfcal.io.dataset_info`
    joints.csv          one row per frame taken: index, joint read-back (deg)
    frames/NNNN_CAMERA.png   one image per camera and frame (images path; CAMERA is the camera's
                        name, the suffix dataset.json's ``image_suffix``)
    detections.csv      index, camera, marker_id, corner, u_px, v_px (analytic path, no images);
                        a board's (dataset.json's target a board): index, camera, feature_id,
                        u_px, v_px, one row per board feature
    truth.json          simulation only; never read by the calibration

A frame counts as taken once its row is in ``joints.csv``: images are written first (atomically,
via a temporary file and rename), detections are appended and flushed, and the joints row comes
last. An interrupted acquisition therefore keeps every complete frame, and a resumed one drops any
partial rows of the frame that was being written.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Container, Iterator
from concurrent.futures import Executor, wait
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.errors import InputError
from selfcal.io.dataset_info import (
    DATASET_FIX,
    DatasetError,
    DatasetInfo,
    read_dataset_info,
    write_dataset_info,
)
from selfcal.io.detections_csv import (
    FEATURE_HEADER,
    MARKER_HEADER,
    Detections,
    board_features,
    detection_rows,
    marker_corners,
)
from selfcal.io.images import read_gray_image
from selfcal.io.jsonfile import dumps
from selfcal.io.png import encode_png

__all__ = [
    "DatasetError",  # defined with dataset.json's reader; what Dataset.open raises
    "DatasetWriter",
    "Dataset",
    "Detections",  # defined with detections.csv's reader
    "joints_row",
    "read_gray",
    "read_joints_csv",
]


def _resume_key(info: DatasetInfo) -> str:
    """What must match to resume a dataset: all of ``dataset.json`` (the scenario by its digest,
    which leaves out how the hardware is reached)."""
    doc = info.to_json()
    doc.pop("encoder_model", None)  # = robot_model when recorded; older datasets lack it
    return dumps(doc)


def _write_bytes_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name("." + path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def _write_png(path: Path, rgb: np.ndarray) -> None:
    """Write frame image ``rgb`` to ``path``; ``DatasetError`` naming the file when the image
    is not one a dataset holds (uint8 grey or RGB)."""
    try:
        data = _encode_png(rgb)
    except InputError as e:
        raise DatasetError(f"{path}: {e.message}", fix="give the camera's frame as uint8 grey or "
                           "RGB (scale a 16-bit frame to 8 bits first)") from e  # fmt: skip
    _write_bytes_atomic(path, data)


def _encode_png(rgb: np.ndarray) -> bytes:
    """A frame's PNG file (:func:`selfcal.io.png.encode_png`; RGB or grey uint8)."""
    return encode_png(rgb)


def joints_row(index: int, joints_deg: np.ndarray) -> str:
    """Frame ``index``'s row of ``joints.csv`` as :class:`DatasetWriter` writes it: the index,
    then each joint reading (deg) to 6 decimals, CRLF-terminated (the csv module's default)."""
    text = io.StringIO()
    csv.writer(text).writerow([index] + [f"{v:.6f}" for v in np.asarray(joints_deg)])
    return text.getvalue()


def _robot_source(root: Path, ref: str) -> str | Path:
    if Path(ref).suffix in (".toml", ".urdf"):
        return Path(ref) if Path(ref).is_absolute() else root / ref
    return ref


def _check_robot_model(root: Path, ref: str, where: Path) -> None:
    """``robot_model`` names a known robot or an existing robot file; else the error names
    ``where`` and the key (before: an encoder-table mismatch was blamed)."""
    from selfcal.robot.definition import (
        list_robots,  # robot files are read by the commands, not here
    )

    src = _robot_source(root, ref)
    if isinstance(src, Path) and not src.is_file():
        raise DatasetError(
            f"{where}: key 'robot_model' names the robot file {src}, which does not exist",
            fix="give robot_model the robot that took the data: a robot of models/<folder>/ or a "
            "robot TOML / URDF path (relative to the dataset folder)",
        )
    if isinstance(src, str) and src not in list_robots():
        raise DatasetError(
            f"{where}: key 'robot_model' is {ref!r}, which names no robot (known: "
            f"{', '.join(list_robots())})",
            fix="give robot_model the robot that took the data: one of the known names, or a "
            "robot TOML / URDF path (relative to the dataset folder)",
        )


def read_text(path: Path) -> str:
    """The UTF-8 text of a dataset file; a :class:`DatasetError` naming it when it is not UTF-8
    (before: a UnicodeDecodeError, exit 1) or cannot be read."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DatasetError(
            f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason})",
            fix="restore the file (the dataset writes UTF-8 text), or re-acquire",
        ) from None
    except OSError as exc:
        raise DatasetError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def _csv_lines(path: Path) -> list[str]:
    """Lines of a CSV file, the header included, ignoring a trailing partial line."""
    if not path.is_file():
        return []
    text = read_text(path)
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    return text.splitlines()


def _read_csv_rows(path: Path) -> list[list[str]]:
    """Rows of a CSV file, header excluded, ignoring a trailing partial line."""
    return list(csv.reader(_csv_lines(path)))[1:]


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
            header = FEATURE_HEADER if info.board is not None else MARKER_HEADER
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
        images: dict[str, np.ndarray] | None = None,
        executor: Executor | None = None,
    ) -> None:
        """Store frame ``index``: images (images path: ``images`` by camera name, or ``left`` and
        ``right``) or detections (analytic path), then joints. ``executor``: the images after
        the first are encoded and written on it while this thread writes the first, side by
        side (PNG encoding and the disk's fsync release the GIL); the joints row is written once
        every image is on disk, as without it."""
        if self.info.observation == "images":
            images = dict(images or {})
            images.update({c: v for c, v in (("left", left), ("right", right)) if v is not None})
            missing = [c for c in self.info.cameras if images.get(c) is None]
            if missing:
                raise DatasetError(f"frame {index}: no image of camera(s) {missing}")
            jobs = [(self.root / "frames" / f"{index:04d}_{cam}.png", images[cam])
                    for cam in self.info.cameras]  # fmt: skip
            others = [] if executor is None else [executor.submit(_write_png, *j) for j in jobs[1:]]
            try:
                for job in jobs[: len(jobs) - len(others)]:
                    _write_png(*job)
            finally:  # every image written (or failed) before this frame goes on
                wait(others)
            for fut in others:
                fut.result()  # a failed image raises here: the frame gets no joints row
        else:
            if detections is None:
                raise DatasetError("a detections dataset needs the detections of each frame")
            rows = detection_rows(index, self.info.cameras, detections,
                                  board=self.info.board is not None)  # fmt: skip
            with open(self._dets, "a", newline="") as fh:
                csv.writer(fh).writerows(rows)
                fh.flush()
                os.fsync(fh.fileno())
        with open(self._joints, "a", newline="") as fh:
            fh.write(joints_row(index, joints_deg))
            fh.flush()
            os.fsync(fh.fileno())
        self.done.append(index)


def _missing(path: Path, index: int) -> DatasetError:
    """A frame's image that joints.csv lists but cannot be read: names the file's full path
    (the dataset's ``frames/`` folder, where every command reads it; a moved or renamed image
    is not looked for elsewhere) and both ways on."""
    joints = path.parent.parent / "joints.csv"
    return DatasetError(
        f"{path}: frame {path.name} is missing or unreadable although {joints} lists frame "
        f"{index}; the dataset is damaged",
        fix=f"put the image back under that name (an imported dataset's sources.csv names the "
        "file each frame was copied from), or write the dataset again (selfcal import, selfcal "
        f"acquire); or remove frame {index}'s row from joints.csv and calibrate with "
        "--allow-missing-frames",
    )


def _frame_list(indices: tuple[int, ...] | list[int]) -> str:
    """``frame 3`` / ``frames 3, 4, 7`` (at most 20 listed)."""
    more = f" ... ({len(indices)} in all)" if len(indices) > 20 else ""
    word = "frame" if len(indices) == 1 else "frames"
    return f"{word} {', '.join(str(i) for i in indices[:20])}{more}"


def read_joints_csv(
    path: Path, n_joints: int, text: str | None = None
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The frames of a dataset's ``joints.csv``: indices (m,), joint read-back (m, n) deg, and
    the cut-off rows left out (a last line without its newline -- an interrupted write -- or a
    row of fewer than ``n_joints`` values), one description each naming line and frame.
    ``text``: the file's text as its writer will leave it, read instead of the file (the
    messages still name ``path``).

    Raises:
        DatasetError: a value that is not a number, NaN or inf, too many values, a frame index
            twice (each naming the file, line and frame).
    """
    if text is None:
        text = read_text(path) if path.is_file() else ""
    lines = text.splitlines()
    cut: list[str] = []
    idx: list[int] = []
    q: list[list[float]] = []
    for no, line in enumerate(lines[1:], start=2):
        cells = next(csv.reader([line]), [])
        if not cells:
            continue
        where = f"{path}: line {no} (frame {cells[0]!r})"
        last = no == len(lines) and not text.endswith("\n")
        if last or len(cells) < n_joints + 1:
            why = "no newline: an interrupted write" if last else f"{len(cells) - 1} values"
            cut.append(f"line {no} (frame {cells[0]}: {why}; the robot has {n_joints} joints)")
            continue
        if len(cells) > n_joints + 1:
            raise DatasetError(f"{where}: {len(cells) - 1} values, the robot has {n_joints} "
                               "joints", fix="give index and one value (deg) per joint")  # fmt: skip
        try:
            i, vals = int(cells[0]), [float(v) for v in cells[1:]]
        except ValueError as exc:
            raise DatasetError(f"{where}: not a number ({exc})", fix=DATASET_FIX) from None
        bad = [f"q{j + 1}_deg = {v}" for j, v in enumerate(vals) if not np.isfinite(v)]
        if bad:
            raise DatasetError(f"{where}: {', '.join(bad)}: joint readings must be finite",
                               fix="re-read the joints of that frame or remove the frame's "
                               "row and calibrate with --allow-missing-frames")  # fmt: skip
        if i in idx:
            raise DatasetError(f"{where}: frame {i} appears twice", fix=DATASET_FIX)
        idx.append(i)
        q.append(vals)
    return np.array(idx, dtype=int), np.array(q, dtype=float).reshape(-1, n_joints), tuple(cut)


def read_gray(path: Path, index: int) -> np.ndarray:
    """A dataset image as gray uint8; raises DatasetError naming the frame if unreadable."""
    img = read_gray_image(path)
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
    missing: tuple[int, ...] = ()
    """Planned frames without a whole ``joints.csv`` row (:meth:`check_complete`)."""
    truncated: tuple[str, ...] = ()
    """The cut-off rows of ``joints.csv``, one description each (line, frame, what is wrong)."""

    @classmethod
    def open(cls, root: str | Path, *, joints_csv: str | None = None) -> Dataset:
        """Open ``root``; raises DatasetError if it is not a complete dataset. ``joints_csv``:
        the text of ``joints.csv`` as its writer will leave it, taken instead of the file
        (``selfcal run`` calibrates while its last frames are still being written:
        :class:`selfcal.acquisition.held_frames.HeldFrames`)."""
        root = Path(root)
        meta = root / "dataset.json"
        if not meta.is_file():
            raise DatasetError(
                f"{root}: no dataset.json: not a dataset folder",
                fix="make one from your images and joint readings with `selfcal import ... --out "
                "DIR` (docs/own-data.md), or in simulation with `selfcal acquire CONFIG --out DIR`",
            )
        info = read_dataset_info(meta)
        _check_robot_model(root, info.robot_model, meta)
        info.check_encoder_model(meta)
        n = info.planned_joints_deg.shape[1]
        idx, q, cut = read_joints_csv(root / "joints.csv", n, joints_csv)
        if not len(idx) and not cut:
            raise DatasetError(f"{root}: joints.csv holds no frames; acquire first")
        missing = sorted(set(range(len(info.planned_joints_deg))) - set(idx.tolist()))
        return cls(root=root, info=info, indices=idx, joints_deg=q, missing=tuple(missing),
                   truncated=cut)  # fmt: skip

    def check_complete(self, *, allow_missing: bool = False) -> tuple[str, ...]:
        """Every planned frame has its ``joints.csv`` row, whole: nothing, or (``allow_missing``)
        the warning sentence naming the frames without one, which the calibration leaves out.

        Raises:
            DatasetError: frames without a row or with a cut-off row, listed by index (and line),
                unless ``allow_missing``.
        """
        if not self.missing and not self.truncated:
            return ()
        path = self.root / "joints.csv"
        text = f"{path}: {_frame_list(self.missing)} of the {len(self.info.planned_joints_deg)} "
        text += "planned have no row (never acquired, or rows lost)"
        if self.truncated:
            text += "; cut-off rows: " + "; ".join(self.truncated)
        if not allow_missing:
            raise DatasetError(
                text,
                fix="complete the acquisition with `selfcal acquire CONFIG --out DIR --resume` "
                "or restore the rows; to calibrate without these frames give "
                "--allow-missing-frames",
            )
        return (text + ": calibrated without them (--allow-missing-frames)",)

    @property
    def robot_source(self) -> str | Path:
        """What :func:`selfcal.robot.definition.load_robot` takes for ``info.robot_model``: a model name,
        or a robot file (a relative path is relative to the dataset folder)."""
        return _robot_source(self.root, self.info.robot_model)

    def frame_paths(self, index: int) -> tuple[Path, ...]:
        """Paths of a frame's images, one per camera in ``info.cameras`` order."""
        suffix = self.info.image_suffix
        return tuple(self.root / "frames" / f"{index:04d}_{c}{suffix}" for c in self.info.cameras)

    def image_paths(
        self, in_memory: Container[tuple[int, str]] = ()
    ) -> list[tuple[int, str, Path]]:
        """``(index, camera, path)`` of every image; raises DatasetError for a missing frame
        before anything is read. ``in_memory``: the ``(index, camera)`` images the reader has
        in memory (:class:`selfcal.io.frame_cache.FrameCache`), whose files are not looked
        for (they may still be being written)."""
        out = []
        for i in self.indices:
            for cam, path in zip(self.info.cameras, self.frame_paths(int(i))):
                if (int(i), cam) not in in_memory and not path.is_file():
                    raise _missing(path, int(i))
                out.append((int(i), cam, path))
        return out

    def iter_images(self) -> Iterator[tuple[int, str, np.ndarray]]:
        """Yield ``(index, camera, gray uint8 image)``; raises DatasetError for a missing frame."""
        for i, cam, path in self.image_paths():
            yield i, cam, read_gray(path, i)

    def read_features(self) -> Detections:
        """A board's features of the analytic path from ``detections.csv``: (frame index,
        camera) -> {feature id: (1, 2) px}, frames of ``joints.csv`` only
        (:func:`selfcal.io.detections_csv.board_features`).

        Raises:
            DatasetError: the file is missing or a row is wrong (the message names the file,
                the line and the column).
        """
        path = self._detections_path()
        return board_features(path, _csv_lines(path)[1:], self.indices, self.info.cameras)

    def _detections_path(self) -> Path:
        path = self.root / "detections.csv"
        if not path.is_file():
            raise DatasetError(f"{path} is missing; this dataset's observation is 'detections'")
        return path

    def read_detections(self) -> Detections:
        """The marker field's corners of the analytic path from ``detections.csv``: (frame
        index, camera) -> {marker id: (4, 2) px}, frames of ``joints.csv`` only
        (:func:`selfcal.io.detections_csv.marker_corners`).

        Raises:
            DatasetError: the file is missing, holds a board's features, or a row or a marker is
                wrong (the message names the file, the line and the column or the marker).
        """
        path = self._detections_path()
        if self.info.board is not None:
            raise DatasetError(
                f"{path} holds a board's features, not the marker field's corners",
                fix="read it with Dataset.read_features (the board route)",
            )
        return marker_corners(path, _csv_lines(path)[1:], self.indices, self.info.cameras)
