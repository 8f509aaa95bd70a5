"""Sparse bundle adjustment: camera parameters, camera poses and 3-D points from image observations.

Frames and units (see docs/DEVELOPING.md): poses ``T_cam_world`` map world coordinates to the OpenCV
camera frame (x right, y down, z forward); pixels follow the OpenCV convention. The camera is a
:class:`selfcal.camera.CameraModel` (the paper's pinhole, eq. 19, with a known principal point);
its free parameters are adjusted, the rest stay fixed. Views are indexed by the pose model (for the
rig models :class:`selfcal.estimation.observations.ViewLayout`).

The adjustment is a problem for the one least-squares engine (:mod:`selfcal.solver`): parameter
blocks ``intrinsics`` (the camera's free parameters; held with ``fix_intrinsics``), ``poses`` (a
pose model's parameters, :mod:`selfcal.estimation.pose_models`) and ``points``, and one residual
block (:class:`selfcal.estimation.reprojection.ReprojectionBlock`). The pose models and the
projection live in :mod:`selfcal.estimation` and :mod:`selfcal.camera`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar, cast

import numpy as np
import scipy.sparse as sp

from selfcal.camera.camera_set import CameraSet
from selfcal.camera.model import CameraModel
from selfcal.errors import InputError
from selfcal.estimation.pose_models import PoseModel
from selfcal.estimation.reprojection import ReprojectionBlock
from selfcal.solver import (
    Loss,
    ParameterBlock,
    Problem,
    ResidualBlock,
    SchurPlans,
    SolverOptions,
    covariance,
    inverse_block,
    solve,
)

C = TypeVar("C", bound=CameraModel | CameraSet)
"""The adjusted camera: one model shared by the rig's cameras, or a set of them (each its own)."""

__all__ = [
    "BundleResult",
    "bundle_adjust",
    "intrinsics_covariance",
]


@dataclass
class BundleResult(Generic[C]):
    """Output of :func:`bundle_adjust` (in the pose model's gauge): the adjusted ``camera``, pose
    parameters, poses ``T_cam_world`` (V, 4, 4), points ``X`` (P, 3), residuals (k, 2) px of the
    rows passed in, the solver's cost/evaluations/status, the final Jacobian :attr:`jac`
    (columns: the ``n_intrinsics`` free camera parameters unless fixed, then poses, then points;
    evaluated on first use: most adjustments never ask for it) and the damping the solver ended
    with (``initial_damping`` of a next adjustment from here; the default for the scipy path);
    :meth:`intrinsics_covariance` the camera's covariance (``unit_covariance``: its ``(J^T J)^-1``
    block by the solver's Schur form, when the solver eliminated the poses; ``n_unknowns``)."""

    camera: C
    pose_params: np.ndarray
    T_cam_world: np.ndarray
    X: np.ndarray
    residuals: np.ndarray
    cost: float
    nfev: int
    status: int
    message: str
    jacobian: Callable[[], sp.csr_matrix] | None = field(default=None, repr=False)
    n_intrinsics: int = 0
    damping: float = SolverOptions.initial_damping
    unit_covariance: Callable[[], np.ndarray] | None = field(default=None, repr=False)
    n_unknowns: int = 0

    @functools.cached_property
    def jac(self) -> sp.csr_matrix | None:
        """The final sparse Jacobian (rows: residuals raveled), None without an analytic one."""
        return None if self.jacobian is None else self.jacobian()

    def intrinsics_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        """:func:`intrinsics_covariance` of the final Jacobian, ``(cov, cov_unit)``: where the
        solver eliminated the poses, from the Schur complement of the poses in ``J^T J`` (the
        camera's parameters and the points; :func:`selfcal.solver.covariance`), without the
        sparse Jacobian and a factorisation of every unknown."""
        if self.unit_covariance is None:
            assert self.jac is not None, "no analytic Jacobian: no covariance"
            return intrinsics_covariance(self.jac, self.residuals, self.n_intrinsics)
        dof = max(self.residuals.size - self.n_unknowns, 1)
        sigma2 = float(np.sum(np.asarray(self.residuals) ** 2) / dof)
        cov_unit = self.unit_covariance()
        return sigma2 * cov_unit, cov_unit


class _Problem(Generic[C]):
    """The bundle adjustment as a :class:`selfcal.solver.Problem` over ``x = [camera's free
    parameters (unless fixed), p, X (3 P)]`` (then the ``extra_params`` blocks, e.g. a tracker
    frame) with the ``reprojection`` block first, then ``extra`` residual blocks over the same
    parameter blocks; ``fun``/``jac``/``sparsity`` serve ``scipy.optimize.least_squares``.
    ``fixed_points`` (P, 3): the points are known (a board's) and held, ``x`` then ends with the
    poses."""

    def __init__(
        self,
        camera: C,
        model: PoseModel,
        view: np.ndarray,
        pidx: np.ndarray,
        uv: np.ndarray,
        n_points: int,
        *,
        fix_intrinsics: bool = False,
        loss: Loss | None = None,
        x0: np.ndarray | None = None,
        extra: Sequence[ResidualBlock] = (),
        fixed_points: np.ndarray | None = None,
        extra_params: Sequence[ParameterBlock] = (),
    ) -> None:
        self.camera = camera
        self.model = model
        self.block = ReprojectionBlock(camera, model, view, pidx, uv, loss)
        self.view, self.pidx, self.uv = self.block.view, self.block.pidx, self.block.uv
        self.n_points = int(n_points)
        n_cam = camera.n_free
        self.ni = 0 if fix_intrinsics else n_cam
        self.np_ = model.n_params
        x = np.zeros(self.ni + self.np_ + 3 * self.n_points) if x0 is None else np.asarray(x0)
        inst = getattr(model, "param_instances", None)
        self.problem = Problem(
            [
                ParameterBlock(
                    "intrinsics",
                    camera.free_values() if fix_intrinsics else x[:n_cam],
                    held=np.full(n_cam, fix_intrinsics),
                ),
                ParameterBlock(
                    "poses",
                    x[self.ni : self.ni + self.np_],
                    instance=inst() if inst is not None else None,
                ),
                ParameterBlock("points", x[self.ni + self.np_ :])
                if fixed_points is None
                else ParameterBlock(
                    "points",
                    np.asarray(fixed_points, dtype=float).ravel(),
                    held=np.ones(3 * self.n_points, bool),
                ),
                *extra_params,
            ],
            [self.block, *extra],
        )
        self.n = self.problem.n

    def unpack(self, x: np.ndarray) -> tuple[C, np.ndarray, np.ndarray]:
        """``(camera, p, X (P, 3))`` for unknowns ``x``."""
        v = self.problem.values(x)
        cam = cast(C, self.camera.with_free_values(v["intrinsics"]))
        return cam, v["poses"], v["points"].reshape(-1, 3)

    def fun(self, x: np.ndarray) -> np.ndarray:
        return self.problem.residual_vector(x)

    def jac(self, x: np.ndarray) -> sp.csr_matrix:
        return self.problem.jacobian(x)

    def sparsity(self) -> sp.csr_matrix:
        return self.problem.sparsity()


def bundle_adjust(
    model: PoseModel,
    p0: np.ndarray,
    X0: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
    camera: C,
    *,
    fix_intrinsics: bool = False,
    fix_points: bool = False,
    loss: str = "soft_l1",
    f_scale_px: float = 1.0,
    max_nfev: int = 100,
    tol: float = 1e-12,
    solver: str = "lm",
    initial_damping: float = SolverOptions.initial_damping,
    plans: SchurPlans | None = None,
) -> BundleResult[C]:
    """Sparse bundle adjustment of ``camera``'s free parameters (unless ``fix_intrinsics``), the
    pose-model parameters (start ``p0``) and the points ``X`` (P, 3) m (start ``X0``; held at
    ``X0`` with ``fix_points``: a board's known geometry, whose frame is then the world).

    Rows are observations ``(view, pidx, uv)``; every view used must have a pose in ``model``.
    ``solver="lm"`` (default): the engine's Levenberg-Marquardt (:func:`selfcal.solver.solve`) with
    the analytic Jacobian, at most ``max_nfev`` trials, robust ``loss`` (linear, soft_l1, huber,
    cauchy; scale ``f_scale_px``) on each observation's 2-D residual norm; the pose parameters are
    eliminated by a Schur complement in large problems when the pose model labels them per view
    (``param_instances``); ``initial_damping``: its first damping (a previous adjustment's
    :attr:`BundleResult.damping` starts a nearby problem warm); ``plans``: the Schur form's
    structures shared with other adjustments of the same rows and the covariance
    (:class:`selfcal.solver.SchurPlans`). ``solver="scipy"``: :func:`scipy.optimize.least_squares` (trf + lsmr,
    loss per coordinate), with the analytic Jacobian or -- when ``model.view_jacobian`` returns None
    -- finite differences restricted by ``jac_sparsity``.

    Raises:
        selfcal.errors.SolverError: NaN/inf residuals or Jacobians (the message names the block).
        ValueError: an unknown ``solver`` or ``loss``.
    """
    if solver not in ("lm", "scipy"):
        raise InputError(f"solver must be 'lm' or 'scipy', got {solver!r}")
    x0 = np.concatenate(
        [
            [] if fix_intrinsics else camera.free_values(),
            p0,
            [] if fix_points else np.asarray(X0).ravel(),
        ]
    )
    prob = _Problem(
        camera,
        model,
        view,
        pidx,
        uv,
        len(X0),
        fix_intrinsics=fix_intrinsics,
        loss=Loss(loss, f_scale_px),
        x0=x0,
        fixed_points=np.asarray(X0) if fix_points else None,
    )
    use_analytic = model.view_jacobian(p0) is not None
    if solver == "lm" and use_analytic:
        has_instances = prob.problem.parameters["poses"].instance is not None
        opt = SolverOptions(
            tol=tol,
            max_iterations=max_nfev,
            max_evaluations=max_nfev,
            eliminate="poses" if has_instances else None,
            initial_damping=initial_damping,
        )
        res = solve(prob.problem, opt, plans)
        x, r, cost, nfev = res.x, res.residuals[prob.block.name], res.cost, res.nfev
        status, message, damping = res.status, res.message, res.damping
        cov = None
        if has_instances and prob.ni:  # the camera's covariance by the solver's Schur form
            cov = functools.partial(covariance, prob.problem, res.x.copy(), ["intrinsics"],
                                    eliminate="poses", plans=plans)  # fmt: skip
    else:
        # optional heavy import (0.15 s): only the scipy path and pose models without Jacobian
        from scipy.optimize import least_squares

        kw = (
            dict(jac=prob.jac)
            if use_analytic
            else dict(jac="2-point", jac_sparsity=prob.sparsity())
        )
        ls = least_squares(
            prob.fun,
            x0,
            method="trf",
            tr_solver="lsmr",
            x_scale="jac",
            loss=loss,
            f_scale=f_scale_px,
            ftol=tol,
            xtol=tol,
            gtol=tol,
            max_nfev=max_nfev,
            tr_options={"atol": 1e-10, "btol": 1e-10},
            **kw,
        )
        x, r, cost, nfev = ls.x, ls.fun.reshape(-1, 2), float(ls.cost), int(ls.nfev)
        status, message = int(ls.status), str(ls.message)
        damping, cov = SolverOptions.initial_damping, None
    cam, p, X = prob.unpack(x)
    T = model.poses(p)
    J = functools.partial(prob.jac, x.copy()) if use_analytic else None
    return BundleResult(cam, p.copy(), T, X.copy(), r, cost, nfev, status, message, J, prob.ni,
                        damping=damping, unit_covariance=cov, n_unknowns=prob.n)  # fmt: skip


def intrinsics_covariance(
    J: sp.csr_matrix, residuals: np.ndarray, n_intrinsics: int
) -> tuple[np.ndarray, np.ndarray]:
    """Covariance of the first ``n_intrinsics`` parameters (the camera's free ones, e.g. ``fx,
    mu``) from the Jacobian: ``sigma^2 (J^T J)^-1`` with ``sigma^2 = |r|^2 / (rows - cols)``
    (px^2).

    Returns ``(cov, cov_unit)`` (n_intrinsics, n_intrinsics) where ``cov_unit`` assumes 1 px noise
    per coordinate (a purely geometric measure of how well the views determine the camera).
    """
    dof = max(J.shape[0] - J.shape[1], 1)
    sigma2 = float(np.sum(np.asarray(residuals) ** 2) / dof)
    cov_unit = inverse_block(J, np.arange(n_intrinsics))
    return sigma2 * cov_unit, cov_unit
