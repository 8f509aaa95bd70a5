"""Atomic file writes: every file the pipeline writes goes through here.

The content goes to a temporary file next to the target (same folder, so the same file system),
is flushed to disk, and replaces the target by one ``os.replace``: a reader, or a run killed at any
moment, sees the old file or the new one, never a half-written one. The temporary name ends in
``.tmp`` (never in the target's extension, so globs such as ``*.png`` never pick one up) and is
removed when writing fails.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from selfcal.errors import OutputError

__all__ = [
    "write_bytes_atomic",
    "write_text_atomic",
    "write_with_atomic",
    "write_image_atomic",
]


def _tmp_path(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (module docstring); returns the path."""
    path = Path(path)
    tmp = _tmp_path(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (module docstring); returns the path."""
    return write_bytes_atomic(path, text.encode(encoding))


def write_with_atomic(path: str | Path, write: Callable[[Path], object]) -> Path:
    """Let ``write(tmp)`` write a file (a plot's ``savefig``, an image encoder) to a temporary
    path, then move it onto ``path`` atomically; the temporary file is removed on failure. The
    temporary path does not end in ``path``'s extension: pass the format explicitly."""
    path = Path(path)
    tmp = _tmp_path(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_image_atomic(path: str | Path, rgb: np.ndarray) -> Path:
    """Write an RGB (or grey) uint8 image to ``path`` atomically, in the format of its extension
    (``.png``, ``.jpg``: OpenCV's encoders).

    Raises:
        OSError: OpenCV cannot encode the image in that format.
    """
    path = Path(path)
    img = np.asarray(rgb)
    bgr = cv2.cvtColor(img, cv2.COLOR_RGB2BGR) if img.ndim == 3 else img
    try:
        ok, buf = cv2.imencode(path.suffix or ".png", np.ascontiguousarray(bgr))
    except cv2.error:
        ok = False
    if not ok:
        raise OutputError(f"cannot encode an image of shape {img.shape} as {path.suffix!r}: {path}")
    return write_bytes_atomic(path, buf.tobytes())
