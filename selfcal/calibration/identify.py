"""Kinematic identification with the MCPC error model (paper eqs. 6-13), as pure functions.

Input: joint read-backs ``q`` (m, n) rad and measured poses ``T_world_cam`` (m, 4, 4) of the tool
(the left camera, OpenCV convention) in an arbitrary but fixed *world* frame (e.g. the bundle
adjustment's reconstruction frame), metres. The model is an :class:`~selfcal.kinematics.mcpc.MCPCModel` whose
``V_0`` maps that world frame to joint 1 and whose ``V_n`` maps the last link to the camera, e.g.
``nominal_mcpc(robot).with_tool(robot.T_flange_cam)`` placed with :func:`initial_base`.

Estimation: Levenberg-Marquardt on the project's solver (:mod:`selfcal.solver`) over the minimal
parameter set (``selfcal.kinematics.mcpc.minimal_indices``, 26 parameters for 5 revolute joints): one residual
block of the pose errors ``y`` (rows ``[d; delta]`` of every pose in the tool frame, weighted by
``1 / sigma``; :class:`selfcal.estimation.tracker.TrackerPoseBlock`), ``y`` the exact pose error of
:func:`selfcal.kinematics.forward.pose_error` and its Jacobian the analytic identification Jacobian
corrected by the exact derivative of that error (:func:`selfcal.kinematics.forward.pose_error_jacobian`), so
the fixed point is the true weighted least-squares minimum, not only a first-order one. The base
and the tool are fitted first with the chain held (a hand-eye far from the robot file's would
otherwise lead a small set astray), then every identifiable parameter. Parameters the postures
do not determine (rank of the scaled Jacobian at the start), and beyond ``6 (m - 1)`` for ``m``
poses, are held at the start's values and named.

Gauge (why parameters must be compared in a common world frame): the world frame is free. ``V_0``
(4 minimal parameters alpha0, beta0, lx0, ly0) describes world -> joint-1 axis; a change of world
frame has 6 degrees of freedom, of which ``V_0`` absorbs 4. The remaining 2 -- a rotation ``phi``
about and a translation ``h`` along joint 1's axis -- commute with joint 1 and are pushed by the MCPC
gauge into ``V_1``: for the SCORBOT (axes 1 and 2 perpendicular) ``phi`` lands almost entirely in
beta1 and ``h`` in ly1. But because a real robot's axes 1 and 2 are not exactly perpendicular, the
push leaves a small rotation about / shift along axis 2 that the gauge carries on into ``V_2 ..
V_n``: measured on a perturbed SCORBOT, phi = 0.5 rad changes ly2, ly3 by ~0.5 mm and beta4 by
~0.13 deg, h = 0.1 m changes ly4 by 0.4 mm. So, strictly, *no* individual MCPC parameter is
intrinsic to the robot when the world frame is arbitrary; only joint 1's zero (the world's
azimuth) and the base height along axis 1 are truly unobservable, the rest is intrinsic geometry
written in a world-dependent way. Two ways to compare models one to one:
- :func:`selfcal.kinematics.alignment.express_in_frame` / :func:`selfcal.kinematics.alignment.align_truth`: re-express one model in the other's world frame
  and joint-offset convention (simulation: the true world transform is known);
- :func:`selfcal.kinematics.dh_table.canonical_base`: express both in a frame attached to axes 1 and 2 (DH frame 0); the
  parameters there do not depend on the measurement frame at all.

Units: SI inside (m, rad); result fields ending in ``_mm`` / ``_deg`` are for reports.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from selfcal.errors import EstimationError, InputError, SelfCalWarning, SolverError
from selfcal.estimation.tracker import ChainLayout, TrackerPoseBlock
from selfcal.kinematics.alignment import fit_placement_and_hand_eye, fit_rigid_transform, regauge
from selfcal.kinematics.forward import fk_tool, pose_error
from selfcal.kinematics.identifiability import (
    O1_SCALE_M,
    O1_SCALE_RAD,
    Identifiability,
    analyse_identifiability,
    pose_sigmas,
    priority_order,
    still_joints,
    triangular_factor,
)
from selfcal.kinematics.mcpc import (
    MCPCModel,
    chain_transforms,
    minimal_indices,
    param_is_angle,
    param_names,
)
from selfcal.kinematics.parameter_estimates import ParameterEstimates
from selfcal.solver import ParameterBlock, Problem, SolverOptions, SolverResult, covariance, solve

__all__ = [
    "IdentificationError",
    "IdentificationSolverError",
    "IdentificationWarning",
    "IdentificationResult",
    "initial_base",
    "identify",
]


class IdentificationError(EstimationError):
    """Identification cannot give a trustworthy answer (too few poses, rank deficiency that is not
    held, no convergence); the message says why and what to change."""


class IdentificationSolverError(IdentificationError):
    """The estimator failed: Levenberg-Marquardt did not converge within its budget or stopped on
    non-finite numbers. The message says what was tried; it does not blame the data (a caller
    that runs a data check names the data when the check shows it, or falls back to the nominal
    chain)."""


class IdentificationWarning(SelfCalWarning):
    """Identification succeeded but something deserves attention (parameters held automatically,
    ill-conditioning, residuals much larger than the stated sigmas, base near Euler singularity)."""


def initial_base(model: MCPCModel, q: np.ndarray, T_world_cam: np.ndarray) -> MCPCModel:
    """Place ``model`` in the measurement frame: ``model.with_base(T_world_base)``.

    ``T_world_base`` is the closed-form rigid fit of the model's tool poses at ``q`` (m, n) rad to
    the measured ``T_world_cam`` (m, 4, 4) (:func:`fit_rigid_transform`), which is all a start for
    Gauss-Newton needs when the world frame is arbitrary.
    """
    q, T = _check_inputs(model, q, T_world_cam)
    return model.with_base(fit_rigid_transform(T, fk_tool(model, q)))


# --------------------------------------------------------------------------------------------
# Identification
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class IdentificationResult(ParameterEstimates):
    """Outcome of :func:`identify`. SI units unless a name says otherwise.

    Attributes:
        names, values, std, estimated, held_reason (``"explicit"`` or ``"unidentifiable from
            this data"``), covariance, rank, n_params: :class:`~selfcal.kinematics.parameter_estimates.ParameterEstimates`
            (the rank of the scaled Jacobian at the start).
        model: identified model, world = measurement frame of ``T_world_cam``.
        initial_model: the start the solver used: the nominal model placed by a rigid fit, or
            with its placement and hand-eye fitted in turn when that fits the poses better (the
            held parameters keep its values).
        identifiability: the analysis at the start (rank, singular values, indices).
        condition_number, o1, o3, singular_values: of the estimated set at the solution
            (see :mod:`selfcal.kinematics.identifiability` for the scaling and index definitions).
        sigma0: a-posteriori standard deviation of unit weight, sqrt(r^T W r / (6m - p)); ~1 when
            the stated sigmas are right. The std include it.
        rms_t_mm_before/after: RMS of the tool position error norm (mm) before (the nominal
            model placed by a rigid fit, :func:`initial_base`) / after.
        rms_r_deg_before/after: RMS of the tool rotation error angle (deg) before/after.
        iterations: Jacobian evaluations; converged: the Gauss-Newton step met ``tol``.
        warnings: what it warned about, one sentence each (also emitted as
            :class:`IdentificationWarning` for people; here as data, so nobody has to catch them).
    """

    model: MCPCModel
    initial_model: MCPCModel
    identifiability: Identifiability
    condition_number: float
    o1: float
    o3: float
    singular_values: np.ndarray
    sigma0: float
    rms_t_mm_before: float
    rms_r_deg_before: float
    rms_t_mm_after: float
    rms_r_deg_after: float
    iterations: int
    converged: bool
    residuals: np.ndarray = field(repr=False)
    warnings: tuple[str, ...] = ()

    def summary(self) -> str:
        """Human-readable table: parameter, value, std (mm / deg)."""
        ang = param_is_angle(minimal_indices(self.model.joint_types))
        return "\n".join(
            [
                f"rank {self.rank}/{self.n_params}, cond {self.condition_number:.3g}, O1 {self.o1:.3g}, "
                f"O3 {self.o3:.3g}, sigma0 {self.sigma0:.3g}, iterations {self.iterations}",
                f"RMS before {self.rms_t_mm_before:.4f} mm / {self.rms_r_deg_before:.4f} deg, "
                f"after {self.rms_t_mm_after:.6f} mm / {self.rms_r_deg_after:.6f} deg",
                *self.table(ang),
            ]
        )


def _check_inputs(
    model: MCPCModel, q: np.ndarray, T_world_cam: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T = np.asarray(T_world_cam, dtype=float)
    if q.ndim != 2 or q.shape[1] != model.n:
        raise InputError(f"q must have shape (m, {model.n}) (rad), got {np.shape(q)}")
    if T.shape != (q.shape[0], 4, 4):
        raise InputError(f"T_world_cam must have shape ({q.shape[0]}, 4, 4), got {T.shape}")
    bad = np.flatnonzero(~(np.isfinite(q).all(axis=1) & np.isfinite(T).all(axis=(1, 2))))
    if bad.size:
        raise InputError(
            f"q and T_world_cam must be finite: poses {bad.tolist()[:20]} hold NaN or inf",
            fix="drop failed poses before identifying",
        )
    if not np.all(np.isfinite(model.params)):
        raise InputError("the nominal model holds NaN or inf parameters",
                         fix="check the robot file the model comes from")  # fmt: skip
    R = T[:, :3, :3]
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(1, 2))
    if np.any(err > 1e-6) or np.any(np.linalg.det(R) < 0):
        worst = int(np.argmax(err))
        raise InputError(
            f"T_world_cam[{worst}] is not a rigid transform (R^T R - I up to {err[worst]:.2g})"
        )
    return q, T


def _rms(y: np.ndarray) -> tuple[float, float]:
    t = float(np.sqrt(np.mean(np.sum(y[:, :3] ** 2, axis=1)))) * 1000.0
    r = float(np.degrees(np.sqrt(np.mean(np.sum(y[:, 3:] ** 2, axis=1)))))
    return t, r


def _note(notes: list[str], text: str) -> None:
    """Record ``text`` for :attr:`IdentificationResult.warnings` and warn the caller of
    :func:`identify` (an :class:`IdentificationWarning`)."""
    notes.append(text)
    warnings.warn(text, IdentificationWarning, stacklevel=3)


def _pose_problem(
    start: MCPCModel, q: np.ndarray, T_meas: np.ndarray, sig: np.ndarray, free: np.ndarray
) -> Problem:
    """The weighted pose errors of ``start``'s chain at ``q`` against ``T_meas`` over the flat
    parameters ``free`` (the others held at ``start``'s values): one parameter block ``"mcpc"``
    (every flat parameter) and one residual block ``"poses"``."""
    held = np.ones(start.params.size, dtype=bool)
    held[free] = False
    block = TrackerPoseBlock(
        ChainLayout.whole(start), q, T_meas, sig[:, :3], sig[:, 3:], name="poses"
    )
    return Problem([ParameterBlock("mcpc", start.params.reshape(-1), held=held)], [block])


def _starts(
    start: MCPCModel, q: np.ndarray, T_meas: np.ndarray, hold: np.ndarray
) -> list[tuple[str, MCPCModel]]:
    """Where the solver may start: ``start`` itself and ``start`` with its placement and a tool
    correction fitted in turn by closed-form rigid fits
    (:func:`selfcal.kinematics.alignment.fit_placement_and_hand_eye`; a robot file's camera mount can be far
    from the real one). Of the flat parameters ``hold`` (held by the caller's request) those of
    the base and the tool keep ``start``'s values; the chain's take the fitted start's: the same
    nominal chain, written from the fitted base (the MCPC gauge carries a change of base into
    ``V_1 ..``)."""
    B, C = fit_placement_and_hand_eye(T_meas, fk_tool(start, q), np.eye(4))
    G = chain_transforms(start)
    ends = hold[np.isin(hold // 6, (0, start.n))]  # held base and tool parameters
    base = start.base_offset if np.any(ends < 6) else None  # V_0's held values need its base
    fitted = regauge([B @ G[0], *G[1:-1], G[-1] @ C], start.joint_types, start.joint_offsets, base)
    flat = fitted.params.reshape(-1).copy()
    flat[ends] = start.params.reshape(-1)[ends]
    return [
        ("the nominal chain as placed", start),
        ("placement and hand-eye fitted in turn", fitted.with_params(flat)),
    ]


def _fit(
    start: MCPCModel,
    q: np.ndarray,
    T_meas: np.ndarray,
    sig: np.ndarray,
    est: np.ndarray,
    hold: np.ndarray,
    options: SolverOptions,
) -> tuple[MCPCModel, MCPCModel, Problem, SolverResult, int]:
    """Levenberg-Marquardt on the estimated parameters ``est`` (flat indices) from the better
    (lower cost) of :func:`_starts` first (``hold``: flat indices held by request), in two
    stages each: the base and the tool (``V_0``, ``V_n``) with the chain at the start's values,
    then every estimated parameter from there. Returns the start used, the fitted model, ...
    the last stage's problem and result and the iterations of all stages; raises
    :class:`IdentificationSolverError` naming what was tried when no start converges (a stage
    stopped on its budget or on non-finite numbers)."""
    n = start.n
    ends = est[np.isin(est // 6, (0, n))]
    stages = [("base and tool", ends)] if 0 < ends.size < est.size else []
    stages.append(("every estimated parameter", est))
    starts = _starts(start, q, T_meas, hold)
    cost = [float(np.sum((pose_error(fk_tool(m0, q), T_meas) / sig) ** 2)) for _, m0 in starts]
    tried: list[str] = []
    iterations = 0
    last: SolverError | None = None
    for k in np.argsort(cost, kind="stable").tolist():
        name, first = starts[k]
        model = first
        tried.append(f"from {name} (weighted RMS {np.sqrt(cost[k] / (6 * len(q))):.3g})")
        for what, free in stages:
            prob = _pose_problem(model, q, T_meas, sig, free)
            try:
                sol = solve(prob, options)
            except SolverError as exc:
                last = exc
                tried.append(f"{what}: {exc.message}")
                break
            iterations += sol.iterations
            tried.append(f"{what} ({free.size} parameters): {sol.iterations} iterations, "
                         f"{sol.trials} trials, {sol.message}")  # fmt: skip
            if not sol.converged:
                break
            model = model.with_params(sol.values["mcpc"])
        else:
            return first, model, prob, sol, iterations
    raise IdentificationSolverError(
        "the kinematic identification did not converge (the estimator failed, not necessarily "
        "the data): Levenberg-Marquardt (damping from "
        f"{options.initial_damping:g}, adapted by the gain ratio; at most "
        f"{options.max_iterations} iterations a stage) " + "; ".join(tried),
        fix="hold parameters the postures do not excite, or add postures",
    ) from last


def identify(
    model: MCPCModel,
    q: np.ndarray,
    T_world_cam: np.ndarray,
    *,
    sigma_t_m: float | np.ndarray = 1e-4,
    sigma_r_rad: float | np.ndarray = 1e-3,
    max_iter: int = 100,
    tol: float = 1e-12,
    hold: list[str] | tuple[str, ...] | None = None,
    auto_hold: bool = True,
    place_base: bool = True,
    rank_rtol: float = 1e-9,
    cond_warn: float = 1e6,
    pose_names: tuple[str, ...] | None = None,
) -> IdentificationResult:
    """Identify the minimal MCPC parameters from joint read-backs and measured tool poses.

    Args:
        model: nominal model with the camera as tool (world frame need not match the data if
            ``place_base``).
        q: (m, n) joint read-backs, rad (m for prismatic joints).
        T_world_cam: (m, 4, 4) measured tool poses in the (arbitrary, fixed) world frame, metres.
        sigma_t_m, sigma_r_rad: standard deviations of the pose error components in the tool frame
            (translation m, rotation rad): scalar, per pose (m,) or per axis (m, 3).
        max_iter: Levenberg-Marquardt iterations (Jacobian evaluations) allowed per stage
            (:func:`_fit`: base and tool, then all).
        tol: the solver's relative tolerance (:mod:`selfcal.solver.lm`: cost decrease, step, and
            ``1e-3 tol`` on the scaled gradient).
        hold: names (e.g. ``"beta1"``) held at their starting values; their std is nan.
        auto_hold: hold parameters that are not identifiable from these configurations, and
            beyond ``6 (m - 1)`` parameters the last in :func:`selfcal.kinematics.identifiability.priority_order`
            (too few poses; named in an :class:`IdentificationWarning`); with ``False`` such data
            raise instead.
        place_base: start from :func:`initial_base` (needed when the world frame is arbitrary).
        rank_rtol: relative singular-value threshold of the numerical rank.
        cond_warn: warn above this condition number of the scaled Jacobian.
        pose_names: what the warnings call each pose (e.g. ``"frame 21"``; default ``"pose k"``,
            ``k`` its row of ``q`` from 0).

    Returns:
        :class:`IdentificationResult`.

    Raises:
        ValueError: malformed inputs or unknown ``hold`` names.
        IdentificationError: fewer than 2 poses, too few poses or a rank deficiency with
            ``auto_hold=False`` (the message names the minimum or the parameters), a Jacobian
            rank deficient at the solution.
        IdentificationSolverError: the solver did not converge within ``max_iter`` or stopped on
            non-finite numbers (the message says what was tried).
    """
    q, T_meas = _check_inputs(model, q, T_world_cam)
    notes: list[str] = []
    m = q.shape[0]
    if pose_names is not None and len(pose_names) != m:
        raise InputError(f"{len(pose_names)} pose_names for {m} poses: give one per row of q")
    idx = minimal_indices(model.joint_types)
    names = tuple(param_names(idx))
    hold = tuple(hold or ())
    unknown = [h for h in hold if h not in names]
    if unknown:
        raise InputError(f"cannot hold {unknown}: not minimal parameters; valid names: {names}")
    p_free = idx.size - len(set(hold))
    if m < 2 or (6 * m <= p_free and not auto_hold):
        need = p_free // 6 + 1 if not auto_hold else 2
        raise IdentificationError(
            f"too few poses: {m} poses give {6 * m} equations for {p_free} parameters; need at "
            f"least {need} poses (more than {p_free} equations), better several times that"
        )
    sig = pose_sigmas(sigma_t_m, sigma_r_rad, m)

    # Canonical form (gauge-fixed, same offsets) so that only minimal parameters move.
    model = regauge(chain_transforms(model), model.joint_types, model.joint_offsets)
    start = initial_base(model, q, T_meas) if place_base else model

    ana = analyse_identifiability(
        start, q, sigma_t_m=sig[:, :3], sigma_r_rad=sig[:, 3:], hold=hold, rank_rtol=rank_rtol
    )
    held_reason = {h: "explicit" for h in hold}
    if ana.unidentifiable:
        if not auto_hold:
            raise IdentificationError(
                f"rank {ana.rank} < {int(ana.considered.sum())} parameters: {list(ana.unidentifiable)} "
                f"cannot be identified from these configurations ({still_joints(q, model.joint_types)}); "
                "add them to hold=, pass auto_hold=True, or move every joint"
            )
        _note(
            notes,
            f"held at nominal, not identifiable from these configurations: {list(ana.unidentifiable)} "
            f"({still_joints(q, model.joint_types)})",
        )
        held_reason.update({nm: "unidentifiable from this data" for nm in ana.unidentifiable})
    estimated = ana.identifiable.copy()
    cap = 6 * (m - 1)  # leave one pose's equations to judge the fit (sigma0)
    if estimated.sum() > cap:
        order = [k for k in priority_order(model.joint_types) if estimated[k]]
        few = tuple(names[k] for k in order[cap:])
        estimated[order[cap:]] = False
        _note(
            notes,
            f"held at nominal, too few poses ({m} poses, {6 * m} equations) to estimate more "
            f"than {cap} parameters: {list(few)}",
        )
        held_reason.update({nm: f"too few poses ({m})" for nm in few})
    est = idx[estimated]
    p = est.size
    N = 6 * m

    y0 = pose_error(fk_tool(start, q), T_meas)
    held_flat = idx[[names.index(h) for h in set(hold)]]
    first, mx, prob, sol, iterations = _fit(start, q, T_meas, sig, est, held_flat,
                        SolverOptions(tol=tol, max_iterations=max_iter, linear_solver="dense"))  # fmt: skip
    y = pose_error(fk_tool(mx, q), T_meas)
    cost = 2.0 * sol.cost  # r^T W r

    # Statistics at the solution (columns in the minimal set's order).
    pos = np.searchsorted(np.sort(est), est)  # est's coordinates among the problem's unknowns
    A = np.asarray(prob.jacobian(sol.x).todense())[:, pos]
    scale = np.linalg.norm(A, axis=0)
    R = triangular_factor(A / scale)
    s = np.linalg.svd(R, compute_uv=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if not s[-1] > rank_rtol * s[0]:
        raise IdentificationError(
            f"the Jacobian became rank deficient at the solution (cond {cond:.3g}); the estimate "
            "is not unique -- hold more parameters or use better-spread configurations"
        )
    if cond > cond_warn:
        _note(
            notes,
            f"ill-conditioned identification: condition number {cond:.3g} > {cond_warn:g}; "
            "std will be large for some parameters -- spread the configurations more",
        )
    dof = N - p
    sigma0 = float(np.sqrt(cost / dof))
    cov = covariance(prob, sol.x, [("mcpc", pos)], sigma2=sigma0**2)
    if sigma0 > 10.0:
        k = int(np.argmax(np.sum((y / sig) ** 2, axis=1)))  # the pose furthest from the fit
        name = f"pose {k}" if pose_names is None else pose_names[k]
        _note(
            notes,
            f"residuals are {sigma0:.3g} times the stated sigmas (the largest at {name}: "
            f"{1000 * np.linalg.norm(y[k, :3]):.3g} mm, "
            f"{np.degrees(np.linalg.norm(y[k, 3:])):.3g} deg): outliers, wrong sigmas, or a "
            "model that does not fit (e.g. joint compliance, wrong camera pairing)",
        )
    phys = np.where(param_is_angle(est), O1_SCALE_RAD, O1_SCALE_M)
    s_phys = np.linalg.svd(R * (scale * phys), compute_uv=False)
    o1 = float(np.exp(np.mean(np.log(s_phys))) / np.sqrt(m))

    try:
        final = regauge(chain_transforms(mx), mx.joint_types, mx.joint_offsets, mx.base_offset)
    except InputError:  # the fit turned joint 1's axis onto the world's x axis, where the
        # start's base offset is singular: a base offset chosen for the fitted chain instead
        final = regauge(chain_transforms(mx), mx.joint_types, mx.joint_offsets)
    values = final.params.reshape(-1)[idx]
    std = np.full(idx.size, np.nan)
    std[estimated] = np.sqrt(np.diag(cov))
    t0, r0 = _rms(y0)
    t1, r1 = _rms(y)
    return IdentificationResult(
        model=final,
        initial_model=first,
        names=names,
        values=values,
        std=std,
        estimated=estimated,
        held_reason=held_reason,
        covariance=cov,
        identifiability=ana,
        rank=ana.rank,
        n_params=int(ana.considered.sum()),
        condition_number=cond,
        o1=o1,
        o3=1.0 / cond,
        singular_values=s,
        sigma0=sigma0,
        rms_t_mm_before=t0,
        rms_r_deg_before=r0,
        rms_t_mm_after=t1,
        rms_r_deg_after=r1,
        iterations=iterations,
        converged=sol.converged,
        residuals=y,
        warnings=tuple(notes),
    )
