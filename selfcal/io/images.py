"""Image files as the gray uint8 pixels the detectors take, whatever the camera wrote.

Industrial cameras write 10-, 12- or 16-bit images (PNG, TIFF, a ROS ``mono16`` stream staged as
PNG). OpenCV's ``IMREAD_GRAYSCALE`` divides a 16-bit image by 256, which leaves 12-bit data at
16 grey levels: ChArUco, AprilGrid and circle grids are then not found at all and a chessboard's
corners lose half their accuracy (``tests/unit/test_images.py``). Here a deep image keeps its
significant bits: a 16-bit image is shifted right by ``bit_length(max) - 8`` (its brightest
pixel sets the depth the sensor used), a floating-point one is scaled by its maximum (1.0 for
images in [0, 1]).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from selfcal.errors import InputError

__all__ = ["gray8", "read_gray_image"]


def gray8(img: np.ndarray) -> np.ndarray:
    """A gray image (H, W) of any depth as uint8 (see the module docstring); a colour image
    (H, W, 3) in OpenCV's BGR order is converted to gray first.

    Raises:
        ValueError: a depth other than 8 or 16 bits unsigned or floating point.
    """
    img = np.asarray(img)
    if img.ndim == 3:
        codes = {3: cv2.COLOR_BGR2GRAY, 4: cv2.COLOR_BGRA2GRAY}
        img = cv2.cvtColor(img, codes[img.shape[2]]) if img.shape[2] in codes else img[:, :, 0]
    if img.dtype == np.uint8:
        return img
    if img.dtype == np.uint16:
        shift = max(8, int(img.max()).bit_length()) - 8
        if shift == 0:
            return img.astype(np.uint8)
        rounded = (img.astype(np.uint32) + (1 << (shift - 1))) >> shift
        return np.minimum(rounded, 255).astype(np.uint8)
    if np.issubdtype(img.dtype, np.floating):
        top = max(float(np.nanmax(img)), 1.0) if img.size else 1.0
        return np.clip(np.rint(np.nan_to_num(img) * (255.0 / top)), 0, 255).astype(np.uint8)
    raise InputError(f"{img.dtype} pixels: give 8- or 16-bit or floating-point images")


def read_gray_image(path: str | Path) -> np.ndarray | None:
    """The image file ``path`` as gray uint8 (:func:`gray8`), or None when OpenCV cannot read
    it (no file, not an image).

    Raises:
        InputError: pixels of a depth :func:`gray8` does not take (signed or 32-bit integers),
            naming the file.
    """
    if not Path(path).is_file():  # no file: None without OpenCV's own warning on stderr
        return None
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
    if img is None:
        return None
    try:
        return gray8(img)
    except ValueError as exc:
        raise InputError(
            f"{path}: {exc}", fix="save the images as 8- or 16-bit PNG or TIFF"
        ) from None
