"""Epipolar geometry between views: fundamental matrices, their noise level, parallax test.

Two-view by nature: every function here works on pairs of views (a pair may be the two cameras of
one frame -- for the stereo rig the left/right pair -- or two frames). Pixels follow the OpenCV
convention; ``x_b^T F x_a = 0``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from selfcal.errors import InputError
from selfcal.estimation.observations import Observations, ViewLayout
from selfcal.estimation.selfcal_errors import InsufficientDataError
from selfcal.threads import helper_threads

__all__ = ["PairEstimate", "fundamental_pairs", "epipolar_sigma", "robust_cv"]


MIN_SHARED = 16
"""Points two views must share for their fundamental matrix (:func:`fundamental_pairs`' default):
a view that shares fewer with every other is not registered by the field route's first pass."""


@dataclass
class PairEstimate:
    """Epipolar geometry of views ``view_a``, ``view_b``: ``x_b^T F x_a = 0`` (pixels).

    ``pidx`` are the shared point indices (into ``Observations.point_index()[0]``), ``inlier``
    the RANSAC inliers among them, ``n_h_inliers`` how many a homography explains equally well;
    ``homography_like`` pairs (no usable parallax: pure rotation or planar points) carry no
    information on ``fx`` and are not used for it.
    """

    view_a: int
    view_b: int
    pidx: np.ndarray
    F: np.ndarray
    inlier: np.ndarray
    n_h_inliers: int
    homography_like: bool
    sampson_px: np.ndarray

    @property
    def n_inliers(self) -> int:
        return int(self.inlier.sum())


def _sampson(F: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    x1 = np.c_[p1, np.ones(len(p1))]
    x2 = np.c_[p2, np.ones(len(p2))]
    Fx1 = x1 @ F.T
    Ftx2 = x2 @ F
    num = np.einsum("ij,ij->i", x2, Fx1)
    den = Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2
    return np.abs(num) / np.sqrt(np.maximum(den, 1e-300))


def _transfer(H: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    x1 = np.c_[p1, np.ones(len(p1))] @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.linalg.norm(x1[:, :2] / x1[:, 2:3] - p2, axis=1)
    return np.where(np.isfinite(d), d, np.inf)


def uv_table(obs: Observations, pidx: np.ndarray, n_points: int) -> np.ndarray:
    """(V, n_points, 2) pixel coordinates of each point index in each view (NaN: not seen)."""
    table = np.full((obs.n_views, n_points, 2), np.nan)
    table[obs.view, pidx] = obs.uv
    return table


def fundamental_pairs(
    obs: Observations,
    *,
    min_shared: int = MIN_SHARED,
    max_pairs: int = 150,
    max_rig_pairs: int = 10,
    ransac_px: float = 3.0,
    seed: int = 0,
) -> list[PairEstimate]:
    """Fundamental matrices (cv2 USAC MAGSAC++) for view pairs sharing ``>= min_shared`` points.

    Up to ``max_rig_pairs`` pairs of two cameras of one frame (the stereo rig's left/right
    pairs) plus up to ``max_pairs`` other pairs (random, reproducible with ``seed``; above
    :data:`DENSE_VIEWS` views drawn without counting every pair's shared points) are
    estimated; a homography is fitted to the same points and pairs it explains (>= 90 % of the
    F inliers within ``ransac_px``) are flagged ``homography_like``. The pairs are estimated on
    two threads where there are two cores (:func:`_pair_estimate`, the same results). Raises
    :class:`InsufficientDataError` if no pair qualifies.
    """
    if min_shared < 8:
        raise InputError("min_shared must be >= 8 (eight-point algorithm)")
    _, pidx = obs.point_index()
    n_points = int(pidx.max()) + 1 if len(pidx) else 0
    table = uv_table(obs, pidx, n_points)
    vis = ~np.isnan(table[..., 0])
    rng = np.random.default_rng(seed)
    if obs.n_views <= DENSE_VIEWS:
        iu, ju, best = _all_pairs(vis, min_shared)
    else:
        iu, ju, best = _sampled_pairs(vis, obs.layout, min_shared, max_pairs, rng)
    if len(iu) == 0:
        raise InsufficientDataError(
            f"no pair of views shares >= {min_shared} marker corners (best pair: {best}); "
            "take views that overlap more (each view should see several markers also seen in "
            "other views) or add markers"
        )
    rig = obs.layout.same_frame(iu, ju)
    rig_sel = np.flatnonzero(rig)
    if len(rig_sel) > max_rig_pairs:
        rig_sel = rig_sel[np.linspace(0, len(rig_sel) - 1, max_rig_pairs).round().astype(int)]
    other = np.flatnonzero(~rig)
    if len(other) > max_pairs:
        other = np.sort(rng.choice(other, max_pairs, replace=False))
    chosen = [(int(iu[s]), int(ju[s])) for s in np.concatenate([rig_sel, other])]

    def estimate(pair: tuple[int, int]) -> PairEstimate | None:
        return _pair_estimate(table, vis, pair[0], pair[1], ransac_px)

    # OpenCV's estimators release the GIL: the pairs go to two threads (issue 32: this loop was
    # 15 % of `selfcal run`'s calibration CPU, on one core while the other idled; two, not every
    # core: a parallel study's worker processes each calibrate). A pair's estimate does not
    # depend on the thread or the order: the same pairs in the same order as one by one.
    workers = helper_threads(len(chosen), cap=2)
    if workers > 1:
        with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="epipolar") as pool:
            found = list(pool.map(estimate, chosen))
    else:
        found = [estimate(pair) for pair in chosen]
    out = [p for p in found if p is not None]
    if not out:
        raise InsufficientDataError(
            "no fundamental matrix could be estimated from the view pairs; check the "
            "correspondences (ids consistent across views?) and the pixel noise"
        )
    return out


def _pair_estimate(
    table: np.ndarray, vis: np.ndarray, a: int, b: int, ransac_px: float
) -> PairEstimate | None:
    """The epipolar estimate of views ``a`` and ``b`` from their shared points (``table``,
    ``vis``: :func:`uv_table` and its visibility), or None where OpenCV finds no fundamental
    matrix or it has fewer than 8 inliers (one pair of :func:`fundamental_pairs`)."""
    common = np.flatnonzero(vis[a] & vis[b])
    p1, p2 = table[a, common], table[b, common]
    F = robust_cv(cv2.findFundamentalMat, p1, p2, cv2.USAC_MAGSAC, ransac_px, 0.9999, 10000)
    if F is None or F.shape != (3, 3):
        return None
    F = F / np.linalg.norm(F)
    d = _sampson(F, p1, p2)
    inl = d < ransac_px
    if inl.sum() < 8:
        return None
    H = robust_cv(
        cv2.findHomography,
        p1,
        p2,
        cv2.USAC_MAGSAC,
        ransac_px,
        maxIters=10000,
        confidence=0.9999,
    )
    n_h = int((_transfer(H, p1, p2) < ransac_px).sum()) if H is not None else 0
    return PairEstimate(a, b, common, F, inl, n_h, bool(n_h >= 0.9 * inl.sum()), d)


DENSE_VIEWS = 1000
"""Up to this many views every pair's shared points are counted (a views x views table); above,
the pairs of different frames are drawn at random (:func:`_sampled_pairs`), so that the cost
stays linear in the views."""


def _all_pairs(vis: np.ndarray, min_shared: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Every view pair ``(a < b)`` sharing ``>= min_shared`` points (row-major order) from the
    visibility table ``vis`` (V, P), and the most points any pair shares."""
    # counted by a BLAS product of floats, exact (float32 below 2^24 points): an integer
    # product is not BLAS and took several times as long at 600 views
    vf = vis.astype(np.float32 if vis.shape[1] < 2**24 else np.float64)
    shared = vf @ vf.T
    iu, ju = np.triu_indices(len(vis), 1)
    s = shared[iu, ju].astype(np.int64)  # the pairs only: the whole table stays float
    ok = s >= min_shared
    return iu[ok], ju[ok], int(np.max(s, initial=0))


def _sampled_pairs(
    vis: np.ndarray, layout: ViewLayout, min_shared: int, max_pairs: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, int]:
    """As :func:`_all_pairs` for the pairs of one frame's cameras (every one), and for the pairs
    of different frames up to ``max_pairs`` drawn uniformly among those that qualify (by drawing
    pairs at random and keeping the ones that do; fewer when fewer than one draw in ~100
    qualifies). Sorted like :func:`_all_pairs`."""
    n_cam = layout.n_cameras
    ca, cb = np.triu_indices(n_cam, 1)
    frames = np.arange(layout.n_frames)
    a = np.ravel(layout.view(frames[:, None], ca[None]))
    b = np.ravel(layout.view(frames[:, None], cb[None]))
    found: set[int] = set()
    best = 0
    V = len(vis)
    for _ in range(100):
        if len(found) >= max_pairs or V < n_cam + 1:
            break
        x, y = rng.integers(0, V, (2, 2 * max_pairs))
        x, y = np.minimum(x, y), np.maximum(x, y)
        diff = ~layout.same_frame(x, y)
        x, y = x[diff], y[diff]
        s = np.count_nonzero(vis[x] & vis[y], axis=1)
        best = max(best, int(np.max(s, initial=0)))
        for key in (x * V + y)[s >= min_shared]:
            if len(found) < max_pairs:
                found.add(int(key))
    key = np.array(sorted(found), dtype=np.int64)
    s = np.count_nonzero(vis[a] & vis[b], axis=1)
    best = max(best, int(np.max(s, initial=0)))
    ok = s >= min_shared
    iu = np.concatenate([a[ok], key // V])
    ju = np.concatenate([b[ok], key % V])
    order = np.lexsort((ju, iu))
    return iu[order], ju[order], best


def robust_cv(fn, *args, **kw):
    """First output of an OpenCV robust estimator, or None where it fails: OpenCV 5's USAC can
    raise (e.g. ``!model.empty()``) on a degenerate sample instead of returning no model; for
    one view pair that only means "no estimate from this pair"."""
    try:
        return fn(*args, **kw)[0]
    except cv2.error:
        return None


def epipolar_sigma(pairs: list[PairEstimate]) -> float:
    """Pixel noise (per coordinate) from the Sampson distances of all shared points of the
    pairs: robust (median) over points, corrected for the 7 dof fitted per F."""
    vals = []
    for p in pairs:
        n = len(p.sampson_px)
        vals.append(p.sampson_px * np.sqrt(n / max(n - 7, 1)))
    return float(np.median(np.concatenate(vals)) / 0.6745)
