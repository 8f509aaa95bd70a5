"""Board detection with OpenCV into :class:`selfcal.target.base.Features` (ids and pixels).

Pixels follow the OpenCV convention (x right, y down, pixel centres at integers); ids are the
boards' feature ids (:mod:`selfcal.target.boards`). An image in which the board is not found gives
empty features.

- chessboard: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` (0.02 px RMS on blurred
  synthetic views, tests/unit/test_boards.py), falling back to ``cv2.findChessboardCornersSB``
  (more robust, but 0.15-0.3 px RMS on the same views); the corner order is then made the
  board's own (:func:`orient_chessboard`): OpenCV may return the grid mirrored or turned by 180
  degrees, which the printed colours and the handedness of a board seen from its front decide.
  A grid OpenCV finds is kept unless the image shows it is not the declared board
  (:func:`refusal`: a sub-grid of a larger printed board, or cells that do not alternate);
- ChArUco: ``cv2.aruco.CharucoDetector.detectBoard`` (partial views: each corner has its id)
  with ``tryRefineMarkers``: OpenCV looks again for the markers the first pass missed where the
  board's layout puts them (a real view, ical-charuco image 2: 4 corners without, 24 with; the
  corners found either way do not move);
- asymmetric circle grid: ``cv2.findCirclesGrid`` with ``CALIB_CB_ASYMMETRIC_GRID``, then with
  a blob detector that accepts large circles (OpenCV's default one, which finds the grid more
  often under strong perspective, ignores blobs above 5000 px^2);
- AprilGrid: the ArUco detector with the AprilTag 36h11 dictionary and the edge-line corner
  refinement of :mod:`selfcal.target.aruco_detect`; ids beyond the grid are dropped.

Each board's ``*_detection`` also counts what OpenCV's own detector finds with its default
parameters (:class:`Detection` ``opencv``; ``selfcal import``'s "OpenCV alone"): the chessboard
corners before :func:`refusal`, ``CharucoDetector`` without ``tryRefineMarkers``,
``findCirclesGrid`` with the default blob detector, the ArUco detector without the edge-line
refinement and screening.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from selfcal.target.aruco import markers_to_features
from selfcal.target.aruco_detect import detect_markers, to_gray
from selfcal.target.base import Features

__all__ = [
    "Detection",
    "chessboard_detection",
    "refusal",
    "detect_chessboard",
    "orient_chessboard",
    "detect_charuco",
    "charuco_detection",
    "detect_circles",
    "circles_detection",
    "detect_aprilgrid",
    "aprilgrid_detection",
]

_EMPTY = Features(np.zeros(0, np.int64), np.zeros((0, 2)))
_SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-3)


def _sample(gray: np.ndarray, uv: np.ndarray, r: int = 1) -> float:
    """Mean grey level of the (2 r + 1)^2 pixels around ``uv`` (clipped to the image)."""
    H, W = gray.shape
    u = int(np.clip(round(uv[0]), r, W - 1 - r))
    v = int(np.clip(round(uv[1]), r, H - 1 - r))
    return float(gray[v - r : v + r + 1, u - r : u + r + 1].mean())


def orient_chessboard(gray: np.ndarray, uv: np.ndarray, cols: int, rows: int) -> np.ndarray:
    """The corners ``uv`` (cols * rows, 2) of a detected chessboard (row-major in OpenCV's
    order) re-ordered into the board's own order (:class:`selfcal.target.boards.Chessboard`):
    right-handed as seen from the printed side (``x`` step cross ``y`` step > 0 in the image) and
    with the black outer square diagonally outside corner 0."""
    g = np.asarray(uv, dtype=float).reshape(rows, cols, 2)
    dx, dy = g[0, 1] - g[0, 0], g[1, 0] - g[0, 0]
    if dx[0] * dy[1] - dx[1] * dy[0] < 0:  # mirrored order
        g = g[:, ::-1]
    p0, px, py, pxy = g[0, 0], g[0, 1], g[1, 0], g[1, 1]
    outer = p0 + 0.5 * (p0 - pxy)  # the outer square diagonally beyond corner 0
    edge = 0.5 * (p0 + px) + 0.5 * (p0 - py)  # the outer square beside it (other colour)
    r = max(1, int(0.15 * min(np.linalg.norm(px - p0), np.linalg.norm(py - p0))))
    if _sample(gray, outer, r) > _sample(gray, edge, r):
        g = g[::-1, ::-1]  # turned by 180 degrees
    return g.reshape(-1, 2)


def _ring_levels(
    gray: np.ndarray, edge: np.ndarray, out: np.ndarray, k: float, r: int
) -> np.ndarray:
    """Grey levels at the centres of the cells ``k`` steps beyond the corner line ``edge``
    (n, 2) px (``out``: the outward step per corner), one per pair of neighbouring corners; NaN
    where the sample falls off the image."""
    H, W = gray.shape
    mid = 0.5 * (edge[:-1] + edge[1:]) + k * 0.5 * (out[:-1] + out[1:])
    inside = (mid[:, 0] > r) & (mid[:, 0] < W - 1 - r) & (mid[:, 1] > r) & (mid[:, 1] < H - 1 - r)
    return np.array(
        [_sample(gray, p, r) if ok else np.nan for p, ok in zip(mid, inside, strict=True)]
    )


def _alternates(levels: np.ndarray, expected: np.ndarray, contrast: float, share: float) -> bool:
    """Whether neighbouring ``levels`` differ with the ``expected`` signs and at least half the
    ``contrast`` (grey levels) in ``share`` of the pairs seen (and at least two)."""
    d = np.diff(levels)
    seen = np.isfinite(d) & np.isfinite(expected) & (expected != 0)
    agree = (np.sign(d) == expected) & (np.abs(d) >= 0.5 * contrast)
    return bool(seen.sum() >= 2 and agree[seen].sum() >= share * seen.sum())


def refusal(gray: np.ndarray, uv: np.ndarray, cols: int, rows: int) -> str:
    """Why the chessboard grid ``uv`` (cols * rows, 2) px that OpenCV found is not the declared
    board, or ``""`` when the image shows nothing against it. Refused are a grid whose cells are
    not a chessboard's (each square's colour opposite to its neighbours') and a sub-grid of a
    larger printed board, which OpenCV also finds: on some side, the cells one square beyond the
    board's own outer squares continue the pattern (squares of the board's pitch, each colour
    opposite to the outer square beside it, with at least half the contrast of the board's own
    squares, in 3 of 4 places). A plain, grey or cluttered surround (a narrow white margin, the
    plate the board is mounted on) continues nothing."""
    g = np.asarray(uv, dtype=float).reshape(rows, cols, 2)
    step = float(np.median(np.linalg.norm(np.diff(g, axis=1), axis=2)))
    r = max(1, int(0.15 * step))
    cells = np.stack(
        [_ring_levels(gray, a, b - a, 0.5, r) for a, b in zip(g[:-1], g[1:], strict=True)]
    )
    dx, dy = np.diff(cells, axis=1), np.diff(cells, axis=0)
    contrast = float(np.median(np.abs(np.concatenate([dx.ravel(), dy.ravel()]))))
    sx = (-1.0) ** np.add.outer(*map(np.arange, dx.shape))  # a chessboard's sign pattern
    sy = (-1.0) ** np.add.outer(*map(np.arange, dy.shape))
    parity = np.sign(np.median(dx * sx))  # which colour the first cell has
    ok_x = (np.sign(dx) == parity * sx) & (np.abs(dx) >= 0.5 * contrast)
    ok_y = (np.sign(dy) == parity * sy) & (np.abs(dy) >= 0.5 * contrast)
    if not contrast > 0 or (ok_x.sum() + ok_y.sum()) < 0.75 * (ok_x.size + ok_y.size):
        return "the grid OpenCV found is not a chessboard's (its cells do not alternate)"
    names = ("first row", "last row", "first column", "last column")
    for name, side in zip(names, (g, g[::-1], g.transpose(1, 0, 2), g.transpose(1, 0, 2)[::-1]),
                          strict=True):  # fmt: skip
        edge, out = side[0], side[0] - side[1]  # corner line and the outward step per corner
        outer = _ring_levels(gray, edge, out, 0.5, r)  # the board's outer squares
        beyond = _ring_levels(gray, edge, out, 1.5, r)  # where a larger board goes on
        if _alternates(beyond, -np.sign(np.diff(outer)), contrast, 0.75):
            return (
                f"squares go on beyond the {name} of corners: part of a larger board than the "
                f"declared {cols} x {rows} inner corners"
            )
    return ""


@dataclass(frozen=True)
class Detection:
    """A board's detection in one image: the ``features`` kept, how many features OpenCV's
    detector returned before the project's checks (``opencv``) and why those checks refused
    them (``refused``; ``""`` when kept or when OpenCV found nothing)."""

    features: Features
    opencv: int
    refused: str = ""


def chessboard_detection(image: np.ndarray, inner_corners: tuple[int, int]) -> Detection:
    """:func:`detect_chessboard` with what OpenCV found and why it was refused
    (:func:`refusal`)."""
    gray = to_gray(image)
    cols, rows = inner_corners
    ok, corners = cv2.findChessboardCorners(
        gray, (cols, rows), flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if ok:
        corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), _SUBPIX)
    else:
        ok, corners = cv2.findChessboardCornersSB(
            gray, (cols, rows), flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
        )
        if not ok:
            return Detection(_EMPTY, 0)
    uv = np.asarray(corners, dtype=float).reshape(-1, 2)
    why = refusal(gray, uv, cols, rows)
    if why:
        return Detection(_EMPTY, len(uv), why)
    return Detection(
        Features(np.arange(cols * rows), orient_chessboard(gray, uv, cols, rows)), len(uv)
    )


def detect_chessboard(image: np.ndarray, inner_corners: tuple[int, int]) -> Features:
    """All inner corners of a chessboard of ``inner_corners = (cols, rows)``, or none (also when
    the grid found is not the declared board, :func:`refusal`: OpenCV finds sub-grids)."""
    return chessboard_detection(image, inner_corners).features


def _charuco(gray: np.ndarray, board: cv2.aruco.CharucoBoard, refine: bool) -> Features:
    params = cv2.aruco.CharucoParameters()
    params.tryRefineMarkers = refine  # look again for the board's markers not found at first
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board, params).detectBoard(gray)
    if ids is None or len(ids) == 0:
        return _EMPTY
    return Features(np.asarray(ids).reshape(-1), np.asarray(corners, dtype=float).reshape(-1, 2))


def detect_charuco(image: np.ndarray, board: cv2.aruco.CharucoBoard) -> Features:
    """The corners of the ChArUco ``board`` found (any subset, each with its id)."""
    return _charuco(to_gray(image), board, refine=True)


def charuco_detection(image: np.ndarray, board: cv2.aruco.CharucoBoard) -> Detection:
    """:func:`detect_charuco` with the corners OpenCV's ``CharucoDetector`` finds with its
    default parameters (without ``tryRefineMarkers``) as ``opencv``."""
    gray = to_gray(image)
    return Detection(_charuco(gray, board, refine=True), len(_charuco(gray, board, False).ids))


def _blob_detector() -> cv2.SimpleBlobDetector:
    """Dark round blobs of any size above 20 px^2 (OpenCV's default caps blobs at 5000 px^2)."""
    p = cv2.SimpleBlobDetector.Params()
    p.minArea = 20.0
    p.maxArea = 1e7
    p.minDistBetweenBlobs = 1.0
    p.filterByConvexity = True
    p.minConvexity = 0.8
    p.filterByInertia = True
    p.minInertiaRatio = 0.1
    return cv2.SimpleBlobDetector.create(p)


def circles_detection(image: np.ndarray, pattern: tuple[int, int]) -> Detection:
    """:func:`detect_circles` with the centres ``cv2.findCirclesGrid`` finds with OpenCV's
    default blob detector as ``opencv`` (0 when only the large-blob detector finds the grid)."""
    gray = to_gray(image)
    flags = cv2.CALIB_CB_ASYMMETRIC_GRID
    ok, centres = cv2.findCirclesGrid(gray, tuple(pattern), flags=flags)
    opencv = int(pattern[0] * pattern[1]) if ok and centres is not None else 0
    if not ok:  # OpenCV's default blob detector ignores blobs above 5000 px^2
        ok, centres = cv2.findCirclesGrid(
            gray, tuple(pattern), flags=flags, blobDetector=_blob_detector()
        )
    if not ok or centres is None:
        return Detection(_EMPTY, opencv)
    uv = np.asarray(centres, dtype=float).reshape(-1, 2)
    return Detection(Features(np.arange(len(uv)), uv), opencv)


def detect_circles(image: np.ndarray, pattern: tuple[int, int]) -> Features:
    """All circle centres of an asymmetric grid ``pattern = (cols, rows)``, or none."""
    return circles_detection(image, pattern).features


def aprilgrid_detection(image: np.ndarray, tags: tuple[int, int]) -> Detection:
    """:func:`detect_aprilgrid` with the tag corners of the grid that OpenCV's ArUco detector
    finds with its default parameters (no corner refinement, no screening) as ``opencv``."""
    n = int(tags[0]) * int(tags[1])
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    )
    _, ids, _ = detector.detectMarkers(to_gray(image))
    ids = np.zeros(0, int) if ids is None else np.asarray(ids).reshape(-1)
    opencv = 4 * len(np.unique(ids[(ids >= 0) & (ids < n)]))
    return Detection(detect_aprilgrid(image, tags), opencv)


def detect_aprilgrid(image: np.ndarray, tags: tuple[int, int]) -> Features:
    """The corners of the AprilGrid's tags found (any subset; tag ids beyond the grid's
    ``cols * rows`` are ignored)."""
    n = int(tags[0]) * int(tags[1])
    found = detect_markers(image, dictionary="DICT_APRILTAG_36h11", refine="lines")
    return markers_to_features({k: c for k, c in found.items() if 0 <= k < n})
