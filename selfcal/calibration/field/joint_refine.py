"""One-step maximum-likelihood refinement: kinematics, camera and scene from the pixels directly.

The paper's two-stage method first estimates every camera pose by bundle adjustment and then fits
the kinematic model to those poses with diagonal weights. That discards information: the per-pose
errors are strongly correlated (camera y-translation with rotation about x) and correlated across
poses through the shared 3-D points. Here the camera poses are *not* free: the left camera of
configuration ``i`` is the tool of the MCPC chain, ``T_world_cam_i = fk_tool(model(rho), q_i)``, the
right camera is ``T_world_cam_i @ T_left_right``, and one sparse Levenberg-Marquardt adjustment
minimises the reprojection error over

- ``fx``, ``mu`` (principal point known: the image centre, as in the camera stage),
- the free minimal MCPC parameters ``rho`` (tool = left camera, OpenCV frame),
- the rig ``T_right_left`` (6 parameters: no baseline gauge, the scale comes from ``d``),
- all 3-D marker corners,

plus one *hard* residual ``(|c_a - c_b| - d) / scale_sigma_m`` (in px, i.e. ``d`` known to
``scale_sigma_m`` relative to 1 px of corner noise) for the two scale-marker centres. It starts from
the two-stage result (:mod:`selfcal.calibration.field.self_calibration` + :func:`selfcal.calibration.identify.identify`).

Joint read-back errors (``joint_sigma``): once the poses are tied to the kinematics, the joint
read-back is a measurement too. Encoder quantisation (SCORBOT: 0.002-0.010 deg RMS) moves the
camera by ~0.1-0.2 px, comparable to the per-pose precision of ~40 corners, and an adjustment
that takes ``q`` as exact pushes that misfit into fx, the points and the kinematics (simulation,
noise-free corners, quantised joints: tool tip 0.29 mm instead of the two-stage 0.01 mm).
With ``joint_sigma`` every configuration gets corrections ``dq`` with the Gaussian prior
``dq ~ N(0, joint_sigma^2)`` (errors in variables), which makes the estimate the maximum-
likelihood one for noisy corners *and* noisy read-back (same case: 0.007 mm).

Gauge (:func:`choose_gauge`, :mod:`selfcal.calibration.field.joint_gauge`): with an unknown scene the world frame (6 dof) and the scale are
free. The scale is fixed by the ``d`` residual. The world frame is fixed by holding six MCPC
parameters at their two-stage values: the four base parameters of ``V_0`` (``alpha0, beta0, lx0,
ly0``) and two of ``V_1``. For the SCORBOT (``|alpha1| ~ 90 deg``) a rotation of the world about
joint 1's axis moves exactly ``beta1`` and a shift along that axis exactly ``ly1``
(``Rz(phi) Rx(+-90) = Rx(+-90) Ry(-+phi)``; ``Rx(+-90)^T z = -+y``), so those two are held.
Otherwise the two are chosen by pivoted QR of the gauge directions (the derivative of the minimal
parameters w.r.t. a change of world frame) in the complement of what the base four absorb. The
held set is verified to be transversal to the gauge orbit twice: the 6 x 6 block of the gauge
directions is well conditioned, and the column-scaled Jacobian over all free unknowns (intrinsics,
free MCPC parameters, rig, points) has full column rank at the start
(:class:`JointRefinementError` otherwise). Parameters the two-stage identifiability analysis held
stay held.

Results are reported in the same frame as the two-stage method (world = left camera of the
reference configuration): after the adjustment the model and the points are re-expressed in the
frame of the *refined* reference camera pose, and the parameter covariance is propagated to that
frame (so every minimal parameter gets a standard deviation, like the two-stage report). The
covariance is ``sigma^2 (J^T J)^-1`` of the final least-squares Jacobian restricted to the
kinematic block (points, rig and intrinsics are nuisance parameters, marginalised by the inverse).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from selfcal.calibration.field.adjust import OUTLIER_FLOOR_PX
from selfcal.calibration.field.joint_gauge import JointRefinementError, choose_gauge
from selfcal.calibration.identify import IdentificationResult
from selfcal.camera import Cameras, CameraSet, first_camera
from selfcal.camera.camera_set import free_std
from selfcal.errors import UsageError
from selfcal.estimation.bundle_adjust import _Problem as _AdjustmentProblem
from selfcal.estimation.gauge import GaugeChoice, gauge_directions
from selfcal.estimation.joint_report import (
    aligned_tool_rms_bound,
    encoder_sigma,
    express_in_reference,
    tool_point_covariance,
)
from selfcal.estimation.joint_result import JointRefinementResult
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.estimation.observations import Observations, views_per_point
from selfcal.estimation.reprojection import reprojection_residuals, robust_sigma
from selfcal.estimation.residuals import joint_prior, scale_block
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, param_names
from selfcal.solver import (
    Loss,
    ResidualBlock,
    SchurPlans,
    SolverOptions,
    covariance,
    scaled_rank,
    schur_scaled_rank,
    solve,
)
from selfcal.target import marker_features
from selfcal.terms.base import Term, TermContext, TermSolution, check_terms, term_blocks
from selfcal.transforms import inv_pose

__all__ = [
    "JointRefinementError",
    "KinematicPoses",
    "GaugeChoice",
    "gauge_directions",
    "choose_gauge",
    "JointRefinementResult",
    "joint_refine",
    "tool_point_covariance",
    "encoder_sigma",
    "refine_calibration",
    "aligned_tool_rms_bound",
]

# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------


def joint_refine(
    obs: Observations,
    q: np.ndarray,
    sc,
    ident: IdentificationResult,
    used: np.ndarray,
    *,
    scale_markers: tuple[int, int],
    scale_distance_m: float,
    scale_sigma_m: float = 1e-7,
    joint_sigma: float | np.ndarray | None = None,
    pixel_sigma_px: float | None = None,
    min_pixel_sigma_px: float = 0.01,
    loss: str = "soft_l1",
    robust_scale_px: float = 1.0,
    outlier_px: float = OUTLIER_FLOOR_PX,
    max_rounds: int = 5,
    max_iter: int = 100,
    tol: float = 1e-12,
    terms: Sequence[Term] = (),
    check_rank: bool = True,
    stds: bool = True,
    initial_damping: float | None = None,
) -> JointRefinementResult:
    """Refine kinematics, intrinsics, rig and points together from the corner observations.

    Args:
        obs: the observations the two-stage method used (configs indexed like ``q``).
        q: (m, n) joint read-backs, rad.
        sc: the :class:`selfcal.calibration.field.self_calibration.SelfCalibrationResult` (metric, world = reference camera).
        ident: the two-stage :class:`selfcal.calibration.identify.IdentificationResult` in the same world.
        used: configuration indices the two-stage identification used (registered).
        scale_markers, scale_distance_m: the two scale markers and the distance of their centres.
        scale_sigma_m: the scale residual is ``(|c_a - c_b| - d) / scale_sigma_m`` px (hard).
        joint_sigma: standard deviation of the joint read-back errors (rad / m; scalar or (n,)),
            e.g. encoder quantisation ``1 / (counts_per_rad sqrt(12))``. When given, every
            active configuration gets joint corrections ``dq`` with the Gaussian prior
            ``sigma_px dq / joint_sigma`` (errors in variables: the maximum-likelihood estimate
            when both the corners and the read-back are noisy). None: read-back taken as exact.
        pixel_sigma_px: corner noise per coordinate that scales the joint prior; default the
            camera stage's a-posteriori value (bundle-adjustment residuals, dof-corrected),
            at least ``min_pixel_sigma_px``.
        loss: ``"soft_l1"`` (robust rounds with outlier rejection, then a plain least-squares
            pass) or ``"linear"`` (plain least squares on the two-stage inliers only).
        robust_scale_px, outlier_px: soft-L1 scale; minimum outlier threshold (the threshold is
            ``max(outlier_px, 4.5 sigma)``; :data:`selfcal.calibration.field.adjust.
            OUTLIER_FLOOR_PX`, the camera stage's). After a robust round the final plain pass
            comes: on the round's rows when the round keeps exactly them (another round would
            solve the same problem again), else on the rows it classifies as inliers, and then
            that pass's own fit classifies them again: when it keeps exactly its rows it is the
            result, else robust rounds go on from it (at most ``max_rounds`` robust rounds; the
            pass after the last is not checked).
        terms: further measurements estimated with the rest (:mod:`selfcal.terms`: tracker
            positions, poses or distances, touch-probe points ...): each adds its residual and
            parameter blocks over the free kinematic parameters (block ``poses``), its residuals
            in pixels (one unit = ``pixel_sigma_px`` of its own noise), and reports its
            diagnostics (merged into ``diagnostics``) and section (``sections``).
        check_rank: test the gauge by the rank of the start's Jacobian (a dense eigenvalue
            problem); False where a fit of more unknowns on the same rows passed it (the fair
            nominal, :mod:`selfcal.calibration.field.nominal_fit`): ``rank`` is then -1.
        stds: the covariance of the camera and the kinematic parameters (NaN without).
        initial_damping: the first solve's damping, a warm start for a problem near a solved
            one (:attr:`JointRefinementResult.damping`, the fair nominal's from its
            calibration); each later round starts with the damping the round before ended with
            (its rows are that fit's inliers, so it starts near its minimum: at 300 postures the
            final pass takes 3 iterations where the default damping took 8). None: the
            damping the camera stage's final adjustment ended with (``sc.damping``, at most the
            default): ``ident``'s chain ties the adjusted poses together near that minimum, so
            the first step is nearly undamped as that adjustment's last (at 300 postures of the
            default scenario the robust round takes 6 iterations where the default damping
            takes 9).

    Raises:
        InputError: two terms of one kind; a ``joint_sigma`` not positive and finite.
        JointRefinementError: the scale markers are not reconstructed, the gauge is not fixed
            (rank-deficient Jacobian) or the adjustment does not converge.
    """
    t_start = time.perf_counter()
    if initial_damping is None:
        initial_damping = min(float(sc.damping), SolverOptions.initial_damping)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m = len(q)
    if obs.n_configs != m:
        raise UsageError(f"obs has {obs.n_configs} configurations but q has {m} rows")
    if not sc.is_metric:
        raise JointRefinementError("the camera stage result is not metric (no scale markers)")
    used = np.asarray(used, dtype=np.int64)
    active_cfg = np.zeros(m, bool)
    active_cfg[used] = True
    model0 = ident.model
    idx = minimal_indices(model0.joint_types)
    names = tuple(param_names(idx))

    gauge = choose_gauge(model0)
    held_reason = {h: "gauge (world frame, two-stage value)" for h in gauge.held}
    for h in ident.held:
        held_reason.setdefault(h, ident.held_reason.get(h, "held by the two-stage method"))
    free = np.array([nm not in held_reason for nm in names])
    free_idx = idx[free]

    # ---- rows: observations of the used configurations whose point is reconstructed
    ids, pidx_all = obs.point_index()
    if not np.array_equal(ids, sc.point_ids):
        raise UsageError("obs and the camera-stage result disagree on the point ids")
    has_X = np.isfinite(sc.X_world).all(axis=1)
    cand = active_cfg[obs.config] & has_X[pidx_all]
    view_all = obs.view
    active = cand & np.asarray(sc.inlier, bool)
    scale_pts = []
    for mk in scale_markers:
        want = marker_features(int(mk))
        pos = np.searchsorted(ids, want)
        if not (
            np.all(pos < len(ids)) and np.array_equal(ids[np.minimum(pos, len(ids) - 1)], want)
        ):
            raise JointRefinementError(f"scale marker {mk} is not observed")
        if not has_X[pos].all():
            raise JointRefinementError(
                f"scale marker {mk} is not fully reconstructed by the camera stage; it must be "
                "seen in at least two views"
            )
        scale_pts.append(pos)

    X = np.where(has_X[:, None], sc.X_world, np.nan)
    use_dq = joint_sigma is not None
    pose_model = KinematicPoses(
        model0, q, free_idx, inv_pose(sc.T_first_cam[1:]), active_cfg, joint_corrections=use_dq
    )
    p = pose_model.initial_params()
    if pixel_sigma_px is None:
        pixel_sigma_px = sc.pixel_sigma_px(len(used))
    pixel_sigma_px = max(float(pixel_sigma_px), float(min_pixel_sigma_px))
    prior: list[ResidualBlock] = []
    if joint_sigma is not None:
        js, prior_block = joint_prior(pose_model.dq_cols, joint_sigma, model0.n, pixel_sigma_px)
        prior.append(prior_block)
    camera: Cameras = sc.camera if sc.cameras is None else sc.cameras
    check_terms(terms)
    term_ctx = TermContext(model0, free_idx, "poses", pixel_sigma_px)
    built = [t.build(term_ctx) for t in terms]

    def select(act):
        """Rows and points of the adjustment: points seen in two inlier views."""
        nviews = views_per_point(view_all[act], pidx_all[act], len(ids))
        pts_used = has_X & (nviews >= 2)
        for sp_ in scale_pts:
            if not pts_used[sp_].all():
                raise JointRefinementError(
                    "a scale-marker corner lost its observations (fewer than 2 inlier views); "
                    "the scale cannot be fixed"
                )
        remap = -np.ones(len(ids), np.int64)
        remap[pts_used] = np.arange(int(pts_used.sum()))
        return act & pts_used[pidx_all], pts_used, remap

    robust_left = max_rounds if loss != "linear" else 0  # robust rounds still allowed
    last = robust_left == 0  # the next solve is the plain least-squares pass
    checked = False  # ... whose own fit classifies its rows again (module docstring)
    total_it = n_robust = n_solves = 0
    converged = False
    diag: dict = {}
    rank_info: tuple[float, int] | None = None
    status, message = 0, ""
    plans = SchurPlans()  # rounds on the same rows, the rank check and covariance share them
    while True:
        act, pts_used, remap = select(active)
        x0 = np.concatenate([camera.free_values(), p, X[pts_used].ravel()])
        scale = scale_block(
            (remap[scale_pts[0]], remap[scale_pts[1]]), scale_distance_m, scale_sigma_m
        )
        extra, extra_params = term_blocks(built)  # blocks: reprojection, scale, prior, terms'
        prob = _AdjustmentProblem(
            camera,
            pose_model,
            view_all[act],
            remap[pidx_all[act]],
            obs.uv[act],
            int(pts_used.sum()),
            loss=Loss("linear" if last else loss, robust_scale_px),
            x0=x0,
            extra=[scale, *prior, *extra],
            extra_params=extra_params,
        )
        if rank_info is None and not check_rank:
            rank_info = (float("nan"), -1)
        if rank_info is None and use_dq:  # J^T J as the solver assembles it (no sparse J)
            x_0 = prob.problem.x0
            rank_info = schur_scaled_rank(prob.problem, x_0, "poses", plans=plans)
        if rank_info is None:
            rank_info = scaled_rank(prob.jac(prob.problem.x0))
            if rank_info[1] < prob.n:
                raise JointRefinementError(
                    f"the joint problem is rank deficient ({rank_info[1]} of {prob.n} unknowns "
                    f"determined): the held parameters {gauge.held} do not fix the gauge for "
                    "these data -- check that every joint moves and that the scale markers are "
                    "seen"
                )
        opt = SolverOptions(
            tol=tol if last else 1e-9,
            max_iterations=max_iter,
            eliminate="poses",  # the joint corrections, in large problems (Schur)
            initial_damping=initial_damping,
        )
        sol = solve(prob.problem, opt, plans)
        n_solves += 1
        # the next round starts where this one ended (warm): its rows are this fit's inliers
        initial_damping = min(sol.damping, SolverOptions.initial_damping)
        x, cost, status, message = sol.x, sol.cost, sol.status, sol.message
        r = np.concatenate([v.ravel() for v in sol.residuals.values()])
        total_it += sol.iterations
        camera, p, Xu = prob.unpack(x)
        p = p.copy()
        built = [b.restarted(sol.values) for b in built]
        X = np.full_like(X, np.nan)
        X[pts_used] = Xu
        if last and not checked:
            converged = status > 0
            break
        # reclassify every candidate row with the current estimate
        T = pose_model.poses(p)
        ok = cand & np.isfinite(X[pidx_all]).all(axis=1)
        e = np.full(len(obs), np.inf)
        rr, zz = reprojection_residuals(
            camera, T, np.nan_to_num(X), view_all[ok], pidx_all[ok], obs.uv[ok]
        )
        e[ok] = np.where(zz > 0, np.linalg.norm(rr, axis=1), np.inf)
        n_res = 2 * int(act.sum())
        dof = max(n_res + len(pose_model.dq_cols) + 1 - prob.n, 1)
        sigma = robust_sigma(e[act]) * np.sqrt(n_res / dof)
        thr = max(outlier_px, 4.5 * sigma)
        new_active = ok & (e < thr)
        same = bool(np.array_equal(new_active, active))
        active = new_active
        if last:  # a checked final pass: its fit keeps exactly its rows, or robust rounds again
            if same:
                converged = status > 0
                break
            last = checked = False
            continue
        n_robust += 1
        robust_left -= 1
        # the final plain pass comes next: on the rows the round was fitted to (another robust
        # round would solve the same problem again), or on the rows it changed, checked by the
        # pass's own fit (a robust round on them, the old way, kept them at 300 postures of
        # the default scenario where it took 3 iterations beside the pass's 3)
        last = True
        checked = not same and robust_left > 0
    if not converged:
        raise JointRefinementError(
            f"the joint refinement did not converge within {max_iter} iterations of its final "
            f"pass ({message}): the estimator failed, no check of the data found them wrong; "
            f"tried: Levenberg-Marquardt from its start, {n_robust} robust round(s) ({loss} loss) then "
            f"plain least squares, {int(free.sum())} kinematic parameters free, "
            f"{int(act.sum())} corner observations",
            fix="add postures from other arm configurations, or raise max_iter",
        )

    # ---- statistics at the solution (final least-squares Jacobian)
    rp = sol.residuals["reprojection"]
    # 6 gauge dof are removed by the held parameters, the 7th (scale) by the hard scale row
    dof = max(len(r) - prob.n, 1)
    sigma2 = sum(float(np.sum(v**2)) for k, v in sol.residuals.items() if k != "scale") / dof
    n_cam = camera.n_free
    if stds:
        C = covariance(
            prob.problem,
            x,
            ["intrinsics", ("poses", np.arange(pose_model.k))],
            sigma2=sigma2,
            eliminate="poses",  # the joint corrections, as the solver eliminates them
            plans=plans,
        )
    else:
        C = np.full((n_cam + pose_model.k,) * 2, np.nan)
    cam_std, cams_std = free_std(camera, C[:n_cam, :n_cam])

    model_g = pose_model.kinematic_model(p)
    ref = int(sc.ref_config) if active_cfg[sc.ref_config] else int(used[0])
    q_act = pose_model.joints(p)  # read-back + estimated corrections, active configurations
    q_ref = q_act[np.searchsorted(np.flatnonzero(active_cfg), ref)][None]
    model_ref, cov_ref = express_in_reference(model_g, free_idx, q_ref, model0, C[n_cam:, n_cam:])
    std = np.sqrt(np.clip(np.diag(cov_ref), 0.0, None))
    for nm, why in held_reason.items():
        if not why.startswith("gauge"):
            std[names.index(nm)] = np.nan

    T_ref_world = inv_pose(fk_tool(model_g, q_ref)[0])
    X_ref = X @ T_ref_world[:3, :3].T + T_ref_world[:3, 3]
    T_first_cam = np.concatenate([np.eye(4)[None], inv_pose(pose_model.rigs(p))])
    T_wc = np.full((m, len(T_first_cam), 4, 4), np.nan)
    T_wc[active_cfg] = fk_tool(model_ref, q_act)[:, None] @ T_first_cam

    e_fin = np.linalg.norm(rp, axis=1)
    rms = float(np.sqrt(np.mean(e_fin**2)))
    diag["cost"] = cost
    diag["status"] = int(status)
    diag["message"] = message
    diag["scale_residual_m"] = float(sol.residuals["scale"][0, 0] / scale.w)
    diag["pixel_sigma_px"] = pixel_sigma_px
    diag["joint_sigma"] = None if not use_dq else js.tolist()
    if use_dq:
        dq = p[pose_model.dq_cols].reshape(-1, model0.n)
        diag["joint_correction_rms"] = np.sqrt(np.mean(dq**2, axis=0)).tolist()
    diag["gauge_condition_number"] = gauge.condition_number
    solved = TermSolution(sol.values, sol.residuals, model_ref, model_g, term_ctx)
    reports = [t.report(b, solved) for t, b in zip(terms, built)]
    for rep_ in reports:
        diag |= rep_.diagnostics
    assert rank_info is not None  # set in the first round (there is always one)
    return JointRefinementResult(
        model=model_ref,
        model_gauge=model_g,
        camera=first_camera(camera),  # type: ignore[arg-type]
        fx_std=cam_std.get("fx", float("nan")),
        mu_std=cam_std.get("mu", float("nan")),
        camera_std=cam_std,
        cameras=camera if isinstance(camera, CameraSet) else None,
        cameras_std=cams_std,
        T_first_cam=T_first_cam,
        T_world_cam=T_wc,
        ref_config=ref,
        point_ids=ids,
        X_world=X_ref,
        names=names,
        values=model_ref.params.reshape(-1)[idx],
        std=std,
        covariance=cov_ref,
        free=free,
        gauge=gauge,
        held_reason=held_reason,
        rms_px=rms,
        sigma_px=float(np.sqrt(sigma2)),
        n_inliers=int(act.sum()),
        n_outliers=int((cand & ~act).sum()),
        iterations=total_it,
        rounds=n_solves,
        converged=converged,
        seconds=time.perf_counter() - t_start,
        rank_min_singular=rank_info[0],
        rank=rank_info[1],
        n_unknowns=prob.n,
        diagnostics=diag,
        inlier=act,
        sections=tuple(r.section for r in reports if r.section is not None),
        damping=sol.damping,
    )


def refine_calibration(
    out, obs: Observations, q: np.ndarray, robot, ds_info, **kw
) -> JointRefinementResult:
    """Run :func:`joint_refine` from a two-stage :class:`selfcal.calibration.field.calibrate.CalibrationOutput`
    (its camera stage and identification); ``diagnostics["used_configs"]`` holds the
    configurations it started from (the registered ones). ``ds_info``: the dataset's info (scale
    markers and distance). Keyword arguments go to :func:`joint_refine`; by default the joint
    read-back is modelled with the robot's encoder resolution (:func:`encoder_sigma`).
    :func:`selfcal.calibration.field.results.with_joint` makes it the calibration result."""
    sc, ident = out.selfcal, out.identification
    used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
    kw.setdefault("joint_sigma", encoder_sigma(robot))
    res = joint_refine(
        obs,
        q,
        sc,
        ident,
        used,
        scale_markers=tuple(ds_info.scale_ids),
        scale_distance_m=ds_info.scale_length_m,
        **kw,
    )
    res.diagnostics["used_configs"] = used
    return res
