"""Initialisation of the camera self-calibration from the images alone (paper section III.A).

Following Hartley's approach for "an uncalibrated camera with intrinsics of eq. 19":

1. :func:`fundamental_pairs` -- fundamental matrices between pairs of views sharing enough points
   (including left/right pairs of one configuration), with a homography test that flags pairs
   without parallax (pure rotation, planar scene);
2. :func:`focal_from_fundamentals` -- ``fx`` and ``mu`` with the principal point known, by
   minimising the Mendonca-Cipolla cost (the two non-zero singular values of ``E = K^T F K`` must
   be equal): robust (median) 2-D grid search, then a robust refinement; raises
   :class:`DegenerateConfigurationError` when the cost does not determine ``fx`` (e.g. all optical
   axes through one point, parallel axes, pure translation);
3. :func:`initial_reconstruction` -- essential matrix and relative pose of the best pair, two-view
   triangulation, then incremental registration of every other view (PnP + RANSAC against the
   points triangulated so far), triangulation of new points, and bundle adjustments when the
   number of registered views doubles. The result has an arbitrary scale (reference pair baseline
   = 1) and its world frame is the first view of the reference pair.

All functions are pure (numpy in, numpy out); pixel coordinates follow the OpenCV convention.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib.bundle_adjust import (
    DegenerateConfigurationError,
    FreePoses,
    InsufficientDataError,
    bundle_adjust,
    reprojection_residuals,
)
from calib.observations import Observations
from calib.transforms import make_pose

__all__ = [
    "PairEstimate",
    "FocalEstimate",
    "InitialReconstruction",
    "calibration_matrix",
    "fundamental_pairs",
    "essential_residuals",
    "essential_constraint",
    "focal_from_fundamentals",
    "triangulate",
    "robust_triangulate",
    "initial_reconstruction",
    "optical_axes_convergence",
]

_RAYLEIGH_MEDIAN = 1.1774  # median of |r| for 2-D Gaussian noise with unit sigma per axis


def calibration_matrix(fx: float, mu: float, cx: float, cy: float) -> np.ndarray:
    """``K = [[fx, 0, cx], [0, mu fx, cy], [0, 0, 1]]`` (eq. 19 with the principal point)."""
    return np.array([[fx, 0.0, cx], [0.0, mu * fx, cy], [0.0, 0.0, 1.0]])


def _normalise(uv: np.ndarray, fx: float, mu: float, cx: float, cy: float) -> np.ndarray:
    return np.stack([(uv[:, 0] - cx) / fx, (uv[:, 1] - cy) / (mu * fx)], axis=1)


# --------------------------------------------------------------------- fundamental matrices
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


def _uv_table(obs: Observations, pidx: np.ndarray, n_points: int) -> np.ndarray:
    table = np.full((obs.n_views, n_points, 2), np.nan)
    table[obs.view, pidx] = obs.uv
    return table


def fundamental_pairs(
    obs: Observations,
    *,
    min_shared: int = 16,
    max_pairs: int = 150,
    max_rig_pairs: int = 10,
    ransac_px: float = 3.0,
    seed: int = 0,
) -> list[PairEstimate]:
    """Fundamental matrices (cv2 USAC MAGSAC++) for view pairs sharing ``>= min_shared`` points.

    Up to ``max_rig_pairs`` left/right pairs of one configuration plus up to ``max_pairs`` other
    pairs (random, reproducible with ``seed``) are estimated; a homography is fitted to the same
    points and pairs it explains (>= 90 % of the F inliers within ``ransac_px``) are flagged
    ``homography_like``. Raises :class:`InsufficientDataError` if no pair qualifies.
    """
    if min_shared < 8:
        raise ValueError("min_shared must be >= 8 (eight-point algorithm)")
    _, pidx = obs.point_index()
    n_points = int(pidx.max()) + 1 if len(pidx) else 0
    table = _uv_table(obs, pidx, n_points)
    vis = ~np.isnan(table[..., 0])
    shared = vis.astype(np.int32) @ vis.T.astype(np.int32)
    iu, ju = np.triu_indices(obs.n_views, 1)
    ok = shared[iu, ju] >= min_shared
    iu, ju = iu[ok], ju[ok]
    if len(iu) == 0:
        best = int(np.max(shared[np.triu_indices(obs.n_views, 1)], initial=0))
        raise InsufficientDataError(
            f"no pair of views shares >= {min_shared} marker corners (best pair: {best}); "
            "take views that overlap more (each view should see several markers also seen in "
            "other views) or add markers"
        )
    rig = (iu % 2 == 0) & (ju == iu + 1)
    rng = np.random.default_rng(seed)
    rig_sel = np.flatnonzero(rig)
    if len(rig_sel) > max_rig_pairs:
        rig_sel = rig_sel[np.linspace(0, len(rig_sel) - 1, max_rig_pairs).round().astype(int)]
    other = np.flatnonzero(~rig)
    if len(other) > max_pairs:
        other = np.sort(rng.choice(other, max_pairs, replace=False))
    out: list[PairEstimate] = []
    for s in np.concatenate([rig_sel, other]):
        a, b = int(iu[s]), int(ju[s])
        common = np.flatnonzero(vis[a] & vis[b])
        p1, p2 = table[a, common], table[b, common]
        F = _robust_cv(cv2.findFundamentalMat, p1, p2, cv2.USAC_MAGSAC, ransac_px, 0.9999, 10000)
        if F is None or F.shape != (3, 3):
            continue
        F = F / np.linalg.norm(F)
        d = _sampson(F, p1, p2)
        inl = d < ransac_px
        if inl.sum() < 8:
            continue
        H = _robust_cv(
            cv2.findHomography,
            p1,
            p2,
            cv2.USAC_MAGSAC,
            ransac_px,
            maxIters=10000,
            confidence=0.9999,
        )
        n_h = int((_transfer(H, p1, p2) < ransac_px).sum()) if H is not None else 0
        out.append(PairEstimate(a, b, common, F, inl, n_h, bool(n_h >= 0.9 * inl.sum()), d))
    if not out:
        raise InsufficientDataError(
            "no fundamental matrix could be estimated from the view pairs; check the "
            "correspondences (ids consistent across views?) and the pixel noise"
        )
    return out


# ------------------------------------------------------------------------ focal estimation
def _essentials(F: np.ndarray, fx: np.ndarray, mu: np.ndarray, cx: float, cy: float):
    F = np.asarray(F, dtype=float).reshape(-1, 3, 3)
    fx = np.atleast_1d(np.asarray(fx, dtype=float)).ravel()
    mu = np.atleast_1d(np.asarray(mu, dtype=float)).ravel()
    fx, mu = np.broadcast_arrays(fx, mu)
    K = np.zeros((len(fx), 3, 3))
    K[:, 0, 0] = fx
    K[:, 1, 1] = mu * fx
    K[:, 0, 2], K[:, 1, 2], K[:, 2, 2] = cx, cy, 1.0
    E = np.einsum("gji,njk,gkl->ngil", K, F, K)
    return E / np.linalg.norm(E, axis=(-2, -1), keepdims=True)


def essential_residuals(
    F: np.ndarray, fx: np.ndarray | float, mu: np.ndarray | float, cx: float, cy: float
) -> np.ndarray:
    """Mendonca-Cipolla residual ``(s1^2 - s2^2) / (s1^2 + s2^2)`` of ``E = K^T F K`` for
    fundamental matrices ``F`` (n, 3, 3) and intrinsics ``fx``, ``mu`` (broadcast, g values):
    shape (n, g). Zero iff the two non-zero singular values of E are equal."""
    s = np.linalg.svd(_essentials(F, fx, mu, cx, cy), compute_uv=False)
    return (s[..., 0] ** 2 - s[..., 1] ** 2) / np.maximum(s[..., 0] ** 2 + s[..., 1] ** 2, 1e-300)


def _grid_residuals(
    F: np.ndarray, fx: np.ndarray, mu: np.ndarray, cx: float, cy: float
) -> np.ndarray:
    """:func:`essential_residuals` for many grid points at once, (n, g), without a batched SVD.

    ``K = A diag(fx, mu fx, 1)`` with ``A = [[1, 0, cx], [0, 1, cy], [0, 0, 1]]``, so up to scale
    (the residual is scale invariant) ``E = D F' D`` with ``F' = A^T F A`` and
    ``D = diag(1, mu, 1/fx)``. The squared singular values of ``E`` are the eigenvalues of
    ``M = E E^T``, ``M_ik = d_i d_k sum_j F'_ij F'_kj d_j^2`` (one matrix product over the grid),
    found in closed form (trigonometric solution for symmetric 3x3 matrices). Agrees with the SVD
    to ~1e-13."""
    A = np.array([[1.0, 0.0, cx], [0.0, 1.0, cy], [0.0, 0.0, 1.0]])
    Fp = A.T @ np.asarray(F, dtype=float).reshape(-1, 3, 3) @ A
    Fp /= np.linalg.norm(Fp, axis=(1, 2), keepdims=True)
    d = np.stack([np.ones_like(fx), mu, 1.0 / fx])  # (3, g)
    iu = np.array([0, 1, 2, 0, 0, 1]), np.array([0, 1, 2, 1, 2, 2])  # a b c d e f
    P = Fp[:, iu[0], :] * Fp[:, iu[1], :]  # (n, 6, 3): F'_ij F'_kj
    S = (P.reshape(-1, 3) @ (d * d)).reshape(len(Fp), 6, -1)
    a, b, c, dd, e, f = (S[:, m] * (d[iu[0][m]] * d[iu[1][m]]) for m in range(6))
    scale = (a + b + c) / 3.0  # normalise M (tr M = 3) for a well-scaled closed form
    scale = np.maximum(scale, 1e-300)
    a, b, c, dd, e, f = (v / scale for v in (a, b, c, dd, e, f))
    p1 = dd * dd + e * e + f * f
    a1, b1, c1 = a - 1.0, b - 1.0, c - 1.0
    p = np.sqrt((a1 * a1 + b1 * b1 + c1 * c1 + 2.0 * p1) / 6.0)
    pi = 1.0 / np.maximum(p, 1e-300)
    a1, b1, c1, dd, e, f = a1 * pi, b1 * pi, c1 * pi, dd * pi, e * pi, f * pi
    det = a1 * (b1 * c1 - f * f) - dd * (dd * c1 - f * e) + e * (dd * f - b1 * e)
    phi = np.arccos(np.clip(0.5 * det, -1.0, 1.0)) / 3.0
    l1 = 1.0 + 2.0 * p * np.cos(phi)
    l3 = 1.0 + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    l2 = 3.0 - l1 - l3
    return (l1 - l2) / np.maximum(l1 + l2, 1e-300)


def essential_constraint(F: np.ndarray, fx: float, mu: float, cx: float, cy: float) -> np.ndarray:
    """Smooth vector form of the same condition: ``2 E E^T E - tr(E E^T) E`` (n, 9) for
    ``E = K^T F K / |K^T F K|_F``; its norm equals :func:`essential_residuals` (for rank-2 F)
    but, unlike the singular-value gap, it is differentiable at the solution."""
    E = _essentials(F, fx, mu, cx, cy)[:, 0]
    EEt = E @ np.swapaxes(E, -1, -2)
    tr = np.trace(EEt, axis1=-2, axis2=-1)[:, None, None]
    return (2.0 * EEt @ E - tr * E).reshape(len(E), 9)


@dataclass
class FocalEstimate:
    """Result of :func:`focal_from_fundamentals`: ``fx`` (px), ``mu``; ``log_fx_std`` is the
    1-sigma uncertainty of ``ln fx`` implied by the spread of the pair residuals,
    ``sensitivity`` = d(ln fx)/d(residual) from the Gauss-Newton covariance (noise-free geometric
    measure: ~1 for well-posed view sets, large when the cost is flat in fx); ``n_pairs`` the
    pairs used (``n_inlier_pairs`` of them consistent)."""

    fx: float
    mu: float
    log_fx_std: float
    sensitivity: float
    n_pairs: int
    n_inlier_pairs: int
    residual_scale: float


def _soft_l1_fit(fun, x0, f_scale, bounds, max_iter=100, tol=1e-12):
    """Minimise ``sum rho(f_i(x)^2 / f_scale^2)``, ``rho(z) = 2 (sqrt(1 + z) - 1)`` (soft-L1 per
    residual component, like ``least_squares(loss="soft_l1")``) for a few parameters ``x``
    within ``bounds``: Levenberg-Marquardt on the iteratively reweighted problem, central
    difference Jacobian. Returns ``x`` and ``f(x)``."""
    lo, hi = bounds
    x = np.asarray(x0, dtype=float).copy()
    f = fun(x)

    def cost(f):
        return float(np.sum(2.0 * (np.sqrt(1.0 + (f / f_scale) ** 2) - 1.0)))

    c = cost(f)
    lam = 1e-3
    h = 1e-6
    eye = np.eye(len(x))
    for _ in range(max_iter):
        J = np.stack([(fun(x + h * e) - fun(x - h * e)) / (2 * h) for e in eye], axis=1)
        w = 1.0 / np.sqrt(1.0 + (f / f_scale) ** 2)  # IRLS weight rho'(z)
        A = J.T @ (w[:, None] * J)
        g = J.T @ (w * f)
        D = np.diag(np.maximum(np.diag(A), 1e-300))
        improved = False
        while lam < 1e12:
            x_new = np.clip(x - np.linalg.solve(A + lam * D, g), lo, hi)
            f_new = fun(x_new)
            c_new = cost(f_new)
            if c_new <= c:
                improved = True
                break
            lam *= 10.0
        if not improved:
            break
        step = np.abs(x_new - x).max()
        done = c - c_new <= tol * c or step <= tol * (1.0 + np.abs(x).max())
        x, f, c = x_new, f_new, c_new
        lam = max(lam / 10.0, 1e-12)
        if done:
            break
    return x, f


def focal_from_fundamentals(
    F: np.ndarray,
    cx: float,
    cy: float,
    width: int,
    *,
    fx_bounds: tuple[float, float] | None = None,
    mu_bounds: tuple[float, float] = (0.75, 1.33),
    max_sensitivity: float = 10.0,
    n_fx: int = 64,
    n_mu: int = 25,
) -> FocalEstimate:
    """``fx``, ``mu`` from fundamental matrices ``F`` (n, 3, 3) with the principal point known.

    Minimises the median over pairs of the squared Mendonca-Cipolla residual on a log grid
    (``fx_bounds`` default ``(0.3, 5) * width`` px, ``mu_bounds``), then refines with a soft-L1
    fit (Levenberg-Marquardt, iteratively reweighted). Raises :class:`InsufficientDataError` with fewer than 2 pairs and
    :class:`DegenerateConfigurationError` when the minimum lies on the grid edge or the cost does
    not pin down ``fx`` (``sensitivity > max_sensitivity``) -- the classic cases are optical axes
    that all meet in one point (e.g. every view aimed at the same target from the same distance),
    parallel optical axes / pure translations, and pure rotations.
    """
    F = np.asarray(F, dtype=float).reshape(-1, 3, 3)
    if len(F) < 2:
        raise InsufficientDataError(
            f"only {len(F)} usable fundamental matrix; at least 2 view pairs with parallax "
            "are needed to estimate fx and mu (add configurations with varied viewpoints)"
        )
    lo, hi = fx_bounds if fx_bounds is not None else (0.3 * width, 5.0 * width)
    fxg = np.geomspace(lo, hi, n_fx)
    mug = np.geomspace(mu_bounds[0], mu_bounds[1], n_mu)
    G_fx, G_mu = np.meshgrid(fxg, mug, indexing="ij")
    r = _grid_residuals(F, G_fx.ravel(), G_mu.ravel(), cx, cy)  # (n, G)
    cost = np.median(r**2, axis=0).reshape(n_fx, n_mu)
    i, j = np.unravel_index(np.argmin(cost), cost.shape)
    x0 = np.log([fxg[i], mug[j]])
    r0 = essential_residuals(F, fxg[i], mug[j], cx, cy)[:, 0]
    scale = max(1.4826 * float(np.median(np.abs(r0))), 1e-4)

    def fun(q):
        return essential_constraint(F, np.exp(q[0]), np.exp(q[1]), cx, cy).ravel()

    bounds = (np.log([lo, mu_bounds[0]]), np.log([hi, mu_bounds[1]]))
    x0 = np.clip(x0, bounds[0] + 1e-9, bounds[1] - 1e-9)
    x_hat, f_hat = _soft_l1_fit(fun, x0, scale, bounds)
    rr = np.linalg.norm(f_hat.reshape(-1, 9), axis=1)
    scale = max(1.4826 * float(np.median(rr)), 1e-4)
    inl = np.repeat(rr < 3.0 * scale, 9)
    fx_hat, mu_hat = np.exp(x_hat)
    # sensitivity of the consistent pairs' residuals to (ln fx, ln mu), central differences
    h = 1e-5
    J = np.stack(
        [(fun(x_hat + h * e)[inl] - fun(x_hat - h * e)[inl]) / (2 * h) for e in np.eye(2)],
        axis=1,
    )
    try:
        cov = np.linalg.inv(J.T @ J)
        sensitivity = float(np.sqrt(max(cov[0, 0], 0.0)))
    except np.linalg.LinAlgError:
        sensitivity = np.inf
    log_fx_std = scale * sensitivity
    est = FocalEstimate(
        float(fx_hat),
        float(mu_hat),
        log_fx_std,
        sensitivity,
        len(F),
        int(inl.sum()) // 9,
        scale,
    )
    causes = (
        ". Typical causes: all optical axes pass through one point (every view aimed at the "
        "same target, especially from equal distances), parallel optical axes / pure "
        "translations, or pure rotations. Aim the views at different points of the field, vary "
        "the distance and the camera roll -- or pass fx_guess (e.g. from the lens data sheet) so "
        "that only the bundle adjustment determines fx"
    )
    if not np.isfinite(sensitivity) or sensitivity > max_sensitivity:
        raise DegenerateConfigurationError(
            f"the fundamental matrices do not determine the focal length (sensitivity "
            f"d(ln fx)/d(residual) = {sensitivity:.3g} > {max_sensitivity} from "
            f"{est.n_inlier_pairs} consistent pairs; well-posed view sets give < 1)" + causes
        )
    on_edge = not (lo * 1.02 < fx_hat < hi / 1.02) or not (
        mu_bounds[0] * 1.005 < mu_hat < mu_bounds[1] / 1.005
    )
    if on_edge:
        raise DegenerateConfigurationError(
            f"the fx/mu estimate from fundamental matrices ({fx_hat:.1f} px, mu {mu_hat:.3f}) "
            f"lies on the edge of the search range fx in [{lo:.0f}, {hi:.0f}] px, mu in "
            f"{mu_bounds}: either the range is wrong (pass fx_bounds/mu_bounds) or the views do "
            "not determine the focal length" + causes
        )
    return est


# --------------------------------------------------------------------------- triangulation
def triangulate(
    T_cam_world: np.ndarray, view: np.ndarray, pidx: np.ndarray, xn: np.ndarray, n_points: int
) -> tuple[np.ndarray, np.ndarray]:
    """Linear (DLT) multi-view triangulation in normalised image coordinates ``xn`` (k, 2).

    Returns ``X`` (n_points, 3) (NaN where fewer than 2 observations) and the number of
    observations per point.
    """
    P = T_cam_world[view, :3, :]
    a1 = xn[:, 0:1] * P[:, 2] - P[:, 0]
    a2 = xn[:, 1:2] * P[:, 2] - P[:, 1]
    a1 /= np.linalg.norm(a1, axis=1, keepdims=True)
    a2 /= np.linalg.norm(a2, axis=1, keepdims=True)
    M = np.zeros((n_points, 4, 4))
    np.add.at(M, pidx, a1[:, :, None] * a1[:, None, :] + a2[:, :, None] * a2[:, None, :])
    cnt = np.bincount(pidx, minlength=n_points)
    X = np.full((n_points, 3), np.nan)
    ok = cnt >= 2
    if ok.any():
        _, vec = np.linalg.eigh(M[ok])
        h = vec[:, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            X[ok] = h[:, :3] / h[:, 3:4]
    return X, cnt


def robust_triangulate(
    T_cam_world: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
    intrinsics: tuple[float, float, float, float],
    n_points: int,
    threshold_px: float,
    X_current: np.ndarray | None = None,
    n_samples: int = 40,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-point RANSAC triangulation with known poses: two-view DLT hypotheses (plus
    ``X_current`` if given) scored by the number of observations reprojecting within
    ``threshold_px`` in front of the camera, refitted on the inliers of the best one.

    ``intrinsics = (fx, mu, cx, cy)``. Returns ``X`` (n_points, 3) (NaN with < 2 inliers) and
    the inlier mask (k,) of the rows.
    """
    fx, mu, cx, cy = intrinsics
    rng = np.random.default_rng(seed)
    xn = _normalise(uv, fx, mu, cx, cy)
    X = np.full((n_points, 3), np.nan)
    inlier = np.zeros(len(view), bool)
    order = np.argsort(pidx, kind="stable")
    bounds = np.searchsorted(pidx[order], np.arange(n_points + 1))
    for p in range(n_points):
        rows = order[bounds[p] : bounds[p + 1]]
        if len(rows) < 2:
            continue
        n = len(rows)
        pairs = rng.integers(0, n, size=(n_samples, 2))
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        if n <= 8:
            ii, jj = np.triu_indices(n, 1)
            pairs = np.stack([ii, jj], axis=1)
        sel = rows[pairs]  # (s, 2)
        s_idx = np.repeat(np.arange(len(sel)), 2)
        hyp, _ = triangulate(T_cam_world, view[sel.ravel()], s_idx, xn[sel.ravel()], len(sel))
        if X_current is not None and np.isfinite(X_current[p]).all():
            hyp = np.vstack([X_current[p], hyp])
        hyp = hyp[np.isfinite(hyp).all(axis=1)]
        if not len(hyp):
            continue
        Tv = T_cam_world[view[rows]]
        Xc = np.einsum("kij,hj->hki", Tv[:, :3, :3], hyp) + Tv[:, :3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            du = fx * Xc[..., 0] / Xc[..., 2] + cx - uv[rows, 0]
            dv = mu * fx * Xc[..., 1] / Xc[..., 2] + cy - uv[rows, 1]
        ok = (Xc[..., 2] > 0) & (np.hypot(du, dv) < threshold_px)
        best = int(np.argmax(ok.sum(axis=1)))
        use = rows[ok[best]]
        if len(use) < 2:
            continue
        Xp, _ = triangulate(T_cam_world, view[use], np.zeros(len(use), int), xn[use], 1)
        r, z = reprojection_residuals(
            fx,
            mu,
            cx,
            cy,
            T_cam_world,
            np.repeat(Xp, 1, axis=0),
            view[rows],
            np.zeros(n, int),
            uv[rows],
        )
        ok2 = (z > 0) & (np.linalg.norm(r, axis=1) < threshold_px)
        if ok2.sum() >= ok[best].sum():
            X[p] = Xp[0]
            inlier[rows] = ok2
        else:
            X[p] = hyp[best]
            inlier[rows] = ok[best]
    return X, inlier


def _ray_angle(T_cam_world, view, pidx, X, n_points):
    """Largest angle (rad) between the viewing rays of each point and its first ray."""
    C = -np.einsum("kji,kj->ki", T_cam_world[view, :3, :3], T_cam_world[view, :3, 3])
    d = X[pidx] - C
    with np.errstate(invalid="ignore"):
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    first = np.full((n_points, 3), np.nan)
    order = np.argsort(pidx, kind="stable")
    starts = np.r_[True, np.diff(pidx[order]) != 0]
    first[pidx[order][starts]] = d[order][starts]
    cosang = np.nan_to_num(np.clip(np.einsum("ki,ki->k", d, first[pidx]), -1, 1), nan=1.0)
    ang = np.zeros(n_points)
    np.maximum.at(ang, pidx, np.nan_to_num(np.arccos(cosang), nan=0.0))
    return ang


# ------------------------------------------------------------------ incremental reconstruction
@dataclass
class InitialReconstruction:
    """Output of :func:`initial_reconstruction` (arbitrary scale: ``|C_scale_view| = 1``).

    ``T_cam_world`` (V, 4, 4) with the world frame = camera ``ref_view`` (NaN for unregistered
    views); ``X`` (P, 3) for ``point_ids`` (NaN if not triangulated); ``active`` (k,) marks the
    observations consistent with the reconstruction (others are outliers or unmodelled).
    """

    fx: float
    mu: float
    T_cam_world: np.ndarray
    registered: np.ndarray
    X: np.ndarray
    point_ids: np.ndarray
    active: np.ndarray
    ref_view: int
    scale_view: int
    threshold_px: float
    n_ba: int


def _pair_init(pair, table, fx, mu, cx, cy, thr_px):
    a, b = pair.view_a, pair.view_b
    pts = pair.pidx[pair.inlier]
    x1 = _normalise(table[a, pts], fx, mu, cx, cy)
    x2 = _normalise(table[b, pts], fx, mu, cx, cy)
    if len(pts) < 8:
        return None
    E = _robust_cv(cv2.findEssentialMat, x1, x2, np.eye(3), cv2.USAC_MAGSAC, 0.9999, thr_px / fx)
    if E is None or E.shape != (3, 3):
        return None
    _, R, t, _ = cv2.recoverPose(E, x1, x2, np.eye(3))
    T = np.stack([np.eye(4), make_pose(R, t.ravel())])
    view = np.r_[np.zeros(len(pts), int), np.ones(len(pts), int)]
    pid = np.r_[np.arange(len(pts)), np.arange(len(pts))]
    X, _ = triangulate(T, view, pid, np.r_[x1, x2], len(pts))
    r, z = reprojection_residuals(
        fx, mu, cx, cy, T, X, view, pid, np.r_[table[a, pts], table[b, pts]]
    )
    err = np.linalg.norm(r, axis=1).reshape(2, -1).max(axis=0)
    good = (z.reshape(2, -1) > 0).all(axis=0) & (err < thr_px) & np.isfinite(err)
    if good.sum() < 6:
        return None
    ang = _ray_angle(T, view, pid, X, len(pts))
    med = float(np.median(ang[good]))
    return T[1], pts[good], X[good], med, int(good.sum())


def _robust_cv(fn, *args, **kw):
    """First output of an OpenCV robust estimator, or None where it fails: OpenCV 5's USAC can
    raise (e.g. ``!model.empty()``) on a degenerate sample instead of returning no model; for
    one view pair that only means "no estimate from this pair"."""
    try:
        return fn(*args, **kw)[0]
    except cv2.error:
        return None


def _pnp(Xw, uv, K, thr_px):
    try:
        ok, rvec, tvec, inl = cv2.solvePnPRansac(
            Xw,
            uv,
            K,
            None,
            iterationsCount=300,
            reprojectionError=thr_px,
            confidence=0.9999,
            flags=cv2.SOLVEPNP_SQPNP,
        )
    except cv2.error:
        return None
    if not ok or inl is None or len(inl) < 6:
        return None
    inl = inl.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(Xw[inl], uv[inl], K, None, rvec, tvec)
    R, _ = cv2.Rodrigues(rvec)
    return make_pose(R, tvec.ravel()), inl


def initial_reconstruction(
    obs: Observations,
    fx: float,
    mu: float,
    cx: float,
    cy: float,
    pairs: list[PairEstimate],
    *,
    threshold_px: float = 3.0,
    min_view_points: int = 6,
    min_angle_deg: float = 1.0,
    refine_intrinsics_from: int = 6,
) -> InitialReconstruction:
    """Incremental reconstruction with intrinsics ``fx, mu`` (refined by the intermediate bundle
    adjustments once ``refine_intrinsics_from`` views are registered).

    Raises :class:`DegenerateConfigurationError` when no pair has enough parallax (median
    triangulation angle < ``min_angle_deg``) and :class:`InsufficientDataError` when fewer than
    3 views can be registered.
    """
    ids, pidx = obs.point_index()
    n_points = len(ids)
    V = obs.n_views
    view = obs.view
    uv = obs.uv
    table = _uv_table(obs, pidx, n_points)
    thr = float(threshold_px)
    # until the intrinsics have been refined by a bundle adjustment, the poses and points carry
    # the error of the fundamental-matrix fx estimate: work with a wider threshold
    work = {"thr": 2.5 * thr}

    # ---- reference pair: most well-triangulated points times parallax
    cands = sorted((p for p in pairs if not p.homography_like), key=lambda p: -p.n_inliers)[:30]
    best, best_score, best_angle = None, -1.0, 0.0
    for p in cands:
        out = _pair_init(p, table, fx, mu, cx, cy, thr)
        if out is None:
            continue
        score = out[4] * min(out[3], np.deg2rad(5.0))
        best_angle = max(best_angle, out[3])
        if out[3] >= np.deg2rad(min_angle_deg) and score > best_score:
            best, best_score = (p, out), score
    if best is None:
        raise DegenerateConfigurationError(
            f"no view pair has enough parallax for a two-view reconstruction (best median "
            f"triangulation angle {np.rad2deg(best_angle):.2f} deg < {min_angle_deg} deg, "
            f"{len(cands)} candidate pairs): the camera centres barely move (pure rotation) or "
            "the scene is planar; move the camera between configurations and add markers at "
            "different heights"
        )
    pair, (T_b, pts, Xp, _, _) = best
    T = np.full((V, 4, 4), np.nan)
    T[pair.view_a] = np.eye(4)
    T[pair.view_b] = T_b
    reg = np.zeros(V, bool)
    reg[[pair.view_a, pair.view_b]] = True
    X = np.full((n_points, 3), np.nan)
    X[pts] = Xp
    has_X = np.zeros(n_points, bool)
    has_X[pts] = True
    active = np.ones(len(obs), bool)
    failed = np.zeros(V, bool)
    K = np.array([[fx, 0, cx], [0, mu * fx, cy], [0, 0, 1.0]])
    n_ba, next_ba = 0, 4

    def classify(T, X, has_X, fx, mu):
        m = reg[view] & has_X[pidx]
        r, z = reprojection_residuals(fx, mu, cx, cy, T, X, view[m], pidx[m], uv[m])
        e = np.linalg.norm(r, axis=1)
        sig = np.median(e) / _RAYLEIGH_MEDIAN if len(e) else 0.0
        t = max(work["thr"], 4.5 * sig)
        act = np.ones(len(obs), bool)
        act[np.flatnonzero(m)] = (e < t) & (z > 0)
        return act

    def triangulate_new(T, X, has_X, active, fx, mu, only_new=True):
        m = active & reg[view]
        if only_new:
            m &= ~has_X[pidx]
        for _ in range(8):
            xn = _normalise(uv[m], fx, mu, cx, cy)
            Xn, cnt = triangulate(T, view[m], pidx[m], xn, n_points)
            cand = cnt >= 2
            if not cand.any():
                return X, has_X, active
            r, z = reprojection_residuals(fx, mu, cx, cy, T, Xn, view[m], pidx[m], uv[m])
            e = np.where(z > 0, np.linalg.norm(r, axis=1), np.inf)
            e = np.where(np.isfinite(e), e, np.inf)
            worst = np.zeros(n_points)
            np.maximum.at(worst, pidx[m], e)
            bad_pt = cand & (worst > work["thr"])
            if not bad_pt.any():
                break
            rows = np.flatnonzero(m)
            drop = bad_pt[pidx[rows]] & (e > np.maximum(work["thr"], 0.5 * worst[pidx[rows]]))
            m[rows[drop]] = False
            active[rows[drop]] = False
        ang = _ray_angle(T, view[m], pidx[m], Xn, n_points)
        ok = cand & ~bad_pt & (ang >= np.deg2rad(min_angle_deg)) & np.isfinite(Xn).all(axis=1)
        X = X.copy()
        X[ok] = Xn[ok]
        has_X = has_X | ok
        return X, has_X, active

    def run_ba(T, X, has_X, active, fx, mu):
        m = active & reg[view] & has_X[pidx]
        ref, sv = pair.view_a, pair.view_b
        model = FreePoses(np.where(reg[:, None, None], T, np.nan), reg, ref, sv)
        used = np.flatnonzero(has_X)
        remap = -np.ones(n_points, int)
        remap[used] = np.arange(len(used))
        fix = reg.sum() < refine_intrinsics_from
        res = bundle_adjust(
            model,
            model.initial_params(),
            X[used],
            view[m],
            remap[pidx[m]],
            uv[m],
            fx,
            mu,
            cx,
            cy,
            fix_intrinsics=fix,
            loss="soft_l1",
            f_scale_px=1.0,
            max_nfev=30,
            tol=1e-8,
        )
        if not fix:
            work["thr"] = thr
        T = np.where(reg[:, None, None], res.T_cam_world, np.nan)
        X = X.copy()
        X[used] = res.X
        return T, X, res.fx, res.mu

    while True:
        usable = active & has_X[pidx]
        counts = np.bincount(view[usable], minlength=V)
        counts[reg | failed] = 0
        v = int(np.argmax(counts))
        if counts[v] < min_view_points:
            break
        rows = np.flatnonzero(usable & (view == v))
        out = _pnp(X[pidx[rows]], uv[rows], K, work["thr"])
        if out is None:
            failed[v] = True
            continue
        T_v, inl = out
        T[v] = T_v
        reg[v] = True
        bad = np.ones(len(rows), bool)
        bad[inl] = False
        active[rows[bad]] = False
        X, has_X, active = triangulate_new(T, X, has_X, active, fx, mu)
        if reg.sum() >= next_ba:
            T, X, fx, mu = run_ba(T, X, has_X, active, fx, mu)
            K = np.array([[fx, 0, cx], [0, mu * fx, cy], [0, 0, 1.0]])
            n_ba += 1
            next_ba = 2 * next_ba
            active = classify(T, X, has_X, fx, mu)
            failed[:] = False
            X, has_X, active = triangulate_new(T, X, has_X, active, fx, mu)
    if reg.sum() < 3:
        raise InsufficientDataError(
            f"only {int(reg.sum())} views could be registered; each view needs >= "
            f"{min_view_points} corners of markers also seen in other views -- or the initial "
            f"focal length ({fx:.0f} px) is far off: pass fx_guess"
        )
    T, X, fx, mu = run_ba(T, X, has_X, active, fx, mu)
    n_ba += 1
    active = classify(T, X, has_X, fx, mu)
    X, has_X, active = triangulate_new(T, X, has_X, active, fx, mu)
    X[~has_X] = np.nan
    active &= reg[view] & has_X[pidx]
    return InitialReconstruction(
        float(fx), float(mu), T, reg, X, ids, active, pair.view_a, pair.view_b, thr, n_ba
    )


def optical_axes_convergence(T_world_cam: np.ndarray) -> tuple[np.ndarray, float]:
    """Point closest (least squares) to all optical axes and the RMS distance of the axes from it.

    ``T_world_cam`` (n, 4, 4). A small RMS distance relative to the camera distances means the
    optical axes (nearly) meet in one point -- the degenerate case for focal length estimation
    from fundamental matrices.
    """
    T = np.asarray(T_world_cam, dtype=float).reshape(-1, 4, 4)
    T = T[np.isfinite(T).all(axis=(1, 2))]
    C = T[:, :3, 3]
    d = T[:, :3, 2]
    Pm = np.eye(3) - d[:, :, None] * d[:, None, :]
    A = Pm.sum(axis=0)
    b = np.einsum("nij,nj->i", Pm, C)
    p = np.linalg.lstsq(A, b, rcond=None)[0]
    dist = np.linalg.norm(np.einsum("nij,nj->ni", Pm, p - C), axis=1)
    return p, float(np.sqrt(np.mean(dist**2)))
