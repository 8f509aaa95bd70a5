"""Frames kept in memory by `selfcal run` are the pixels `read_gray` reads back from the PNGs: the
in-memory gray conversion equals OpenCV's PNG decoding to gray for every RGB value (issue 17)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from selfcal.io.dataset import DatasetInfo, DatasetWriter, read_gray
from selfcal.io.frame_cache import gray_of_png


def test_every_rgb_value_decodes_to_the_same_gray():
    # pixel r * 65536 + g * 256 + b holds (r, g, b): every value once, built in uint8 (a uint32
    # stack of 2**24 values cost 1.3 of the test's 2.5 CPU s)
    a = np.arange(256, dtype=np.uint8)
    rgb = np.empty((256, 256, 256, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = a[:, None, None], a[None, :, None], a
    rgb = rgb.reshape(4096, 4096, 3)
    # stored uncompressed and unfiltered to save time (lossless either way: the same pixels
    # reach the decoder's gray conversion; encoding and decoding 0.9 -> 0.36 CPU s)
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    png = [cv2.IMWRITE_PNG_COMPRESSION, 0, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
    ok, buf = cv2.imencode(".png", bgr, png)
    assert ok
    decoded = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    np.testing.assert_array_equal(gray_of_png(rgb), decoded)
    # the plain colour conversion is not it (so the test can tell them apart)
    assert not np.array_equal(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), decoded)


def test_written_frames_read_back_as_gray_of_png(tmp_path):
    W, H = 64, 48
    info = DatasetInfo(
        robot_model="er4u-paper",
        resolution=(W, H),
        dictionary="DICT_4X4_50",
        scale_ids=(48, 49),
        scale_length_m=0.2,
        observation="images",
        planned_joints_deg=np.zeros((1, 5)),
        validation_joints_deg=np.zeros((1, 5)),
    )
    rng = np.random.default_rng(4)
    w = DatasetWriter(tmp_path, info)
    left = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    right = rng.integers(0, 256, (H, W), dtype=np.uint8)  # a gray camera stays as it is
    w.add_frame(0, info.planned_joints_deg[0], left=left, right=right)
    for cam, img in (("left", left), ("right", right)):
        got = read_gray(tmp_path / "frames" / f"0000_{cam}.png", 0)
        np.testing.assert_array_equal(gray_of_png(img), got)


@pytest.mark.parametrize("bad", [np.zeros((4, 4, 3), np.float32), np.zeros((4, 4, 4), np.uint8)])
def test_refuses_what_the_writer_would_not_store_as_rgb(bad):
    with pytest.raises(ValueError, match="uint8 RGB"):
        gray_of_png(bad)
