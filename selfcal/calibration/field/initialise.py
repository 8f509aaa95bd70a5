"""Initialisation of the camera self-calibration from the images alone (paper section III.A).

Following Hartley's approach for "an uncalibrated camera with intrinsics of eq. 19"
(:func:`initialise`):

1. fundamental matrices between pairs of views sharing enough points, including the pairs of
   cameras of one frame (:func:`selfcal.estimation.epipolar.fundamental_pairs`), with a homography
   test that flags pairs without parallax (pure rotation, planar scene), and the pixel noise they
   imply;
2. ``fx`` and ``mu`` with the principal point known (:mod:`selfcal.estimation.focal`), unless the
   caller gives them;
3. :func:`initial_reconstruction` -- essential matrix and relative pose of the best pair,
   two-view triangulation, then incremental registration of every other view (PnP + RANSAC
   against the points triangulated so far), triangulation of new points, and bundle adjustments
   when the number of registered views doubles, until one has refined the intrinsics; after it,
   only when points were triangulated or a view failed to register since the last one (views
   registered against the same adjusted points by PnP, each on its own, carry no error into
   each other: a marker field is whole after a few views). The views registered after the last adjustment are adjusted by
   the camera stage's adjustment that follows (:mod:`selfcal.calibration.field.adjust`). The
   result has an arbitrary scale (reference pair baseline = 1) and its world frame is the first
   view of the reference pair.

The initialisation is the paper's pinhole by nature (:class:`selfcal.camera.Pinhole`, no lens
term); models with more parameters start from it. Pixel coordinates follow the OpenCV convention.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from selfcal.camera import Pinhole
from selfcal.errors import InputError
from selfcal.estimation.bundle_adjust import bundle_adjust
from selfcal.estimation.epipolar import (
    PairEstimate,
    epipolar_sigma,
    fundamental_pairs,
    robust_cv,
    uv_table,
)
from selfcal.estimation.focal import focal_from_fundamentals
from selfcal.estimation.observations import Observations, RowGroups
from selfcal.estimation.pose_models import FreePoses
from selfcal.estimation.reprojection import reprojection_residuals, robust_sigma
from selfcal.estimation.selfcal_errors import (
    PLANAR_FIX,
    DegenerateConfigurationError,
    InsufficientDataError,
)
from selfcal.estimation.triangulation import ray_angle, triangulate
from selfcal.transforms import make_pose

__all__ = ["InitialReconstruction", "initialise", "initial_reconstruction"]


def initialise(
    obs: Observations,
    width: int,
    height: int,
    *,
    fx_guess: float | None = None,
    mu_guess: float = 1.0,
    fx_bounds: tuple[float, float] | None = None,
    mu_bounds: tuple[float, float] = (0.75, 1.33),
    ransac_px: float = 3.0,
    min_view_points: int = 6,
    seed: int = 0,
) -> InitialReconstruction:
    """Steps 1-3 of the module docstring for an image of ``width`` x ``height`` px (principal
    point at its centre). ``fx_guess``/``mu_guess`` skip the fundamental-matrix estimate of
    fx/mu; ``fx_bounds``/``mu_bounds`` its search range; ``ransac_px`` the epipolar RANSAC
    threshold (raised when the data are noisier). Timings and the estimate's quality go to the
    result's ``diagnostics``.

    Raises :class:`DegenerateConfigurationError` (every pair explained by a homography, fx not
    determined, no parallax), :class:`InsufficientDataError` (too few pairs or views) and
    ``ValueError`` for a bad ``fx_guess``.
    """
    diag: dict = {}
    t0 = time.perf_counter()
    pairs = fundamental_pairs(obs, ransac_px=ransac_px, seed=seed)
    useful = [p for p in pairs if not p.homography_like]
    diag["n_pairs"] = len(pairs)
    diag["n_parallax_pairs"] = len(useful)
    if not useful:
        rig_pairs = [p for p in pairs if obs.layout.same_frame(p.view_a, p.view_b)]
        if rig_pairs:
            raise DegenerateConfigurationError(
                "every view pair, including the pairs of cameras of one frame, is explained by "
                "a homography: the marker corners are (nearly) coplanar, so neither fx nor the "
                "poses can be initialised from fundamental matrices. Put markers at different "
                "heights (relief >= ~10 % of the field size)",
                fix=PLANAR_FIX,
            )
        raise DegenerateConfigurationError(
            "every view pair is explained by a homography (no parallax): the camera centres do "
            "not move enough between configurations (pure rotation) or the scene is planar; "
            "translate the camera between configurations and add relief to the marker field",
            fix=PLANAR_FIX,
        )
    sigma_epi = epipolar_sigma(useful)
    if 3.0 * sigma_epi > ransac_px:  # noisier than the RANSAC threshold assumes: redo
        pairs = fundamental_pairs(obs, ransac_px=3.0 * sigma_epi, seed=seed)
        useful = [p for p in pairs if not p.homography_like] or useful
        sigma_epi = epipolar_sigma(useful)
    thr = max(ransac_px, 4.5 * sigma_epi)
    diag["sigma_px_epipolar"] = sigma_epi
    centred = Pinhole.centered(1.0, 1.0, width, height)
    if fx_guess is None:
        Fs = np.stack([p.F for p in useful])
        foc = focal_from_fundamentals(
            Fs, centred.cx, centred.cy, width, fx_bounds=fx_bounds, mu_bounds=mu_bounds
        )
        fx0, mu0 = foc.fx, foc.mu
        diag["focal_log_fx_std"] = foc.log_fx_std
        diag["focal_sensitivity"] = foc.sensitivity
        diag["focal_inlier_pairs"] = foc.n_inlier_pairs
    else:
        if not (np.isfinite(fx_guess) and fx_guess > 0):
            raise InputError(f"fx_guess must be a positive focal length in px, got {fx_guess}")
        fx0, mu0 = float(fx_guess), float(mu_guess)
    diag["t_focal_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    camera = Pinhole.centered(fx0, mu0, width, height)
    init = initial_reconstruction(
        obs, camera, useful, threshold_px=thr, min_view_points=min_view_points
    )
    diag["t_init_s"] = time.perf_counter() - t0
    diag["init_registered_views"] = int(init.registered.sum())
    diag["init_fx"], diag["init_mu"] = init.camera.fx, init.camera.mu
    init.diagnostics.update(diag)
    return init


@dataclass
class InitialReconstruction:
    """Output of :func:`initial_reconstruction` (arbitrary scale: ``|C_scale_view| = 1``).

    ``camera`` the pinhole after the intermediate adjustments; ``T_cam_world`` (V, 4, 4) with the
    world frame = camera ``ref_view`` (NaN for unregistered views); ``X`` (P, 3) for
    ``point_ids`` (NaN if not triangulated); ``active`` (k,) marks the observations consistent
    with the reconstruction (others are outliers or unmodelled); ``threshold_px`` the inlier
    threshold (px); ``camera_init`` the camera it started from; ``diagnostics`` timings and
    the focal estimate's quality.
    """

    camera: Pinhole
    T_cam_world: np.ndarray
    registered: np.ndarray
    X: np.ndarray
    point_ids: np.ndarray
    active: np.ndarray
    ref_view: int
    scale_view: int
    threshold_px: float
    n_ba: int
    camera_init: Pinhole
    diagnostics: dict = field(default_factory=dict)


def _pair_init(pair: PairEstimate, table: np.ndarray, camera: Pinhole, thr_px: float):
    """Relative pose, points and parallax of one view pair (essential matrix, two-view
    triangulation), or None: ``(T_b_a, point indices, X (n, 3), median ray angle, n)``."""
    a, b = pair.view_a, pair.view_b
    pts = pair.pidx[pair.inlier]
    x1 = camera.unproject_normalised(table[a, pts])
    x2 = camera.unproject_normalised(table[b, pts])
    if len(pts) < 8:
        return None
    E = robust_cv(
        cv2.findEssentialMat, x1, x2, np.eye(3), cv2.USAC_MAGSAC, 0.9999, thr_px / camera.fx
    )
    if E is None or E.shape != (3, 3):
        return None
    _, R, t, _ = cv2.recoverPose(E, x1, x2, np.eye(3))
    T = np.stack([np.eye(4), make_pose(R, t.ravel())])
    view = np.r_[np.zeros(len(pts), int), np.ones(len(pts), int)]
    pid = np.r_[np.arange(len(pts)), np.arange(len(pts))]
    X, _ = triangulate(T, view, pid, np.r_[x1, x2], len(pts))
    r, z = reprojection_residuals(camera, T, X, view, pid, np.r_[table[a, pts], table[b, pts]])
    err = np.linalg.norm(r, axis=1).reshape(2, -1).max(axis=0)
    good = (z.reshape(2, -1) > 0).all(axis=0) & (err < thr_px) & np.isfinite(err)
    if good.sum() < 6:
        return None
    ang = ray_angle(T, view, pid, X, len(pts))
    med = float(np.median(ang[good]))
    return T[1], pts[good], X[good], med, int(good.sum())


def _pnp(Xw: np.ndarray, uv: np.ndarray, K: np.ndarray, thr_px: float):
    """Camera pose from world points and pixels (SQPnP + RANSAC, refined), or None."""
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
    camera: Pinhole,
    pairs: list[PairEstimate],
    *,
    threshold_px: float = 3.0,
    min_view_points: int = 6,
    min_angle_deg: float = 1.0,
    refine_intrinsics_from: int = 6,
) -> InitialReconstruction:
    """Incremental reconstruction with the pinhole ``camera`` (its free parameters refined by the
    intermediate bundle adjustments once ``refine_intrinsics_from`` views are registered).
    ``pairs``: the epipolar estimates (:func:`selfcal.estimation.epipolar.fundamental_pairs`).

    Raises :class:`DegenerateConfigurationError` when no pair has enough parallax (median
    triangulation angle < ``min_angle_deg``) and :class:`InsufficientDataError` when fewer than
    3 views can be registered.
    """
    camera_init = camera
    ids, pidx = obs.point_index()
    n_points = len(ids)
    V = obs.n_views
    view = obs.view
    uv = obs.uv
    table = uv_table(obs, pidx, n_points)
    thr = float(threshold_px)
    # until the intrinsics have been refined by a bundle adjustment, the poses and points carry
    # the error of the fundamental-matrix fx estimate: work with a wider threshold
    work = {"thr": 2.5 * thr}

    # ---- reference pair: most well-triangulated points times parallax
    cands = sorted((p for p in pairs if not p.homography_like), key=lambda p: -p.n_inliers)[:30]
    best, best_score, best_angle = None, -1.0, 0.0
    for p in cands:
        out = _pair_init(p, table, camera, thr)
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
            "different heights",
            fix=PLANAR_FIX,
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
    n_ba, next_ba, pts_at_ba = 0, 4, 0  # pts_at_ba: points reconstructed at the last one

    def classify(T, X, has_X, camera):
        m = reg[view] & has_X[pidx]
        r, z = reprojection_residuals(camera, T, X, view[m], pidx[m], uv[m])
        e = np.linalg.norm(r, axis=1)
        sig = robust_sigma(e) if len(e) else 0.0
        t = max(work["thr"], 4.5 * sig)
        act = np.ones(len(obs), bool)
        act[np.flatnonzero(m)] = (e < t) & (z > 0)
        return act

    by_view, by_point = RowGroups(view, V), RowGroups(pidx, n_points)

    def triangulate_new(T, X, has_X, active, camera):
        """Triangulate the points not yet reconstructed from their active rows in registered
        views (only those points' rows are visited, in row order)."""
        sel = by_point.rows_of(np.flatnonzero(~has_X))
        sel = sel[active[sel] & reg[view[sel]]]
        if not np.any(np.bincount(pidx[sel], minlength=n_points) >= 2):
            return X, has_X, active  # no point with two rows: nothing to triangulate (most views)
        for _ in range(8):
            xn = camera.unproject_normalised(uv[sel])
            Xn, cnt = triangulate(T, view[sel], pidx[sel], xn, n_points)
            cand = cnt >= 2
            if not cand.any():
                return X, has_X, active
            r, z = reprojection_residuals(camera, T, Xn, view[sel], pidx[sel], uv[sel])
            e = np.where(z > 0, np.linalg.norm(r, axis=1), np.inf)
            e = np.where(np.isfinite(e), e, np.inf)
            worst = np.zeros(n_points)
            np.maximum.at(worst, pidx[sel], e)
            bad_pt = cand & (worst > work["thr"])
            if not bad_pt.any():
                break
            drop = bad_pt[pidx[sel]] & (e > np.maximum(work["thr"], 0.5 * worst[pidx[sel]]))
            active[sel[drop]] = False
            sel = sel[~drop]
        ang = ray_angle(T, view[sel], pidx[sel], Xn, n_points)
        ok = cand & ~bad_pt & (ang >= np.deg2rad(min_angle_deg)) & np.isfinite(Xn).all(axis=1)
        X = X.copy()
        X[ok] = Xn[ok]
        return X, has_X | ok, active

    def run_ba(T, X, has_X, active, camera):
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
            camera,
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
        return T, X, res.camera

    def usable_counts(active, has_X):
        """(V,) active rows of reconstructed points per view (-1 for registered or failed
        views: no candidates)."""
        counts = np.bincount(view[active & has_X[pidx]], minlength=V)
        counts[reg | failed] = -1
        return counts

    def triangulate_counted(T, X, has_X, active, camera, counts):
        """:func:`triangulate_new`, adding the rows of the newly reconstructed points to the
        candidates' ``counts`` (the rows it deactivates belong to points without X: uncounted)."""
        X, new_has_X, active = triangulate_new(T, X, has_X, active, camera)
        rows = by_point.rows_of(np.flatnonzero(new_has_X & ~has_X))
        rows = rows[active[rows]]
        counts += np.where(counts >= 0, np.bincount(view[rows], minlength=V), 0)
        return X, new_has_X, active

    # the next view is the unregistered one with the most usable rows; the counts are kept up to
    # date from the rows that change, so that one registration visits its own view's rows and
    # the new points' rows only (not every observation: linear in the number of views)
    counts = usable_counts(active, has_X)
    n_reg = 2
    while True:
        v = int(np.argmax(counts))
        if counts[v] < min_view_points:
            break
        rows = by_view.rows_of_one(v)
        rows = rows[active[rows] & has_X[pidx[rows]]]
        out = _pnp(X[pidx[rows]], uv[rows], camera.K, work["thr"])
        counts[v] = -1
        if out is None:
            failed[v] = True
            continue
        T_v, inl = out
        T[v] = T_v
        reg[v] = True
        n_reg += 1
        bad = np.ones(len(rows), bool)
        bad[inl] = False
        active[rows[bad]] = False
        X, has_X, active = triangulate_counted(T, X, has_X, active, camera, counts)
        # an adjustment when the registered views have doubled, unless the intrinsics have been
        # refined, no point has been added since the last one and no view failed (the views that
        # failed are tried again after an adjustment; step 3 of the docstring)
        if n_reg >= next_ba and (work["thr"] != thr or has_X.sum() > pts_at_ba or failed.any()):
            T, X, camera = run_ba(T, X, has_X, active, camera)
            n_ba += 1
            next_ba = 2 * next_ba
            pts_at_ba = int(has_X.sum())
            active = classify(T, X, has_X, camera)
            failed[:] = False
            X, has_X, active = triangulate_new(T, X, has_X, active, camera)
            counts = usable_counts(active, has_X)
    if reg.sum() < 3:
        raise InsufficientDataError(
            f"only {int(reg.sum())} views could be registered; each view needs >= "
            f"{min_view_points} corners of markers also seen in other views -- or the initial "
            f"focal length ({camera.fx:.0f} px) is far off: pass fx_guess"
        )
    if work["thr"] != thr:
        # no adjustment has refined the intrinsics yet: this one does. Once one has, the views
        # registered since are left to the camera stage's adjustment (adjust.adjust), which
        # starts from this reconstruction and adjusts every view at once: a pass here would
        # repeat it on more unknowns (a pose per view); they are classified with the poses
        # PnP refined against the adjusted points
        T, X, camera = run_ba(T, X, has_X, active, camera)
        n_ba += 1
    active = classify(T, X, has_X, camera)
    X, has_X, active = triangulate_new(T, X, has_X, active, camera)
    X[~has_X] = np.nan
    active &= reg[view] & has_X[pidx]
    return InitialReconstruction(
        camera, T, reg, X, ids, active, pair.view_a, pair.view_b, thr, n_ba, camera_init
    )
