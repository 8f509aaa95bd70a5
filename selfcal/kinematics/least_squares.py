"""Small least-squares problems of the kinematics (IK, nearest reachable point, compensation) on
the one solver (:mod:`selfcal.solver`).

:func:`damped_least_squares` takes a residual function and its Jacobian over the joints, keeps the
joints inside their ranges (the solver's bounds: steps projected onto the box) and runs the
solver's Levenberg-Marquardt loop; IK (:mod:`selfcal.kinematics.ik_numeric`), the nearest
reachable tool point (:func:`selfcal.kinematics.ik.nearest_reachable`) and the calibrated-model
compensation (:mod:`selfcal.export.compensate`) call it.

Units: whatever the residual's (m, and metres per radian for angles in the IK); joints rad / m.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from selfcal.solver import (
    Evaluation,
    JacobianPiece,
    Loss,
    ParameterBlock,
    Problem,
    SolverOptions,
    solve,
)

__all__ = ["damped_least_squares"]


class _Rows:
    """``residual(q) -> (k,)`` with ``jacobian(q) -> (k, n)`` as one residual row of dimension
    ``k`` over the parameter block ``q``."""

    name = "residual"

    def __init__(self, residual, jacobian, k: int, n: int) -> None:
        self.residual, self.jacobian, self.dim = residual, jacobian, k
        self.loss = Loss()
        self.cols = np.arange(n)[None]

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        q = values["q"]
        r = np.asarray(self.residual(q), dtype=float)[None]
        if not jacobian:
            return Evaluation(r)
        J = np.asarray(self.jacobian(q), dtype=float)[None]
        return Evaluation(r, (JacobianPiece("q", J, self.cols),))


def damped_least_squares(
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    q0: np.ndarray,
    limits: np.ndarray | None,
    *,
    max_iter: int = 60,
    tol: float = 1e-12,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Levenberg-Marquardt (:func:`selfcal.solver.solve`, dense) from ``q0`` (n,) on
    ``residual(q) -> (k,)`` with ``jacobian(q) -> (k, n)``, the joints kept inside ``limits``
    (n, 2; None: unconstrained; a start outside is moved onto them). It stops at the solver's
    relative ``tol`` on the cost or the step (a residual that reaches zero: at rounding level),
    or after ``max_iter`` Jacobians.

    Returns ``(q, r, iterations)``.

    Raises:
        SolverError: NaN/inf residuals or Jacobian at the start (a model with NaN parameters).
    """
    q0 = np.asarray(q0, dtype=float).reshape(-1)
    k = int(np.asarray(residual(q0)).size)
    lo, hi = (None, None) if limits is None else (limits[:, 0], limits[:, 1])
    prob = Problem(
        [ParameterBlock("q", q0, lower=lo, upper=hi)],
        [_Rows(residual, jacobian, k, len(q0))],
    )
    opt = SolverOptions(
        tol=tol, max_iterations=max_iter, linear_solver="dense", initial_damping=1e-6
    )
    sol = solve(prob, opt)
    return sol.values["q"], sol.residuals["residual"][0], sol.iterations
