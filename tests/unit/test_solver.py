"""The least-squares engine (selfcal.solver) on small problems with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

from selfcal.errors import SolverError
from selfcal.solver import (
    LOSSES,
    Evaluation,
    JacobianPiece,
    Loss,
    ParameterBlock,
    Problem,
    SolverOptions,
    covariance,
    solve,
)
from selfcal.solver import linear as linear_mod

T = np.linspace(0.0, 2.0, 40)
TRUE = np.array([2.0, -1.3, 0.5])  # y = a exp(b t) + c


class ExpFit:
    """Rows ``a exp(b t_i) + c - y_i`` over blocks ``ab`` (2) and ``c`` (1); optional faults."""

    dim = 1

    def __init__(self, y, loss=None, name="fit", nan_rows=False, nan_jac=False, nan_trials=False):
        self.name, self.y, self.loss = name, y, loss or Loss()
        self.nan_rows, self.nan_jac, self.nan_trials = nan_rows, nan_jac, nan_trials
        self.calls = 0
        self.start = None

    def evaluate(self, values, jacobian):
        self.calls += 1
        (a, b), (c,) = values["ab"], values["c"]
        e = np.exp(b * T)
        r = (a * e + c - self.y)[:, None]
        if self.start is None:
            self.start = values["ab"].copy()
        if self.nan_rows or (self.nan_trials and not np.array_equal(values["ab"], self.start)):
            r = r.copy()
            r[3] = np.nan
        if not jacobian:
            return Evaluation(r)
        Jab = np.stack([e, a * T * e], axis=1)[:, None, :]
        if self.nan_jac:
            Jab = Jab.copy()
            Jab[5, 0, 1] = np.inf
        k = len(T)
        return Evaluation(
            r,
            (
                JacobianPiece("ab", Jab, np.broadcast_to(np.arange(2), (k, 2))),
                JacobianPiece("c", np.ones((k, 1, 1)), np.zeros((k, 1), np.int64)),
            ),
        )


def _data(seed=0, outliers=0):
    rng = np.random.default_rng(seed)
    y = TRUE[0] * np.exp(TRUE[1] * T) + TRUE[2] + 0.01 * rng.standard_normal(len(T))
    y[:outliers] += 1.0
    return y


def _problem(block, start=(1.0, -0.5, 0.0), held_c=False):
    return Problem(
        [
            ParameterBlock("ab", start[:2]),
            ParameterBlock("c", start[2:], held=[held_c]),
        ],
        [block],
    )


def _scipy(y, loss="linear", x0=(1.0, -0.5, 0.0)):
    def f(x):
        return x[0] * np.exp(x[1] * T) + x[2] - y

    def j(x):
        e = np.exp(x[1] * T)
        return np.stack([e, x[0] * T * e, np.ones_like(T)], axis=1)

    return least_squares(f, x0, jac=j, method="trf", loss=loss, ftol=1e-15, xtol=1e-15, gtol=1e-15)


# ---------------------------------------------------------------------------------- losses
@pytest.mark.parametrize("kind", LOSSES)
def test_irls_weight_is_the_derivative_of_the_loss(kind):
    loss = Loss(kind, 0.7)
    e2 = np.array([0.01, 0.3, 0.45, 2.0, 9.0])
    h = 1e-6
    rho_p, _ = loss.evaluate(e2 + h)
    rho_m, _ = loss.evaluate(e2 - h)
    _, w = loss.evaluate(e2)
    np.testing.assert_allclose((rho_p - rho_m) / (2 * h), w, rtol=1e-7)


def test_unknown_loss_and_bad_scale_raise():
    with pytest.raises(ValueError, match="unknown loss"):
        Loss("l2")
    with pytest.raises(ValueError, match="scale"):
        Loss("cauchy", 0.0)


# ---------------------------------------------------------------------------- the minimum
@pytest.mark.parametrize("loss", ["linear", "soft_l1", "cauchy"])
def test_one_dimensional_rows_reach_scipys_minimum(loss):
    """With d = 1 the row norm is the coordinate, so the robust cost is scipy's."""
    y = _data(outliers=3)
    res = solve(_problem(ExpFit(y, Loss(loss))))
    ref = _scipy(y, loss)
    assert res.converged
    assert abs(res.cost - ref.cost) <= 6e-14 * ref.cost  # measured <= 1.7e-14
    # the minimum is flat: x agrees to ~sqrt(eps) (measured <= 6.8e-8)
    np.testing.assert_allclose(np.r_[res.values["ab"], res.values["c"]], ref.x, rtol=2e-7)


def test_held_coordinate_stays_and_the_rest_fits():
    y = _data() - TRUE[2] + 0.25  # offset 0.25, held at that value
    res = solve(_problem(ExpFit(y), start=(1.0, -0.5, 0.25), held_c=True))
    assert res.values["c"][0] == 0.25 and res.x.size == 2
    np.testing.assert_allclose(res.values["ab"], TRUE[:2], atol=0.01)  # measured 0.0033


def test_covariance_of_a_linear_problem_is_the_inverse_normal_matrix():
    y = _data()
    prob = _problem(ExpFit(y))
    res = solve(prob)
    C = covariance(prob, res.x, ["c", "ab"])
    J = prob.jacobian(res.x).toarray()
    ref = np.linalg.inv(J.T @ J)[np.ix_([2, 0, 1], [2, 0, 1])]
    np.testing.assert_allclose(C, ref, rtol=1e-14)  # measured 3e-15


# -------------------------------------------------------------------------- NaN and budget
def test_nan_residual_at_the_start_names_the_block():
    blk = ExpFit(_data(), name="curve", nan_rows=True)
    with pytest.raises(SolverError, match="'curve'.*NaN/inf residuals at the start"):
        solve(_problem(blk))
    assert blk.calls == 1


def test_nan_jacobian_names_residual_and_parameter_block():
    blk = ExpFit(_data(), name="curve", nan_jac=True)
    with pytest.raises(SolverError, match="'curve'.*Jacobian w.r.t. parameter block 'ab'"):
        solve(_problem(blk))
    assert blk.calls == 2  # the start, then the first Jacobian


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_overflowing_normal_equations_name_the_block():
    """Finite residuals whose squares overflow: the error names the block that did it."""

    class Huge(ExpFit):
        def evaluate(self, values, jacobian):
            ev = super().evaluate(values, jacobian)
            pieces = tuple(JacobianPiece(p.block, p.J * 1e160, p.cols) for p in ev.pieces)
            return Evaluation(ev.residuals * 1e160, pieces)

    y = _data()
    prob = Problem(
        [ParameterBlock("ab", [1.0, -0.5]), ParameterBlock("c", [0.0])],
        [ExpFit(y, name="sane"), Huge(y, name="huge")],
    )
    with pytest.raises(SolverError, match=r"overflow .* in residual blocks \['huge'\]"):
        solve(prob)


@pytest.mark.parametrize("budget", [5, 1000])
def test_nan_at_every_trial_ends_within_the_budget(budget):
    blk = ExpFit(_data(), name="curve", nan_trials=True)
    with pytest.raises(SolverError, match="'curve' gives NaN/inf residuals at every trial"):
        solve(_problem(blk), SolverOptions(max_evaluations=budget))
    # start + Jacobian + trials: the budget, or the damping saturating (lam > 1e16) first
    assert blk.calls <= 2 + min(budget - 1, 12)


def test_the_damping_handed_on_is_the_last_accepted_steps():
    """A loop that ends on rejected steps (here: no tolerance, so it runs until no step
    decreases the cost and the damping saturates past 1e16) hands on the damping of its last
    accepted step as the next nearby solve's warm start, not the one its rejections raised."""
    res = solve(_problem(ExpFit(_data())), SolverOptions(tol=0.0))
    assert res.status == 3 and res.iterations > 5
    assert 0 < res.damping <= 1e16  # measured 1.8e3 (its lam ended at 6.3e16)
    # its last iteration accepted no step: the damping is the one the iteration before ended
    # with (the same loop stopped there by its budget)
    before = SolverOptions(tol=0.0, max_iterations=res.iterations - 1)
    assert solve(_problem(ExpFit(_data())), before).damping == res.damping
    # a loop that stops at a tolerance hands on the damping it ended with, as before
    again = solve(_problem(ExpFit(_data())), SolverOptions(tol=1e-12))
    assert again.status == 2 and 0 < again.damping < SolverOptions.initial_damping


def test_unfactorable_system_ends_within_the_budget(monkeypatch):
    def fail(self, lam):
        raise linear_mod.SingularSystem("injected")

    monkeypatch.setattr(linear_mod.DampedSystem, "solve", fail)
    blk = ExpFit(_data())
    with pytest.raises(SolverError, match="cannot be solved \\(injected\\)"):
        solve(_problem(blk), SolverOptions(max_evaluations=8))
    assert blk.calls == 2  # no residual evaluation after a failed factorisation


def test_rank_deficient_problem_terminates_at_the_minimum():
    """Residuals that see only a + c (a gauge freedom): the damping keeps the system solvable."""

    class Sum:
        dim, name, loss = 1, "sum", Loss()

        def evaluate(self, values, jacobian):
            a, c = values["ab"][0], values["c"][0]
            r = np.array([[a + c - 3.0], [2 * (a + c) - 6.2]])
            if not jacobian:
                return Evaluation(r)
            J = np.array([[[1.0]], [[2.0]]])
            cols = np.zeros((2, 1), np.int64)
            return Evaluation(r, (JacobianPiece("ab", J, cols), JacobianPiece("c", J, cols)))

    prob = Problem([ParameterBlock("ab", [0.0, 0.0]), ParameterBlock("c", [0.0])], [Sum()])
    res = solve(prob, SolverOptions(max_evaluations=200))
    assert res.converged and res.trials <= 200
    s = res.values["ab"][0] + res.values["c"][0]
    assert abs(s - 3.08) < 1e-9  # least squares of a + c = 3, 2 (a + c) = 6.2


def test_schur_refuses_rows_that_couple_two_instances():
    y = _data()
    prob = Problem(
        [ParameterBlock("ab", [1.0, -0.5], instance=[0, 1]), ParameterBlock("c", [0.0])],
        [ExpFit(y)],
    )
    with pytest.raises(ValueError, match="couples two instances"):
        solve(prob, SolverOptions(linear_solver="schur", eliminate="ab"))


def test_an_elimination_with_nothing_to_eliminate_solves_densely():
    """A block that declares instances but has none free (all held): "auto" does not take the
    Schur form, and an explicit "schur" still solves (an empty elimination)."""
    y = _data()
    blocks = [
        ParameterBlock("ab", [1.0, -0.5], instance=[0, 1], held=[True, True]),
        ParameterBlock("c", [0.0]),
    ]
    prob = Problem(blocks, [ExpFit(y)])
    auto = solve(prob, SolverOptions(eliminate="ab"))
    schur = solve(prob, SolverOptions(linear_solver="schur", eliminate="ab"))
    assert auto.linear_solver == "dense" and auto.converged and schur.converged
    # Both stop on the relative cost decrease (tol 1e-12), which leaves x within ~sqrt(tol) of
    # the minimum: they agree to 3e-9 on one machine and exactly on another.
    assert schur.x == pytest.approx(auto.x, rel=1e-8)


def test_scaled_rank_above_dense_max_matches_the_dense_eigenvalues(monkeypatch):
    """The Lanczos path (problems above DENSE_MAX unknowns) gives the dense path's smallest
    relative singular value (measured: 3e-15 relative) and rank, and a rank-deficient Jacobian
    still reports its rank."""
    import importlib

    import scipy.sparse as sp

    cov_mod = importlib.import_module("selfcal.solver.covariance")  # the package exports a function

    rng = np.random.default_rng(3)
    J = sp.random(400, 80, density=0.05, random_state=4, format="csr")
    J = (J + sp.vstack([sp.eye(80)] * 5) * 1e-2) @ sp.diags(rng.uniform(0.1, 10.0, 80))
    dense = cov_mod.scaled_rank(J)
    monkeypatch.setattr(cov_mod, "DENSE_MAX", 10)
    lanczos = cov_mod.scaled_rank(J)
    assert lanczos[1] == dense[1] == 80
    assert lanczos[0] == pytest.approx(dense[0], rel=1e-10)
    J_def = sp.hstack([J, sp.csr_matrix((400, 1))]).tocsr()  # an unknown no row sees
    assert cov_mod.scaled_rank(J_def) == (0.0, 80)


@pytest.mark.parametrize("chunk", [1 << 16, 7])
def test_normal_matrix_with_dense_columns_is_jtj(chunk, monkeypatch):
    """The split product (dense columns by BLAS, the rest sparse) is ``J^T J``; also without
    dense columns and with only dense ones, and a chunk of a few rows at a time."""
    import importlib

    import scipy.sparse as sp

    cov_mod = importlib.import_module("selfcal.solver.covariance")
    monkeypatch.setattr(cov_mod, "NORMAL_CHUNK", chunk)
    rng = np.random.default_rng(5)
    S = sp.random(300, 40, density=0.03, random_state=6, format="csr")
    D = sp.csr_matrix(rng.standard_normal((300, 4)) * (rng.random((300, 1)) < 0.6))
    for J in (sp.hstack([S[:, :20], D, S[:, 20:]]).tocsr(), S, D):
        ref = (J.T @ J).toarray()
        got = cov_mod.normal_matrix(J)
        assert sp.issparse(got) and got.format == "csc"
        np.testing.assert_allclose(got.toarray(), ref, rtol=0, atol=1e-14 * np.abs(ref).max())


class _Pieces:
    """Rows over block ``a`` (10 unknowns, every row names all ten slots, some of them unused:
    ``-1``, like a camera that has no rig columns) and block ``b`` (one unknown per row)."""

    name, loss = "pieces", Loss()

    def __init__(self, J_a, cols_a, J_b):
        self.J_a, self.cols_a, self.J_b = J_a, cols_a, J_b

    def evaluate(self, values, jacobian):
        k = len(self.J_a)
        r = np.einsum("kdc,kc->kd", self.J_a, values["a"][np.maximum(self.cols_a, 0)])
        if not jacobian:
            return Evaluation(r)
        return Evaluation(r, (JacobianPiece("a", self.J_a, self.cols_a),
                              JacobianPiece("b", self.J_b, np.arange(k)[:, None])))  # fmt: skip


@settings(max_examples=examples(40), deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(2, 30), p_unused=st.floats(0.05, 0.6))
def test_dense_normal_equations_with_unused_slots_match_the_sparse_ones(seed, k, p_unused):
    """Unused (-1) slots of a wide shared piece: the dense assembly equals ``J^T W J`` (it once
    wrote an unused slot's zero over a used column of the same row, and the board rig and the
    robot with two cameras crawled for hundreds of iterations instead of converging in 9)."""
    rng = np.random.default_rng(seed)
    cols = np.broadcast_to(np.arange(10), (k, 10)).copy()
    for row in cols:
        row[rng.permutation(10)] = row  # any order of the slots
    cols[rng.random((k, 10)) < p_unused] = -1
    block = _Pieces(rng.normal(size=(k, 2, 10)), cols, rng.normal(size=(k, 2, 1)))
    prob = Problem([ParameterBlock("a", rng.normal(size=10)), ParameterBlock("b", np.zeros(k))],
                   [block])  # fmt: skip
    evals = prob.evaluate(prob.x0, jacobian=True)
    w = [rng.uniform(0.5, 2.0, k)]
    dense = linear_mod.assemble(prob, evals, w, "dense")
    sparse = linear_mod.assemble(prob, evals, w, "sparse")
    np.testing.assert_allclose(dense.A, sparse.A.toarray(), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dense.g, sparse.g, rtol=1e-12, atol=1e-12)


def test_a_solve_at_its_minimum_stops_at_the_first_step_the_model_calls_negligible():
    """Started at its minimum with almost no damping (a warm start from a solve of the same rows),
    the first steps lie at the cost's rounding: a trial that does not lower the cost though the
    model promised less than the cost's rounding ends the solve (status 2) at once, where raising
    the damping step by step took a residual evaluation each (8 at the joint refinement's final
    pass, 300 postures) and moved x by nothing that counts."""
    first = solve(_problem(ExpFit(_data())), SolverOptions(tol=1e-12))
    blk = ExpFit(_data())
    again = solve(
        _problem(blk, start=tuple(first.x)), SolverOptions(tol=1e-12, initial_damping=1e-14)
    )
    assert again.status == 2 and again.trials <= 3  # measured 2 (15 and status 3 without the rule)
    assert np.allclose(again.x, first.x, rtol=1e-9, atol=0)
