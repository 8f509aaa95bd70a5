"""The chessboard detector's sub-grid check (selfcal.target.board_detect): a board OpenCV finds is
kept unless squares of its pitch continue its pattern beyond it (a larger printed board)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from selfcal.importing.dataset import (
    CameraImages,
    TargetNotFoundWarning,
    detection_summary,
    import_dataset,
)
from selfcal.target import Charuco, Chessboard
from selfcal.target.board_detect import chessboard_detection, refusal

REAL = Path(__file__).resolve().parents[1] / "data" / "real"  # README.md there: source, licence
REAL_PLATES = (  # boards on a grey plate with a white margin narrower than one square on two sides
    "nachi-2025-01-17-photoneo/handeye_data/2025-01-17_data_photoneo/group5/img_12-47-33_2DImage.png",
    "nachi-2025-02-05-mecheye/handeye_data/2025-02-05_data_mecheye/group6/rgb_image_right_00000_2DImage.png",
)


def _corners_cv(gray: np.ndarray, inner: tuple[int, int]) -> np.ndarray:
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, c = cv2.findChessboardCorners(gray, inner, flags=flags)
    assert ok, "OpenCV itself finds this board"
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-3)
    return cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), crit).reshape(-1, 2)


@pytest.mark.parametrize("name", REAL_PLATES)
def test_real_boards_on_a_grey_plate_with_a_narrow_margin_are_found(name):
    """Real images (11 x 8 inner corners, 15 mm): the grey plate beyond the board's narrow white
    margin is not more squares; every corner OpenCV finds is kept."""
    gray = cv2.imread(str(REAL / name), cv2.IMREAD_GRAYSCALE)
    found = Chessboard((11, 8), 0.015).detect(gray)
    assert len(found) == 88
    cv = _corners_cv(gray, (11, 8))
    # the same corners, in the board's own order
    d = np.linalg.norm(found.uv[:, None] - cv[None], axis=2).min(axis=1)
    assert d.max() < 1e-6


def _plate(
    board: Chessboard, margin_mm: float, plate: int, angle_deg: float, size=None
) -> np.ndarray:
    """The board printed with a white ``margin_mm`` on a plate of grey level ``plate``, turned
    by ``angle_deg`` and seen in mild perspective, blurred like optics (an image of ``size``
    (W, H), default 200 px more than the plate's)."""
    bi = board.image(px_per_mm=2.5, margin_mm=margin_mm)
    pad = 60
    img = np.pad(bi.pixels, pad, constant_values=plate)
    h, w = img.shape
    size = size or (w + 200, h + 200)
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    C = np.array([[1, 0, -w / 2], [0, 1, -h / 2], [0, 0, 1.0]])
    P = np.array([[1, 0, 0], [0, 1, 0], [1e-4, -1e-4, 1]])
    T = np.array([[1, 0, size[0] / 2], [0, 1, size[1] / 2], [0, 0, 1.0]])
    out = cv2.warpPerspective(img, T @ P @ R @ C, size, flags=cv2.INTER_LINEAR, borderValue=20)
    return cv2.GaussianBlur(out, (0, 0), 0.8)


@pytest.mark.parametrize("plate", [40, 110])
@pytest.mark.parametrize("angle", [0.0, 15.0, 100.0])
def test_a_board_with_a_narrow_margin_on_a_dark_plate_is_kept(plate, angle):
    board = Chessboard((9, 6), 0.02)
    assert len(board.detect(_plate(board, 4.0, plate, angle))) == 54


@pytest.mark.parametrize(
    ("r0", "r1", "c0", "c1"),
    [(0, 6, 1, 9), (0, 6, 2, 9), (0, 6, 0, 8), (0, 6, 1, 8), (1, 6, 0, 9), (0, 4, 0, 9),
     (1, 5, 1, 8), (2, 6, 3, 9)],
)  # fmt: skip
def test_a_sub_grid_of_a_larger_printed_board_is_refused(r0, r1, c0, c1):
    """Any sub-grid of a printed 9 x 6 board (larger by one or two corners on a side, or on
    both axes): the squares beyond it continue the pattern."""
    img = _plate(Chessboard((9, 6), 0.02), 20.0, 110, 15.0)
    full = chessboard_detection(img, (9, 6))
    assert len(full.features) == 54 and not full.refused
    sub = full.features.uv.reshape(6, 9, 2)[r0:r1, c0:c1]
    why = refusal(img, sub.reshape(-1, 2), c1 - c0, r1 - r0)
    assert "part of a larger board" in why and f"{c1 - c0} x {r1 - r0}" in why


def test_a_grid_that_skips_corner_lines_is_refused():
    """OpenCV's findChessboardCornersSB finds a 9 x 4 grid in a 9 x 6 board with every other
    corner line: its cells are not a chessboard's."""
    img = _plate(Chessboard((9, 6), 0.02), 20.0, 110, 100.0)
    found = chessboard_detection(img, (9, 4))
    assert found.opencv == 36, "OpenCV finds that grid (else this case tests nothing)"
    assert len(found.features) == 0 and "not a chessboard" in found.refused


def test_a_charuco_marker_the_first_pass_misses_is_found_where_the_board_puts_it():
    """A stained marker (6 of its 36 bits inverted): OpenCV's first pass does not decode it and
    loses the corners it gives; its refinement looks where the board's layout puts the marker
    and finds them, where the clean board has them."""
    board = Charuco((4, 6), 0.036, 0.018, "DICT_6X6_250")
    clean = board.image(px_per_mm=4.0).pixels
    cv = board.cv_board()
    mc, mi = cv2.aruco.CharucoDetector(cv).detectBoard(clean)[2:]
    m = mc[list(mi.ravel()).index(0)].reshape(4, 2)
    (x0, y0), x1 = m.min(axis=0), m[:, 0].max()
    cell = (x1 - x0) / 8  # 6 x 6 bits inside a one-bit black border
    stained = clean.copy()
    for q in np.random.default_rng(6).choice(36, 6, replace=False):
        v, u = int(y0 + (1 + q // 6) * cell + 0.5), int(x0 + (1 + q % 6) * cell + 0.5)
        stained[v : v + int(cell), u : u + int(cell)] ^= 255
    clean, stained = (cv2.GaussianBlur(i, (0, 0), 0.8) for i in (clean, stained))
    first = cv2.aruco.CharucoDetector(cv).detectBoard(stained)[1]
    assert len(first) < 24, "OpenCV's first pass misses the marker (else this tests nothing)"
    found, ref = board.detect(stained), board.detect(clean)
    assert len(ref) == 24 and np.array_equal(found.ids, ref.ids)
    np.testing.assert_allclose(found.uv, ref.uv, atol=1e-6)  # measured: identical


def test_import_names_each_refused_image_and_counts_what_opencv_found(tmp_path):
    """``selfcal import``: an image in which OpenCV finds the declared grid but the checks
    refuse it is named with the reason, and the summary counts both."""
    printed, declared = Chessboard((9, 6), 0.02), Chessboard((9, 4), 0.02)
    (tmp_path / "img").mkdir()
    size = (920, 900)
    cv2.imwrite(str(tmp_path / "img" / "a.png"), _plate(printed, 20.0, 110, 100.0, size))
    cv2.imwrite(str(tmp_path / "img" / "b.png"), _plate(declared, 20.0, 110, 10.0, size))
    (tmp_path / "j.csv").write_text("j1,j2,j3,j4,j5,j6\n" + "0,-1.2,1.4,0,0.6,0\n" * 2)
    (tmp_path / "t.toml").write_text(
        'type = "chessboard"\ninner_corners = [9, 4]\nsquare_mm = 20\n'
    )
    cams = [CameraImages.parse(f"cam0={tmp_path}/img/*.png")]
    with pytest.warns(TargetNotFoundWarning) as caught:
        info = import_dataset("kr6-r900", cams, tmp_path / "j.csv", "rad", tmp_path / "t.toml",
                              tmp_path / "ds")  # fmt: skip
    text = " ".join(str(w.message) for w in caught)
    assert "OpenCV finds the chessboard target" in text and "in 1 image(s)" in text
    assert "a.png (the grid OpenCV found is not a chessboard's" in text
    assert detection_summary(info) == "board found in 1 of 2 images (OpenCV alone: 2)"
    # an ArUco field's count is the project's own detector's: no "OpenCV alone" for it
    field = dataclasses.replace(info, board=None)
    assert detection_summary(field) == "target found in 1 of 2 images"
