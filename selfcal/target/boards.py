"""Printed boards of known geometry: chessboard, ChArUco, asymmetric circle grid, AprilGrid.

Board frame (m): the board's plane is ``z = 0``, ``x`` runs along its columns (to the right on
the printed page), ``y`` along its rows (down the page), so ``z`` points into the board and a
camera that sees the printed side sees the board's ``x``/``y`` as image ``x``/``y`` up to a
rotation (the same frame as OpenCV's board objects).

Feature ids (the same in every image):

- chessboard and ChArUco: inner corner at column ``c``, row ``r`` (``inner_corners = (cols,
  rows)``) is feature ``r * cols + c`` at ``((c + 1) s, (r + 1) s, 0)`` for square ``s`` (OpenCV's
  ChArUco corner ids and ``CharucoBoard.getChessboardCorners``);
- asymmetric circle grid (``pattern = (cols, rows)``, circles per row, rows): circle ``j`` of row
  ``i`` is feature ``i * cols + j`` at ``((2 j + i mod 2) s, i s, 0)`` for ``spacing`` ``s``
  (OpenCV's ``CALIB_CB_ASYMMETRIC_GRID`` layout: ``s`` is the row pitch and half the pitch along a
  row);
- AprilGrid (``tags = (cols, rows)`` AprilTag 36h11 tags of side ``tag``, gaps ``spacing_ratio *
  tag``, Kalibr's layout without its corner squares): corner ``k`` of tag ``t`` is feature ``4 t +
  k`` (:func:`selfcal.target.aruco.feature_id`, cv2.aruco corner order), tag 0 top-left, row-major.

Board images (:meth:`Board.image`) come from OpenCV's generators where OpenCV has one
(``cv2.aruco.CharucoBoard.generateImage``, ``cv2.aruco.GridBoard.generateImage``) and are drawn
with OpenCV primitives otherwise; :class:`BoardImage` says which part of the board frame the
image covers, so it can be printed, warped or used as a texture with exact geometry.
Detection is in :mod:`selfcal.target.board_detect`.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from selfcal.target.aruco import marker_features
from selfcal.target.aruco_detect import aruco_dictionary
from selfcal.target.base import Features, Target
from selfcal.target.board_detect import (
    Detection,
    aprilgrid_detection,
    charuco_detection,
    chessboard_detection,
    circles_detection,
    detect_aprilgrid,
    detect_charuco,
    detect_chessboard,
    detect_circles,
)

__all__ = [
    "Board",
    "BoardImage",
    "Chessboard",
    "Charuco",
    "CirclesGrid",
    "AprilGrid",
    "APRILGRID_DICTIONARY",
]

APRILGRID_DICTIONARY = "DICT_APRILTAG_36h11"


@dataclass(frozen=True)
class BoardImage:
    """A generated board image: ``pixels`` (H, W) uint8 (black on white) covering the rectangle
    ``extent_m = (x0, y0, x1, y1)`` of the board frame (m) with its outer pixel edges, i.e. pixel
    centre ``(u, v)`` (OpenCV) shows the board point ``(x0 + (u + 0.5) / ppm, y0 + (v + 0.5) /
    ppm)`` with ``ppm = W / (x1 - x0) = H / (y1 - y0)`` px/m."""

    pixels: np.ndarray
    extent_m: tuple[float, float, float, float]

    @property
    def px_per_m(self) -> float:
        """Pixels per metre of the board (the same along x and y)."""
        return self.pixels.shape[1] / (self.extent_m[2] - self.extent_m[0])

    def board_to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Image pixels (..., 2) of board points ``xy`` (..., 2) (m)."""
        xy = np.asarray(xy, dtype=float)
        return (xy - np.array(self.extent_m[:2])) * self.px_per_m - 0.5


class Board(Target):
    """A planar target of known geometry (see the module docstring). Subclasses give the
    feature layout (:meth:`layout`), the detector and the image generator."""

    source: str  # where the board was declared (a target TOML), for messages

    @abstractmethod
    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        """All features: ids (n,) int and positions (n, 3) m in the board frame."""

    @abstractmethod
    def image(self, px_per_mm: float = 8.0, margin_mm: float | None = None) -> BoardImage:
        """The printed board at about ``px_per_mm`` (rounded so that the board's squares, tags
        or circle pitch are whole pixels) with a white quiet zone ``margin_mm`` around it
        (default: one square, tag or pitch)."""

    @property
    def min_features(self) -> int:
        """Fewest features a view needs to be used (a homography needs 4; fewer than this many
        usually means a misdetection)."""
        return 6

    @property
    def whole_grid(self) -> bool:
        """True when the detector finds every feature of the board or none (a chessboard, a
        circles grid), False when it finds any subset (ChArUco, AprilGrid)."""
        return False

    def detection(self, image: np.ndarray) -> Detection:
        """:meth:`detect` with how many features OpenCV's detector found before the project's
        checks and why they refused them (:class:`selfcal.target.board_detect.Detection`); every
        board overrides it with OpenCV's own detector's count (this default counts the
        project's)."""
        found = self.detect(image)
        return Detection(found, len(found))

    @cached_property
    def _lookup(self) -> dict[int, int]:
        ids, _ = self.layout()
        return {int(i): k for k, i in enumerate(ids)}

    @property
    def n_features(self) -> int:
        return len(self.layout()[0])

    def points(self, ids: np.ndarray) -> np.ndarray:
        """Positions (k, 3) m of features ``ids`` (k,) in the board frame; NaN for ids that
        are not on this board."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        _, pts = self.layout()
        out = np.full((len(ids), 3), np.nan)
        for k, i in enumerate(ids.tolist()):
            j = self._lookup.get(i)
            if j is not None:
                out[k] = pts[j]
        return out

    def describe(self) -> str:
        """One line naming the board and where it was declared."""
        return (
            f"{type(self).__name__.lower()} target{' from ' + self.source if self.source else ''}"
        )


def _ppm(pitch_mm: float, px_per_mm: float) -> tuple[int, float]:
    """Whole pixels per ``pitch_mm`` near ``px_per_mm`` and the exact px/m that gives."""
    pitch_px = max(4, int(round(pitch_mm * px_per_mm)))
    return pitch_px, pitch_px / (pitch_mm / 1000.0)


def _grid(cols: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Row-major (column, row) indices of a cols x rows grid."""
    r, c = np.divmod(np.arange(cols * rows), cols)
    return c, r


@dataclass(frozen=True)
class Chessboard(Board):
    """A chessboard of ``inner_corners = (cols, rows)`` inner corners and square side
    ``square_m``; the outer square at the board origin is black. One of ``cols``, ``rows``
    must be odd and the other even, so the printed pattern fixes its own orientation."""

    inner_corners: tuple[int, int]
    square_m: float
    source: str = ""

    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        cols, rows = self.inner_corners
        c, r = _grid(cols, rows)
        pts = np.stack([(c + 1) * self.square_m, (r + 1) * self.square_m, 0.0 * c], axis=1)
        return np.arange(cols * rows), pts

    @property
    def squares(self) -> tuple[int, int]:
        """Squares along x and y (inner corners + 1)."""
        return self.inner_corners[0] + 1, self.inner_corners[1] + 1

    def image(self, px_per_mm: float = 8.0, margin_mm: float | None = None) -> BoardImage:
        sq_px, ppm = _ppm(self.square_m * 1000.0, px_per_mm)
        m_px = int(round((self.square_m if margin_mm is None else margin_mm / 1000.0) * ppm))
        sx, sy = self.squares
        img = np.full((sy * sq_px + 2 * m_px, sx * sq_px + 2 * m_px), 255, np.uint8)
        for j in range(sy):
            for i in range(sx):
                if (i + j) % 2 == 0:
                    y0, x0 = m_px + j * sq_px, m_px + i * sq_px
                    img[y0 : y0 + sq_px, x0 : x0 + sq_px] = 0
        return _image(img, m_px, ppm)

    @property
    def whole_grid(self) -> bool:
        return True  # detect_chessboard: all inner corners or none

    def detect(self, image: np.ndarray) -> Features:
        return detect_chessboard(image, self.inner_corners)

    def detection(self, image: np.ndarray) -> Detection:
        return chessboard_detection(image, self.inner_corners)


@dataclass(frozen=True)
class Charuco(Board):
    """A ChArUco board (``cv2.aruco.CharucoBoard``) of ``inner_corners = (cols, rows)`` (squares
    ``cols + 1`` by ``rows + 1``), square side ``square_m``, marker side ``marker_m`` and ArUco
    ``dictionary``. Partial views are used: every corner carries its id."""

    inner_corners: tuple[int, int]
    square_m: float
    marker_m: float
    dictionary: str = "DICT_5X5_100"
    source: str = ""

    def cv_board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV board object (new, non-legacy pattern)."""
        cols, rows = self.inner_corners
        return cv2.aruco.CharucoBoard(
            (cols + 1, rows + 1), self.square_m, self.marker_m, aruco_dictionary(self.dictionary)
        )

    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        pts = np.asarray(self.cv_board().getChessboardCorners(), dtype=float).reshape(-1, 3)
        return np.arange(len(pts)), pts

    @property
    def min_features(self) -> int:
        return 6

    def image(self, px_per_mm: float = 8.0, margin_mm: float | None = None) -> BoardImage:
        sq_px, ppm = _ppm(self.square_m * 1000.0, px_per_mm)
        m_px = int(round((self.square_m if margin_mm is None else margin_mm / 1000.0) * ppm))
        cols, rows = self.inner_corners
        size = ((cols + 1) * sq_px + 2 * m_px, (rows + 1) * sq_px + 2 * m_px)
        img = self.cv_board().generateImage(size, marginSize=m_px, borderBits=1)
        return _image(img, m_px, ppm)

    def detect(self, image: np.ndarray) -> Features:
        return detect_charuco(image, self.cv_board())

    def detection(self, image: np.ndarray) -> Detection:
        return charuco_detection(image, self.cv_board())


@dataclass(frozen=True)
class CirclesGrid(Board):
    """An asymmetric grid of black circles (OpenCV's ``CALIB_CB_ASYMMETRIC_GRID``):
    ``pattern = (cols, rows)`` circles per row and rows, pitch ``spacing_m`` (module
    docstring), circle diameter ``diameter_m``. Positions are the circles' centres; the detector
    returns blob centres, which differ from the projected centres by the perspective bias of a
    circle (sub-pixel for small circles)."""

    pattern: tuple[int, int]
    spacing_m: float
    diameter_m: float
    source: str = ""

    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        cols, rows = self.pattern
        j, i = _grid(cols, rows)
        s = self.spacing_m
        pts = np.stack([(2 * j + i % 2) * s, i * s, 0.0 * j], axis=1)
        return np.arange(cols * rows), pts

    @property
    def min_features(self) -> int:
        return self.n_features  # the detector finds the whole grid or nothing

    @property
    def whole_grid(self) -> bool:
        return True

    def image(self, px_per_mm: float = 8.0, margin_mm: float | None = None) -> BoardImage:
        s_px, ppm = _ppm(self.spacing_m * 1000.0, px_per_mm)
        r_m = self.diameter_m / 2.0
        m_m = self.spacing_m if margin_mm is None else margin_mm / 1000.0
        off = r_m + m_m  # board origin sits this far inside the image's top-left edge
        cols, rows = self.pattern
        W = int(np.ceil((2 * off + (2 * cols - 1) * self.spacing_m) * ppm))
        H = int(np.ceil((2 * off + (rows - 1) * self.spacing_m) * ppm))
        img = np.full((H, W), 255, np.uint8)
        shift = 4  # sub-pixel centres: 1/16 px
        _, pts = self.layout()
        for x, y, _z in pts:
            u, v = (x + off) * ppm - 0.5, (y + off) * ppm - 0.5
            cv2.circle(
                img,
                (int(round(u * 2**shift)), int(round(v * 2**shift))),
                int(round(r_m * ppm * 2**shift)),
                0,
                thickness=-1,
                lineType=cv2.LINE_AA,
                shift=shift,
            )
        return BoardImage(img, (-off, -off, W / ppm - off, H / ppm - off))

    def detect(self, image: np.ndarray) -> Features:
        return detect_circles(image, self.pattern)

    def detection(self, image: np.ndarray) -> Detection:
        return circles_detection(image, self.pattern)


@dataclass(frozen=True)
class AprilGrid(Board):
    """Kalibr's AprilGrid: ``tags = (cols, rows)`` AprilTag 36h11 tags of side ``tag_m`` (the
    black square, edge to edge) with gaps ``spacing_ratio * tag_m``, drawn by
    ``cv2.aruco.GridBoard``. Partial views are used: every tag corner carries its id."""

    tags: tuple[int, int]
    tag_m: float
    spacing_ratio: float
    source: str = ""

    def cv_board(self) -> cv2.aruco.GridBoard:
        """The OpenCV board object."""
        return cv2.aruco.GridBoard(
            self.tags,
            self.tag_m,
            self.tag_m * self.spacing_ratio,
            aruco_dictionary(APRILGRID_DICTIONARY),
        )

    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        obj = np.asarray(self.cv_board().getObjPoints(), dtype=float).reshape(-1, 4, 3)
        ids = marker_features(np.arange(len(obj)))
        return ids.reshape(-1), obj.reshape(-1, 3)

    def image(self, px_per_mm: float = 8.0, margin_mm: float | None = None) -> BoardImage:
        tag_px, ppm = _ppm(self.tag_m * 1000.0, px_per_mm)
        m_px = int(round((self.tag_m if margin_mm is None else margin_mm / 1000.0) * ppm))
        cols, rows = self.tags
        gap = self.tag_m * self.spacing_ratio
        w = int(round((cols * self.tag_m + (cols - 1) * gap) * ppm))
        h = int(round((rows * self.tag_m + (rows - 1) * gap) * ppm))
        img = self.cv_board().generateImage((w + 2 * m_px, h + 2 * m_px), marginSize=m_px)
        return _image(img, m_px, ppm)

    def detect(self, image: np.ndarray) -> Features:
        return detect_aprilgrid(image, self.tags)

    def detection(self, image: np.ndarray) -> Detection:
        return aprilgrid_detection(image, self.tags)


def _image(img: np.ndarray, margin_px: int, ppm: float) -> BoardImage:
    """A board image whose board origin is ``margin_px`` inside its top-left edge."""
    H, W = img.shape[:2]
    x0 = -margin_px / ppm
    return BoardImage(np.ascontiguousarray(img), (x0, x0, W / ppm + x0, H / ppm + x0))
