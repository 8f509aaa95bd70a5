"""Error classes and sparse bundle adjustment for the self-calibration stage.

Frames and units (see docs/DEVELOPING.md): poses ``T_cam_world`` map world coordinates to the OpenCV
camera frame (x right, y down, z forward); pixels follow the OpenCV convention. Intrinsics are the
paper's eq. 19 with a known principal point: ``K = [[fx, 0, cx], [0, mu fx, cy], [0, 0, 1]]``.

Views are indexed by the pose model (:class:`calib.observations.ViewLayout` for the rig models).

The adjustment is a problem for the one least-squares engine (:mod:`calib.solver`): parameter
blocks ``intrinsics`` (fx, mu; held with ``fix_intrinsics``), ``poses`` (a pose model's
parameters, :mod:`calib.estimation.pose_models`) and ``points``, and one residual block
(:class:`calib.estimation.reprojection.ReprojectionBlock`). The pose models and the projection
live in :mod:`calib.estimation`; they are re-exported here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from calib.errors import EstimationError
from calib.estimation.pose_models import FreePoses, PoseModel, RigPoses, so3_left_jacobian
from calib.estimation.reprojection import (
    ReprojectionBlock,
    projection_blocks,
    reprojection_residuals,
)
from calib.solver import (
    Loss,
    ParameterBlock,
    Problem,
    ResidualBlock,
    SolverOptions,
    inverse_block,
    solve,
)

__all__ = [
    "SelfCalibrationError",
    "InsufficientDataError",
    "DegenerateConfigurationError",
    "ScaleMarkerError",
    "ConvergenceError",
    "so3_left_jacobian",
    "PoseModel",
    "FreePoses",
    "RigPoses",
    "BundleResult",
    "bundle_adjust",
    "projection_blocks",
    "reprojection_residuals",
    "intrinsics_covariance",
]


# ----------------------------------------------------------------------------------- errors
class SelfCalibrationError(EstimationError):
    """Base class: the camera self-calibration cannot produce a trustworthy result."""


class InsufficientDataError(SelfCalibrationError):
    """Too few views, shared points or correspondences for a step of the pipeline."""


class DegenerateConfigurationError(SelfCalibrationError):
    """The viewing geometry does not determine the unknowns (e.g. optical axes through one point,
    pure rotation, planar scene)."""


class ScaleMarkerError(SelfCalibrationError):
    """The scale markers are missing from the reconstruction or the distance is invalid."""


class ConvergenceError(SelfCalibrationError):
    """An optimisation did not converge or ended with implausible residuals."""


@dataclass
class BundleResult:
    """Output of :func:`bundle_adjust` (in the pose model's gauge)."""

    fx: float
    mu: float
    pose_params: np.ndarray
    T_cam_world: np.ndarray  # (V, 4, 4)
    X: np.ndarray  # (P, 3)
    residuals: np.ndarray  # (k, 2) px for the rows passed in
    cost: float
    nfev: int
    status: int
    message: str
    jac: sp.csr_matrix | None = field(default=None, repr=False)
    n_intrinsics: int = 2


class _Problem:
    """The bundle adjustment as a :class:`calib.solver.Problem` over ``x = [fx, mu (unless
    fixed), p, X (3 P)]`` with the ``reprojection`` block first, then ``extra`` residual blocks
    over the same parameter blocks; ``fun``/``jac``/``sparsity`` serve
    ``scipy.optimize.least_squares``."""

    def __init__(
        self,
        model: PoseModel,
        view: np.ndarray,
        pidx: np.ndarray,
        uv: np.ndarray,
        n_points: int,
        cx: float,
        cy: float,
        fixed_fx_mu: tuple[float, float] | None,
        loss: Loss | None = None,
        x0: np.ndarray | None = None,
        extra: Sequence[ResidualBlock] = (),
    ) -> None:
        self.model = model
        self.block = ReprojectionBlock(model, view, pidx, uv, cx, cy, loss)
        self.view, self.pidx, self.uv = self.block.view, self.block.pidx, self.block.uv
        self.cx, self.cy = float(cx), float(cy)
        self.n_points = int(n_points)
        self.ni = 0 if fixed_fx_mu is not None else 2
        self.np_ = model.n_params
        x = np.zeros(self.ni + self.np_ + 3 * self.n_points) if x0 is None else np.asarray(x0)
        inst = getattr(model, "param_instances", None)
        self.problem = Problem(
            [
                ParameterBlock(
                    "intrinsics",
                    x[:2] if fixed_fx_mu is None else fixed_fx_mu,
                    held=np.full(2, fixed_fx_mu is not None),
                ),
                ParameterBlock(
                    "poses",
                    x[self.ni : self.ni + self.np_],
                    instance=inst() if inst is not None else None,
                ),
                ParameterBlock("points", x[self.ni + self.np_ :]),
            ],
            [self.block, *extra],
        )
        self.n = self.problem.n

    def unpack(self, x: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
        """``(fx, mu, p, X (P, 3))`` for unknowns ``x``."""
        v = self.problem.values(x)
        fx, mu = v["intrinsics"]
        return fx, mu, v["poses"], v["points"].reshape(-1, 3)

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
    fx0: float,
    mu0: float,
    cx: float,
    cy: float,
    *,
    fix_intrinsics: bool = False,
    loss: str = "soft_l1",
    f_scale_px: float = 1.0,
    max_nfev: int = 100,
    tol: float = 1e-12,
    solver: str = "lm",
) -> BundleResult:
    """Sparse bundle adjustment of ``fx, mu`` (unless fixed), the pose-model parameters and the
    points ``X`` (P, 3).

    Rows are observations ``(view, pidx, uv)``; every view used must have a pose in ``model``.
    ``solver="lm"`` (default): the engine's Levenberg-Marquardt (:func:`calib.solver.solve`) with
    the analytic Jacobian, at most ``max_nfev`` trials, robust ``loss`` (linear, soft_l1, huber,
    cauchy; scale ``f_scale_px``) on each observation's 2-D residual norm; the pose parameters
    are eliminated by a Schur complement in large problems when the pose model labels them per
    view (``param_instances``). ``solver="scipy"``: :func:`scipy.optimize.least_squares` (trf +
    lsmr, loss per coordinate), with the analytic Jacobian or -- when ``model.view_jacobian``
    returns None -- finite differences restricted by ``jac_sparsity``.

    Raises:
        calib.errors.SolverError: NaN/inf residuals or Jacobians (the message names the block).
        ValueError: an unknown ``solver`` or ``loss``.
    """
    if solver not in ("lm", "scipy"):
        raise ValueError(f"solver must be 'lm' or 'scipy', got {solver!r}")
    fixed = (float(fx0), float(mu0)) if fix_intrinsics else None
    x0 = np.concatenate([[] if fix_intrinsics else [fx0, mu0], p0, np.asarray(X0).ravel()])
    prob = _Problem(model, view, pidx, uv, len(X0), cx, cy, fixed, Loss(loss, f_scale_px), x0)
    use_analytic = model.view_jacobian(p0) is not None
    if solver == "lm" and use_analytic:
        has_instances = prob.problem.parameters["poses"].instance is not None
        opt = SolverOptions(
            tol=tol,
            max_iterations=max_nfev,
            max_evaluations=max_nfev,
            eliminate="poses" if has_instances else None,
        )
        res = solve(prob.problem, opt)
        x, r, cost, nfev = res.x, res.residuals[prob.block.name], res.cost, res.nfev
        status, message = res.status, res.message
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
    fx, mu, p, X = prob.unpack(x)
    T = model.poses(p)
    J = prob.jac(x) if use_analytic else None
    return BundleResult(
        float(fx), float(mu), p.copy(), T, X.copy(), r, cost, nfev, status, message, J, prob.ni
    )


def intrinsics_covariance(
    J: sp.csr_matrix, residuals: np.ndarray, n_intrinsics: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Covariance of the first ``n_intrinsics`` parameters ``(fx, mu)`` from the Jacobian:
    ``sigma^2 (J^T J)^-1`` with ``sigma^2 = |r|^2 / (rows - cols)`` (px^2).

    Returns ``(cov (2, 2), cov_unit (2, 2))`` where ``cov_unit`` assumes 1 px noise per coordinate
    (a purely geometric measure of how well the views determine fx and mu).
    """
    dof = max(J.shape[0] - J.shape[1], 1)
    sigma2 = float(np.sum(np.asarray(residuals) ** 2) / dof)
    cov_unit = inverse_block(J, np.arange(n_intrinsics))
    return sigma2 * cov_unit, cov_unit
