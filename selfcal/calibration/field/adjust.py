"""The self-calibration's bundle adjustment: its gauge, and robust rounds with outlier rejection.

:func:`gauge` puts the initial reconstruction (:mod:`selfcal.calibration.field.initialise`) into the adjustment's
gauge: world = the first camera of the reference configuration, scale = the rig's first baseline
(``|t(T_cam_first)|`` of the second camera = 1; or, without a rig model, the distance between the
reference view and one other view). With ``rig=True`` the poses are one first-camera pose per
configuration plus one shared transform per further camera (:class:`RigPoses`), else one pose per
view (:class:`FreePoses`).

:func:`adjust` runs the sparse bundle adjustment (:func:`selfcal.estimation.bundle_adjust.bundle_adjust`) with a
soft-L1 loss, re-triangulates every point robustly with the adjusted poses, reclassifies the
observations (threshold ``max(outlier_px, 4.5 sigma)``, ``outlier_px`` by default
:data:`OUTLIER_FLOOR_PX`), and ends with a final least-squares pass over the rows the last
round keeps: at once when a round keeps every row it was fitted to; after a round that drops
rows, a pass whose own fit classifies its rows again the same way, and which is the result
when it keeps exactly them (else the robust rounds go on from it). Views:
:class:`selfcal.estimation.observations.ViewLayout`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.field.initialise import InitialReconstruction
from selfcal.camera import Cameras
from selfcal.estimation.bundle_adjust import BundleResult, bundle_adjust
from selfcal.estimation.observations import Observations, ViewLayout, views_per_point
from selfcal.estimation.pose_models import FreePoses, RigPoses
from selfcal.estimation.reprojection import reprojection_residuals, robust_sigma
from selfcal.estimation.selfcal_errors import ConvergenceError, InsufficientDataError
from selfcal.estimation.triangulation import ray_angle, robust_triangulate
from selfcal.solver import SchurPlans, SolverOptions
from selfcal.transforms import inv_pose, make_pose, mean_rotation

__all__ = ["Reconstruction", "Adjustment", "rig_from_views", "gauge", "adjust", "OUTLIER_FLOOR_PX"]

OUTLIER_FLOOR_PX = 1.0
"""The field route's least outlier threshold (px; its camera stage's and its one-step
refinement's: a corner is an outlier beyond ``max(OUTLIER_FLOOR_PX, 4.5 sigma)``, sigma the
residuals' robust noise per coordinate). The floor keeps near-noise-free data from rejecting
rows on a tiny sigma; above ~0.22 px of noise 4.5 sigma is the threshold. It was 3 px, which
kept corners 1 - 3.4 px off among corners with 0.015 px of noise: on rendered field images a
marker partly hidden behind a raised neighbour gives such corners, and the one or two kept
raised the calibration's noise estimate from ~0.02 to 0.05 - 0.09 px and its tool-point error
several times over. 0.5 px was tried and rejected: on the rendered stereo-lens scenario it also
dropped edge corners 0.5 - 1 px off and moved the right camera's k1 / k2 to 3.1 sigma from the
truth (tests/integration/test_stereo_lenses.py), where 1 px leaves them as 3 px did
(docs/plan.md, "Rendered, on the KR 6's cell")."""


def rig_from_views(
    T_cam_world: np.ndarray, registered: np.ndarray, layout: ViewLayout
) -> np.ndarray:
    """The rig ``T_cam_first`` (N - 1, 4, 4) from per-view poses ``T_cam_world`` (V, 4, 4):
    over the frames where both cameras are ``registered`` (V,), the mean rotation and the median
    translation of ``T_cam_world(c) @ inv(T_cam_world(first))``.

    Raises :class:`InsufficientDataError` when a camera never shares a frame with the first."""
    T = layout.by_frame(T_cam_world)
    reg = layout.by_frame(registered)
    out = []
    for c in range(1, layout.n_cameras):
        both = reg[:, 0] & reg[:, c]
        if not both.any():
            raise InsufficientDataError(
                "no configuration has both cameras registered, so the rig transform cannot be "
                "initialised; make sure left and right images of some configurations see common "
                "markers, or call with rig=False"
            )
        Trl = T[both, c] @ inv_pose(T[both, 0])
        R = mean_rotation(Trl[:, :3, :3])
        out.append(make_pose(R, np.median(Trl[:, :3, 3], axis=0)))
    return np.stack(out) if out else np.zeros((0, 4, 4))


def _reference(registered: np.ndarray, scores: np.ndarray | None) -> int:
    """The registered configuration with the lowest score (the first one without scores)."""
    idx = np.flatnonzero(registered)
    if scores is None:
        return int(idx[0])
    return int(idx[np.argmin(np.asarray(scores, dtype=float)[idx])])


@dataclass
class Reconstruction:
    """A reconstruction in the adjustment's gauge (see the module docstring).

    ``camera``; with ``rig``: ``T_first`` (m, 4, 4) first-camera poses ``T_cam_world`` and
    ``T_rigs`` (N - 1, 4, 4) ``T_cam_first``; without: ``T`` (V, 4, 4) per view. ``reg_v`` (V,)
    and ``reg_c`` (m,) registered views and configurations (the rig model registers whole
    configurations); ``X`` (P, 3) points, ``has_X`` which are reconstructed; the gauge's
    ``ref_config``, ``ref_view`` and (free poses) ``scale_view``.
    """

    layout: ViewLayout
    rig: bool
    camera: Cameras
    T: np.ndarray | None
    T_first: np.ndarray | None
    T_rigs: np.ndarray | None
    reg_v: np.ndarray
    reg_c: np.ndarray
    X: np.ndarray
    has_X: np.ndarray
    ref_config: int
    ref_view: int
    scale_view: int

    def view_ok(self) -> np.ndarray:
        """(V,) bool: views with a pose."""
        return self.layout.per_view(self.reg_c) if self.rig else self.reg_v

    def poses(self) -> np.ndarray:
        """``T_cam_world`` (V, 4, 4) of every view, NaN where not registered."""
        if not self.rig:
            return np.where(self.reg_v[:, None, None], self._free(), np.nan)
        T_first, T_rigs = self.rig_poses()
        Tv = np.empty((self.layout.n_views, 4, 4))
        by = self.layout.by_frame(Tv)
        by[:, 0] = T_first
        for c, T_rig in enumerate(T_rigs, start=1):
            by[:, c] = T_rig @ self.T_first
        Tv[~self.view_ok()] = np.nan
        return Tv

    def pose_model(self) -> RigPoses | FreePoses:
        """The pose model of the next adjustment, started at the current poses."""
        if self.rig:
            return RigPoses(*self.rig_poses(), self.reg_c, self.ref_config)
        return FreePoses(self.poses(), self.reg_v, self.ref_view, self.scale_view)

    def rig_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """``(T_first, T_rigs)`` of the rig model."""
        assert self.T_first is not None and self.T_rigs is not None, "not a rig reconstruction"
        return self.T_first, self.T_rigs

    def _free(self) -> np.ndarray:
        """``T`` of the free-pose model."""
        assert self.T is not None, "a rig reconstruction has no per-view poses"
        return self.T


def gauge(
    init: InitialReconstruction,
    layout: ViewLayout,
    *,
    rig: bool,
    ref_scores: np.ndarray | None = None,
) -> Reconstruction:
    """The initial reconstruction in the adjustment's gauge (module docstring); the reference
    configuration is the registered one with the lowest ``ref_scores`` (default: the first)."""
    T_views = init.T_cam_world.copy()
    T: np.ndarray | None
    T_first: np.ndarray | None
    T_rigs: np.ndarray | None
    reg_v = init.registered.copy()
    X = init.X.copy()
    has_X = np.isfinite(X).all(axis=1)
    reg_c = layout.frame_any(reg_v)
    ref_config = _reference(reg_c, ref_scores)
    reg_ref = layout.by_frame(reg_v)[ref_config]
    ref_cam = int(np.flatnonzero(reg_ref)[0])
    ref_view = int(layout.view(ref_config, ref_cam))
    if rig:
        T_rigs = rig_from_views(T_views, reg_v, layout)
        T_first = np.full((layout.n_frames, 4, 4), np.nan)
        by, reg = layout.by_frame(T_views), layout.by_frame(reg_v)
        done = np.zeros(layout.n_frames, bool)
        for c in range(layout.n_cameras):  # from the first camera registered in the frame
            take = reg[:, c] & ~done
            T_first[take] = by[take, c] if c == 0 else inv_pose(T_rigs[c - 1]) @ by[take, c]
            done |= take
        G = T_first[ref_config].copy()
        s = 1.0 / np.linalg.norm(T_rigs[0, :3, 3])
        T_first = T_first @ inv_pose(G)
        T_first[:, :3, 3] *= s
        T_rigs[:, :3, 3] *= s
        T, scale_view = None, -1
    else:
        G = T_views[ref_view].copy()
        T = T_views @ inv_pose(G)
        same = [int(layout.view(ref_config, c)) for c in range(ref_cam + 1, layout.n_cameras)]
        same = [v for v in same if reg_v[v]]
        others = np.flatnonzero(reg_v & (np.arange(layout.n_views) != ref_view))
        scale_view = same[0] if same else int(others[0])
        s = 1.0 / np.linalg.norm(T[scale_view, :3, 3])
        T[:, :3, 3] *= s
        T_first = T_rigs = None
    X = (X @ G[:3, :3].T + G[:3, 3]) * s
    return Reconstruction(
        layout, rig, init.camera, T, T_first, T_rigs, reg_v, reg_c, X, has_X,
        ref_config, ref_view, scale_view,
    )  # fmt: skip


@dataclass
class Adjustment:
    """Result of :func:`adjust`: the final least-squares pass ``bundle`` over the rows
    ``active`` (k,) (the inliers of reconstructed points in registered views), the number of
    rounds and of evaluations summed over them."""

    bundle: BundleResult
    active: np.ndarray
    rounds: int
    nfev: int


def residuals(rec: Reconstruction, obs: Observations) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals (k, 2) px and depths (k,) of every observation row under ``rec`` (NaN where
    not modelled: unregistered view or unreconstructed point) and the modelled mask (k,)."""
    _, pidx = obs.point_index()
    view = obs.view
    mod = rec.view_ok()[view] & rec.has_X[pidx]
    r = np.full((len(obs), 2), np.nan)
    z = np.full(len(obs), np.nan)
    r[mod], z[mod] = reprojection_residuals(
        rec.camera, rec.poses(), rec.X, view[mod], pidx[mod], obs.uv[mod]
    )
    return r, z, mod


def _prune(rec: Reconstruction, obs: Observations, active: np.ndarray, min_view_points: int):
    """The usable rows of ``active``: drop points seen in fewer than two views and views (or
    configurations, rig model) with fewer than ``min_view_points`` rows, until none is left to
    drop. Updates ``rec`` (registration, reconstructed points)."""
    _, pidx = obs.point_index()
    view = obs.view
    while True:
        a = active & rec.view_ok()[view] & rec.has_X[pidx]
        nv = views_per_point(view[a], pidx[a], len(rec.X))
        lost_pts = rec.has_X & (nv < 2)
        unit = obs.config if rec.rig else view
        ok_unit = rec.reg_c if rec.rig else rec.reg_v
        cnt = np.bincount(unit[a], minlength=len(ok_unit))
        lost_units = ok_unit & (cnt < min_view_points)
        if not lost_pts.any() and not lost_units.any():
            return a
        rec.has_X = rec.has_X & ~lost_pts
        if rec.rig:
            rec.reg_c = rec.reg_c & ~lost_units
        else:
            rec.reg_v = rec.reg_v & ~lost_units
        if (rec.rig and not rec.reg_c[rec.ref_config]) or (
            not rec.rig and not rec.reg_v[rec.ref_view]
        ):
            raise ConvergenceError(
                "the reference configuration lost its observations during outlier rejection;"
                " the data are inconsistent (wrong marker ids or very large noise?)"
            )


def _retriangulate(
    rec: Reconstruction,
    obs: Observations,
    res: BundleResult,
    fitted: np.ndarray,
    outlier_px: float,
    seed: int,
) -> np.ndarray:
    """Robust re-triangulation with the adjusted poses (a point dragged by an outlier in an early
    view is recovered, and its correct observations re-enter); returns the new inlier rows. A
    point whose inlier rows are the rows ``fitted`` (k,) the adjustment used keeps its adjusted
    position (the next pass starts from it)."""
    _, pidx = obs.point_index()
    view = obs.view
    n_res = res.residuals.size
    dof = max(n_res - len(res.pose_params) - res.X.size - res.n_intrinsics, 1)
    sigma = robust_sigma(np.linalg.norm(res.residuals, axis=1))
    sigma *= np.sqrt(n_res / dof)  # residuals of a fit are smaller than the noise
    thr_out = max(outlier_px, 4.5 * sigma)
    Tv = rec.poses()
    vis = rec.view_ok()[view]
    Xr, inl_r = robust_triangulate(
        Tv,
        view[vis],
        pidx[vis],
        obs.uv[vis],
        rec.camera,
        len(rec.X),
        thr_out,
        X_current=np.where(rec.has_X[:, None], rec.X, np.nan),
        seed=seed,
    )
    ang = ray_angle(Tv, view[vis][inl_r], pidx[vis][inl_r], Xr, len(rec.X))
    good = np.isfinite(Xr).all(axis=1) & (rec.has_X | (ang >= np.deg2rad(1.0)))
    new_active = np.zeros(len(obs), bool)
    new_active[np.flatnonzero(vis)] = inl_r & good[pidx[vis]]
    moved = np.zeros(len(rec.X), bool)
    moved[pidx[new_active != fitted]] = True
    take = good & (moved | ~rec.has_X)
    rec.X = np.where(take[:, None], Xr, rec.X)
    rec.has_X = rec.has_X | good
    return new_active


def adjust(
    rec: Reconstruction,
    obs: Observations,
    active: np.ndarray,
    *,
    outlier_px: float = OUTLIER_FLOOR_PX,
    robust_scale_px: float = 1.0,
    max_rounds: int = 5,
    max_nfev: int = 200,
    min_view_points: int = 6,
    seed: int = 0,
) -> Adjustment:
    """Robust rounds, then the final least-squares pass (module docstring), starting from the
    rows ``active`` (k,): at most ``max_rounds`` robust rounds (the pass after the last is not
    checked). Updates ``rec`` to the adjusted reconstruction.

    Raises :class:`ConvergenceError` when the reference configuration loses its observations."""
    _, pidx = obs.point_index()
    view = obs.view
    n_points = len(rec.X)
    n_rounds = total_nfev = 0
    rnd = 0
    damping = SolverOptions.initial_damping  # each round starts with the last one's (warm)
    plans = SchurPlans()  # rounds on the same rows (and the covariance) share their structure
    checked = False  # a final pass on rows a robust round changed: its own fit classifies them
    while True:
        last = checked or rnd == max_rounds
        a = _prune(rec, obs, active, min_view_points)
        used = np.flatnonzero(rec.has_X)
        remap = -np.ones(n_points, int)
        remap[used] = np.arange(len(used))
        model = rec.pose_model()
        res = bundle_adjust(
            model,
            model.initial_params(),
            rec.X[used],
            view[a],
            remap[pidx[a]],
            obs.uv[a],
            rec.camera,
            loss="linear" if last else "soft_l1",
            f_scale_px=robust_scale_px,
            max_nfev=max_nfev,
            tol=1e-12 if last else 1e-9,
            initial_damping=min(damping, SolverOptions.initial_damping),
            plans=plans,
        )
        damping = res.damping
        n_rounds += 1
        total_nfev += res.nfev
        rec.camera = res.camera
        rec.X = rec.X.copy()
        rec.X[used] = res.X
        if isinstance(model, RigPoses):
            first = rec.layout.of_camera(res.T_cam_world, 0)
            rec.T_first = np.where(rec.reg_c[:, None, None], first, np.nan)
            rec.T_rigs = model.rigs(res.pose_params)
        else:
            rec.T = res.T_cam_world
        if last and not checked:
            return Adjustment(res, a, n_rounds, total_nfev)
        kept = (rec.X, rec.has_X)  # the pass's points, should its classification keep its rows
        new_active = _retriangulate(rec, obs, res, a, outlier_px, seed + rnd)
        if checked:
            checked = False
            if np.array_equal(new_active, a):
                rec.X, rec.has_X = kept
                return Adjustment(res, a, n_rounds, total_nfev)
            active = new_active  # the plain fit changes its rows: robust rounds go on from it
            continue
        if not np.any(a & ~new_active):
            # the round keeps every row it was fitted to: another robust round would solve the
            # same problem again, or one with a few more rows that lie within the threshold of
            # this fit (rows an earlier step left out), so the final pass comes next, over them
            max_rounds = rnd + 1
        elif rnd + 1 < max_rounds:
            # it drops rows: the final pass comes next, over the rows it keeps, and its own fit
            # classifies them again (a robust round on them, the old way, kept them at 300
            # postures of the default scenario, 5 iterations beside the pass's 3)
            checked = True
        active = new_active
        rnd += 1
