"""Image messages decoded by selfcal/ros/rosbag.py: every supported encoding, row padding, byte order,
compressed jpeg and png, and the errors for the others."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from selfcal.ros.rosbag import COMPRESSED_TYPE, RAW_TYPE, BagError, decode_image

RNG = np.random.default_rng(0)
GRAY = RNG.integers(0, 255, (6, 5), np.uint8)
BGR = RNG.integers(0, 255, (6, 5, 3), np.uint8)


def raw(img: np.ndarray, encoding: str, pad: int = 0, big: bool = False) -> SimpleNamespace:
    h = img.shape[0]
    rows = img.reshape(h, -1)
    if img.dtype == np.uint16:
        rows = rows.astype(">u2" if big else "<u2").view(np.uint8).reshape(h, -1)
    rows = np.hstack([rows, np.zeros((h, pad), np.uint8)])
    return SimpleNamespace(height=h, width=img.shape[1], encoding=encoding, step=rows.shape[1],
                           is_bigendian=int(big), data=rows.ravel())  # fmt: skip


@pytest.mark.parametrize("pad", [0, 3])
def test_raw_encodings(pad):
    assert np.array_equal(decode_image(raw(GRAY, "mono8", pad), RAW_TYPE, "t"), GRAY)
    assert np.array_equal(decode_image(raw(BGR, "bgr8", pad), RAW_TYPE, "t"), BGR)
    rgb = np.ascontiguousarray(BGR[:, :, ::-1])
    assert np.array_equal(decode_image(raw(rgb, "rgb8", pad), RAW_TYPE, "t"), BGR)
    g16 = RNG.integers(0, 65535, (6, 5), np.uint16)
    for big in (False, True):
        out = decode_image(raw(g16, "mono16", pad, big), RAW_TYPE, "t")
        assert out.dtype == np.uint16 and np.array_equal(out, g16)


def test_compressed():
    png = SimpleNamespace(format="mono8; png compressed ",
                          data=np.frombuffer(cv2.imencode(".png", GRAY)[1], np.uint8))  # fmt: skip
    assert np.array_equal(decode_image(png, COMPRESSED_TYPE, "t"), GRAY)
    flat = np.full((16, 16), 120, np.uint8)
    jpg = SimpleNamespace(
        format="jpeg", data=np.frombuffer(cv2.imencode(".jpg", flat)[1], np.uint8)
    )
    assert np.abs(decode_image(jpg, COMPRESSED_TYPE, "t").astype(int) - 120).max() <= 1


def test_errors_name_the_topic_and_encoding():
    with pytest.raises(BagError, match="bag.bag: topic /c: image encoding 'yuv422'"):
        decode_image(raw(GRAY, "yuv422"), RAW_TYPE, "bag.bag: topic /c")
    depth = SimpleNamespace(format="16UC1; compressedDepth png", data=np.zeros(4, np.uint8))
    with pytest.raises(BagError, match="compressed image format"):
        decode_image(depth, COMPRESSED_TYPE, "t")
    short = raw(GRAY, "mono8")
    short.data = short.data[:-1]
    with pytest.raises(BagError, match="bytes for a 5x6 mono8 image"):
        decode_image(short, RAW_TYPE, "t")
