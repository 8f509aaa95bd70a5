"""Camera self-calibration of a wrist stereo rig from marker-corner correspondences (paper sec. III).

Pipeline (:func:`self_calibrate`), pure functions over point correspondences:

1. initialisation from the images alone (:mod:`calib.selfcal_init`): fundamental matrices,
   ``fx``/``mu`` from the Mendonca-Cipolla cost with the principal point known (image centre),
   essential matrices, two-view reconstruction and incremental PnP registration;
2. sparse bundle adjustment (:mod:`calib.bundle_adjust`) over ``fx``, ``mu``, the camera poses and
   the 3-D points with a robust loss, gross-outlier rejection, then a final least-squares pass;
   by default the poses are one left-camera pose per configuration plus one shared rig transform;
3. scale from the known distance between two markers (eqs. 20-24) and the sign choice against a
   nominal camera trajectory (:func:`scale_from_markers`, :func:`choose_scale_sign`).

Frames, units and gauge of the result (:class:`SelfCalibrationResult`):

- world frame = the left camera frame of configuration ``ref_config`` (the registered
  configuration with the lowest ``ref_scores``, by default the first registered one):
  ``T_world_cam[ref_config, 0] = I``;
- during the bundle adjustment the scale gauge is the stereo baseline ``|t(T_left_right)| = 1``;
  afterwards everything is multiplied by ``k = d / d_hat`` so that lengths are in metres
  (``is_metric``); without scale markers the units stay "baselines" and ``is_metric`` is False;
- views: ``view = 2 * config + camera`` with camera 0 = left, 1 = right; ``T_world_cam`` has
  shape (m, 2, 4, 4) and is NaN for configurations that could not be registered.

Every failure mode raises a subclass of :class:`SelfCalibrationError` whose message names the
problem and what to change; no silently wrong numbers are returned.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from calib.bundle_adjust import (
    ConvergenceError,
    DegenerateConfigurationError,
    FreePoses,
    InsufficientDataError,
    RigPoses,
    ScaleMarkerError,
    SelfCalibrationError,
    bundle_adjust,
    intrinsics_covariance,
    reprojection_residuals,
)
from calib.camera import Intrinsics, centered_principal_point, project
from calib.observations import Observations
from calib.selfcal_init import (
    _RAYLEIGH_MEDIAN,
    _ray_angle,
    focal_from_fundamentals,
    fundamental_pairs,
    initial_reconstruction,
    optical_axes_convergence,
    robust_triangulate,
)
from calib.transforms import inv_pose, kabsch, make_pose, rot_y

__all__ = [
    "Observations",
    "SelfCalibrationError",
    "InsufficientDataError",
    "DegenerateConfigurationError",
    "ScaleMarkerError",
    "ConvergenceError",
    "SelfCalibrationResult",
    "self_calibrate",
    "ScaleEstimate",
    "scale_from_markers",
    "SignChoice",
    "choose_scale_sign",
    "rigid_align",
    "cheirality_fraction",
    "SyntheticScene",
    "synthetic_stereo_scene",
]


# ----------------------------------------------------------------------------- scale & sign
@dataclass(frozen=True)
class ScaleEstimate:
    """``d_hat``: distance between the two scale-marker centres in reconstruction units;
    ``k = d / d_hat`` (positive; the sign is chosen by :func:`choose_scale_sign`)."""

    d_hat: float
    k: float
    centre_a: np.ndarray
    centre_b: np.ndarray


def scale_from_markers(
    point_ids: np.ndarray,
    X: np.ndarray,
    marker_a: int,
    marker_b: int,
    distance_m: float,
) -> ScaleEstimate:
    """Scale factor from two markers whose centres are ``distance_m`` apart (paper eqs. 21-23).

    ``point_ids`` (P,) and ``X`` (P, 3) are the reconstructed corners (NaN = not reconstructed);
    each marker centre is the mean of its 4 corners. Raises :class:`ScaleMarkerError` if a corner
    of either marker is missing or the distance is not positive.
    """
    if not (np.isfinite(distance_m) and distance_m > 0):
        raise ScaleMarkerError(f"scale distance must be a positive length in m, got {distance_m}")
    if marker_a == marker_b:
        raise ScaleMarkerError("the two scale markers must be different markers")
    ids = np.asarray(point_ids)
    X = np.asarray(X, dtype=float)
    centres = []
    for mk in (marker_a, marker_b):
        want = 4 * int(mk) + np.arange(4)
        pos = np.searchsorted(ids, want)
        found = (pos < len(ids)) & (ids[np.minimum(pos, len(ids) - 1)] == want)
        if not found.all() or not np.isfinite(X[pos]).all():
            missing = want[~found | ~np.isfinite(X[np.minimum(pos, len(ids) - 1)]).all(axis=1)]
            raise ScaleMarkerError(
                f"scale marker {mk}: corners {sorted(int(c) % 4 for c in missing)} are not in the "
                "reconstruction (never seen, seen in fewer than 2 views, or rejected as "
                "outliers); make sure both scale markers are visible in several configurations"
            )
        centres.append(X[pos].mean(axis=0))
    d_hat = float(np.linalg.norm(centres[0] - centres[1]))
    if d_hat <= 0:
        raise ScaleMarkerError("the two scale-marker centres coincide in the reconstruction")
    return ScaleEstimate(d_hat, float(distance_m) / d_hat, centres[0], centres[1])


def rigid_align(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, float]:
    """Best proper rigid transform ``T`` (4, 4) with ``T @ A ~ B`` (:func:`calib.transforms.kabsch`)
    for point sets (n, 3); returns ``(T, rms)`` with the RMS residual in the units of B."""
    T = kabsch(A, B)
    rms = float(np.sqrt(np.mean(np.sum((np.asarray(A) @ T[:3, :3].T + T[:3, 3] - B) ** 2, axis=1))))
    return T, rms


@dataclass(frozen=True)
class SignChoice:
    """Result of :func:`choose_scale_sign`: ``sign`` (+1/-1), the RMS distance (m) of the
    rigidly aligned trajectories for ``+|k|`` and ``-|k|``, and ``ambiguous`` when the nominal
    trajectory cannot tell them apart (coplanar/collinear camera positions)."""

    sign: int
    rms_plus_m: float
    rms_minus_m: float
    ambiguous: bool


def choose_scale_sign(
    cam_positions: np.ndarray,
    nominal_positions: np.ndarray,
    *,
    ambiguity_ratio: float = 0.8,
) -> SignChoice:
    """Choose the sign of the scale factor (paper eq. 24 and the paragraph after it).

    ``cam_positions`` (n, 3): reconstructed camera centres already multiplied by ``|k|``;
    ``nominal_positions`` (n, 3): the same cameras predicted by the nominal robot model, in the
    robot frame (unknown rigid transform to the reconstruction frame). Both candidate
    trajectories ``+C`` and ``-C`` are rigidly aligned (proper rotation + translation) to the
    nominal one and the closer one wins. ``ambiguous`` is set when the two RMS values are within
    ``ambiguity_ratio`` of each other.

    When does the sign question arise? ``-k`` maps every point ``X -> -X`` and every translation
    ``t -> -t``; the projections are unchanged (``Xc -> -Xc``), so the images alone admit both
    signs *unless* cheirality is enforced: with ``-k`` all points lie behind the cameras. The
    factorisation/essential-matrix formulation of the paper recovers ``t`` only up to sign, hence
    eq. 20's ``+-``; our reconstruction is cheirality-checked (recoverPose, PnP), so the nominal
    trajectory acts as an independent cross-check (and must agree with cheirality, which
    :func:`self_calibrate` verifies). A point reflection of the camera positions is an improper
    transform, so the two candidates differ after rigid alignment unless the positions are
    coplanar (then the reflection equals a rotation by pi and the question cannot be decided
    from the trajectory: ``ambiguous``).
    """
    C = np.asarray(cam_positions, dtype=float)
    N = np.asarray(nominal_positions, dtype=float)
    if C.shape != N.shape or C.ndim != 2 or C.shape[1] != 3:
        raise ValueError(
            f"cam_positions {C.shape} and nominal_positions {N.shape} must both be (n, 3)"
        )
    if len(C) < 3:
        raise InsufficientDataError("the sign choice needs at least 3 camera positions")
    _, rp = rigid_align(C, N)
    _, rm = rigid_align(-C, N)
    ambiguous = min(rp, rm) > ambiguity_ratio * max(rp, rm)
    return SignChoice(1 if rp <= rm else -1, rp, rm, bool(ambiguous))


def cheirality_fraction(
    T_cam_world: np.ndarray, X: np.ndarray, view: np.ndarray, pidx: np.ndarray
) -> float:
    """Fraction of observations (view, point index) whose point lies in front of the camera."""
    R = T_cam_world[view, :3, :3]
    z = np.einsum("kj,kj->k", R[:, 2], X[pidx]) + T_cam_world[view, 2, 3]
    return float(np.mean(z > 0)) if len(z) else 1.0


# ----------------------------------------------------------------------------------- result
@dataclass
class SelfCalibrationResult:
    """Self-calibration output (see the module docstring for frames, units and gauge).

    ``T_world_cam`` (m, 2, 4, 4): pose of camera c of configuration i in the world frame (the
    left camera of ``ref_config``); NaN where ``registered`` is False. ``T_left_right``: pose of
    the right camera in the left camera frame (rig). ``X_world`` (P, 3) for ``point_ids``
    (``4 * marker + corner``; NaN if not reconstructed). ``residuals`` (k, 2) px per observation
    row (projected - observed; NaN if unmodelled), ``inlier`` (k,) the rows used by the final
    adjustment, ``rms_px = sqrt(mean |r|^2)`` over the inliers (2-D norm: ~ sigma * sqrt(2) for
    Gaussian noise of sigma px per coordinate). ``fx_std``/``mu_std``/``cov_fx_mu`` from the final Jacobian with the
    fitted noise level; ``cov_fx_mu_unit`` for 1 px noise (geometry only).
    """

    fx: float
    mu: float
    cx: float
    cy: float
    width: int
    height: int
    T_world_cam: np.ndarray
    registered: np.ndarray
    T_left_right: np.ndarray
    point_ids: np.ndarray
    X_world: np.ndarray
    residuals: np.ndarray
    inlier: np.ndarray
    rms_px: float
    n_inliers: int
    n_outliers: int
    fx_std: float
    mu_std: float
    cov_fx_mu: np.ndarray
    cov_fx_mu_unit: np.ndarray
    ref_config: int
    is_metric: bool
    scale: float
    d_hat: float
    sign: int
    rig: bool
    fx_init: float
    mu_init: float
    sign_choice: SignChoice | None = None
    diagnostics: dict = field(default_factory=dict)

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics(self.fx, self.mu, self.cx, self.cy, self.width, self.height)

    @property
    def K(self) -> np.ndarray:
        return self.intrinsics.K

    @property
    def T_cam_world(self) -> np.ndarray:
        """(m, 2, 4, 4) inverse poses (world -> camera)."""
        return inv_pose(self.T_world_cam)

    @property
    def points(self) -> dict[int, np.ndarray]:
        """Reconstructed points ``{point_id: xyz (3,)}`` (only the reconstructed ones)."""
        ok = np.isfinite(self.X_world).all(axis=1)
        return {int(i): x for i, x in zip(self.point_ids[ok], self.X_world[ok], strict=True)}


# --------------------------------------------------------------------------------- pipeline
def _rig_from_views(T: np.ndarray, reg: np.ndarray) -> np.ndarray:
    both = reg[0::2] & reg[1::2]
    if not both.any():
        raise InsufficientDataError(
            "no configuration has both cameras registered, so the rig transform cannot be "
            "initialised; make sure left and right images of some configurations see common "
            "markers, or call with rig=False"
        )
    Trl = T[1::2][both] @ inv_pose(T[0::2][both])
    R = Rotation.from_matrix(Trl[:, :3, :3]).mean().as_matrix()
    return make_pose(R, np.median(Trl[:, :3, 3], axis=0))


def _epipolar_sigma(pairs) -> float:
    """Pixel noise (per coordinate) from the Sampson distances of all shared points of the
    pairs: robust (median) over points, corrected for the 7 dof fitted per F."""
    vals = []
    for p in pairs:
        n = len(p.sampson_px)
        vals.append(p.sampson_px * np.sqrt(n / max(n - 7, 1)))
    return float(np.median(np.concatenate(vals)) / 0.6745)


def _views_per_point(view, pidx, n_points):
    key = np.unique(pidx * (int(view.max()) + 1 if len(view) else 1) + view)
    return np.bincount(key // (int(view.max()) + 1 if len(view) else 1), minlength=n_points)


def _reference(registered: np.ndarray, scores: np.ndarray | None) -> int:
    """The registered configuration with the lowest score (the first one without scores)."""
    idx = np.flatnonzero(registered)
    if scores is None:
        return int(idx[0])
    return int(idx[np.argmin(np.asarray(scores, dtype=float)[idx])])


def self_calibrate(
    obs: Observations,
    width: int,
    height: int,
    *,
    ref_scores: np.ndarray | None = None,
    scale_markers: tuple[int, int] | None = None,
    scale_distance_m: float | None = None,
    nominal_cam_positions: np.ndarray | None = None,
    rig: bool = True,
    fx_guess: float | None = None,
    mu_guess: float = 1.0,
    fx_bounds: tuple[float, float] | None = None,
    mu_bounds: tuple[float, float] = (0.75, 1.33),
    ransac_px: float = 3.0,
    outlier_px: float = 3.0,
    robust_scale_px: float = 1.0,
    max_rounds: int = 5,
    max_nfev: int = 200,
    min_configs: int = 3,
    min_view_points: int = 6,
    max_fx_rel_std_per_px: float = 0.02,
    seed: int = 0,
) -> SelfCalibrationResult:
    """Self-calibrate ``fx``, ``mu``, all camera poses, the rig and the marker corners.

    ``obs``: observations (see :class:`Observations`); ``width``, ``height``: image size (px), the
    principal point is its centre. ``scale_markers=(a, b)`` with ``scale_distance_m`` (distance of
    their centres, m) makes the result metric. ``nominal_cam_positions`` (m, 3) left-camera
    positions (or (m, 2, 3) both cameras) from the nominal robot model in the robot frame: used
    to choose the sign of ``k`` (:func:`choose_scale_sign`); cheirality must then hold.
    ``rig``: model the stereo rig as rigid (default). ``fx_guess``/``mu_guess`` skip the
    fundamental-matrix estimate of fx/mu (use when it is degenerate). Thresholds in px:
    ``ransac_px`` (epipolar/PnP RANSAC), ``outlier_px`` (minimum rejection threshold; the actual
    one is ``max(outlier_px, 4.5 sigma)``), ``robust_scale_px`` (soft-L1 scale).

    Raises :class:`InsufficientDataError` (too few views/points), :class:`DegenerateConfiguration
    Error` (fx not observable, pure rotation, planar scene), :class:`ScaleMarkerError`,
    :class:`ConvergenceError`; ``ValueError`` for malformed input.
    """
    t_start = time.perf_counter()
    if not isinstance(obs, Observations):
        raise TypeError("obs must be an Observations (see Observations.from_corners)")
    cx, cy = centered_principal_point(width, height)
    if len(obs) and (obs.uv.min(axis=0) < -0.5).any() | (obs.uv[:, 0].max() > width - 0.5) | (
        obs.uv[:, 1].max() > height - 0.5
    ):
        raise ValueError(
            f"observations lie outside the {width}x{height} image; check width/height and the "
            "pixel convention (OpenCV, pixel centres at integers)"
        )
    if (scale_markers is None) != (scale_distance_m is None):
        raise ValueError("give both scale_markers and scale_distance_m, or neither")
    cfg_seen = np.unique(obs.config)
    if len(cfg_seen) < min_configs:
        raise InsufficientDataError(
            f"only {len(cfg_seen)} configuration(s) have observations; at least {min_configs} "
            "are needed (the paper's setting uses 6 or more varied viewpoints)"
        )
    ids, pidx = obs.point_index()
    n_points = len(ids)
    view = obs.view
    uv = obs.uv
    diag: dict = {}

    # ---- 1. fundamental matrices and fx, mu
    t0 = time.perf_counter()
    pairs = fundamental_pairs(obs, ransac_px=ransac_px, seed=seed)
    useful = [p for p in pairs if not p.homography_like]
    diag["n_pairs"] = len(pairs)
    diag["n_parallax_pairs"] = len(useful)
    if not useful:
        rig_pairs = [p for p in pairs if p.view_a % 2 == 0 and p.view_b == p.view_a + 1]
        if rig_pairs and all(p.homography_like for p in pairs):
            raise DegenerateConfigurationError(
                "every view pair, including the left/right pairs, is explained by a homography: "
                "the marker corners are (nearly) coplanar, so neither fx nor the poses can be "
                "initialised from fundamental matrices. Put markers at different heights (relief "
                ">= ~10 % of the field size)"
            )
        raise DegenerateConfigurationError(
            "every view pair is explained by a homography (no parallax): the camera centres do "
            "not move enough between configurations (pure rotation) or the scene is planar; "
            "translate the camera between configurations and add relief to the marker field"
        )
    sigma_epi = _epipolar_sigma(useful)
    if 3.0 * sigma_epi > ransac_px:  # noisier than the RANSAC threshold assumes: redo
        pairs = fundamental_pairs(obs, ransac_px=3.0 * sigma_epi, seed=seed)
        useful = [p for p in pairs if not p.homography_like] or useful
        sigma_epi = _epipolar_sigma(useful)
    thr = max(ransac_px, 4.5 * sigma_epi)
    diag["sigma_px_epipolar"] = sigma_epi
    if fx_guess is None:
        Fs = np.stack([p.F for p in useful])
        foc = focal_from_fundamentals(Fs, cx, cy, width, fx_bounds=fx_bounds, mu_bounds=mu_bounds)
        fx0, mu0 = foc.fx, foc.mu
        diag["focal_log_fx_std"] = foc.log_fx_std
        diag["focal_sensitivity"] = foc.sensitivity
        diag["focal_inlier_pairs"] = foc.n_inlier_pairs
    else:
        if not (np.isfinite(fx_guess) and fx_guess > 0):
            raise ValueError(f"fx_guess must be a positive focal length in px, got {fx_guess}")
        fx0, mu0 = float(fx_guess), float(mu_guess)
    diag["t_focal_s"] = time.perf_counter() - t0

    # ---- 2. incremental reconstruction
    t0 = time.perf_counter()
    init = initial_reconstruction(
        obs, fx0, mu0, cx, cy, useful, threshold_px=thr, min_view_points=min_view_points
    )
    diag["t_init_s"] = time.perf_counter() - t0
    diag["init_registered_views"] = int(init.registered.sum())
    diag["init_fx"], diag["init_mu"] = init.fx, init.mu

    # ---- 3. gauge for the bundle adjustment
    T = init.T_cam_world.copy()
    reg_v = init.registered.copy()
    X = init.X.copy()
    has_X = np.isfinite(X).all(axis=1)
    m = obs.n_configs
    if rig:
        T_rl = _rig_from_views(T, reg_v)
        TL = np.full((m, 4, 4), np.nan)
        TL[reg_v[0::2]] = T[0::2][reg_v[0::2]]
        only_r = reg_v[1::2] & ~reg_v[0::2]
        TL[only_r] = inv_pose(T_rl) @ T[1::2][only_r]
        reg_c = reg_v[0::2] | reg_v[1::2]
        ref_config = _reference(reg_c, ref_scores)
        G = TL[ref_config].copy()
        s = 1.0 / np.linalg.norm(T_rl[:3, 3])
        TL = TL @ inv_pose(G)
        TL[:, :3, 3] *= s
        T_rl[:3, 3] *= s
        X = (X @ G[:3, :3].T + G[:3, 3]) * s
    else:
        reg_c = reg_v[0::2] | reg_v[1::2]
        ref_config = _reference(reg_c, ref_scores)
        ref_view = 2 * ref_config if reg_v[2 * ref_config] else 2 * ref_config + 1
        G = T[ref_view].copy()
        T = T @ inv_pose(G)
        others = np.flatnonzero(reg_v & (np.arange(2 * m) != ref_view))
        scale_view = (
            2 * ref_config + 1
            if reg_v[2 * ref_config + 1] and ref_view % 2 == 0
            else int(others[0])
        )
        s = 1.0 / np.linalg.norm(T[scale_view, :3, 3])
        T[:, :3, 3] *= s
        X = (X @ G[:3, :3].T + G[:3, 3]) * s
        T_rl = None

    def current_poses():
        if rig:
            Tv = np.empty((2 * m, 4, 4))
            Tv[0::2] = TL
            Tv[1::2] = T_rl @ TL
            Tv[~np.repeat(reg_c, 2)] = np.nan
            return Tv
        return np.where(reg_v[:, None, None], T, np.nan)

    def view_ok():
        return np.repeat(reg_c, 2) if rig else reg_v

    def all_residuals(Tv, X, fx, mu):
        mod = view_ok()[view] & has_X[pidx]
        r = np.full((len(obs), 2), np.nan)
        z = np.full(len(obs), np.nan)
        rr, zz = reprojection_residuals(fx, mu, cx, cy, Tv, X, view[mod], pidx[mod], uv[mod])
        r[mod], z[mod] = rr, zz
        return r, z, mod

    def prune(active):
        nonlocal has_X, reg_c, reg_v
        while True:
            a = active & view_ok()[view] & has_X[pidx]
            nv = _views_per_point(view[a], pidx[a], n_points)
            lost_pts = has_X & (nv < 2)
            unit = obs.config if rig else view
            n_unit = m if rig else 2 * m
            cnt = np.bincount(unit[a], minlength=n_unit)
            ok_unit = reg_c if rig else reg_v
            lost_units = ok_unit & (cnt < min_view_points)
            if not lost_pts.any() and not lost_units.any():
                return a
            has_X = has_X & ~lost_pts
            if rig:
                reg_c = reg_c & ~lost_units
            else:
                reg_v = reg_v & ~lost_units
            if (rig and not reg_c[ref_config]) or (not rig and not reg_v[ref_view]):
                raise ConvergenceError(
                    "the reference configuration lost its observations during outlier rejection;"
                    " the data are inconsistent (wrong marker ids or very large noise?)"
                )

    # ---- 4. robust bundle adjustment with outlier rejection, then a least-squares pass
    t0 = time.perf_counter()
    fx, mu = init.fx, init.mu
    active = init.active.copy()
    n_rounds = 0
    total_nfev = 0
    final = None
    for rnd in range(max_rounds + 1):
        last = rnd == max_rounds
        a = prune(active)
        used = np.flatnonzero(has_X)
        remap = -np.ones(n_points, int)
        remap[used] = np.arange(len(used))
        if rig:
            model = RigPoses(TL, T_rl, reg_c, ref_config)
        else:
            model = FreePoses(current_poses(), reg_v, ref_view, scale_view)
        res = bundle_adjust(
            model,
            model.initial_params(),
            X[used],
            view[a],
            remap[pidx[a]],
            uv[a],
            fx,
            mu,
            cx,
            cy,
            loss="linear" if last else "soft_l1",
            f_scale_px=robust_scale_px,
            max_nfev=max_nfev,
            tol=1e-12 if last else 1e-9,
        )
        n_rounds += 1
        total_nfev += res.nfev
        fx, mu = res.fx, res.mu
        X = X.copy()
        X[used] = res.X
        if rig:
            TL = np.where(reg_c[:, None, None], res.T_cam_world[0::2], np.nan)
            T_rl = model.rig(res.pose_params)
        else:
            T = res.T_cam_world
        if last:
            final = (res, a)
            break
        Tv = current_poses()
        n_res = res.residuals.size
        dof = max(n_res - len(res.pose_params) - res.X.size - 2, 1)
        sigma = float(np.median(np.linalg.norm(res.residuals, axis=1)) / _RAYLEIGH_MEDIAN)
        sigma *= np.sqrt(n_res / dof)  # residuals of a fit are smaller than the noise
        thr_out = max(outlier_px, 4.5 * sigma)
        # robust re-triangulation with the adjusted poses: a point dragged by an outlier in an
        # early view is recovered, and its correct observations re-enter
        vis = view_ok()[view]
        Xr, inl_r = robust_triangulate(
            Tv,
            view[vis],
            pidx[vis],
            uv[vis],
            (fx, mu, cx, cy),
            n_points,
            thr_out,
            X_current=np.where(has_X[:, None], X, np.nan),
            seed=seed + rnd,
        )
        ang = _ray_angle(Tv, view[vis][inl_r], pidx[vis][inl_r], Xr, n_points)
        good = np.isfinite(Xr).all(axis=1) & (has_X | (ang >= np.deg2rad(1.0)))
        X = np.where(good[:, None], Xr, X)
        has_X = has_X | good
        new_active = np.zeros(len(obs), bool)
        new_active[np.flatnonzero(vis)] = inl_r & good[pidx[vis]]
        if np.array_equal(new_active, active) and rnd > 0:
            # converged classification: do the final least-squares pass next
            active = new_active
            max_rounds = rnd + 1
            continue
        active = new_active
    assert final is not None
    res, a = final
    diag["t_ba_s"] = time.perf_counter() - t0
    diag["ba_rounds"] = n_rounds
    diag["ba_nfev"] = total_nfev
    if res.status <= 0:
        raise ConvergenceError(
            f"bundle adjustment did not converge within max_nfev={max_nfev} evaluations "
            f"({res.message}; fx at stop {res.fx:.1f} px, initial {init.fx:.1f} px); increase "
            "max_nfev, or check the observations (outliers, wrong ids); an fx running away "
            "means the views do not constrain it (add configurations with more varied "
            "viewpoints or pass fx_guess)"
        )

    Tv = current_poses()
    r_all, z_all, mod = all_residuals(Tv, X, fx, mu)
    e = np.linalg.norm(r_all[a], axis=1)
    rms = float(np.sqrt(np.mean(e**2)))
    if rms > 3.0 * thr:
        raise ConvergenceError(
            f"bundle adjustment ended with reprojection RMS {rms:.2f} px (> {3 * thr:.1f} px); "
            "the data are inconsistent with one rigid scene and one pinhole camera (lens "
            "distortion? moving markers? wrong ids?)"
        )
    if cheirality_fraction(Tv, X, view[a], pidx[a]) < 0.99:
        raise ConvergenceError(
            "the adjusted reconstruction has points behind the cameras (cheirality violated); "
            "the initialisation converged to a wrong solution -- check the data"
        )
    used = np.flatnonzero(has_X)
    cov, cov_unit = intrinsics_covariance(res.jac, res.residuals, 2)
    fx_rel_unit = float(np.sqrt(max(cov_unit[0, 0], 0.0)) / fx)
    diag["fx_rel_std_per_px"] = fx_rel_unit
    if not np.isfinite(fx_rel_unit) or fx_rel_unit > max_fx_rel_std_per_px:
        Twc = inv_pose(Tv[np.isfinite(Tv).all(axis=(1, 2))])
        p, d_axes = optical_axes_convergence(Twc)
        dist = float(np.median(np.linalg.norm(Twc[:, :3, 3] - p, axis=1)))
        raise DegenerateConfigurationError(
            f"the views do not determine fx: 1 px of noise would give a relative fx uncertainty "
            f"of {fx_rel_unit:.3g} (> {max_fx_rel_std_per_px}). Optical axes meet within "
            f"{d_axes:.3g} (RMS) of one point at median distance {dist:.3g} (baseline units); "
            "vary viewpoints, aim points and camera roll, and use more configurations"
        )

    # ---- 5. scale and sign
    inl_view = view[a]
    if scale_markers is not None:
        for mk in scale_markers:
            seen = obs.point // 4 == int(mk)
            n_seen = len(np.unique(view[seen]))
            n_inl = len(np.unique(inl_view[obs.point[a] // 4 == int(mk)]))
            if n_seen == 0:
                raise ScaleMarkerError(
                    f"scale marker {mk} is never observed; the scale d/d_hat needs both scale "
                    "markers visible in at least 2 views (better: many configurations)"
                )
            if n_inl < 2:
                raise ScaleMarkerError(
                    f"scale marker {mk} is seen in {n_seen} view(s) but only {n_inl} usable "
                    "view(s) remain; it must be seen in at least 2 views (better: many "
                    "configurations) to be triangulated"
                )
        X_out = np.where(has_X[:, None], X, np.nan)
        sc = scale_from_markers(ids, X_out, scale_markers[0], scale_markers[1], scale_distance_m)
        k_abs, d_hat, metric = sc.k, sc.d_hat, True
    else:
        k_abs, d_hat, metric = 1.0, float("nan"), False

    sign_choice = None
    sign = 1
    if nominal_cam_positions is not None:
        nom = np.asarray(nominal_cam_positions, dtype=float)
        Twc_all = inv_pose(Tv).reshape(m, 2, 4, 4)
        if nom.shape == (m, 3):
            C, N = Twc_all[:, 0, :3, 3], nom
        elif nom.shape == (m, 2, 3):
            C, N = Twc_all[..., :3, 3].reshape(-1, 3), nom.reshape(-1, 3)
        else:
            raise ValueError(f"nominal_cam_positions must be ({m}, 3) or ({m}, 2, 3)")
        ok = np.isfinite(C).all(axis=1) & np.isfinite(N).all(axis=1)
        sign_choice = choose_scale_sign(k_abs * C[ok], N[ok])
        sign = sign_choice.sign
        if sign_choice.ambiguous:
            sign = 1
        elif sign < 0:
            raise SelfCalibrationError(
                "the nominal camera trajectory matches the mirrored reconstruction (-k), but "
                "-k puts every point behind the cameras (cheirality). The nominal positions are "
                f"mirrored relative to the images (RMS +k {sign_choice.rms_plus_m:.4g} m, -k "
                f"{sign_choice.rms_minus_m:.4g} m): check the robot frame handedness, the "
                "camera mounting transform and the order of nominal_cam_positions"
            )
    k = sign * k_abs
    X = X * k
    Tv = Tv.copy()
    Tv[:, :3, 3] *= k
    if rig:
        T_rl = T_rl.copy()
        T_rl[:3, 3] *= k
    else:
        both = reg_v[0::2] & reg_v[1::2]
        T_rl = _rig_from_views(Tv, reg_v) if both.any() else np.full((4, 4), np.nan)
    T_world_cam = inv_pose(Tv).reshape(m, 2, 4, 4)
    registered = reg_c if rig else (reg_v[0::2] & reg_v[1::2])
    if not rig:
        T_world_cam[~reg_v.reshape(m, 2)] = np.nan
    r_out = np.full((len(obs), 2), np.nan)
    r_out[mod] = r_all[mod]
    n_out = int((mod & ~a).sum())
    diag["t_total_s"] = time.perf_counter() - t_start
    diag["outlier_threshold_px"] = float(max(outlier_px, 4.5 * rms / np.sqrt(2)))
    return SelfCalibrationResult(
        fx=float(fx),
        mu=float(mu),
        cx=cx,
        cy=cy,
        width=int(width),
        height=int(height),
        T_world_cam=T_world_cam,
        registered=registered.copy(),
        T_left_right=inv_pose(T_rl),
        point_ids=ids,
        X_world=np.where(has_X[:, None], X, np.nan),
        residuals=r_out,
        inlier=a.copy(),
        rms_px=rms,
        n_inliers=int(a.sum()),
        n_outliers=n_out,
        fx_std=float(np.sqrt(max(cov[0, 0], 0.0))),
        mu_std=float(np.sqrt(max(cov[1, 1], 0.0))),
        cov_fx_mu=cov,
        cov_fx_mu_unit=cov_unit,
        ref_config=ref_config,
        is_metric=metric,
        scale=float(k),
        d_hat=d_hat,
        sign=int(sign),
        rig=rig,
        fx_init=float(fx0),
        mu_init=float(mu0),
        sign_choice=sign_choice,
        diagnostics=diag,
    )


# ------------------------------------------------------------------------ synthetic scenes
@dataclass
class SyntheticScene:
    """Ground truth and detections of :func:`synthetic_stereo_scene` (field frame: z up)."""

    detections: dict
    intrinsics: Intrinsics
    T_world_cam: np.ndarray  # (m, 2, 4, 4)
    T_left_right: np.ndarray
    point_ids: np.ndarray
    X_world: np.ndarray
    scale_markers: tuple[int, int]
    scale_distance_m: float
    outlier_rows: list = field(default_factory=list)

    def observations(self) -> Observations:
        return Observations.from_corners(self.detections, n_configs=len(self.T_world_cam))


def _look_at(C: np.ndarray, target: np.ndarray, roll: float) -> np.ndarray:
    z = target - C
    z /= np.linalg.norm(z)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1)
    c, s = np.cos(roll), np.sin(roll)
    R = R @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return make_pose(R, C)


def synthetic_stereo_scene(
    n_configs: int,
    *,
    seed: int = 0,
    fx: float = 800.0,
    mu: float = 1.0,
    width: int = 640,
    height: int = 480,
    n_markers: int = 20,
    marker_size_m: float = 0.03,
    field_m: float = 0.3,
    relief_m: float = 0.08,
    baseline_m: float = 0.06,
    distance_m: tuple[float, float] = (0.2, 0.4),
    tilt_max_deg: float = 35.0,
    roll_max_deg: float = 30.0,
    aim_jitter_m: float = 0.08,
    vergence_distance_m: float | None = None,
    fixate: bool = False,
    noise_px: float = 0.0,
    outlier_fraction: float = 0.0,
    outlier_px: float = 20.0,
    T_world_left: np.ndarray | None = None,
) -> SyntheticScene:
    """Random marker field + stereo rig views, projected with :func:`calib.camera.project`.

    Markers: squares of ``marker_size_m`` at random positions in ``field_m`` x ``field_m``, heights
    uniform in ``[0, relief_m]``, facing +z. Each configuration places the rig midpoint at a
    distance in ``distance_m`` from an aim point (field centre +- ``aim_jitter_m``), tilted up to
    ``tilt_max_deg`` from vertical, rolled up to ``roll_max_deg``; the right camera sits
    ``baseline_m`` along the left x axis (slightly misaligned, or toed-in to meet at
    ``vergence_distance_m``). ``fixate``: every configuration aims both cameras at the field
    centre from the vergence distance (optical axes through one point -- degenerate for fx).
    ``T_world_left`` (m, 4, 4) overrides the sampled left-camera poses.
    Markers with a corner outside the image or behind the camera are dropped. Gaussian noise
    ``noise_px`` per coordinate; ``outlier_fraction`` of the corners displaced by ``outlier_px``.
    """
    rng = np.random.default_rng(seed)
    intr = Intrinsics.centered(fx, mu, width, height)
    centres = np.c_[
        rng.uniform(-field_m / 2, field_m / 2, (n_markers, 2)), rng.uniform(0, relief_m, n_markers)
    ]
    ang = rng.uniform(0, 2 * np.pi, n_markers)
    h = marker_size_m / 2
    local = np.array([[-h, h], [h, h], [h, -h], [-h, -h]])
    X = np.zeros((n_markers, 4, 3))
    for i in range(n_markers):
        c, s = np.cos(ang[i]), np.sin(ang[i])
        X[i, :, :2] = centres[i, :2] + local @ np.array([[c, s], [-s, c]])
        X[i, :, 2] = centres[i, 2]
    X = X.reshape(-1, 3)
    if vergence_distance_m is None and not fixate:
        toe = 0.02
        T_lr = make_pose(
            Rotation.from_rotvec([0.01, -toe, 0.005]).as_matrix(), [baseline_m, 0.001, -0.002]
        )
    else:
        D = vergence_distance_m if vergence_distance_m is not None else np.mean(distance_m)
        toe = 2 * np.arctan2(baseline_m / 2, D)
        T_lr = make_pose(rot_y(-toe)[:3, :3], rot_y(-toe / 2)[:3, :3] @ [baseline_m, 0.0, 0.0])
    # rig midpoint frame -> left camera: left camera at -b/2 along x, toed in by +toe/2
    if vergence_distance_m is None and not fixate:
        T_mid_left = make_pose(np.eye(3), [-baseline_m / 2, 0.0, 0.0])
    else:
        T_mid_left = make_pose(rot_y(toe / 2)[:3, :3], [-baseline_m / 2, 0.0, 0.0])
    zc = relief_m / 2
    Twc = np.zeros((n_configs, 2, 4, 4))
    for i in range(n_configs):
        if fixate:
            target = np.array([0.0, 0.0, zc])
            dist = vergence_distance_m if vergence_distance_m is not None else np.mean(distance_m)
        else:
            target = np.r_[rng.uniform(-aim_jitter_m, aim_jitter_m, 2), zc]
            dist = rng.uniform(*distance_m)
        tilt = np.deg2rad(tilt_max_deg) * np.sqrt(rng.uniform())
        az = rng.uniform(0, 2 * np.pi)
        d = np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        roll = np.deg2rad(rng.uniform(-roll_max_deg, roll_max_deg))
        T_mid = _look_at(target + dist * d, target, roll)
        Twc[i, 0] = T_mid @ T_mid_left if T_world_left is None else T_world_left[i]
        Twc[i, 1] = Twc[i, 0] @ T_lr
    Tcw = inv_pose(Twc)
    det: dict = {}
    rows = []
    for i in range(n_configs):
        for c in range(2):
            uvp = project(intr, Tcw[i, c], X).reshape(n_markers, 4, 2)
            uvp = uvp + noise_px * rng.standard_normal(uvp.shape)
            z = (X @ Tcw[i, c, :3, :3].T + Tcw[i, c, :3, 3])[:, 2].reshape(n_markers, 4)
            inside = (
                (uvp[..., 0] >= 0)
                & (uvp[..., 0] <= width - 1)
                & (uvp[..., 1] >= 0)
                & (uvp[..., 1] <= height - 1)
                & (z > 0)
            ).all(axis=1)
            markers = {}
            for mk in np.flatnonzero(inside):
                markers[int(mk)] = uvp[mk]
                rows.extend((i, c, int(mk), j) for j in range(4))
            if markers:
                det[(i, c)] = markers
    outliers = []
    if outlier_fraction > 0 and rows:
        n_out = int(round(outlier_fraction * len(rows)))
        for idx in rng.choice(len(rows), n_out, replace=False):
            i, c, mk, j = rows[idx]
            phi = rng.uniform(0, 2 * np.pi)
            moved = det[(i, c)][mk][j] + outlier_px * np.array([np.cos(phi), np.sin(phi)])
            if 0 <= moved[0] <= width - 1 and 0 <= moved[1] <= height - 1:
                det[(i, c)][mk][j] = moved
                outliers.append(rows[idx])
    # scale markers: the two markers closest to the centre-left and centre-right of the field
    a = int(np.argmin(np.linalg.norm(centres[:, :2] - [-field_m / 4, 0], axis=1)))
    b = int(np.argmin(np.linalg.norm(centres[:, :2] - [field_m / 4, 0], axis=1)))
    dist_ab = float(np.linalg.norm(X[4 * a : 4 * a + 4].mean(0) - X[4 * b : 4 * b + 4].mean(0)))
    return SyntheticScene(
        det, intr, Twc, T_lr, np.arange(4 * n_markers), X, (a, b), dist_ab, outliers
    )
