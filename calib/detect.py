"""ArUco marker detection with sub-pixel corners (OpenCV ``cv2.aruco.ArucoDetector``).

Corners are returned in the OpenCV pixel convention (x right, y down, pixel centres at integers)
and in cv2.aruco's order (top-left, top-right, bottom-right, bottom-left of the upright marker),
matching ``sim.markers.MarkerField.corners_world``.

Refinement methods (measured on rendered views 0.25-0.4 m from the field, 136 corners, markers
30-90 px wide; error = detection - analytic projection, see tests/test_projection.py):

=========  ========  ==================  ========
method     RMS (px)  mean x, y (px)      max (px)
=========  ========  ==================  ========
none       0.75      -0.03, +0.00        1.5
subpix     0.22      -0.01, -0.00        0.53
contour    0.72      -0.00, -0.00        1.2
apriltag   1.35      +0.27, +0.37        9.8
lines      0.014     +0.001, +0.000      0.07
=========  ========  ==================  ========

On a synthetic marker pasted at integer pixels, ``apriltag`` is off by exactly (+0.5, +0.5) px
(a pixel-corner vs pixel-centre convention) and ``contour``/``none`` return the outer pixel
centres (0.5 px inside along each axis), which explains most of their error above.
``subpix`` (cv2.cornerSubPix) is biased on L-shaped corners: the blurred corner tip pulls the
estimate inwards (about 0.16 px per axis on a 200 px marker). ``lines`` (the default) starts from
the ``subpix`` corners and re-estimates each of the four sides of the black square as a straight
line: at many points along the middle 70 % of a side it integrates the normalised intensity
profile across the edge (an estimate that is exact for any symmetric blur, e.g. anti-aliasing and
bilinear texture filtering), fits a line (with outlier rejection) and intersects adjacent lines.
Straight sides are exact under a pinhole camera; with strong lens distortion undistort first.
"""

from __future__ import annotations

import warnings
from functools import lru_cache

import cv2
import numpy as np

__all__ = [
    "detect_markers",
    "REFINE_METHODS",
    "make_detector",
    "refine_corners_lines",
    "DuplicateMarkerWarning",
]

REFINE_METHODS = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
    "lines": cv2.aruco.CORNER_REFINE_SUBPIX,  # + edge-line refinement, see module docstring
}


class DuplicateMarkerWarning(UserWarning):
    """An image showed the same marker id more than once; those detections were dropped."""


def _dictionary(name: str) -> cv2.aruco.Dictionary:
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        valid = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
        raise ValueError(f"unknown ArUco dictionary {name!r}; choose one of {valid}")
    return cv2.aruco.getPredefinedDictionary(code)


@lru_cache(maxsize=16)
def make_detector(
    dictionary: str = "DICT_4X4_50", refine: str = "subpix"
) -> cv2.aruco.ArucoDetector:
    """A configured (cached) ``cv2.aruco.ArucoDetector``.

    ``refine``: one of ``REFINE_METHODS`` ("lines" configures the detector as "subpix").
    cornerSubPix window: half-size ``min(3, round(0.5 * module size))`` px with 100 iterations /
    0.001 px termination; larger windows reach into the data bits and raise the RMS error
    (0.22 px at this setting vs 0.26 px with half-size 2 and 0.4-2.6 px with half-size >= 4).
    Raises ``ValueError`` for an unknown dictionary or method.
    """
    if refine not in REFINE_METHODS:
        raise ValueError(f"unknown refine method {refine!r}; choose one of {list(REFINE_METHODS)}")
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = REFINE_METHODS[refine]
    p.cornerRefinementWinSize = 3
    p.relativeCornerRefinmentWinSize = 0.5
    p.cornerRefinementMaxIterations = 100
    p.cornerRefinementMinAccuracy = 0.001
    return cv2.aruco.ArucoDetector(_dictionary(dictionary), p)


def _to_gray(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise ValueError(f"image must be uint8, got {img.dtype}; convert with np.clip(...).astype")
    if img.ndim == 2:
        return img
    if img.ndim == 3 and img.shape[2] == 3:
        return cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    if img.ndim == 3 and img.shape[2] == 1:
        return img[:, :, 0]
    raise ValueError(f"image must be (H, W) gray or (H, W, 3) RGB, got shape {img.shape}")


def refine_corners_lines(
    gray: np.ndarray, corners: np.ndarray, n_modules: int, min_contrast: float = 20.0
) -> np.ndarray | None:
    """Re-estimate the 4 corners (4, 2) of one marker's black square from its straight sides.

    ``n_modules``: modules across the black square (6 for 4x4 dictionaries); sets the width of
    the profile across each edge (0.45 module, clamped to 1.5-6 px, inside the black border and
    the white quiet zone). Returns ``None`` if a side has too few usable profiles (contrast below
    ``min_contrast`` grey levels), or the result moved more than 2 px from ``corners``.
    """
    c = np.asarray(corners, dtype=float).reshape(4, 2)
    g = gray if gray.dtype == np.float32 else gray.astype(np.float32)
    centre = c.mean(axis=0)
    side = float(np.mean(np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)))
    half_w = float(np.clip(0.45 * side / n_modules, 1.5, 6.0))
    step = 0.25
    offs = -half_w + step / 2 + step * np.arange(int(round(2 * half_w / step)))
    n_end = max(1, len(offs) // 5)
    lines = []
    for k in range(4):
        a, b = c[k], c[(k + 1) % 4]
        length = float(np.linalg.norm(b - a))
        if length < 4.0:
            return None
        t = (b - a) / length
        nrm = np.array([-t[1], t[0]])
        if nrm @ ((a + b) / 2 - centre) < 0:
            nrm = -nrm  # outward: black (inside) -> white (quiet zone)
        s = np.linspace(0.15, 0.85, max(8, int(0.7 * length)))
        base = a + np.outer(s, b - a)
        pts = (base[:, None, :] + offs[None, :, None] * nrm).astype(np.float32)
        prof = cv2.remap(
            g, pts[..., 0], pts[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        black = prof[:, :n_end].mean(axis=1, keepdims=True)
        white = prof[:, -n_end:].mean(axis=1, keepdims=True)
        contrast = (white - black)[:, 0]
        ok = contrast > min_contrast
        if ok.sum() < 4:
            return None
        frac_black = np.clip((white - prof) / np.maximum(white - black, 1e-6), -0.5, 1.5)
        edge = -half_w + step * frac_black.sum(axis=1)  # exact for any symmetric blur
        P = (base + edge[:, None] * nrm)[ok]
        for _ in range(2):  # total least squares line, then reject outliers and refit
            m = P.mean(axis=0)
            n_line = np.linalg.svd(P - m)[2][1]
            res = (P - m) @ n_line
            mad = 1.4826 * float(np.median(np.abs(res - np.median(res))))
            keep = np.abs(res) <= 3.0 * mad + 0.05
            if keep.sum() < 4:
                return None
            P = P[keep]
        m = P.mean(axis=0)
        n_line = np.linalg.svd(P - m)[2][1]
        lines.append((n_line, float(n_line @ m)))
    out = np.empty((4, 2))
    for k in range(4):  # corner k = side k-1 (ends at corner k) x side k (starts at corner k)
        (n1, d1), (n2, d2) = lines[k - 1], lines[k]
        A = np.array([n1, n2])
        if abs(np.linalg.det(A)) < 1e-6:
            return None
        out[k] = np.linalg.solve(A, [d1, d2])
    if np.abs(out - c).max() > 2.0:
        return None
    return out


def detect_markers(
    image: np.ndarray, dictionary: str = "DICT_4X4_50", refine: str = "lines"
) -> dict[int, np.ndarray]:
    """Detect ArUco markers in an RGB (H, W, 3) or gray (H, W) uint8 image.

    Returns ``{id: corners}`` with corners (4, 2) float64 in OpenCV pixel coordinates, cv2.aruco
    order. An image without markers gives ``{}``. An id seen more than once is dropped entirely
    with a :class:`DuplicateMarkerWarning` (we never guess which detection is right). With
    ``refine="lines"`` a marker whose sides cannot be fitted (too little contrast, occluded
    border) is dropped rather than returned with less accurate corners.
    Raises ``ValueError`` for a bad image, dictionary or refine method.
    """
    gray = _to_gray(image)
    corners, ids, _rejected = make_detector(dictionary, refine).detectMarkers(gray)
    if ids is None or len(ids) == 0:
        return {}
    ids = np.asarray(ids).reshape(-1)
    uniq, counts = np.unique(ids, return_counts=True)
    dups = set(uniq[counts > 1].tolist())
    if dups:
        warnings.warn(
            f"marker ids {sorted(dups)} detected more than once in one image; dropped them",
            DuplicateMarkerWarning,
            stacklevel=2,
        )
    out: dict[int, np.ndarray] = {}
    n_modules = int(_dictionary(dictionary).markerSize) + 2
    for i, c in zip(ids.tolist(), corners, strict=True):
        if i in dups:
            continue
        c = np.asarray(c, dtype=np.float64).reshape(4, 2)
        if refine == "lines":
            c = refine_corners_lines(gray, c, n_modules)
            if c is None:
                continue
        out[int(i)] = c
    return out
