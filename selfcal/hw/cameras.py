"""Stereo capture through ``cv2.VideoCapture``: two sources (left, right) -> ``StereoPair`` (RGB).

A source string is one of:

- a device index (``"0"``): a local camera (V4L2 on Linux);
- a stream URL (``"http://..."``, ``"rtsp://..."``) or a video file: opened with FFmpeg;
- an image-sequence pattern with a printf field (``"frames/%04d_left.png"``): opened with
  ``cv2.CAP_IMAGES``. In ``"latest"`` mode (default) every capture re-opens the sequence and reads
  its newest frame -- the form the ACL emulator serves, where a frame is written whenever the arm
  comes to rest (OpenCV fixes a sequence's length when it is opened, so a long-lived capture would
  never see later files). In ``"next"`` mode one capture stays open and each call returns the next
  frame (replaying a recording).

For live devices a few buffered frames are grabbed and dropped first (``flush_frames``) so the image
is taken after the arm stopped, not before. Frames are checked against the expected
``(width, height)`` and converted BGR -> RGB uint8.
"""

from __future__ import annotations

import re
import time
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

from selfcal.errors import InputError
from selfcal.robot.interface import RobotError, StereoPair

__all__ = ["CameraError", "Camera", "StereoCamera", "source_kind"]

_PATTERN_RE = re.compile(r"%0?\d*d")


class CameraError(RobotError):
    """A camera cannot be opened, gives no frame or gives frames of the wrong size."""


def source_kind(source: str | int) -> str:
    """``"device"``, ``"sequence"`` or ``"stream"`` (URL or video file) for a source string."""
    s = str(source).strip()
    if re.fullmatch(r"\d+", s):
        return "device"
    if _PATTERN_RE.search(s) and "://" not in s:
        return "sequence"
    return "stream"


def _to_rgb(frame: np.ndarray, name: str, source: str) -> np.ndarray:
    if frame.dtype != np.uint8:
        raise CameraError(
            f"{name} camera {source!r} gives {frame.dtype} images; 8-bit images are expected"
        )
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2RGB)
    if frame.ndim == 3 and frame.shape[2] == 3:
        return cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
    if frame.ndim == 3 and frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2RGB)
    if frame.ndim == 3 and frame.shape[2] == 1:
        return cv2.cvtColor(frame[:, :, 0], cv2.COLOR_GRAY2RGB)
    raise CameraError(f"{name} camera {source!r} gives images of shape {frame.shape}")


class Camera:
    """One camera over ``cv2.VideoCapture``.

    Args:
        source: device index, stream URL / video file, or image-sequence pattern (see module doc).
        name: ``"left"`` / ``"right"``, used in messages.
        expected_size: (width, height) in pixels to enforce, or ``None``.
        sequence_mode: ``"latest"`` or ``"next"`` for image sequences.
        flush_frames: frames grabbed and dropped before each read (default 2 for devices, 0
            otherwise).
        timeout_s: how long to wait for an image sequence's first file to appear.

    Raises:
        CameraError: a device or stream cannot be opened (at construction).
    """

    def __init__(
        self,
        source: str | int,
        *,
        name: str = "camera",
        expected_size: tuple[int, int] | None = None,
        sequence_mode: str = "latest",
        flush_frames: int | None = None,
        timeout_s: float = 2.0,
    ):
        self.source = str(source).strip()
        self.name = name
        self.kind = source_kind(self.source)
        if expected_size is not None:
            w, h = (int(v) for v in expected_size)
            if w <= 0 or h <= 0:
                raise InputError(
                    f"{name} camera: expected_size must be positive, got {expected_size}"
                )
            expected_size = (w, h)
        self.expected_size = expected_size
        if sequence_mode not in ("latest", "next"):
            raise InputError(f"sequence_mode must be 'latest' or 'next', got {sequence_mode!r}")
        self.sequence_mode = sequence_mode
        self.flush_frames = (
            (2 if self.kind == "device" else 0) if flush_frames is None else int(flush_frames)
        )
        self.timeout_s = float(timeout_s)
        self._cap: cv2.VideoCapture | None = None
        self.frames_read = 0
        if self.kind in ("device", "stream"):
            self._cap = self._open_live()

    # -- opening -------------------------------------------------------------------------------

    def _open_live(self) -> cv2.VideoCapture:
        if self.kind == "device":
            cap = cv2.VideoCapture(int(self.source))
        else:
            cap = cv2.VideoCapture(self.source)
        if not cap.isOpened():
            cap.release()
            hint = (
                "is the camera plugged in and not used by another program? (ls /dev/video*)"
                if self.kind == "device"
                else "is the URL or file right and the server running?"
            )
            raise CameraError(f"cannot open {self.name} camera {self.source!r}: {hint}")
        if self.expected_size is not None and self.kind == "device":
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, self.expected_size[0])
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self.expected_size[1])
        return cap

    def _open_sequence(self) -> cv2.VideoCapture:
        deadline = time.monotonic() + self.timeout_s
        while True:
            cap = cv2.VideoCapture(self.source, cv2.CAP_IMAGES)
            if cap.isOpened():
                return cap
            cap.release()
            if time.monotonic() > deadline:
                first = ", ".join(repr(self._file(i)) for i in (0, 1))
                raise CameraError(
                    f"{self.name} camera: no frame: image sequence {self.source!r} has no first "
                    f"file ({first}) after {self.timeout_s:g} s"
                )
            time.sleep(0.01)

    def _file(self, i: int) -> str:
        try:
            return self.source % i
        except TypeError:
            return self.source

    # -- reading -------------------------------------------------------------------------------

    def frame_count(self) -> int:
        """Number of frames currently in an image sequence (``"latest"`` mode)."""
        if self.kind != "sequence":
            raise CameraError(f"{self.name} camera {self.source!r} is not an image sequence")
        cap = self._open_sequence()
        try:
            return int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        finally:
            cap.release()

    def read(self, index: int | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """One RGB uint8 frame (H, W, 3) and its metadata.

        ``index`` (0-based position within an image sequence, ``"latest"`` mode only) picks a
        frame; default the newest.

        Raises:
            CameraError: no frame, or a frame of the wrong size or type.
        """
        meta: dict[str, Any] = {"source": self.source}
        if self.kind == "sequence" and self.sequence_mode == "latest":
            cap = self._open_sequence()
            try:
                n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
                i = n - 1 if index is None else int(index)
                if not 0 <= i < n:
                    raise CameraError(
                        f"{self.name} camera: frame {i} requested but {self.source!r} holds {n}"
                    )
                if i > 0:
                    cap.set(cv2.CAP_PROP_POS_FRAMES, i)
                ok, frame = cap.read()
            finally:
                cap.release()
            meta["frame_index"] = i
        else:
            if self._cap is None:
                self._cap = self._open_sequence() if self.kind == "sequence" else self._open_live()
            for _ in range(self.flush_frames):
                self._cap.grab()
            ok, frame = self._cap.read()
            if self.kind == "sequence":
                meta["frame_index"] = int(self._cap.get(cv2.CAP_PROP_POS_FRAMES)) - 1
        if not ok or frame is None or frame.size == 0:
            what = (
                f"image sequence {self.source!r} is exhausted"
                if self.kind == "sequence"
                else "the capture returned no frame (disconnected, wrong mode, or stream ended)"
            )
            raise CameraError(f"{self.name} camera gave no frame: {what}")
        rgb = _to_rgb(frame, self.name, self.source)
        h, w = rgb.shape[:2]
        if self.expected_size is not None and (w, h) != self.expected_size:
            raise CameraError(
                f"{self.name} camera {self.source!r} gives {w}x{h} frames but {self.expected_size[0]}x"
                f"{self.expected_size[1]} are expected (check the camera mode or camera_size)"
            )
        self.frames_read += 1
        meta["timestamp"] = time.time()
        return np.ascontiguousarray(rgb), meta

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


class StereoCamera:
    """Left and right ``Camera`` captured together into a ``StereoPair``.

    With two image sequences in ``"latest"`` mode both are read at the same frame index (the
    newest index present in both), so a pair never mixes two postures.
    """

    def __init__(self, left: Camera, right: Camera):
        self.left = left
        self.right = right

    @classmethod
    def from_sources(
        cls,
        sources: Sequence[str | int],
        *,
        expected_size: tuple[int, int] | None = None,
        sequence_mode: str = "latest",
        flush_frames: int | None = None,
        timeout_s: float = 2.0,
    ) -> StereoCamera:
        """Open ``[left, right]`` sources (strings as in ``[robot.hardware] cameras``)."""
        if isinstance(sources, (str, bytes)) or len(sources) != 2:
            raise InputError(
                f"cameras must be a list [left, right] of two sources, got {sources!r}"
            )

        def open_one(source: str | int, name: str) -> Camera:
            return Camera(source, name=name, expected_size=expected_size,
                          sequence_mode=sequence_mode, flush_frames=flush_frames,
                          timeout_s=timeout_s)  # fmt: skip

        left = open_one(sources[0], "left")
        try:
            right = open_one(sources[1], "right")
        except BaseException:
            left.close()
            raise
        return cls(left, right)

    def capture(self) -> StereoPair:
        """Capture both cameras; raises ``CameraError`` (no frame, wrong size, size mismatch)."""
        seq = (
            self.left.kind == "sequence"
            and self.right.kind == "sequence"
            and self.left.sequence_mode == "latest"
            and self.right.sequence_mode == "latest"
        )
        if seq:
            n = min(self.left.frame_count(), self.right.frame_count())
            left, lm = self.left.read(n - 1)
            right, rm = self.right.read(n - 1)
        else:
            left, lm = self.left.read()
            right, rm = self.right.read()
        if left.shape != right.shape:
            raise CameraError(
                f"left ({left.shape[1]}x{left.shape[0]}) and right ({right.shape[1]}x"
                f"{right.shape[0]}) cameras give frames of different sizes"
            )
        meta = {f"left_{k}": v for k, v in lm.items()} | {f"right_{k}": v for k, v in rm.items()}
        return StereoPair(left=left, right=right, meta=meta)

    def close(self) -> None:
        self.left.close()
        self.right.close()

    def __enter__(self) -> StereoCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
