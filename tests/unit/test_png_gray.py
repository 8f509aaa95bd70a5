"""Frames kept in memory by `selfcal run` are the pixels `read_gray` reads back from the PNGs: the
in-memory gray conversion equals OpenCV's PNG decoding to gray for every RGB value (issue 17)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from selfcal.io.dataset import DatasetInfo, DatasetWriter, read_gray
from selfcal.io.frame_cache import gray_of_png


def test_every_rgb_value_decodes_to_the_same_gray():
    v = np.arange(1 << 24, dtype=np.uint32)
    rgb = np.stack([v >> 16, (v >> 8) & 255, v & 255], axis=-1).astype(np.uint8)
    rgb = rgb.reshape(4096, 4096, 3)
    # stored uncompressed to save time: the gray conversion happens in the decoder
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 0])
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
