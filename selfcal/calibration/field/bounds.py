"""Cramer-Rao bounds of the one-step (joint) calibration model: parameters and the tool tip.

The measurement model is the one :func:`selfcal.calibration.field.joint_refine.joint_refine` fits: every marker corner
seen in camera ``c`` of configuration ``i`` is observed as ``proj(camera, T_cam_world(i, c), X) +
e`` (the camera model's projection, :mod:`selfcal.camera`) with ``e ~ N(0, sigma^2 I_2)`` px, the left
camera is the MCPC tool at the *true* joints ``q_i + dq_i`` (read-back ``q_i``, read-back error
``dq_i ~ N(0, diag(joint_sigma^2))``), the right camera is rigidly attached (rig), the corners' 3-D
positions are unknown, and the distance of the two scale markers' centres is known (a hard
constraint). The Fisher information of all unknowns ``[camera's free parameters (fx, mu), rho_free,
rig, dq, X]`` is ``J^T J`` of the whitened residuals (the joint refinement's own sparse Jacobian,
rows divided by sigma; the ``dq`` prior rows make it the Bayesian/errors-in-variables information).
The gauge is fixed like the joint refinement fixes it (six MCPC parameters of the world frame held,
:func:`selfcal.calibration.field.joint_refine.choose_gauge`); nuisance parameters (intrinsics, rig, read-back errors,
points) are marginalised by the inverse.

Bounds given (:class:`CramerRao`):

- every minimal MCPC parameter in the *reference-camera frame* (world = left camera of the
  reference configuration, the frame of ``calibration.json`` and of the report's parameter
  table; the uncertainty of that camera's pose -- including its read-back error -- is propagated);
- every free camera parameter (``fx``, ``mu``);
- the RMS error of a camera-attached point (the tool tip) over validation postures *after the
  best rigid alignment*, as :mod:`selfcal.kinematics.accuracy` measures it: ``sqrt(trace(P S P) / k)`` with ``S``
  the (3k, 3k) covariance of the stacked predicted points and ``P`` the projector removing rigid
  motions (first order; the metric is gauge invariant, so the held-parameter gauge can be used).

For an unbiased estimator, ``E[rms^2] >= bound^2`` and ``E[(theta_j - theta_j*)^2] >= bound_j^2``.
The bound is a property of the *data* (poses, visible corners, noise levels), not of the
estimator: the two-stage method has the same bound and a larger achieved error.

:mod:`selfcal.calibration.field.bounds_setup` builds the :class:`FisherSetup` of a planned data set or of a calibration;
:func:`selfcal.calibration.field.results.with_bounds` puts the bounds into the calibration result.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.field.joint_refine import KinematicPoses, choose_gauge
from selfcal.camera import Cameras, first_camera
from selfcal.camera.camera_set import free_std
from selfcal.errors import EstimationError, InputError
from selfcal.estimation.bundle_adjust import _Problem as _AdjustmentProblem
from selfcal.estimation.residuals import joint_prior, scale_block
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.solver import (
    ResidualBlock,
    SchurPlans,
    covariance,
    inverse_block,
    scaled_rank,
    schur_scaled_rank,
)
from selfcal.transforms import inv_pose, skew

__all__ = [
    "BoundsError",
    "FisherSetup",
    "CramerRao",
    "fisher_jacobian",
    "cramer_rao",
    "aligned_rms_from_covariance",
    "aligned_error_dof",
]


class BoundsError(EstimationError, ValueError):
    """The Fisher information is singular or the inputs are inconsistent; the message says why."""


@dataclass(frozen=True)
class FisherSetup:
    """Everything the Fisher information of the joint model depends on (SI, px).

    Attributes:
        model: MCPC chain whose tool is the left camera (OpenCV frame), world frame arbitrary.
        q: (m, n) joints (rad / m) of the configurations (read-back; the information is
            evaluated there).
        camera: the camera model (its free parameters are unknowns), shared by every camera
            of the rig, or a :class:`selfcal.camera.CameraSet` (each camera its own).
        T_first_cam: (N, 4, 4) the rig: each camera's pose in the first camera's frame (m).
        X_world: (P, 3) corner positions in the model's world frame.
        view: (k,) view of every observation (:class:`selfcal.estimation.observations.ViewLayout` over the
            configurations of ``q``); ``pidx``: (k,) its point index.
        scale_points: two arrays of point indices (each marker's four corners) whose centres are
            ``scale_distance_m`` apart.
        pixel_sigma_px: corner noise per coordinate; ``joint_sigma``: (n,) read-back standard
            deviation (rad / m) or None (read-back exact).
        held: minimal parameters held beyond the gauge (e.g. unidentifiable ones).
        ref_config: index into ``q`` of the reference configuration (world of the reported
            parameters = its left camera).
    """

    model: MCPCModel
    q: np.ndarray
    camera: Cameras
    T_first_cam: np.ndarray
    X_world: np.ndarray
    view: np.ndarray
    pidx: np.ndarray
    scale_points: tuple[np.ndarray, np.ndarray]
    scale_distance_m: float
    pixel_sigma_px: float
    joint_sigma: np.ndarray | None = None
    held: tuple[str, ...] = ()
    ref_config: int = 0
    scale_sigma_m: float = 1e-7

    @property
    def fx(self) -> float:
        """The (first camera's) pinhole's focal length (px)."""
        return first_camera(self.camera).fx  # type: ignore[attr-defined]

    @property
    def mu(self) -> float:
        """The (first camera's) pinhole's aspect ratio."""
        return first_camera(self.camera).mu  # type: ignore[attr-defined]

    @property
    def T_left_right(self) -> np.ndarray:
        """The second (right) camera's pose in the first (left) camera frame (m)."""
        return self.T_first_cam[1]


@dataclass
class _Layout:
    pose_model: KinematicPoses
    names: tuple[str, ...]
    held: dict[str, str]
    free: np.ndarray  # mask over the minimal parameters
    free_idx: np.ndarray  # flat indices of the free ones
    n_camera: int  # the camera's free parameters: the first columns of x
    kin_cols: np.ndarray  # columns of [camera's free parameters, rho_free] in x
    dq_ref_cols: np.ndarray  # columns of the reference configuration's read-back errors (or [])


class _ReferenceKept(KinematicPoses):
    """:class:`KinematicPoses` whose reference configuration's read-back errors are not
    eliminated with their configuration but kept with the shared unknowns: the bounds need
    their covariance, which :func:`selfcal.solver.covariance` gives for kept unknowns."""

    def __init__(self, *args, ref_config: int, **kw) -> None:
        super().__init__(*args, **kw)
        self.ref_config = ref_config

    def param_instances(self) -> np.ndarray:
        inst = super().param_instances()
        n = self.model.n
        inst[self.dq_cols[n * self.ref_config : n * (self.ref_config + 1)]] = -1
        return inst


def _layout(s: FisherSetup) -> _Layout:
    idx = minimal_indices(s.model.joint_types)
    names = tuple(param_names(idx))
    gauge = choose_gauge(s.model)
    held = {h: "gauge (world frame)" for h in gauge.held}
    for h in s.held:
        if h not in names:
            raise BoundsError(f"held parameter {h!r} is not a minimal parameter; known: {names}")
        held.setdefault(h, "held")
    free = np.array([nm not in held for nm in names])
    free_idx = idx[free]
    use_dq = s.joint_sigma is not None
    pm = _ReferenceKept(
        s.model, s.q, free_idx, inv_pose(s.T_first_cam[1:]), joint_corrections=use_dq,
        ref_config=s.ref_config,
    )  # fmt: skip
    nc = s.camera.n_free
    kin_cols = np.arange(nc + pm.k)
    n = s.model.n
    dq_ref = nc + pm.dq_cols[n * s.ref_config : n * (s.ref_config + 1)] if use_dq else np.zeros(0)
    return _Layout(pm, names, held, free, free_idx, nc, kin_cols, dq_ref.astype(np.int64))


def fisher_jacobian(s: FisherSetup) -> tuple:
    """The whitened Jacobian ``J`` (sparse, rows / sigma) with Fisher information ``J^T J``, the
    unknowns ``x = [camera's free parameters, rho_free, rig (6 per further camera), dq (n per
    configuration), X (3 P)]`` and the layout. Returns ``(J, layout)``."""
    prob, x, lay = _fisher_problem(s)
    return (prob.jac(x) / s.pixel_sigma_px).tocsr(), lay


def _fisher_problem(s: FisherSetup) -> tuple[_AdjustmentProblem, np.ndarray, _Layout]:
    """The joint model's problem of the setup (residuals in px against zero observations: only
    its Jacobian is used), its unknowns ``x`` at the setup's values and the layout."""
    q = np.atleast_2d(np.asarray(s.q, dtype=float))
    if q.shape[1] != s.model.n:
        raise BoundsError(f"q must have shape (m, {s.model.n}), got {q.shape}")
    if not (0 <= s.ref_config < len(q)):
        raise BoundsError(
            f"ref_config {s.ref_config} is not a configuration index (0..{len(q) - 1})"
        )
    if not (s.pixel_sigma_px > 0):
        raise BoundsError(f"pixel_sigma_px must be > 0, got {s.pixel_sigma_px}")
    X = np.asarray(s.X_world, dtype=float)
    if not np.isfinite(X[np.unique(s.pidx)]).all():
        raise BoundsError("an observed point has no (finite) position; drop its observations")
    lay = _layout(s)
    pm = lay.pose_model
    extra: list[ResidualBlock] = [scale_block(s.scale_points, s.scale_distance_m, s.scale_sigma_m)]
    if s.joint_sigma is not None:
        try:
            extra.append(joint_prior(pm.dq_cols, s.joint_sigma, s.model.n, s.pixel_sigma_px)[1])
        except InputError as e:
            raise BoundsError(e.message, fix=e.fix) from e
    prob = _AdjustmentProblem(
        s.camera,
        pm,
        np.asarray(s.view, dtype=np.int64),
        np.asarray(s.pidx, dtype=np.int64),
        np.zeros((len(s.view), 2)),
        len(X),
        extra=extra,
    )
    x = np.concatenate([s.camera.free_values(), pm.initial_params(), X.ravel()])
    return prob, x, lay


def aligned_rms_from_covariance(points_m: np.ndarray, S: np.ndarray) -> float:
    """RMS (m) of the errors of ``k`` points (k, 3) with stacked covariance ``S`` (3k, 3k) after
    the best rigid alignment (first order: the rigid motions about the centroid are projected
    out): ``sqrt(trace(P S P) / k)``."""
    P_world = np.asarray(points_m, dtype=float)
    k = len(P_world)
    c = P_world - P_world.mean(axis=0)
    rigid = np.concatenate([np.tile(np.eye(3), (k, 1)), -skew(c).reshape(-1, 3)], axis=1)
    Q, _ = np.linalg.qr(rigid)
    PS = S - Q @ (Q.T @ S)
    tr = np.trace(PS) - np.trace(Q.T @ PS @ Q)
    return float(np.sqrt(max(tr, 0.0) / k))


def aligned_error_dof(points_m: np.ndarray, S: np.ndarray) -> float:
    """Effective degrees of freedom ``nu = (sum l)^2 / sum l^2`` of the aligned squared error
    (eigenvalues ``l`` of ``P S P``): ``k rms^2 / trace(P S P)`` of an efficient Gaussian
    estimator is then approximately ``chi2(nu) / nu`` (Satterthwaite), which gives the sampling
    interval of a Monte Carlo ratio achieved / bound."""
    P_world = np.asarray(points_m, dtype=float)
    k = len(P_world)
    c = P_world - P_world.mean(axis=0)
    rigid = np.concatenate([np.tile(np.eye(3), (k, 1)), -skew(c).reshape(-1, 3)], axis=1)
    Q, _ = np.linalg.qr(rigid)
    Pr = np.eye(3 * k) - Q @ Q.T
    lam = np.clip(np.linalg.eigvalsh(Pr @ S @ Pr), 0.0, None)
    return float(lam.sum() ** 2 / max(np.sum(lam**2), 1e-300))


@dataclass
class CramerRao:
    """Cramer-Rao bounds of one data set (see the module docstring). SI units.

    ``names``: minimal parameters (eq. 10 order); ``held``: name -> why (gauge or held);
    ``std_ref`` (P,): bound of every minimal parameter in the reference-camera frame (NaN for
    parameters held beyond the gauge); ``cov_ref`` (P, P) their covariance; ``model_ref`` the
    setup's model in that frame. ``cov_free``: covariance of ``rho_free`` (``free_idx`` flat
    indices of ``model``) in the held-parameter gauge. ``camera_std``: the bound of every free
    camera parameter by name (``fx_std``, ``mu_std`` the pinhole's; the first camera's when the
    rig's cameras have their own models, ``cameras_std`` then holds each camera's by name).
    """

    model: MCPCModel
    model_ref: MCPCModel
    names: tuple[str, ...]
    held: dict[str, str]
    free_idx: np.ndarray
    cov_free: np.ndarray
    cov_ref: np.ndarray
    std_ref: np.ndarray
    camera_std: dict[str, float]
    pixel_sigma_px: float
    n_observations: int
    n_unknowns: int
    extra: dict = field(default_factory=dict)
    cameras_std: dict[str, dict[str, float]] | None = None

    @property
    def fx_std(self) -> float:
        """Bound of the pinhole's ``fx`` (px; NaN when held)."""
        return self.camera_std.get("fx", float("nan"))

    @property
    def mu_std(self) -> float:
        """Bound of the pinhole's ``mu`` (NaN when held)."""
        return self.camera_std.get("mu", float("nan"))

    def tool_points(self, q: np.ndarray, T_cam_point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted points (k, 3) m and their stacked covariance (3k, 3k) m^2 at joints ``q``."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        T = fk_tool(self.model, q)
        Jb = identification_jacobian(self.model, q)[:, :, self.free_idx]
        pt = np.asarray(T_cam_point, dtype=float)[:3, 3]
        Jp = (T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])).reshape(-1, len(self.free_idx))
        P = (T @ np.asarray(T_cam_point, dtype=float))[:, :3, 3]
        return P, Jp @ self.cov_free @ Jp.T

    def aligned_tool_rms(self, q: np.ndarray, T_cam_point: np.ndarray) -> float:
        """Bound (m) of the RMS error of a camera-attached point over postures ``q`` after the
        best rigid alignment (the validation metric of :mod:`selfcal.kinematics.accuracy`)."""
        P, S = self.tool_points(q, T_cam_point)
        return aligned_rms_from_covariance(P, S)

    def scaled(self, pixel_sigma_px: float) -> CramerRao:
        """The bound for another corner noise with the read-back noise scaled alike (the whole
        information scales by ``(sigma_old / sigma_new)^2``)."""
        f = (float(pixel_sigma_px) / self.pixel_sigma_px) ** 2
        return dataclasses.replace(
            self,
            cov_free=self.cov_free * f,
            cov_ref=self.cov_ref * f,
            std_ref=self.std_ref * np.sqrt(f),
            camera_std={k: v * np.sqrt(f) for k, v in self.camera_std.items()},
            cameras_std=None
            if self.cameras_std is None
            else {
                c: {k: v * np.sqrt(f) for k, v in d.items()} for c, d in self.cameras_std.items()
            },
            pixel_sigma_px=float(pixel_sigma_px),
        )


def cramer_rao(s: FisherSetup, *, rank_tol: float = 1e-10) -> CramerRao:
    """Cramer-Rao bounds of the setup's data (see the module docstring).

    Raises:
        BoundsError: the Fisher information is singular (a parameter is not determined by these
            data in this gauge: too few configurations, a joint that never moves, points seen
            once, no scale markers).
    """
    prob, x, lay = _fisher_problem(s)
    n_unknowns, rtol = prob.n, float(np.sqrt(rank_tol))
    # the scaled eigenvalue ratio of J^T J (dense up to DENSE_MAX unknowns, Lanczos above; with
    # read-back errors on the Schur parts, as the solver eliminates them per configuration)
    plans = SchurPlans(normal=True)  # the rank check's J^T J, for the covariance
    if s.joint_sigma is not None:
        ratio, rank = schur_scaled_rank(prob.problem, x, "poses", rtol=rtol, plans=plans)
    else:
        J = prob.jac(x) / s.pixel_sigma_px
        ratio, rank = scaled_rank(J, rtol=rtol)
    if ratio**2 <= rank_tol:
        raise BoundsError(
            f"the Fisher information is singular (scaled eigenvalue ratio {ratio**2:.2e}, "
            f"{n_unknowns - rank} direction(s)): these data do not determine every unknown -- "
            "check that every joint moves, that points are seen in two views and that the scale "
            "markers are seen"
        )
    if s.joint_sigma is not None:  # the Schur complement of the other configurations' dq
        pm, n = lay.pose_model, s.model.n
        sel = np.r_[np.arange(pm.k), pm.dq_cols[n * s.ref_config : n * (s.ref_config + 1)]]
        C = covariance(prob.problem, x, ["intrinsics", ("poses", sel)],
                       sigma2=s.pixel_sigma_px**2, eliminate="poses", plans=plans)  # fmt: skip
    else:
        C = inverse_block(J, np.r_[lay.kin_cols, lay.dq_ref_cols])
    nk, nc = len(lay.kin_cols), lay.n_camera
    camera_std, cameras_std = free_std(s.camera, C[:nc, :nc])
    cov_free = C[nc:nk, nc:nk]
    # ---- the reference-camera frame: world = left camera at the reference configuration
    model = s.model
    idx = minimal_indices(model.joint_types)
    q_ref = np.atleast_2d(np.asarray(s.q, dtype=float))[s.ref_config]

    def to_ref(theta: np.ndarray, dq: np.ndarray) -> MCPCModel:
        flat = model.params.reshape(-1).copy()
        flat[lay.free_idx] = theta
        mg = model.with_params(flat)
        T = fk_tool(mg, (q_ref + dq)[None])[0]
        return express_in_frame(mg, inv_pose(T), like=model)

    theta0 = model.params.reshape(-1)[lay.free_idx]
    n_dq = len(lay.dq_ref_cols)
    z = np.r_[theta0, np.zeros(n_dq)]
    k = len(theta0)
    model_ref = to_ref(theta0, np.zeros(model.n))
    H = np.empty((idx.size, len(z)))
    h = 1e-7
    for j in range(len(z)):
        e = np.zeros(len(z))
        e[j] = h
        zp, zm = z + e, z - e
        dqp = zp[k:] if n_dq else np.zeros(model.n)
        dqm = zm[k:] if n_dq else np.zeros(model.n)
        H[:, j] = minimal_difference(to_ref(zp[:k], dqp), to_ref(zm[:k], dqm)) / (2 * h)
    Cz = C[nc:, nc:]
    cov_ref = H @ Cz @ H.T
    std_ref = np.sqrt(np.clip(np.diag(cov_ref), 0.0, None))
    for nm, why in lay.held.items():
        if not why.startswith("gauge"):
            std_ref[lay.names.index(nm)] = np.nan
    return CramerRao(
        model=model,
        model_ref=model_ref,
        names=lay.names,
        held=lay.held,
        free_idx=lay.free_idx,
        cov_free=cov_free,
        cov_ref=cov_ref,
        std_ref=std_ref,
        camera_std=camera_std,
        cameras_std=cameras_std,
        pixel_sigma_px=float(s.pixel_sigma_px),
        n_observations=int(len(s.view)),
        n_unknowns=int(n_unknowns),
    )
