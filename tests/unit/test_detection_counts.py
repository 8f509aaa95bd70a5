"""`selfcal import`'s "(OpenCV alone: N)": each board's `detection` counts what OpenCV's own
detector finds with its default parameters, not the project's detector (which it was for
ChArUco, AprilGrid and circle grids)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from selfcal.target.boards import AprilGrid, Charuco, CirclesGrid

ICAL = Path(__file__).parents[1] / "data" / "real" / "ical-charuco" / "inputs"


def test_charuco_opencv_alone_is_the_detector_without_marker_refinement():
    """ical-charuco image 2: 24 corners with tryRefineMarkers, 4 by OpenCV's CharucoDetector
    with its defaults (below the board's 6: not found by OpenCV alone)."""
    board = Charuco((4, 6), 0.036195, 0.018256, "DICT_6X6_250")
    d = board.detection(cv2.imread(str(ICAL / "images_calib" / "02.png"), cv2.IMREAD_GRAYSCALE))
    assert (len(d.features), d.opencv) == (24, 4)


def test_circles_opencv_alone_is_the_default_blob_detector():
    """Circles of 90 px (6400 px^2) are beyond OpenCV's default blob detector (5000 px^2): the
    project's large-blob detector finds the grid, OpenCV alone does not."""
    board = CirclesGrid((4, 5), 0.02, 0.015)
    small = board.detection(board.image(px_per_mm=3.0, margin_mm=20).pixels)
    large = board.detection(board.image(px_per_mm=6.0, margin_mm=20).pixels)
    assert (len(small.features), small.opencv) == (20, 20)
    assert (len(large.features), large.opencv) == (20, 0)


def test_aprilgrid_opencv_alone_keeps_what_the_screening_drops():
    """A grey bar along one side of tag 0: the project's screening drops the tag (a side
    bordered by a foreign surface), OpenCV's ArUco detector with its defaults keeps it."""
    board = AprilGrid((3, 2), 0.03, 0.3)
    im = board.image(px_per_mm=4.0)
    _, pts = board.layout()
    u = (pts[:4, 0] - im.extent_m[0]) * im.px_per_m
    v = (pts[:4, 1] - im.extent_m[1]) * im.px_per_m
    img = im.pixels.copy()
    img[int(v.min()) : int(v.max()), int(u.max()) + 1 : int(u.max()) + 7] = 90
    d = board.detection(cv2.GaussianBlur(img, (3, 3), 0.8))
    assert (len(d.features), d.opencv) == (20, 24)
    assert np.isin(np.arange(4), d.features.ids).sum() == 0
