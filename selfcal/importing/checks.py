"""What ``selfcal import`` checks of the detections and says of them: the declared board's
geometry against the detections (:func:`check_geometry`: a board whose squares or size were
declared wrong does not fit them, even with OpenCV's lens model), the images whose target was
not found (named and counted, :class:`TargetNotFoundWarning`), and the one-line summary with
OpenCV's own count beside the project's (:func:`detection_summary`)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from selfcal.calibration.board.calibrate import BoardMismatchError, calibrate_board
from selfcal.choices import DEFAULT_FREE
from selfcal.errors import InputError, SelfCalWarning
from selfcal.importing.field import MIN_FIELD_FEATURES, FieldTarget
from selfcal.io.dataset_info import DatasetInfo
from selfcal.target.base import Features
from selfcal.target.board_detect import Detection
from selfcal.target.boards import Board

MISMATCH_PX = 3.0
"""Reprojection RMS (px, 2-D) above which the declared board does not fit the detections."""


class ImportError_(InputError):  # noqa: N801 (ImportError is Python's)
    """Inputs of ``selfcal import`` that do not fit together (names the file and the fix)."""


class TargetNotFoundWarning(SelfCalWarning):
    """Images in which the target is not found (named and counted; their frames are skipped)."""


def check_geometry(
    board: Board,
    features: Sequence[Features],
    size: tuple[int, int],
    model: str = "pinhole",
    free: Sequence[str] = DEFAULT_FREE["pinhole"],
) -> None:
    """The declared geometry against the detections of one camera (``size`` (W, H) px).

    The board calibration of the camera ``model`` with parameters ``free``
    (:func:`selfcal.calibration.board.calibrate.calibrate_board`) judges it; when it finds a mismatch, OpenCV's
    lens model (k1, k2, p1, p2, k3 free) gets a second say, so that a strongly distorting lens is
    not mistaken for a wrong board.

    Raises:
        selfcal.calibration.board.calibrate.BoardMismatchError: naming the target file and its keys.
    """
    ok = [f for f in features if len(f) >= board.min_features]
    if len(ok) < 3:
        return
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            calibrate_board(board, ok, *size, free=free, model=model)
    except BoardMismatchError:
        if not _fits_with_lens(board, ok, size):
            raise


def _fits_with_lens(board: Board, features: Sequence[Features], size: tuple[int, int]) -> bool:
    """Whether OpenCV's calibration with its lens model fits ``features`` within MISMATCH_PX."""
    if any(not np.isin(f.ids, board.layout()[0]).all() for f in features):
        return False  # ids the declared board does not have
    obj = [board.points(f.ids).astype(np.float32) for f in features]
    img = [f.uv.astype(np.float32).reshape(-1, 1, 2) for f in features]
    rms = float(cv2.calibrateCamera(obj, img, size, None, None)[0])  # RMS of the 2-D point errors
    return rms < MISMATCH_PX


def _min_features(target: Board | FieldTarget) -> int:
    return target.min_features if isinstance(target, Board) else MIN_FIELD_FEATURES


def warn_not_found(
    board: Board | FieldTarget,
    images: Sequence[Any],
    files: dict[str, list[Path]],
    found: dict[str, list[Detection]],
    labels: Mapping[Path, str],
) -> None:
    """Name and count the images without the target, and apart from them each image in which
    OpenCV found the board but the project's checks refused it, with the reason. ``images``:
    the cameras (:class:`selfcal.importing.dataset.CameraImages`: their ``name``)."""
    need = _min_features(board)
    pairs = [(labels.get(f, str(f)), d) for c in images
             for f, d in zip(files[c.name], found[c.name], strict=True)]  # fmt: skip
    total = len(pairs)
    missed = [name for name, d in pairs if len(d.features) < need and d.opencv < need]
    refused = [f"{name} ({d.refused})" for name, d in pairs if len(d.features) < need <= d.opencv]
    if missed:
        more = " ..." if len(missed) > 8 else ""
        warnings.warn(
            f"the {board.describe()} is not found in {len(missed)} of {total} image(s), skipped: "
            f"{', '.join(missed[:8])}{more}",
            TargetNotFoundWarning,
            stacklevel=3,
        )
    if refused:
        warnings.warn(
            f"OpenCV finds the {board.describe()} in {len(refused)} image(s) that the detector's "
            f"checks refuse, skipped: {'; '.join(refused)}",
            TargetNotFoundWarning,
            stacklevel=3,
        )


def _counts(board: Board | FieldTarget, found: dict[str, list[Detection]]) -> dict[str, int]:
    """Images searched, images with the target found, and images in which OpenCV's detector
    alone found it (before the project's checks), over every camera."""
    need = _min_features(board)
    ds = [d for v in found.values() for d in v]
    return {"images": len(ds), "found": sum(len(d.features) >= need for d in ds),
            "opencv": sum(d.opencv >= need for d in ds)}  # fmt: skip


def detection_summary(info: DatasetInfo) -> str:
    """One line of what ``import`` found, e.g. ``board found in 24 of 24 images (OpenCV alone:
    24)``; ``""`` for a dataset that does not record it."""
    c = info.provenance.get("detection")
    if not isinstance(c, dict):
        return ""
    if info.board is None:  # an ArUco field: its count is the project's detector's, not OpenCV's
        return f"target found in {c['found']} of {c['images']} images"
    return f"board found in {c['found']} of {c['images']} images (OpenCV alone: {c['opencv']})"
