"""The dataset's PNG writer (``selfcal.io.png``): OpenCV reads back the very pixels, and the files
are no larger than OpenCV's own writer makes them."""

import io

import cv2
import numpy as np
import pytest

from selfcal.errors import InputError
from selfcal.io.png import encode_png


def _noisy(shape: tuple[int, ...], seed: int = 0) -> np.ndarray:
    """A smooth gradient with 2 grey levels of noise: a rendered frame's statistics."""
    rng = np.random.default_rng(seed)
    h, w = shape[:2]
    ramp = np.add.outer(np.arange(h), np.arange(w)) * (200 / (h + w))
    base = ramp if len(shape) == 2 else ramp[..., None] + np.arange(shape[2]) * 20.0
    return np.clip(np.rint(base + rng.normal(0, 2, shape)), 0, 255).astype(np.uint8)


def _read(png: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)


@pytest.mark.parametrize("shape", [(48, 64, 3), (7, 1, 3), (1, 5, 3)])
def test_rgb_images_read_back_the_same(shape):
    img = _noisy(shape)
    np.testing.assert_array_equal(cv2.cvtColor(_read(encode_png(img)), cv2.COLOR_BGR2RGB), img)


@pytest.mark.parametrize("shape", [(48, 64), (48, 64, 1)])
def test_grey_images_read_back_the_same(shape):
    img = _noisy(shape)
    back = _read(encode_png(img))
    assert back.shape == (48, 64)
    np.testing.assert_array_equal(back, img.reshape(48, 64))


def test_extreme_values_wrap_in_the_filter_and_come_back():
    img = np.zeros((4, 6, 3), np.uint8)
    img[:, 1::2] = 255  # every SUB difference is +-255, modulo 256
    np.testing.assert_array_equal(cv2.cvtColor(_read(encode_png(img)), cv2.COLOR_BGR2RGB), img)


def test_files_no_larger_than_opencvs():
    img = _noisy((480, 640, 3), seed=3)
    params = (cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY)
    ok, theirs = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR), params)
    assert ok
    assert len(encode_png(img)) <= 1.01 * len(theirs)


@pytest.mark.parametrize(
    "bad",
    [np.zeros((4, 4), np.uint16), np.zeros((4, 4, 2), np.uint8), np.zeros(4, np.uint8)],
)
def test_other_images_are_refused(bad):
    with pytest.raises(InputError, match="uint8 .* grey, .* RGB or .* RGBA"):
        encode_png(bad)


def test_a_dataset_frame_that_is_not_8_bit_names_its_file(tmp_path):
    """A 16-bit frame (OpenCV's writer took it) is refused naming the frame's file and the fix."""
    from selfcal.io.dataset import DatasetError, _write_png

    path = tmp_path / "0003_left.png"
    with pytest.raises(DatasetError, match="0003_left.png: a PNG image must be uint8") as e:
        _write_png(path, np.zeros((48, 64, 3), np.uint16))
    assert "8 bits" in (e.value.fix or "")
    assert not path.exists()


@pytest.mark.parametrize("shape", [(48, 64, 3), (48, 64, 4), (48, 64), (1, 5, 4)])
def test_drawings_read_back_the_same(shape):
    """The UP filter's rows (the first against zeros) and RGBA come back; OpenCV reads BGR(A)."""
    img = _noisy(shape)
    img[10:20] = 255  # flat rows, as a figure's margins
    back = _read(encode_png(img, drawing=True))
    if img.ndim == 3:
        back = cv2.cvtColor(back, cv2.COLOR_BGR2RGB if shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
    np.testing.assert_array_equal(back, img)


def test_a_drawing_records_its_dpi():
    from PIL import Image

    png = encode_png(np.full((3, 4, 3), 255, np.uint8), drawing=True, dpi=110.0)
    with Image.open(io.BytesIO(png)) as im:
        assert im.info["dpi"] == pytest.approx((110.0, 110.0), abs=0.01)
    with Image.open(io.BytesIO(encode_png(np.zeros((3, 4), np.uint8)))) as im:
        assert "dpi" not in im.info
