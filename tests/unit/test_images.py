"""Deep images (10-16 bit, float) read as the gray uint8 the detectors take (selfcal/io/images.py):
12-bit data in a 16-bit file is found as an 8-bit image is, where OpenCV's IMREAD_GRAYSCALE left
it at 16 grey levels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from selfcal.io.images import gray8, read_gray_image
from tests.unit.test_boards import BOARDS, truth_uv, view


@pytest.mark.parametrize("name", ["chessboard", "charuco", "aprilgrid", "circles"])
@pytest.mark.parametrize("suffix", [".png", ".tiff"])
def test_12_bit_images_in_16_bit_files_are_detected_as_8_bit_ones(tmp_path, name, suffix):
    board = BOARDS[name]
    img, H, bi = view(board, 20.0)
    path = tmp_path / f"deep{suffix}"
    assert cv2.imwrite(str(path), img.astype(np.uint16) * 16 + 5)  # 12 bits, a dark offset
    old = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert old.max() <= 16  # what OpenCV's gray read leaves of it
    gray = read_gray_image(path)
    assert gray.dtype == np.uint8 and gray.max() > 250
    f, f8 = board.detect(gray), board.detect(img)
    assert len(f) == len(f8) == board.n_features
    rms = [
        np.sqrt(np.mean(np.sum((g.uv - truth_uv(board, g.ids, H, bi)) ** 2, 1))) for g in (f, f8)
    ]
    assert rms[0] < 1.5 * rms[1] + 0.005


def test_depths_and_colours():
    rng = np.random.default_rng(1)
    full = rng.integers(0, 65536, (40, 50), dtype=np.uint16)
    np.testing.assert_array_equal(gray8(full), np.minimum((full.astype(np.uint32) + 128) >> 8, 255))
    ten = rng.integers(0, 1024, (40, 50), dtype=np.uint16)
    assert np.abs(gray8(ten).astype(int) - np.rint(ten / 4)).max() <= 1
    eight = rng.integers(0, 256, (40, 50), dtype=np.uint8)
    assert gray8(eight) is eight and gray8(eight.astype(np.uint16)).tolist() == eight.tolist()
    unit = eight / 255.0
    np.testing.assert_array_equal(gray8(unit), eight)
    bgr16 = np.repeat(ten[:, :, None], 3, axis=2)
    np.testing.assert_array_equal(gray8(bgr16), gray8(ten))
    with pytest.raises(ValueError, match="int32 pixels"):
        gray8(ten.astype(np.int32))


def test_an_unreadable_file_is_none(tmp_path):
    (tmp_path / "x.png").write_text("not an image")
    assert read_gray_image(tmp_path / "x.png") is None
    assert read_gray_image(tmp_path / "missing.png") is None


def test_unsupported_depths_are_named_with_the_file(tmp_path):
    from selfcal.errors import InputError

    path = tmp_path / "signed.tif"
    assert cv2.imwrite(str(path), np.full((8, 8), 1000, np.int16))
    with pytest.raises(InputError, match=r"signed.tif: int16 pixels.*8- or 16-bit PNG or TIFF"):
        read_gray_image(path)
    bgra = np.zeros((4, 4, 4), np.uint8)
    bgra[..., 2] = 200  # red
    assert gray8(bgra)[0, 0] == cv2.cvtColor(bgra[..., :3], cv2.COLOR_BGR2GRAY)[0, 0] > 50
