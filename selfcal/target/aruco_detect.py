"""ArUco marker detection with sub-pixel corners (OpenCV ``cv2.aruco.ArucoDetector``).

Corners are returned in the OpenCV pixel convention (x right, y down, pixel centres at integers)
and in cv2.aruco's order (top-left, top-right, bottom-right, bottom-left of the upright marker),
matching ``selfcal.sim.markers.MarkerField.corners_world``.

Refinement methods (measured on rendered views 0.25-0.4 m from the field, 136 corners, markers
30-90 px wide; error = detection - analytic projection, see tests/integration/test_projection.py):

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
from collections.abc import Mapping
from functools import lru_cache

import cv2
import numpy as np

from selfcal.errors import InputError, SelfCalWarning
from selfcal.target.marker_sides import (
    MAX_LEVEL_DROP,
    MAX_SIDE_SPREAD,
    corner_sigma,
    fit_lines,
    sides_clean,
)

__all__ = [
    "detect_markers",
    "detect_markers_noise",
    "aruco_dictionary",
    "to_gray",
    "REFINE_METHODS",
    "make_detector",
    "refine_corners_lines",
    "refine_corners_lines_batch",
    "DuplicateMarkerWarning",
    "foreshortening",
    "MIN_ASPECT",
    "MAX_LEVEL_DROP",
    "MAX_SIDE_SPREAD",
    "REFINE_PASSES",
]

REFINE_METHODS = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
    "lines": cv2.aruco.CORNER_REFINE_SUBPIX,  # + edge-line refinement, see module docstring
}


class DuplicateMarkerWarning(SelfCalWarning):
    """An image showed the same marker id more than once; those detections were dropped."""


def aruco_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The predefined cv2.aruco dictionary ``name`` (e.g. ``DICT_5X5_100``); ``ValueError``
    naming the valid ones otherwise."""
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        valid = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
        raise InputError(f"unknown ArUco dictionary {name!r}; choose one of {valid}")
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
        raise InputError(f"unknown refine method {refine!r}; choose one of {list(REFINE_METHODS)}")
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = REFINE_METHODS[refine]
    p.cornerRefinementWinSize = 3
    p.relativeCornerRefinmentWinSize = 0.5
    p.cornerRefinementMaxIterations = 100
    p.cornerRefinementMinAccuracy = 0.001
    return cv2.aruco.ArucoDetector(aruco_dictionary(dictionary), p)


def to_gray(image: np.ndarray) -> np.ndarray:
    """A uint8 RGB (H, W, 3), (H, W, 1) or gray (H, W) image as gray (H, W); ``ValueError``
    otherwise."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise InputError(f"image must be uint8, got {img.dtype}; convert with np.clip(...).astype")
    if img.ndim == 2:
        return img
    if img.ndim == 3 and img.shape[2] == 3:
        return cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    if img.ndim == 3 and img.shape[2] == 1:
        return img[:, :, 0]
    raise InputError(f"image must be (H, W) gray or (H, W, 3) RGB, got shape {img.shape}")


def refine_corners_lines(
    gray: np.ndarray, corners: np.ndarray, n_modules: int, min_contrast: float = 20.0
) -> np.ndarray | None:
    """Re-estimate the 4 corners (4, 2) of one marker's black square from its straight sides.

    ``n_modules``: modules across the black square (6 for 4x4 dictionaries); sets the width of
    the profile across each edge (0.45 module, clamped to 1.5-6 px, inside the black border and
    the white quiet zone). Returns ``None`` if a side has too few usable profiles (contrast below
    ``min_contrast`` grey levels), or the result moved more than 2 px from ``corners``.
    (One marker of :func:`refine_corners_lines_batch`.)
    """
    c = np.asarray(corners, dtype=float).reshape(1, 4, 2)
    out = refine_corners_lines_batch(gray, c, n_modules, min_contrast)[0]
    return None if np.isnan(out).any() else out


_STEP = 0.25  # px between samples across an edge

REFINE_PASSES = 2
"""Line refinements in a row: the first samples its edge profiles across the sides through the
``subpix`` corners, which can be 0.1-0.5 px off on small or oblique markers, so the profile
window is off-centre on the edge and the blur it cuts off biases the edge estimate; the second
pass centres the profiles on the first pass's sides (rendered default scenario, noise-free,
``python -m selfcal.studies.diagnose_render``: corner RMS 0.038 -> 0.027 px with the side screening
unchanged; a third pass changes nothing measurable)."""
_REMAP_WIDTH = 4096  # cv2.remap maps must stay below 32767 px per dimension


def refine_corners_lines_batch(
    gray: np.ndarray,
    corners: np.ndarray,
    n_modules: int,
    min_contrast: float = 20.0,
    *,
    screen: bool = True,
    passes: int | None = None,
) -> np.ndarray:
    """:func:`refine_corners_lines` for all markers of one image at once: ``corners`` (n, 4, 2)
    -> (n, 4, 2), NaN rows for the markers it would return ``None`` for. All edge profiles of
    all markers are sampled by one ``cv2.remap`` and the lines are fitted together.
    ``screen=False`` skips the occlusion checks (:data:`MAX_LEVEL_DROP`,
    :data:`MAX_SIDE_SPREAD`). ``passes``: refinements in a row, each centring its edge profiles
    on the previous one's sides (None: :data:`REFINE_PASSES`)."""
    p = REFINE_PASSES if passes is None else passes
    return _refine_batch(gray, corners, n_modules, min_contrast, screen, p)[0]


def _refine_batch(
    gray: np.ndarray,
    corners: np.ndarray,
    n_modules: int,
    min_contrast: float,
    screen: bool,
    passes: int,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine_corners_lines_batch` and the corners' predicted noise (n,) px per coordinate
    of the last pass (:func:`corner_sigma`; NaN where the refinement failed)."""
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    g = gray if gray.dtype == np.float32 else gray.astype(np.float32)
    cur = c.copy()
    sigma = np.full(len(c), np.nan)
    n_pass = max(int(passes), 1)
    for k in range(n_pass):
        ok = ~np.isnan(cur).any(axis=(1, 2))  # a pass's sigma is kept only from the last one
        cur[ok], sigma[ok] = _refine_pass(g, cur[ok], n_modules, min_contrast, screen,
                                          noise=k == n_pass - 1)  # fmt: skip
    bad = ~(np.abs(cur - c).max(axis=(1, 2)) <= 2.0)  # moved too far (or failed)
    cur[bad], sigma[bad] = np.nan, np.nan
    return cur, sigma


def _refine_pass(
    g: np.ndarray,
    corners: np.ndarray,
    n_modules: int,
    min_contrast: float,
    screen: bool,
    noise: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """One pass of :func:`refine_corners_lines_batch`: edge profiles across the sides of
    ``corners`` (n, 4, 2) in the float32 image ``g``, lines fitted, corners intersected;
    NaN rows for markers that fail (or moved more than 2 px). Also the corners' predicted
    noise (n,) px (:func:`corner_sigma`; with ``noise=False`` NaN: a pass before the last)."""
    c = corners
    n = len(c)
    out = np.full((n, 4, 2), np.nan)
    if n == 0:
        return out, np.zeros(0)
    centre = c.mean(axis=1)  # (n, 2)
    a = c  # side k runs from corner k to corner k+1
    b = np.roll(c, -1, axis=1)
    seg = b - a  # (n, 4, 2)
    length = np.linalg.norm(seg, axis=2)  # (n, 4)
    side = length.mean(axis=1)
    half_w = np.clip(0.45 * side / n_modules, 1.5, 6.0)  # (n,)
    n_off = np.round(2 * half_w / _STEP).astype(int)  # (n,)
    n_end = np.maximum(1, n_off // 5)
    good = (length >= 4.0).all(axis=1)
    t = seg / np.where(length > 0, length, 1.0)[..., None]
    nrm = np.stack([-t[..., 1], t[..., 0]], axis=2)
    flip = np.einsum("nkj,nkj->nk", nrm, (a + b) / 2 - centre[:, None, :]) < 0
    nrm[flip] *= -1.0  # outward: black (inside) -> white (quiet zone)
    # profiles: one row per sample along a side, padded to the widest marker's offsets
    n_s = np.maximum(8, (0.7 * length).astype(int))  # (n, 4)
    n_s[~good] = 0
    prof_side = np.repeat(np.arange(4 * n), n_s.ravel())  # side index (marker * 4 + k)
    if len(prof_side) == 0:
        return out, np.full(n, np.nan)
    first = np.repeat(np.cumsum(n_s.ravel()) - n_s.ravel(), n_s.ravel())
    j = np.arange(len(prof_side)) - first  # sample index along its side
    ns_p = n_s.ravel()[prof_side]
    s_p = 0.15 + 0.7 * j / np.maximum(ns_p - 1, 1)  # == np.linspace(0.15, 0.85, n_s)
    mk = prof_side // 4
    a_p = a.reshape(-1, 2)[prof_side]
    base = a_p + s_p[:, None] * seg.reshape(-1, 2)[prof_side]  # (Np, 2)
    nrm_p = nrm.reshape(-1, 2)[prof_side]
    hw_p = half_w[mk]
    no_p = n_off[mk]
    ne_p = n_end[mk]
    width = int(n_off.max())
    col = np.arange(width)
    offs = -hw_p[:, None] + _STEP / 2 + _STEP * col[None, :]  # (Np, width)
    total = len(offs) * width
    rows = -(-total // _REMAP_WIDTH)
    grid = np.empty((rows * _REMAP_WIDTH, 2), np.float32)
    grid[total:] = 0.0
    # the sample points base + offs * nrm, x and y each as one (Np, width) product in float64
    # rounded to float32 in the map (a broadcast over the last axis of two is several times
    # slower: numpy's inner loop would run over two elements)
    pts = grid[:total].reshape(-1, width, 2)
    for k in range(2):
        xy = offs * nrm_p[:, k, None]
        xy += base[:, k, None]
        pts[..., k] = xy
    maps = grid.reshape(rows, _REMAP_WIDTH, 2)
    prof = cv2.remap(
        g, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    prof = prof.reshape(-1)[:total].reshape(-1, width).astype(np.float64)
    inside = col[None, :] < no_p[:, None]
    outside = ~inside
    prof[outside] = 0.0
    cs = np.cumsum(prof, axis=1)
    r_idx = np.arange(len(prof))
    black = cs[r_idx, ne_p - 1] / ne_p
    white = (cs[r_idx, no_p - 1] - cs[r_idx, no_p - 1 - ne_p]) / ne_p
    contrast = white - black
    frac_black = white[:, None] - prof  # in place below: the same values, fewer arrays
    frac_black /= np.maximum(contrast, 1e-6)[:, None]
    np.clip(frac_black, -0.5, 1.5, out=frac_black)
    frac_black[outside] = 0.0
    edge = -hw_p + _STEP * frac_black.sum(axis=1)  # any symmetric blur
    P = base + edge[:, None] * nrm_p  # (Np, 2)
    # pad the edge points into (sides, max samples) for the line fits
    S = 4 * n
    max_s = int(n_s.max())
    Ppad = np.zeros((S, max_s, 2))
    valid = np.zeros((S, max_s), bool)
    Ppad[prof_side, j] = P
    valid[prof_side, j] = contrast > min_contrast
    n_line, d_line, ok, kept = fit_lines(Ppad, valid)
    ok = ok.reshape(n, 4) & good[:, None]
    if screen:  # occluded or bordered by a foreign edge: see MAX_LEVEL_DROP
        ok &= sides_clean(prof_side, j, white, black, valid, n_s)
    n_line = n_line.reshape(n, 4, 2)
    d_line = d_line.reshape(n, 4)
    # corner k = side k-1 (ends at corner k) x side k (starts at corner k)
    n1, d1 = np.roll(n_line, 1, axis=1), np.roll(d_line, 1, axis=1)
    det = n1[..., 0] * n_line[..., 1] - n1[..., 1] * n_line[..., 0]
    ok_all = ok.all(axis=1) & (np.abs(det) >= 1e-6).all(axis=1)
    dsafe = np.where(np.abs(det) >= 1e-6, det, 1.0)
    x = (d1 * n_line[..., 1] - n1[..., 1] * d_line) / dsafe
    y = (n1[..., 0] * d_line - d1 * n_line[..., 0]) / dsafe
    res = np.stack([x, y], axis=2)
    ok_all &= np.abs(res - c).max(axis=(1, 2)) <= 2.0
    out[ok_all] = res[ok_all]
    sigma = np.full(n, np.nan)
    if noise:
        sigma[ok_all] = corner_sigma(Ppad, kept, n_line, res)[ok_all]
    return out, sigma


MIN_ASPECT = 0.5
"""Smallest foreshortening (:func:`foreshortening`) of a marker kept by ``refine="lines"``:
markers seen more obliquely than about 60 deg border their support's dark side and blur
anisotropically; on the rendered default scenario they carried most of the remaining corner
error (``python -m selfcal.studies.diagnose_render``: RMS 0.071 -> 0.038 px, 4 % of the detections)."""


def foreshortening(corners: np.ndarray) -> np.ndarray:
    """(n,) ratio of the shorter to the longer pair of opposite sides of quadrilaterals
    ``corners`` (n, 4, 2) px: 1 for a square seen head-on, about cos(viewing angle) for an
    oblique one (NaN corners give NaN)."""
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    L = np.linalg.norm(c - np.roll(c, -1, axis=1), axis=2)
    a, b = L[:, 0] + L[:, 2], L[:, 1] + L[:, 3]
    return np.minimum(a, b) / np.maximum(a, b)


def detect_markers(
    image: np.ndarray,
    dictionary: str = "DICT_4X4_50",
    refine: str = "lines",
    *,
    screen: bool = True,
    passes: int | None = None,
) -> dict[int, np.ndarray]:
    """Detect ArUco markers in an RGB (H, W, 3) or gray (H, W) uint8 image.

    Returns ``{id: corners}`` with corners (4, 2) float64 in OpenCV pixel coordinates, cv2.aruco
    order. An image without markers gives ``{}``. An id seen more than once is dropped entirely
    with a :class:`DuplicateMarkerWarning` (we never guess which detection is right). With
    ``refine="lines"`` a marker whose sides cannot be fitted (too little contrast anywhere
    along a side, an uneven quiet zone or border, a side bordered by a foreign surface:
    occluded, see :data:`MAX_LEVEL_DROP` and :data:`MAX_SIDE_SPREAD`) or that is seen too
    obliquely (:data:`MIN_ASPECT`) is dropped rather than returned with less accurate corners;
    ``screen=False`` keeps the occluded and oblique ones; ``passes`` (None:
    :data:`REFINE_PASSES`) the line refinements in a row (``screen=False, passes=1`` is the
    detector before issue #14, for ``selfcal/studies/diagnose_render.py``'s comparison).
    Raises ``ValueError`` for a bad image, dictionary or refine method.
    """
    return detect_markers_noise(image, dictionary, refine, screen=screen, passes=passes)[0]


def detect_markers_noise(
    image: np.ndarray,
    dictionary: str = "DICT_4X4_50",
    refine: str = "lines",
    *,
    screen: bool = True,
    passes: int | None = None,
    start: Mapping[int, np.ndarray] | None = None,
) -> tuple[dict[int, np.ndarray], dict[int, float]]:
    """:func:`detect_markers` and the detector's own noise estimate of every marker's corners:
    ``{id: sigma}`` px per coordinate, from the scatter of its sides' edge points about their
    fitted lines (``refine="lines"``; other methods: an empty dict). A bias that shifts a whole
    side does not enter it (docs/accuracy.md, "The bound's pixel sigma").

    ``start``: corners (4, 2) px in this image, by marker id, known from elsewhere (another
    detection of the same view: the image before undistortion, mapped through the lens). A
    detected marker of ``start`` whose line refinement from the detector's ``subpix`` corners
    fails is refined again from them (``refine="lines"``): on small oblique markers in a
    resampled image ``subpix`` can be 1.5 - 3 px off, the refinement then moves more than 2 px
    and the marker was lost (rendered scenarios/mono.toml, frame 29: two of its three markers,
    the frame unregistered). Markers that refine from their own corners are not touched."""
    gray = to_gray(image)
    corners, ids, _rejected = make_detector(dictionary, refine).detectMarkers(gray)
    if ids is None or len(ids) == 0:
        return {}, {}
    ids = np.asarray(ids).reshape(-1)
    uniq, counts = np.unique(ids, return_counts=True)
    dups = set(uniq[counts > 1].tolist())
    if dups:
        warnings.warn(
            f"marker ids {sorted(dups)} detected more than once in one image; dropped them",
            DuplicateMarkerWarning,
            stacklevel=3,
        )
    keep = [k for k, i in enumerate(ids.tolist()) if i not in dups]
    c = np.asarray([corners[k] for k in keep], dtype=np.float64).reshape(-1, 4, 2)
    sigma = np.full(len(c), np.nan)
    if refine == "lines":
        n_modules = int(aruco_dictionary(dictionary).markerSize) + 2
        p = REFINE_PASSES if passes is None else passes
        raw = c
        c, sigma = _refine_batch(gray, raw, n_modules, 20.0, screen, p)
        kept_ids = ids[keep]
        again = [k for k in np.flatnonzero(np.isnan(c).any(axis=(1, 2)))
                 if start is not None and int(kept_ids[k]) in start]  # fmt: skip
        if again:
            s0 = np.asarray([start[int(kept_ids[k])] for k in again], dtype=np.float64)  # type: ignore[index]
            c[again], sigma[again] = _refine_batch(gray, s0.reshape(-1, 4, 2), n_modules, 20.0,
                                                   screen, p)  # fmt: skip
        if screen:
            c[foreshortening(c) < MIN_ASPECT] = np.nan
    found = {int(ids[k]): ck for k, ck in zip(keep, c, strict=True) if not np.isnan(ck).any()}
    noise = {
        int(ids[k]): float(sk)
        for k, ck, sk in zip(keep, c, sigma, strict=True)
        if not np.isnan(ck).any() and np.isfinite(sk)
    }
    return found, noise
