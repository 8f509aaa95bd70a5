"""Bounded unknowns in the one solver (selfcal.solver: projected Levenberg-Marquardt).

Against scipy's bounded least squares (trust region reflective) on a small nonlinear fit whose
optimum lies on a bound and on one whose optimum is inside the box; a start outside the box is
moved onto it; bad bounds are refused.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from selfcal.solver import (
    Evaluation,
    JacobianPiece,
    Loss,
    ParameterBlock,
    Problem,
    SolverOptions,
    solve,
)

T = np.linspace(0.0, 2.0, 40)
Y = 2.0 * np.exp(-1.3 * T) + 0.5 + 0.01 * np.sin(7 * T)


class ExpFit:
    """Rows ``a exp(b t_i) + c - y_i`` over one block ``p = [a, b, c]``."""

    name, dim = "fit", 1

    def __init__(self) -> None:
        self.loss = Loss()

    @staticmethod
    def rows(p: np.ndarray) -> np.ndarray:
        return p[0] * np.exp(p[1] * T) + p[2] - Y

    def evaluate(self, values, jacobian):
        p = values["p"]
        r = self.rows(p)[:, None]
        if not jacobian:
            return Evaluation(r)
        e = np.exp(p[1] * T)
        J = np.stack([e, p[0] * T * e, np.ones_like(T)], axis=1)[:, None, :]
        return Evaluation(r, (JacobianPiece("p", J, np.broadcast_to(np.arange(3), (len(T), 3))),))


def _jac(p):
    e = np.exp(p[1] * T)
    return np.stack([e, p[0] * T * e, np.ones_like(T)], axis=1)


@pytest.mark.parametrize(
    "lower, upper", [([0.0, -5.0, 0.0], [1.5, 0.0, 1.0]), ([-np.inf, -1.0, 0.6], [3.0, 5.0, 2.0])]
)
@pytest.mark.parametrize("linear_solver", ["dense", "sparse"])
def test_an_optimum_on_a_bound_matches_scipy(lower, upper, linear_solver):
    start = np.array([1.0, -0.5, 0.7])
    prob = Problem([ParameterBlock("p", start, lower=lower, upper=upper)], [ExpFit()])
    sol = solve(prob, SolverOptions(tol=1e-15, linear_solver=linear_solver))
    ref = least_squares(ExpFit.rows, start, jac=_jac, bounds=(lower, upper), xtol=1e-15,
                        ftol=1e-15, gtol=1e-15)  # fmt: skip
    assert sol.converged
    assert np.all(sol.x >= np.asarray(lower)) and np.all(sol.x <= np.asarray(upper))
    assert np.any(np.isclose(sol.x, lower) | np.isclose(sol.x, upper))  # a bound is active
    np.testing.assert_allclose(sol.x, ref.x, atol=1e-8)
    assert sol.cost == pytest.approx(ref.cost, rel=1e-12)


def test_an_optimum_inside_the_box_is_the_unbounded_one():
    start = np.array([1.0, -0.5, 0.7])
    free = solve(Problem([ParameterBlock("p", start)], [ExpFit()]))
    box = solve(Problem([ParameterBlock("p", start, lower=-10.0, upper=10.0)], [ExpFit()]))
    np.testing.assert_allclose(box.x, free.x, atol=1e-10)


def test_a_start_outside_the_box_is_moved_onto_it_and_bad_bounds_are_refused():
    prob = Problem([ParameterBlock("p", [5.0, -0.5, 0.7], upper=[3.0, 0.0, 1.0])], [ExpFit()])
    assert prob.x0[0] == 3.0 and prob.bounded
    assert not Problem([ParameterBlock("p", [1.0, -0.5, 0.7])], [ExpFit()]).bounded
    with pytest.raises(ValueError, match="lower bound above its upper"):
        ParameterBlock("p", [0.0, 0.0, 0.0], lower=[1.0, 0.0, 0.0], upper=0.5)
