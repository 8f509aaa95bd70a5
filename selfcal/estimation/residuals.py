"""Residual blocks besides the reprojection: a known distance in the scene and Gaussian priors.

Each is a batch of rows for :mod:`selfcal.solver` (see :class:`selfcal.solver.ResidualBlock`), in
units of its own standard deviation (or of the pixel noise, when the caller scales it so).
:func:`scale_block` and :func:`joint_prior` build the two that every adjustment of the field route
over :class:`selfcal.estimation.kinematic_poses.KinematicPoses` carries (the one-step refinement
and its Cramer-Rao bound): the scale fixed by the scale markers and the errors-in-variables prior
on the joint read-back. They are not :mod:`selfcal.terms`: they are the images' own model, always
present, the scale row indexes the ``points`` block (re-indexed every outlier round) and the
prior the joint corrections, neither has a ``calibration.json`` section.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from selfcal.errors import InputError
from selfcal.solver import Evaluation, JacobianPiece, Loss

__all__ = ["ScaleDistanceBlock", "GaussianPriorBlock", "scale_block", "joint_prior"]


class ScaleDistanceBlock:
    """One row ``weight (|c_a - c_b| - d)``: ``c_a``, ``c_b`` the centroids (m) of the points
    ``a``, ``b`` (indices into the ``points`` block, (P, 3) raveled); ``d`` the known distance
    (m); ``weight`` 1/m (e.g. px of residual per m of distance error). Plain least squares."""

    dim = 1

    def __init__(
        self,
        a: np.ndarray,
        b: np.ndarray,
        distance_m: float,
        weight: float,
        *,
        name: str = "scale",
        points: str = "points",
    ) -> None:
        self.name = name
        self.loss = Loss()
        self.a = np.asarray(a, dtype=np.int64)
        self.b = np.asarray(b, dtype=np.int64)
        self.d, self.w = float(distance_m), float(weight)
        self.points = points
        self.cols = (3 * np.concatenate([self.a, self.b])[:, None] + np.arange(3)).reshape(1, -1)

    def distance(self, X: np.ndarray) -> tuple[float, np.ndarray]:
        """``(|c_a - c_b|, c_a - c_b)`` for points ``X`` (P, 3) m."""
        u = X[self.a].mean(axis=0) - X[self.b].mean(axis=0)
        return float(np.linalg.norm(u)), u

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """The residual (1, 1) and its derivative w.r.t. the points of ``a`` and ``b``."""
        dist, u = self.distance(values[self.points].reshape(-1, 3))
        r = np.array([[self.w * (dist - self.d)]])
        if not jacobian:
            return Evaluation(r)
        g = self.w * u / max(dist, 1e-300)
        na, nb = len(self.a), len(self.b)
        J = np.concatenate([np.tile(g / na, na), np.tile(-g / nb, nb)])[None, None, :]
        return Evaluation(r, (JacobianPiece(self.points, J, self.cols),))


class GaussianPriorBlock:
    """Rows ``weight_i (x[cols_i] - mean_i)`` on coordinates ``cols`` of parameter block
    ``block`` (a zero-mean prior by default): ``weight = 1 / sigma`` in the residual's unit."""

    dim = 1

    def __init__(
        self,
        block: str,
        cols: np.ndarray,
        weight: np.ndarray,
        mean: np.ndarray | None = None,
        *,
        name: str = "prior",
    ) -> None:
        self.name = name
        self.loss = Loss()
        self.block = block
        self.cols = np.asarray(cols, dtype=np.int64).reshape(-1, 1)
        self.w = np.broadcast_to(np.asarray(weight, dtype=float), (len(self.cols),)).copy()
        self.mean = np.zeros(len(self.cols)) if mean is None else np.asarray(mean, dtype=float)

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (E, 1) and the diagonal Jacobian."""
        r = (self.w * (values[self.block][self.cols[:, 0]] - self.mean))[:, None]
        if not jacobian:
            return Evaluation(r)
        return Evaluation(r, (JacobianPiece(self.block, self.w[:, None, None], self.cols),))


def scale_block(
    points: tuple[np.ndarray, np.ndarray], distance_m: float, sigma_m: float
) -> ScaleDistanceBlock:
    """The hard scale row ``(|c_a - c_b| - d) / sigma_m`` (in the problem's residual unit, e.g.
    px: ``d`` known to ``sigma_m`` relative to one unit) on the centroids of the two scale
    markers' corners ``points`` (indices into the ``points`` block) ``distance_m`` (m) apart."""
    return ScaleDistanceBlock(points[0], points[1], distance_m, 1.0 / float(sigma_m))


def joint_prior(
    dq_cols: np.ndarray, joint_sigma: float | np.ndarray, n_joints: int, unit_sigma: float
) -> tuple[np.ndarray, GaussianPriorBlock]:
    """The zero-mean Gaussian prior ``unit_sigma dq / joint_sigma`` on the joint corrections.

    Args:
        dq_cols: coordinates of the corrections in the ``poses`` block (n per configuration,
            configuration-major: :attr:`selfcal.estimation.kinematic_poses.KinematicPoses.dq_cols`).
        joint_sigma: standard deviation of the joint read-back errors (rad / m; scalar or (n,)).
        n_joints: ``n``, the joints of the chain.
        unit_sigma: standard deviation of one unit of the problem's residuals (e.g. px).

    Returns:
        ``(joint_sigma as (n,), block)``.

    Raises:
        InputError: a ``joint_sigma`` that is not positive and finite.
    """
    js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (n_joints,))
    if not (np.all(np.isfinite(js)) and np.all(js > 0)):
        raise InputError(f"joint_sigma must be positive and finite, got {joint_sigma}")
    weight = np.tile(unit_sigma / js, len(dq_cols) // n_joints)
    return js, GaussianPriorBlock("poses", dq_cols, weight)
