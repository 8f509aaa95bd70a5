"""Kinematic identification with the MCPC error model (paper eqs. 6-13), as pure functions.

Input: joint read-backs ``q`` (m, n) rad and measured poses ``T_world_cam`` (m, 4, 4) of the tool
(the left camera, OpenCV convention) in an arbitrary but fixed *world* frame (e.g. the bundle
adjustment's reconstruction frame), metres. The model is an :class:`~calib.mcpc.MCPCModel` whose
``V_0`` maps that world frame to joint 1 and whose ``V_n`` maps the last link to the camera, e.g.
``dh_to_mcpc(robot).with_tool(robot.T_flange_cam)`` placed with :func:`initial_base`.

Estimation: Gauss-Newton with Levenberg-Marquardt fallback on the minimal parameter set
(``calib.mcpc.minimal_indices``, 26 parameters for 5 revolute joints). Each iteration solves the
linearised eq. 12, ``y = J rho`` (rows ``[d; delta]`` of every pose in the tool frame, weighted by
``1 / sigma``), by least squares. ``y`` is the exact pose error of :func:`calib.kinematics.pose_error`
and ``J`` the analytic identification Jacobian, corrected by the exact derivative of that error
(``d x delta`` for the translation rows, the inverse left Jacobian of SO(3) for the rotation rows),
so the fixed point is the true weighted least-squares minimum, not only a first-order one.

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
- :func:`express_in_frame` / :func:`align_truth`: re-express one model in the other's world frame
  and joint-offset convention (simulation: the true world transform is known);
- :func:`canonical_base`: express both in a frame attached to axes 1 and 2 (DH frame 0); the
  parameters there do not depend on the measurement frame at all.

Units: SI inside (m, rad); result fields ending in ``_mm`` / ``_deg`` are for reports.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from calib.errors import EstimationError, SelfCalWarning
from calib.identifiability import (
    O1_SCALE_M,
    O1_SCALE_RAD,
    Identifiability,
    analyse_identifiability,
    pose_sigmas,
    triangular_factor,
)
from calib.kinematics import fk_frames, fk_tool, identification_jacobian, pose_error
from calib.mcpc import (
    MCPCModel,
    chain_transforms,
    gauge_fix,
    minimal_indices,
    param_is_angle,
    param_names,
)
from calib.robot_def import RobotDef
from calib.transforms import (
    inv_pose,
    kabsch,
    make_pose,
    rot_x,
    rot_z,
    skew,
    trans,
)

__all__ = [
    "IdentificationError",
    "IdentificationWarning",
    "DHNotRepresentableWarning",
    "IdentificationResult",
    "DHTable",
    "fit_rigid_transform",
    "initial_base",
    "identify",
    "express_in_frame",
    "align_truth",
    "regauge",
    "wrap_params",
    "minimal_difference",
    "to_dh",
    "dh_table",
    "canonical_base",
]


class IdentificationError(EstimationError):
    """Identification cannot give a trustworthy answer (too few poses, rank deficiency that is not
    held, no convergence); the message says why and what to change."""


class IdentificationWarning(SelfCalWarning):
    """Identification succeeded but something deserves attention (parameters held automatically,
    ill-conditioning, residuals much larger than the stated sigmas, base near Euler singularity)."""


class DHNotRepresentableWarning(SelfCalWarning):
    """A model has (nearly but not exactly) parallel consecutive axes: no continuous DH table."""


# --------------------------------------------------------------------------------------------
# Rigid alignment and gauge
# --------------------------------------------------------------------------------------------


def fit_rigid_transform(T_a: np.ndarray, T_b: np.ndarray, length_m: float = 0.1) -> np.ndarray:
    """Least-squares rigid ``T_a_b`` with ``T_a_b @ T_b[i] ~ T_a[i]`` (poses (m, 4, 4) in two frames).

    Closed form (Kabsch/Umeyama without scale) on virtual points: each pose contributes its origin
    and the three points ``origin + length_m * axis``, so positions and orientations both count
    (an orientation error of 1 rad weighs like ``length_m`` metres).
    """
    T_a = np.asarray(T_a, dtype=float).reshape(-1, 4, 4)
    T_b = np.asarray(T_b, dtype=float).reshape(-1, 4, 4)

    def pts(T: np.ndarray) -> np.ndarray:
        o = T[:, :3, 3]
        ax = np.swapaxes(T[:, :3, :3], -1, -2) * length_m  # rows: scaled axes
        return np.concatenate([o, (o[:, None, :] + ax).reshape(-1, 3)], axis=0)

    return kabsch(pts(T_b), pts(T_a))


def regauge(
    chain: list[np.ndarray], joint_types: tuple[str, ...], joint_offsets: np.ndarray
) -> MCPCModel:
    """The MCPC model of the chain ``G_0 Q_1 G_1 ... Q_n G_n`` using *given* joint offsets.

    Same gauge as :func:`calib.mcpc.gauge_fix` (gamma_i = lz_i = 0 for i < n), but the constant
    offsets are imposed rather than chosen for conditioning, so two models of (nearly) the same
    robot get comparable parameters. Angles are wrapped to (-pi, pi].
    """
    params, offsets = gauge_fix(chain, tuple(joint_types), offsets=joint_offsets)
    return MCPCModel(wrap_params(params), tuple(joint_types), offsets)


def wrap_params(params: np.ndarray) -> np.ndarray:
    """Parameters (n + 1, 6) with the angle columns wrapped to (-pi, pi] (same chain)."""
    p = np.array(params, dtype=float, copy=True)
    p[:, :3] = -((-p[:, :3] + np.pi) % (2 * np.pi) - np.pi)
    return p


def minimal_difference(a: MCPCModel, b: MCPCModel) -> np.ndarray:
    """``a - b`` over the minimal parameters (eq. 10 order, SI), angles wrapped to (-pi, pi].

    Raises:
        ValueError: different joint types or joint offsets (re-express one with
            :func:`express_in_frame` ``like=`` the other first).
    """
    if a.joint_types != b.joint_types:
        raise ValueError("models have different joint types")
    if not np.allclose(a.joint_offsets, b.joint_offsets, atol=1e-12):
        raise ValueError(
            "models use different joint offsets, so their parameters are not comparable; "
            "re-express one with express_in_frame(model, T, like=other)"
        )
    idx = minimal_indices(a.joint_types)
    d = a.params.reshape(-1)[idx] - b.params.reshape(-1)[idx]
    ang = param_is_angle(idx)
    d[ang] = (d[ang] + np.pi) % (2 * np.pi) - np.pi
    return d


def express_in_frame(
    model: MCPCModel, T_new_old: np.ndarray, *, like: MCPCModel | None = None
) -> MCPCModel:
    """The same physical chain with its world frame changed: ``T_new_tool = T_new_old T_old_tool``.

    Without ``like`` this is ``model.with_base(T_new_old)`` (joint offsets re-chosen for
    conditioning); with ``like`` the joint offsets of ``like`` are imposed (:func:`regauge`), so the
    result's minimal parameters are directly comparable with ``like``'s.
    """
    T_new_old = np.asarray(T_new_old, dtype=float)
    if like is None:
        return model.with_base(T_new_old)
    G = chain_transforms(model)
    return regauge([T_new_old @ G[0], *G[1:]], model.joint_types, like.joint_offsets)


def align_truth(
    true_model: MCPCModel,
    est_model: MCPCModel,
    q_ref: np.ndarray,
    *,
    length_m: float = 0.1,
) -> MCPCModel:
    """The true model expressed in the estimate's world frame, in the estimate's offset convention.

    The world transform is the best rigid fit (:func:`fit_rigid_transform`) between the two models'
    tool poses at ``q_ref`` (m, n) rad -- use configurations where both models are meaningful, e.g.
    the measurement configurations (if a joint never moved there, the two models only agree for that
    joint value). When the true world -> measurement transform is known (simulation), prefer
    ``express_in_frame(true_model, T_meas_trueworld, like=est_model)``: it does not mix estimation
    error into the alignment. See the module docstring for which parameters are gauge.
    """
    T = fit_rigid_transform(fk_tool(est_model, q_ref), fk_tool(true_model, q_ref), length_m)
    return express_in_frame(true_model, T, like=est_model)


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
class IdentificationResult:
    """Outcome of :func:`identify`. SI units unless a name says otherwise.

    Attributes:
        model: identified model, world = measurement frame of ``T_world_cam``.
        initial_model: the starting model (after base placement).
        names: minimal parameter names, eq. 10 order (``alpha0 .. ly5, lz5``).
        values: identified values of all minimal parameters (rad, m); held ones at their start.
        std: standard deviations (rad, m); ``nan`` for held parameters.
        estimated: boolean mask of estimated parameters; ``held = ~estimated``.
        held_reason: name -> why it was held (``"explicit"`` or ``"unidentifiable from this data"``).
        covariance: (p, p) covariance of the estimated parameters (order of ``names[estimated]``).
        identifiability: the analysis at the start (rank, singular values, indices).
        rank / n_params: numerical rank of the scaled Jacobian of all non-explicitly-held minimal
            parameters / their number.
        condition_number, o1, o3, singular_values: of the estimated set at the solution
            (see :mod:`calib.identifiability` for the scaling and index definitions).
        sigma0: a-posteriori standard deviation of unit weight, sqrt(r^T W r / (6m - p)); ~1 when
            the stated sigmas are right. The std include it.
        rms_t_mm_before/after: RMS of the tool position error norm (mm) before/after.
        rms_r_deg_before/after: RMS of the tool rotation error angle (deg) before/after.
        iterations: Jacobian evaluations; converged: the Gauss-Newton step met ``tol``.
        warnings: what it warned about, one sentence each (also emitted as
            :class:`IdentificationWarning` for people; here as data, so nobody has to catch them).
    """

    model: MCPCModel
    initial_model: MCPCModel
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    estimated: np.ndarray
    held_reason: dict[str, str]
    covariance: np.ndarray
    identifiability: Identifiability
    rank: int
    n_params: int
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

    @property
    def held(self) -> tuple[str, ...]:
        """Names of the parameters held at their starting (nominal) values."""
        return tuple(n for n, e in zip(self.names, self.estimated) if not e)

    def summary(self) -> str:
        """Human-readable table: parameter, value, std (mm / deg)."""
        idx = minimal_indices(self.model.joint_types)
        ang = param_is_angle(idx)
        lines = [
            f"rank {self.rank}/{self.n_params}, cond {self.condition_number:.3g}, O1 {self.o1:.3g}, "
            f"O3 {self.o3:.3g}, sigma0 {self.sigma0:.3g}, iterations {self.iterations}",
            f"RMS before {self.rms_t_mm_before:.4f} mm / {self.rms_r_deg_before:.4f} deg, "
            f"after {self.rms_t_mm_after:.6f} mm / {self.rms_r_deg_after:.6f} deg",
        ]
        for nm, v, s, a in zip(self.names, self.values, self.std, ang):
            k, u = (np.degrees(1.0), "deg") if a else (1000.0, "mm")
            note = f"  held: {self.held_reason[nm]}" if nm in self.held_reason else ""
            lines.append(f"{nm:>7s} {v * k:12.5f} +- {s * k:9.5f} {u}{note}")
        return "\n".join(lines)


def _check_inputs(
    model: MCPCModel, q: np.ndarray, T_world_cam: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T = np.asarray(T_world_cam, dtype=float)
    if q.ndim != 2 or q.shape[1] != model.n:
        raise ValueError(f"q must have shape (m, {model.n}) (rad), got {np.shape(q)}")
    if T.shape != (q.shape[0], 4, 4):
        raise ValueError(f"T_world_cam must have shape ({q.shape[0]}, 4, 4), got {T.shape}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(T))):
        raise ValueError("q and T_world_cam must be finite (drop failed poses before identifying)")
    R = T[:, :3, :3]
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(1, 2))
    if np.any(err > 1e-6) or np.any(np.linalg.det(R) < 0):
        bad = int(np.argmax(err))
        raise ValueError(
            f"T_world_cam[{bad}] is not a rigid transform (R^T R - I up to {err[bad]:.2g})"
        )
    return q, T


def _so3_left_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """Inverse left Jacobian of SO(3) for rotation vectors (..., 3): (..., 3, 3)."""
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = th < 1e-4
    th_s = np.where(small, 1.0, th)
    coef = np.where(
        small,
        1.0 / 12.0 + th**2 / 720.0,
        1.0 / th_s**2 - (1.0 + np.cos(th_s)) / (2.0 * th_s * np.sin(th_s)),
    )
    return np.eye(3) - 0.5 * K + coef * (K @ K)


def _residual_jacobian(J: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Exact ``-d y / d params`` of ``y = pose_error(T_model, T_meas)`` from the tool Jacobian ``J``.

    ``J`` (m, 6, p) gives the model's tool-frame twist per parameter, ``y`` (m, 6) the current error.
    """
    Jv, Jw = J[:, :3], J[:, 3:]
    out = np.empty_like(J)
    out[:, :3] = Jv - skew(y[:, :3]) @ Jw
    out[:, 3:] = _so3_left_jacobian_inv(y[:, 3:]) @ Jw
    return out


def _rms(y: np.ndarray) -> tuple[float, float]:
    t = float(np.sqrt(np.mean(np.sum(y[:, :3] ** 2, axis=1)))) * 1000.0
    r = float(np.degrees(np.sqrt(np.mean(np.sum(y[:, 3:] ** 2, axis=1)))))
    return t, r


def _note(notes: list[str], text: str) -> None:
    """Record ``text`` for :attr:`IdentificationResult.warnings` and warn the caller of
    :func:`identify` (an :class:`IdentificationWarning`)."""
    notes.append(text)
    warnings.warn(text, IdentificationWarning, stacklevel=3)


def identify(
    model: MCPCModel,
    q: np.ndarray,
    T_world_cam: np.ndarray,
    *,
    sigma_t_m: float | np.ndarray = 1e-4,
    sigma_r_rad: float | np.ndarray = 1e-3,
    max_iter: int = 50,
    tol: float = 1e-9,
    hold: list[str] | tuple[str, ...] | None = None,
    auto_hold: bool = True,
    place_base: bool = True,
    rank_rtol: float = 1e-9,
    cond_warn: float = 1e6,
) -> IdentificationResult:
    """Identify the minimal MCPC parameters from joint read-backs and measured tool poses.

    Args:
        model: nominal model with the camera as tool (world frame need not match the data if
            ``place_base``).
        q: (m, n) joint read-backs, rad (m for prismatic joints).
        T_world_cam: (m, 4, 4) measured tool poses in the (arbitrary, fixed) world frame, metres.
        sigma_t_m, sigma_r_rad: standard deviations of the pose error components in the tool frame
            (translation m, rotation rad): scalar, per pose (m,) or per axis (m, 3).
        max_iter: maximum Gauss-Newton / LM iterations.
        tol: convergence when the Gauss-Newton step changes the weighted residuals by less than
            ``tol * max(1, RMS weighted residual)`` (RMS over rows, in units of sigma); equivalently
            the weighted gradient ``J^T W r`` is negligible.
        hold: names (e.g. ``"beta1"``) held at their starting values; their std is nan.
        auto_hold: hold parameters that are not identifiable from these configurations (named in an
            :class:`IdentificationWarning`); with ``False`` such data raise instead.
        place_base: start from :func:`initial_base` (needed when the world frame is arbitrary).
        rank_rtol: relative singular-value threshold of the numerical rank.
        cond_warn: warn above this condition number of the scaled Jacobian.

    Returns:
        :class:`IdentificationResult`.

    Raises:
        ValueError: malformed inputs or unknown ``hold`` names.
        IdentificationError: too few poses (the message names the minimum), rank deficiency with
            ``auto_hold=False``, or no convergence within ``max_iter``.
    """
    q, T_meas = _check_inputs(model, q, T_world_cam)
    notes: list[str] = []
    m = q.shape[0]
    idx = minimal_indices(model.joint_types)
    names = tuple(param_names(idx))
    hold = tuple(hold or ())
    unknown = [h for h in hold if h not in names]
    if unknown:
        raise ValueError(f"cannot hold {unknown}: not minimal parameters; valid names: {names}")
    p_free = idx.size - len(set(hold))
    if 6 * m <= p_free:
        need = p_free // 6 + 1
        raise IdentificationError(
            f"too few poses: {m} poses give {6 * m} equations for {p_free} parameters; need at "
            f"least {need} poses (more than {p_free} equations), better several times that"
        )
    sig = pose_sigmas(sigma_t_m, sigma_r_rad, m)

    # Canonical form (gauge-fixed, same offsets) so that only minimal parameters move.
    model = regauge(chain_transforms(model), model.joint_types, model.joint_offsets)
    start = initial_base(model, q, T_meas) if place_base else model
    if abs(start.params[0, 1]) > np.radians(80.0):
        _note(
            notes,
            f"beta0 = {np.degrees(start.params[0, 1]):.1f} deg: joint 1's axis is nearly along the "
            "world x axis, where V_0's Euler angles are singular; express the measurements in a "
            "frame whose x axis is not along joint 1 (e.g. the nominal base frame) for reliable std",
        )

    ana = analyse_identifiability(
        start, q, sigma_t_m=sig[:, :3], sigma_r_rad=sig[:, 3:], hold=hold, rank_rtol=rank_rtol
    )
    held_reason = {h: "explicit" for h in hold}
    if ana.unidentifiable:
        if not auto_hold:
            raise IdentificationError(
                f"rank {ana.rank} < {int(ana.considered.sum())} parameters: {list(ana.unidentifiable)} "
                "cannot be identified from these configurations (e.g. a joint that never moves); "
                "add them to hold=, pass auto_hold=True, or move every joint"
            )
        _note(
            notes,
            f"held at nominal, not identifiable from these configurations: {list(ana.unidentifiable)}",
        )
        held_reason.update({nm: "unidentifiable from this data" for nm in ana.unidentifiable})
    estimated = ana.identifiable.copy()
    est = idx[estimated]
    p = est.size
    N = 6 * m

    def evaluate(x: np.ndarray) -> tuple[MCPCModel, np.ndarray, np.ndarray]:
        mx = start.with_params(x.reshape(-1, 6))
        y = pose_error(fk_tool(mx, q), T_meas)
        return mx, y, (y / sig).reshape(-1)

    def weighted_jacobian(mx: MCPCModel, y: np.ndarray) -> np.ndarray:
        J = identification_jacobian(mx, q)[:, :, est]
        return (_residual_jacobian(J, y) / sig[:, :, None]).reshape(N, p)

    x = start.params.reshape(-1).copy()
    mx, y, r = evaluate(x)
    y0 = y
    cost = float(r @ r)
    lam = 0.0
    converged = False
    it = 0
    step_rms = np.inf
    while it < max_iter:
        it += 1
        A = weighted_jacobian(mx, y)
        scale = np.linalg.norm(A, axis=0)
        # [As | r] = Q [R, Q^T r; 0, rho]: solve the small triangular system instead of A itself.
        Raug = triangular_factor(np.column_stack([A / scale, r]))
        R, qtr = Raug[:p, :p], Raug[:p, p]
        z = np.linalg.lstsq(R, qtr, rcond=None)[0]
        step_rms = float(np.linalg.norm(R @ z) / np.sqrt(N))
        if step_rms <= tol * max(1.0, float(np.sqrt(cost / N))):
            x_new = x.copy()
            x_new[est] += z / scale
            mx_n, y_n, r_n = evaluate(x_new)
            if float(r_n @ r_n) <= cost * (1 + 1e-10) + 1e-30:
                x, mx, y, r, cost = x_new, mx_n, y_n, r_n, float(r_n @ r_n)
            converged = True
            break
        while True:
            if lam > 0:
                Aug = np.vstack([R, np.sqrt(lam) * np.eye(p)])
                z = np.linalg.lstsq(Aug, np.concatenate([qtr, np.zeros(p)]), rcond=None)[0]
            x_new = x.copy()
            x_new[est] += z / scale
            mx_n, y_n, r_n = evaluate(x_new)
            c_n = float(r_n @ r_n)
            # Accept a decrease, or a change within the rounding noise of the cost (near the
            # minimum the predicted decrease ||A z||^2 is far below eps * cost).
            if np.isfinite(c_n) and (c_n < cost or c_n - cost <= 1e-10 * cost):
                x, mx, y, r, cost = x_new, mx_n, y_n, r_n, c_n
                lam = 0.0 if lam < 1e-6 else lam / 10.0
                break
            lam = max(1e-4, 10.0 * lam)
            if lam > 1e12:
                raise IdentificationError(
                    f"Levenberg-Marquardt cannot reduce the cost after {it} iterations (weighted "
                    f"RMS {np.sqrt(cost / N):.3g}); the start is too far from the data -- check the "
                    "joint/pose pairing, units (m, rad) and the camera convention"
                )
    if not converged:
        raise IdentificationError(
            f"no convergence in {max_iter} iterations (last Gauss-Newton step changed the weighted "
            f"residuals by {step_rms:.3g} sigma RMS, tol {tol:g}); raise max_iter or check the data"
        )

    # Statistics at the solution.
    A = weighted_jacobian(mx, y)
    scale = np.linalg.norm(A, axis=0)
    R = triangular_factor(A / scale)
    _, s, Vt = np.linalg.svd(R)
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
    cov_s = (Vt.T / s**2) @ Vt
    cov = sigma0**2 * cov_s / np.outer(scale, scale)
    if sigma0 > 10.0:
        _note(
            notes,
            f"residuals are {sigma0:.3g} times the stated sigmas: outliers, wrong sigmas, or a "
            "model that does not fit (e.g. joint compliance, wrong camera pairing)",
        )
    phys = np.where(param_is_angle(est), O1_SCALE_RAD, O1_SCALE_M)
    s_phys = np.linalg.svd(R * (scale * phys), compute_uv=False)
    o1 = float(np.exp(np.mean(np.log(s_phys))) / np.sqrt(m))

    final = regauge(chain_transforms(mx), mx.joint_types, mx.joint_offsets)
    values = final.params.reshape(-1)[idx]
    std = np.full(idx.size, np.nan)
    std[estimated] = np.sqrt(np.diag(cov))
    t0, r0 = _rms(y0)
    t1, r1 = _rms(y)
    return IdentificationResult(
        model=final,
        initial_model=start,
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
        iterations=it,
        converged=converged,
        residuals=y,
        warnings=tuple(notes),
    )


# --------------------------------------------------------------------------------------------
# DH equivalent
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DHTable:
    """Standard-DH equivalent of an MCPC model (SI units).

    ``T_world_cam(q) = T_world_base @ prod_i A_i(q_i) @ T_flange_tool`` with
    ``A_i = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``.

    Attributes:
        offset, d, a, alpha: (n,) DH rows (rad, m, m, rad).
        T_world_base: DH frame 0 in the model's world frame.
        T_flange_tool: the tool (camera) in the last DH frame.
    """

    offset: np.ndarray
    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    T_world_base: np.ndarray
    T_flange_tool: np.ndarray

    def rows(self) -> list[tuple[float, float, float, float]]:
        """``[(offset, d, a, alpha), ...]`` per joint (rad, m, m, rad)."""
        return [tuple(float(v) for v in r) for r in zip(self.offset, self.d, self.a, self.alpha)]


def _angle_about(u: np.ndarray, v: np.ndarray, axis: np.ndarray) -> float:
    """Signed angle (rad) rotating unit ``u`` to unit ``v`` about unit ``axis`` (both normal to it)."""
    return float(np.arctan2(np.cross(u, v) @ axis, u @ v))


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def to_dh(
    model: MCPCModel,
    robot: RobotDef,
    *,
    parallel_tol_deg: float = 1.0,
    exact_parallel_rad: float = 1e-9,
) -> DHTable | None:
    """The standard-DH table equivalent to ``model`` (revolute joints), or None where none is sound.

    Frames follow the usual construction on the joint axes at ``q = 0``: ``z_i`` = axis ``i + 1``,
    ``x_i`` along the common normal of axes ``i`` and ``i + 1`` (sign chosen closest to the nominal
    table of ``robot``). The free choices are fixed like the nominal table: DH frame 0 is placed so
    that row 1 has the nominal ``offset_1`` and ``d_1`` (both are gauge with an arbitrary world,
    see the module docstring), the last frame is the nominal last row on top of frame ``n - 1``, and
    the remainder goes to ``T_flange_tool``. For exactly parallel consecutive axes (angle below
    ``exact_parallel_rad``) the common normal is taken through the previous origin (``d_i = 0``).

    Parallel axes: DH is discontinuous there. For two axes at a small angle ``theta`` the common
    normal lies at a distance ~ (offset) / theta along the axes, so ``d`` jumps from 0 to huge values
    and back as ``theta`` passes through zero: a 0.01 deg misalignment of the SCORBOT's parallel
    joints 2, 3, 4 cannot be written as a small DH change. Such models return ``None`` and a
    :class:`DHNotRepresentableWarning` naming the joints and the angle; the MCPC ``beta`` (like
    Hayati's parameter) is the continuous description.

    Raises:
        ValueError: prismatic joints (not supported) or a joint count different from ``robot``'s.
    """
    table, why = dh_table(
        model, robot, parallel_tol_deg=parallel_tol_deg, exact_parallel_rad=exact_parallel_rad
    )
    if why is not None:
        warnings.warn(why, DHNotRepresentableWarning, stacklevel=2)
    return table


def dh_table(
    model: MCPCModel,
    robot: RobotDef,
    *,
    parallel_tol_deg: float = 1.0,
    exact_parallel_rad: float = 1e-9,
) -> tuple[DHTable | None, str | None]:
    """:func:`to_dh` without the warning: ``(table, None)``, or ``(None, why)`` naming the
    nearly parallel joints and their angle when no sound DH table exists.

    Raises:
        ValueError: prismatic joints (not supported) or a joint count different from ``robot``'s.
    """
    out = _dh_impl(model, robot, parallel_tol_deg, exact_parallel_rad, frame0_only=False)
    if isinstance(out, str):
        return None, out
    assert isinstance(out, DHTable)
    return out, None


def canonical_base(
    model: MCPCModel, robot: RobotDef, *, parallel_tol_deg: float = 1.0
) -> np.ndarray:
    """``T_world_base`` of a world-independent frame attached to the robot's first two axes.

    z = joint 1's axis; x and the origin are those of DH frame 0 as in :func:`to_dh` (from the
    common normal of axes 1 and 2 at q = 0, with the nominal ``offset_1`` and ``d_1``). Expressing
    a model there, ``express_in_frame(model, inv_pose(canonical_base(model, robot)), like=ref)``,
    removes the world gauge: the resulting parameters no longer depend on the measurement frame,
    so models identified in different reconstruction frames can be compared one to one (what is
    lost is exactly what is unobservable with an unknown scene: joint 1's zero and the height of
    the base along axis 1). Needs axes 1 and 2 not nearly parallel (true for the SCORBOT).

    Raises:
        ValueError: prismatic joints, or axes 1 and 2 nearly parallel.
    """
    out = _dh_impl(model, robot, parallel_tol_deg, 1e-9, frame0_only=True)
    if isinstance(out, str):
        raise ValueError(f"no canonical base frame: {out}")
    return out


def _dh_impl(
    model: MCPCModel,
    robot: RobotDef,
    parallel_tol_deg: float,
    exact_parallel_rad: float,
    frame0_only: bool,
) -> DHTable | np.ndarray | str:
    """The DH table (or, ``frame0_only``, DH frame 0 as ``T_world_base``), or the reason why
    none exists (a string naming the nearly parallel axes)."""
    if any(t != "revolute" for t in model.joint_types):
        raise ValueError("to_dh supports revolute joints only")
    n = model.n
    if robot.n != n:
        raise ValueError(f"model has {n} joints, robot {robot.name} has {robot.n}")
    F = fk_frames(model, np.zeros((1, n)))[0]
    z = [F[k, :3, 2] for k in range(n)]  # axis k+1 direction
    p = [F[k, :3, 3] for k in range(n)]  # a point on axis k+1
    tol = np.sin(np.radians(parallel_tol_deg))
    for k in range(1 if frame0_only else n - 1):
        s = np.linalg.norm(np.cross(z[k], z[k + 1]))
        if np.sin(exact_parallel_rad) <= s < tol:
            return (
                f"axes of joints {k + 1} and {k + 2} are {np.degrees(np.arcsin(s)):.4g} deg from "
                f"parallel (< {parallel_tol_deg} deg): no continuous DH table exists; use the MCPC "
                "parameters (beta) instead"
            )

    def normal(k: int, origin_prev: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Common normal of axes k+1, k+2 (0-based k): (unit x, foot on axis k+1, point on k+2)."""
        zi, zj = z[k], z[k + 1]
        c = np.cross(zi, zj)
        if np.linalg.norm(c) < np.sin(exact_parallel_rad):
            base = p[k] if origin_prev is None else origin_prev
            w = p[k + 1] - base
            w = w - (w @ zi) * zi
            if np.linalg.norm(w) < 1e-12:
                raise ValueError(f"axes of joints {k + 1} and {k + 2} coincide: DH undefined")
            return w / np.linalg.norm(w), base, base + w
        # closest points P = p_k + t zi, Q = p_{k+1} + u zj
        b = zi @ zj
        w0 = p[k] - p[k + 1]
        dd, e = zi @ w0, zj @ w0
        den = 1.0 - b * b
        t = (b * e - dd) / den
        u = (e - b * dd) / den
        P, Q = p[k] + t * zi, p[k + 1] + u * zj
        return c / np.linalg.norm(c), P, Q

    def row(x_prev, z_prev, o_prev, x_i, z_i, foot, o_i) -> tuple[float, float, float, float]:
        th = _angle_about(x_prev, x_i, z_prev)
        d = float((foot - o_prev) @ z_prev)
        a = float((o_i - foot) @ x_i)
        al = _angle_about(z_prev, z_i, x_i)
        return th, d, a, al

    def closeness(r: tuple[float, float, float, float], i: int) -> float:
        return (
            abs(_wrap(r[0] - robot.dh_offset[i]))
            + abs(_wrap(r[3] - robot.dh_alpha[i]))
            + abs(r[2] - robot.dh_a[i]) / 0.1
        )

    offs, ds, as_, als = [], [], [], []
    # frame 1 from axes 1, 2 -- it fixes frame 0 (nominal offset_1 and d_1)
    x1, foot, o1 = normal(0, None)
    z0 = z[0]
    best = None
    for sgn in (1.0, -1.0):
        xi = sgn * x1
        # x0: xi rotated about z0 by -offset_1 (Rodrigues), so row 1 has the nominal offset
        c, s_ = np.cos(-robot.dh_offset[0]), np.sin(-robot.dh_offset[0])
        x0 = c * xi + s_ * np.cross(z0, xi) + (1 - c) * (z0 @ xi) * z0
        o0 = foot - robot.dh_d[0] * z0
        r = row(x0, z0, o0, xi, z[1], foot, o1)
        if best is None or closeness(r, 0) < closeness(best[0], 0):
            best = (r, x0, o0, xi, o1)
    r, x0, o0, x_prev, o_prev = best
    T_world_base = make_pose(np.column_stack([x0, np.cross(z0, x0), z0]), o0)
    if frame0_only:
        return T_world_base
    offs.append(r[0])
    ds.append(r[1])
    as_.append(r[2])
    als.append(r[3])  # noqa: E702
    z_prev = z[1]
    for k in range(1, n - 1):
        xk, foot, ok = normal(k, o_prev)
        best = None
        for sgn in (1.0, -1.0):
            r = row(x_prev, z_prev, o_prev, sgn * xk, z[k + 1], foot, ok)
            if best is None or closeness(r, k) < closeness(best[0], k):
                best = (r, sgn * xk)
        r, x_prev = best
        o_prev, z_prev = ok, z[k + 1]
        offs.append(r[0])
        ds.append(r[1])
        as_.append(r[2])
        als.append(r[3])  # noqa: E702
    # last row: nominal, on top of frame n-1
    offs.append(float(robot.dh_offset[-1]))
    ds.append(float(robot.dh_d[-1]))
    as_.append(float(robot.dh_a[-1]))
    als.append(float(robot.dh_alpha[-1]))
    T_prev = make_pose(np.column_stack([x_prev, np.cross(z_prev, x_prev), z_prev]), o_prev)
    A_n = (
        rot_z(offs[-1])
        @ trans(np.array([0.0, 0.0, ds[-1]]))
        @ trans(np.array([as_[-1], 0.0, 0.0]))
        @ rot_x(als[-1])
    )
    T_flange_tool = inv_pose(T_prev @ A_n) @ F[n]
    return DHTable(
        offset=np.array([_wrap(v) for v in offs]),
        d=np.array(ds),
        a=np.array(as_),
        alpha=np.array([_wrap(v) for v in als]),
        T_world_base=T_world_base,
        T_flange_tool=T_flange_tool,
    )
