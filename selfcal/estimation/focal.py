"""Focal length and aspect ratio from fundamental matrices (paper section III.A, Hartley).

The paper's pinhole (eq. 19) with the principal point known: ``fx`` and ``mu`` minimise the
Mendonca-Cipolla cost -- the two non-zero singular values of ``E = K^T F K`` must be equal -- by a
robust (median) 2-D grid search, then a robust refinement; :class:`DegenerateConfigurationError`
when the cost does not determine ``fx`` (e.g. all optical axes through one point, parallel axes,
pure translation). Specific to this camera model by nature: a model with more free parameters
starts from this estimate and frees them in the bundle adjustment.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from selfcal.estimation.selfcal_errors import DegenerateConfigurationError, InsufficientDataError
from selfcal.solver import (
    Evaluation,
    JacobianPiece,
    Loss,
    ParameterBlock,
    Problem,
    SolverOptions,
    solve,
)

__all__ = [
    "FocalEstimate",
    "essential_residuals",
    "essential_constraint",
    "focal_from_fundamentals",
]


def _essentials(
    F: np.ndarray, fx: np.ndarray | float, mu: np.ndarray | float, cx: float, cy: float
) -> np.ndarray:
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


class _ConstraintBlock:
    """The rows ``fun(x)`` (one residual component each) over the parameter block ``"x"``, with a
    soft-L1 loss of scale ``f_scale`` and a central-difference Jacobian (``x`` has two
    coordinates: ``ln fx``, ``ln mu``)."""

    dim = 1

    def __init__(self, fun, f_scale: float) -> None:
        self.name = "essential_constraint"
        self.loss = Loss("soft_l1", f_scale)
        self.fun = fun

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        x = values["x"]
        f = self.fun(x)[:, None]
        if not jacobian:
            return Evaluation(f)
        h = 1e-6
        J = np.stack([(self.fun(x + h * e) - self.fun(x - h * e)) / (2 * h) for e in np.eye(len(x))],
                     axis=1)  # fmt: skip
        cols = np.broadcast_to(np.arange(len(x)), (len(f), len(x)))
        return Evaluation(f, (JacobianPiece("x", J[:, None, :], cols),))


def _soft_l1_fit(fun, x0, f_scale, bounds, max_iter=100, tol=1e-12):
    """Minimise ``sum rho(f_i(x)^2 / f_scale^2)``, ``rho(z) = 2 (sqrt(1 + z) - 1)`` (soft-L1 per
    residual component) for a few parameters ``x`` on the project's solver (Levenberg-Marquardt,
    iteratively reweighted; central-difference Jacobian), the result clipped to ``bounds`` (the
    grid search's box the start comes from). Returns ``x`` and ``f(x)``."""
    prob = Problem([ParameterBlock("x", np.asarray(x0, dtype=float))],
                   [_ConstraintBlock(fun, f_scale)])  # fmt: skip
    sol = solve(prob, SolverOptions(tol=tol, max_iterations=max_iter, linear_solver="dense"))
    x = np.clip(sol.x, *bounds)
    return x, fun(x)


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
    (``fx_bounds`` default ``(0.3, 5) * width`` px, ``mu_bounds``), then refines with a soft-L1 fit
    (Levenberg-Marquardt, iteratively reweighted). Raises :class:`InsufficientDataError` with fewer
    than 2 pairs and :class:`DegenerateConfigurationError` when the minimum lies on the grid edge or
    the cost does not pin down ``fx`` (``sensitivity > max_sensitivity``) -- the classic cases are
    optical axes that all meet in one point (e.g. every view aimed at the same target from the same
    distance), parallel optical axes / pure translations, and pure rotations.
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
