"""Residual blocks besides the reprojection: a known distance in the scene and Gaussian priors.

Each is a batch of rows for :mod:`selfcal.solver` (see :class:`selfcal.solver.ResidualBlock`), in
units of its own standard deviation (or of the pixel noise, when the caller scales it so).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from selfcal.solver import Evaluation, JacobianPiece, Loss

__all__ = ["ScaleDistanceBlock", "GaussianPriorBlock"]


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
