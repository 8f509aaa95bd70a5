"""Robust losses applied to the norm of each residual row, by iteratively reweighted least squares.

A residual block of ``k`` rows of dimension ``d`` contributes ``1/2 sum_i f^2 rho(|r_i|^2 / f^2)``
to the cost (``f`` the loss scale, in the residual's units). Each LM iteration weights row ``i`` by
``rho'(|r_i|^2 / f^2)`` in the normal equations (IRLS on the row norm, not per coordinate as in
``scipy.optimize.least_squares``): a 2-D image residual is down-weighted as one observation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError

__all__ = ["Loss", "LOSSES"]

LOSSES = ("linear", "soft_l1", "huber", "cauchy")


@dataclass(frozen=True)
class Loss:
    """``kind`` one of :data:`LOSSES`; ``scale`` ``f`` > 0 (residual units, e.g. px).

    Raises ``ValueError`` for an unknown kind or a non-positive scale."""

    kind: str = "linear"
    scale: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in LOSSES:
            raise InputError(f"unknown loss {self.kind!r}; use linear, soft_l1, huber or cauchy")
        if not float(self.scale) > 0:
            raise InputError(f"loss scale must be > 0, got {self.scale}")

    def evaluate(self, e2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(f^2 rho(e2 / f^2), rho'(e2 / f^2))`` per row for squared row norms ``e2`` (k,):
        twice the row's cost and its IRLS weight."""
        f = float(self.scale)
        if self.kind == "linear":
            return e2, np.ones_like(e2)
        z = e2 / f**2
        if self.kind == "soft_l1":
            return f**2 * 2.0 * (np.sqrt(1.0 + z) - 1.0), 1.0 / np.sqrt(1.0 + z)
        if self.kind == "huber":
            return f**2 * np.where(z <= 1, z, 2.0 * np.sqrt(z) - 1.0), np.where(
                z <= 1, 1.0, 1.0 / np.sqrt(np.maximum(z, 1e-300))
            )
        return f**2 * np.log1p(z), 1.0 / (1.0 + z)  # cauchy
