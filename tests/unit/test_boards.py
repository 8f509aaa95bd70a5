"""Boards of known geometry (selfcal.target.boards): layout, generated images, detection, TOML."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from selfcal.io.target_toml import (
    TargetFileError,
    load_board,
    load_target,
    parse_target,
    target_document,
)
from selfcal.target import AprilGrid, ArucoField, Board, Charuco, Chessboard, CirclesGrid

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "models" / "targets").glob("*.toml"))

BOARDS = {
    "chessboard": Chessboard((9, 6), 0.02),
    "charuco": Charuco((7, 5), 0.02, 0.015, "DICT_5X5_100"),
    "circles": CirclesGrid((4, 11), 0.02, 0.015),
    "aprilgrid": AprilGrid((6, 4), 0.02, 0.3),
}
# Detection error (px RMS) against the exact warped positions, measured over the four angles
# below (blur sigma 0.8 px): chessboard 0.020, charuco 0.027, circles 0.074 (a blob centre is
# not the projected circle centre), aprilgrid 0.064. Tolerance about 3x the worst.
RMS_TOL_PX = {"chessboard": 0.06, "charuco": 0.08, "circles": 0.2, "aprilgrid": 0.18}


def homography(board_img, angle_deg: float, size=(1200, 900)) -> np.ndarray:
    """A view of the board image: turned by ``angle_deg``, shrunk and seen in perspective."""
    h, w = board_img.pixels.shape
    a = np.radians(angle_deg)
    T1 = np.array([[1, 0, -w / 2], [0, 1, -h / 2], [0, 0, 1.0]])
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    S = np.diag([0.85, 0.85, 1.0])
    P = np.array([[1, 0, 0], [0, 1, 0], [2e-4, -1.5e-4, 1]])
    T2 = np.array([[1, 0, size[0] / 2], [0, 1, size[1] / 2], [0, 0, 1.0]])
    return T2 @ P @ S @ R @ T1


def view(board: Board, angle_deg: float, size=(1200, 900)):
    """(image, H, board image): the board warped by :func:`homography`, blurred like optics."""
    bi = board.image(px_per_mm=2.5)
    H = homography(bi, angle_deg, size)
    img = cv2.warpPerspective(bi.pixels, H, size, flags=cv2.INTER_LINEAR, borderValue=255)
    return cv2.GaussianBlur(img, (0, 0), 0.8), H, bi


def truth_uv(board: Board, ids: np.ndarray, H: np.ndarray, bi) -> np.ndarray:
    src = bi.board_to_pixels(board.points(ids)[:, :2])
    return cv2.perspectiveTransform(src.reshape(-1, 1, 2), H).reshape(-1, 2)


@pytest.mark.parametrize("name", sorted(BOARDS))
@pytest.mark.parametrize("angle", [20.0, 110.0, 200.0, 290.0])
def test_detection_finds_every_feature_with_its_id(name, angle):
    board = BOARDS[name]
    img, H, bi = view(board, angle)
    f = board.detect(img)
    assert len(f) == board.n_features
    assert len(np.unique(f.ids)) == len(f)
    e = np.linalg.norm(f.uv - truth_uv(board, f.ids, H, bi), axis=1)
    assert np.sqrt(np.mean(e**2)) < RMS_TOL_PX[name]


@pytest.mark.parametrize("name", ["charuco", "aprilgrid"])
def test_partial_views_keep_their_ids(name):
    board = BOARDS[name]
    img, H, bi = view(board, 20.0)
    img[:, 600:] = 255  # half of the board hidden
    f = board.detect(img)
    assert 0.2 * board.n_features < len(f) < 0.8 * board.n_features
    e = np.linalg.norm(f.uv - truth_uv(board, f.ids, H, bi), axis=1)
    assert np.sqrt(np.mean(e**2)) < RMS_TOL_PX[name]


@pytest.mark.parametrize("name", sorted(BOARDS))
def test_no_board_in_the_image_gives_no_features(name):
    rng = np.random.default_rng(0)
    img = (rng.random((480, 640)) * 60 + 150).astype(np.uint8)
    assert len(BOARDS[name].detect(img)) == 0


def test_chessboard_order_is_the_boards_own_under_a_mirrored_detection():
    board = BOARDS["chessboard"]
    img, H, bi = view(board, 200.0)
    f = board.detect(img)
    np.testing.assert_array_equal(f.ids, np.arange(board.n_features))
    assert np.abs(f.uv - truth_uv(board, f.ids, H, bi)).max() < 0.5


@pytest.mark.parametrize("name", sorted(BOARDS))
def test_layout_ids_are_distinct_and_points_planar(name):
    board = BOARDS[name]
    ids, pts = board.layout()
    assert len(np.unique(ids)) == len(ids) == len(pts)
    np.testing.assert_array_equal(pts[:, 2], 0.0)
    np.testing.assert_allclose(board.points(ids), pts)
    assert np.isnan(board.points(np.array([10**6]))).all()


def test_layouts_follow_the_declared_geometry():
    _, pts = BOARDS["chessboard"].layout()
    np.testing.assert_allclose(pts[1] - pts[0], [0.02, 0, 0])
    np.testing.assert_allclose(pts[9] - pts[0], [0, 0.02, 0])
    # the ChArUco corners are OpenCV's and on the same lattice as the chessboard's
    _, pc = BOARDS["charuco"].layout()
    np.testing.assert_allclose(pc[0], [0.02, 0.02, 0])
    np.testing.assert_allclose(pc[8] - pc[0], [0.02, 0.02, 0])
    _, pa = BOARDS["aprilgrid"].layout()
    np.testing.assert_allclose(pa[1] - pa[0], [0.02, 0, 0])  # tag 0: top-left -> top-right
    np.testing.assert_allclose(pa[4] - pa[0], [0.026, 0, 0])  # next tag: tag + 0.3 tag gap
    _, pci = BOARDS["circles"].layout()
    np.testing.assert_allclose(pci[4] - pci[0], [0.02, 0.02, 0])  # row 1 is shifted by s


@pytest.mark.parametrize("name", sorted(BOARDS))
def test_board_image_extent_matches_its_pixels(name):
    bi = BOARDS[name].image(px_per_mm=3.0)
    x0, y0, x1, y1 = bi.extent_m
    H, W = bi.pixels.shape
    assert bi.pixels.dtype == np.uint8
    assert W / (x1 - x0) == pytest.approx(H / (y1 - y0), rel=1e-9)
    assert x0 < 0 and y0 < 0  # a quiet zone around the board origin


# ------------------------------------------------------------------------------ target TOML
def test_examples_load():
    kinds = {type(load_target(p)) for p in EXAMPLES}
    assert kinds == {ArucoField, Chessboard, Charuco, CirclesGrid, AprilGrid}


def test_load_board_refuses_the_field_by_its_file():
    models = ROOT / "models" / "targets"
    assert isinstance(load_board(models / "charuco.toml"), Charuco)
    with pytest.raises(TargetFileError, match=r"field\.toml: declares the ArUco field"):
        load_board(models / "field.toml")


def test_docs_examples_are_the_example_files():
    text = (ROOT / "docs" / "targets.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", text, flags=re.S)
    files = {p.read_text() for p in EXAMPLES}
    assert len(blocks) == len(EXAMPLES)
    assert set(blocks) == files


def _doc(**kw):
    return dict(kw)


def _charuco(**over):
    base = dict(type="charuco", inner_corners=[5, 4], square_mm=20, marker_mm=15)
    return {**base, "dictionary": "DICT_5X5_100", **over}


@pytest.mark.parametrize(
    "doc, key",
    [
        (_doc(type="chessboard", inner_corners=[11, 8], square_mm=15, squares=3), "squares"),
        (_doc(type="chessboard", inner_corners=[11, 8]), "square_mm"),
        (_doc(type="chessboard", inner_corners=[10, 8], square_mm=15), "inner_corners"),
        (_doc(type="chessboard", inner_corners=[11], square_mm=15), "inner_corners"),
        (_doc(type="chessboard", inner_corners=[11, 8], square_mm=-1), "square_mm"),
        (_doc(type="board", inner_corners=[11, 8], square_mm=15), "type"),
        (_charuco(marker_mm=25), "marker_mm"),
        (_charuco(dictionary="DICT_9X9"), "dictionary"),
        (_charuco(inner_corners=[20, 20], dictionary="DICT_4X4_50"), "dictionary"),
        (_doc(type="circles", pattern=[4, 11], spacing_mm=10, diameter_mm=20), "diameter_mm"),
        (_doc(type="aprilgrid", tags=[6, 6], tag_mm=25, spacing_ratio=0), "spacing_ratio"),
        (_doc(type="field", dictionary="DICT_4X4_50", inner_corners=[3, 4]), "inner_corners"),
    ],
)
def test_bad_target_files_name_file_and_key(doc, key):
    with pytest.raises(TargetFileError, match=rf"board\.toml.*{key}") as info:
        parse_target(doc, "board.toml")
    assert info.value.fix


@pytest.mark.parametrize("doc, key", [
    (_charuco(square_mm=0.02, marker_mm=0.015), "square_mm"),  # a new user's, in metres
    (_charuco(marker_mm=0.5), "marker_mm"),
    (_doc(type="chessboard", inner_corners=[11, 8], square_mm=0.015), "square_mm"),
    (_doc(type="circles", pattern=[4, 11], spacing_mm=0.01), "spacing_mm"),
    (_doc(type="aprilgrid", tags=[6, 6], tag_mm=0.025, spacing_ratio=0.3), "tag_mm"),
])  # fmt: skip
def test_a_length_below_a_millimetre_is_refused_as_metres_or_centimetres(doc, key):
    """A printed target's length below 1 mm is a length in another unit: refused when the file
    is read (it imported silently and calibrate failed 20 s later), naming the key and the mm."""
    with pytest.raises(TargetFileError, match=rf"board\.toml: key '{key}' must be a length in "
                       r"millimetres, at least 1") as info:  # fmt: skip
        parse_target(doc, "board.toml")
    v = doc[key]
    assert f"if {v:g} is metres, write {key} = {v * 1000:g}" in info.value.message
    parse_target(_doc(type="chessboard", inner_corners=[11, 8], square_mm=1.0), "board.toml")


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(TargetFileError, match="no such target file"):
        load_target(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("type = ")
    with pytest.raises(TargetFileError, match="bad.toml: not a valid TOML"):
        load_target(bad)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_target_document_declares_the_same_target(path):
    target = load_target(path)
    again = parse_target(target_document(target), str(path))
    assert again == target
