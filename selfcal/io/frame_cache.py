"""A dataset's images already in memory: ``selfcal run`` calibrates and reports from the images
its acquisition just took instead of reading the PNGs back, and detects each image's markers once
for the calibration and the report (issue 17).

The gray image kept for a frame is bit-identical to what :func:`selfcal.io.dataset.read_gray` reads
from the PNG the dataset writer stores: OpenCV decodes a colour PNG to gray by libpng's
fixed-point weights (``png_set_rgb_to_gray`` with 0.299, 0.587), which differ from
``cv2.cvtColor`` by one grey level in places; :func:`gray_of_png` applies those weights
(tests/unit/test_png_gray.py checks every RGB value against OpenCV's decoder).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from selfcal.errors import UsageError

if TYPE_CHECKING:
    from selfcal.io.dataset import Dataset

__all__ = ["gray_of_png", "FrameCache"]

# libpng's RGB -> gray weights in 1/32768 (0.299, 0.587 and the rest), the sum truncated
_PNG_GRAY_WEIGHTS = (9797, 19234, 3737)


def gray_of_png(image: np.ndarray) -> np.ndarray:
    """The gray uint8 image :func:`selfcal.io.dataset.read_gray` returns for the PNG the dataset
    writer stores from ``image`` (uint8 RGB (H, W, 3), or gray (H, W)), without encoding or
    decoding it."""
    img = np.asarray(image)
    if not _is_png_rgb_or_gray(img):
        raise UsageError(
            f"expected a uint8 RGB (H, W, 3) or gray (H, W) image, got {img.dtype} {img.shape}"
        )
    if img.ndim == 2:
        return img.copy()
    wr, wg, wb = _PNG_GRAY_WEIGHTS
    acc = img[..., 0] * np.uint32(wr)
    acc += img[..., 1] * np.uint32(wg)
    acc += img[..., 2] * np.uint32(wb)
    acc >>= 15
    return acc.astype(np.uint8)


def _is_png_rgb_or_gray(img: np.ndarray) -> bool:
    return img.dtype == np.uint8 and (img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3))


@dataclass
class FrameCache:
    """One dataset's images and marker detections held by this process.

    ``images[(index, camera)]``: the gray image of that frame (:func:`gray_of_png`), kept by
    :meth:`add` while the acquisition writes the frame (the readers take only the frames the
    dataset lists: those on disk) and while the images fit in ``max_bytes``
    (default 256 MiB: 870 images of 640 x 480); the readers read the others from the files.
    ``detections``: what :func:`selfcal.calibration.field.calibrate.detect_dataset` found in each image (it fills
    and reuses it). Use one cache for one dataset folder only.
    """

    max_bytes: int = 256 * 2**20
    images: dict[tuple[int, str], np.ndarray] = field(default_factory=dict)
    detections: dict[tuple, tuple[dict, dict]] = field(default_factory=dict)
    nbytes: int = 0
    on_image: Callable[[int, str, np.ndarray], None] | None = None
    """Called with ``(index, camera, gray)`` for every image :meth:`add` is given, kept or not
    (``selfcal run`` detects the markers there, while the acquisition goes on:
    :func:`selfcal.calibration.field.detections.detect_ahead`)."""
    left_out: int = 0
    """Images :meth:`add` was given and did not keep (over ``max_bytes``, or of another kind)."""
    dataset: Dataset | None = None
    """The dataset as its writer will leave it, while its last frames are still being written
    (``selfcal run``: :class:`selfcal.acquisition.held_frames.HeldFrames`; every image of those
    frames is in ``images`` then): the calibration takes it instead of opening the folder.
    None: open the folder."""

    def add(self, index: int, images: dict[str, np.ndarray]) -> None:
        """Keep frame ``index``'s images (uint8 RGB or gray, by camera) while they fit; an image
        of another kind (say 16 bits from a camera) is left to be read from its file."""
        full = False
        for cam, img in images.items():
            if not _is_png_rgb_or_gray(img):
                self.left_out += 1
                continue
            gray = gray_of_png(img)
            if self.on_image is not None:
                self.on_image(index, cam, gray)
            full = full or self.nbytes + gray.nbytes > self.max_bytes
            if full:
                self.left_out += 1
            else:
                self.images[(index, cam)] = gray
                self.nbytes += gray.nbytes
