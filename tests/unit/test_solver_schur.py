"""The Schur-form assembly (selfcal.solver.schur) against the dense normal equations, on residual
blocks with every column kind: instance columns, constant and varying kept columns, a column that
is an instance's unknown in some rows and a shared one in others, unused (-1) and held entries,
rows without instance columns, and a one-row block."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import examples
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from selfcal.solver import Evaluation, JacobianPiece, Loss, ParameterBlock, Problem
from selfcal.solver.linear import _spd_solve, assemble
from selfcal.solver.schur import SchurAssembler, SchurPlans

N_INST, N_PTS = 5, 7


class Fixed:
    """A residual block that returns stored residuals and Jacobian pieces (values replaceable)."""

    def __init__(self, name, residuals, pieces):
        self.name, self.dim, self.loss = name, residuals.shape[1], Loss()
        self.residuals, self.pieces = residuals, pieces

    def evaluate(self, values, jacobian):
        return Evaluation(self.residuals, tuple(self.pieces) if jacobian else ())


def _blocks(rng, k=60, d=2):
    """Four residual blocks over ``a`` (4 shared), ``p`` (3 per instance + 2 shared, one held)
    and ``x`` (3 per point)."""
    inst = rng.integers(0, N_INST, k)
    pts = rng.integers(0, N_PTS, k)
    a_cols = np.broadcast_to(np.arange(4), (k, 4)).copy()
    a_cols[rng.random((k, 4)) < 0.2] = -1  # some rows do not use some shared columns
    p_cols = 3 * inst[:, None] + np.arange(3)
    mixed = rng.random(k) < 0.3  # column 2: the instance's third unknown or a shared one
    p_cols[mixed, 2] = 15 + rng.integers(0, 2, int(mixed.sum()))
    p_cols[rng.random(k) < 0.1, 0] = -1
    x_cols = 3 * pts[:, None] + np.arange(3)
    x_cols[rng.random(k) < 0.05] = -1  # rows that see no point
    main = Fixed(
        "main",
        rng.standard_normal((k, d)),
        [
            JacobianPiece("a", rng.standard_normal((k, d, 4)), a_cols),
            JacobianPiece("p", rng.standard_normal((k, d, 3)), p_cols),
            JacobianPiece("x", rng.standard_normal((k, d, 3)), x_cols),
        ],
    )
    one = Fixed(  # one row over several points (every column is "constant")
        "one",
        rng.standard_normal((1, 1)),
        [JacobianPiece("x", rng.standard_normal((1, 1, 6)), np.array([[0, 1, 2, 9, 10, 11]]))],
    )
    m = 2 * N_INST
    prior_cols = rng.integers(0, 17, (m, 1))
    prior = Fixed(  # one unknown per row, instance or shared (a prior)
        "prior", rng.standard_normal((m, 1)), [JacobianPiece("p", np.ones((m, 1, 1)), prior_cols)]
    )
    only_a = Fixed(  # rows without instance columns
        "only_a",
        rng.standard_normal((8, 3)),
        [JacobianPiece("a", rng.standard_normal((8, 3, 2)), np.array([[3, 1]]))],
    )
    return [main, one, prior, only_a]


def _problem(rng):
    held = np.zeros(17, bool)
    held[4] = True  # an instance unknown held: its entries are no columns
    instance = np.concatenate([np.repeat(np.arange(N_INST), 3), [-1, -1]])
    params = [
        ParameterBlock("a", rng.standard_normal(4)),
        ParameterBlock("p", rng.standard_normal(17), held=held, instance=instance),
        ParameterBlock("x", rng.standard_normal(3 * N_PTS)),
    ]
    return Problem(params, _blocks(rng))


def _full(ne):
    """The (n, n) matrix of a Schur-form NormalEquations."""
    U, W, V, elim, kept = ne.schur_parts
    A = np.zeros((ne.n, ne.n))
    for i in range(len(elim)):
        e = elim[i] >= 0
        ei = elim[i][e]
        A[np.ix_(ei, ei)] = U[i][np.ix_(e, e)]
        A[np.ix_(ei, kept)] = W[i][e]
        A[np.ix_(kept, ei)] = W[i][e].T
    A[np.ix_(kept, kept)] = V
    return A


def _weights(rng, evals):
    return [rng.uniform(0.2, 1.0, len(ev.residuals)) for ev in evals]


@settings(max_examples=examples(25), deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_schur_assembly_is_the_dense_normal_matrix(seed):
    rng = np.random.default_rng(seed)
    prob = _problem(rng)
    evals = prob.evaluate(prob.x0, jacobian=True)
    w = _weights(rng, evals)
    dense = assemble(prob, evals, w, "dense")
    schur = assemble(prob, evals, w, "schur", prob.instance_of_columns("p"))
    scale = np.abs(dense.dense_A).max()
    np.testing.assert_allclose(_full(schur), dense.dense_A, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(schur.g, dense.g, rtol=0, atol=1e-13 * np.abs(dense.g).max())


def test_the_structure_is_reused_and_rebuilt_when_the_columns_change():
    rng = np.random.default_rng(7)
    prob = _problem(rng)
    asm = SchurAssembler(prob, prob.instance_of_columns("p"))
    for it in range(3):
        main = prob.residuals[0]
        main.pieces = [
            JacobianPiece(pc.block, rng.standard_normal(pc.J.shape), pc.cols) for pc in main.pieces
        ]
        if it == 2:  # a new column pattern: the points of the rows move
            pc = main.pieces[2]
            main.pieces[2] = JacobianPiece("x", pc.J, np.roll(pc.cols, 3, axis=0))
        evals = prob.evaluate(prob.x0, jacobian=True)
        w = _weights(rng, evals)
        schur = assemble(prob, evals, w, "schur", schur=asm)
        dense = assemble(prob, evals, w, "dense")
        scale = np.abs(dense.dense_A).max()
        np.testing.assert_allclose(_full(schur), dense.dense_A, rtol=0, atol=1e-13 * scale)


def test_kept_structures_serve_only_a_problem_of_the_same_structure():
    """SchurPlans hands an assembler of another problem the structure an earlier one built
    when the instances and every row's global columns are the same (a new problem object, new
    values); a held unknown more (other global columns, same shapes) or rows that see other
    points build their own. Every assembly, with row weights or all of them 1, is the dense
    normal matrix."""
    plans = SchurPlans()
    seen = []
    for case in ("first", "same", "moved", "held"):
        rng = np.random.default_rng(11)
        prob = _problem(rng)
        if case == "held":
            prob.parameters["p"].held[7] = True
            prob = Problem(list(prob.parameters.values()), prob.residuals)
        if case == "moved":
            pc = prob.residuals[0].pieces[2]
            prob.residuals[0].pieces[2] = JacobianPiece("x", pc.J, np.roll(pc.cols, 3, axis=0))
        asm = SchurAssembler(prob, prob.instance_of_columns("p"), plans)
        evals = prob.evaluate(prob.x0, jacobian=True)
        for w in (_weights(rng, evals), [np.ones(len(ev.residuals)) for ev in evals]):
            schur = assemble(prob, evals, w, "schur", schur=asm)
            dense = assemble(prob, evals, w, "dense")
            scale = np.abs(dense.dense_A).max()
            np.testing.assert_allclose(_full(schur), dense.dense_A, rtol=0, atol=1e-13 * scale)
            np.testing.assert_allclose(schur.g, dense.g, rtol=0, atol=1e-13 * np.abs(dense.g).max())
        seen.append(asm._plans[0][1])
    assert seen[1] is seen[0]  # the same structure: kept
    assert seen[2] is not seen[1] and seen[3] is not seen[2]  # other columns: built anew


def test_a_rank_check_hands_its_normal_matrix_to_the_covariance_at_the_same_point():
    """SchurPlans(normal=True): covariance after schur_scaled_rank at the same point evaluates
    no Jacobian and gives the same matrix as without; at another point it evaluates its own."""
    from selfcal.solver import covariance, schur_scaled_rank

    prob = _problem(np.random.default_rng(3))
    blocks = ["a", ("x", np.arange(6))]
    alone = covariance(prob, prob.x0, blocks, eliminate="p")
    calls = []
    evaluate = prob.evaluate

    def counted(x, jacobian=False):
        calls.append(jacobian)
        return evaluate(x, jacobian)

    prob.evaluate = counted
    plans = SchurPlans(normal=True)
    schur_scaled_rank(prob, prob.x0, "p", plans=plans)
    shared = covariance(prob, prob.x0, blocks, eliminate="p", plans=plans)
    assert calls == [True]  # one Jacobian for both
    np.testing.assert_array_equal(shared, alone)
    x1 = prob.x0 + 1e-3  # another point: its own Jacobian (the kept one was taken, and is gone)
    schur_scaled_rank(prob, prob.x0, "p", plans=plans)
    covariance(prob, x1, blocks, eliminate="p", plans=plans)
    assert calls == [True, True, True]


def test_a_row_that_couples_two_instances_is_refused():
    rng = np.random.default_rng(3)
    prob = _problem(rng)
    main = prob.residuals[0]
    cols = main.pieces[1].cols.copy()
    cols[0] = [0, 1, 3]  # instance 0 and instance 1 in one row
    main.pieces[1] = JacobianPiece("p", main.pieces[1].J, cols)
    evals = prob.evaluate(prob.x0, jacobian=True)
    with pytest.raises(ValueError, match="couples two instances"):
        assemble(prob, evals, _weights(rng, evals), "schur", prob.instance_of_columns("p"))


@settings(max_examples=examples(10), deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_covariance_of_kept_unknowns_through_the_schur_complement(seed):
    """covariance(..., eliminate=) of kept unknowns (the shared ``a``, two of ``p``'s shared
    ones, points) is the block of the inverse of the whole J^T J; asked for an instance's
    unknown it falls back to the whole inverse."""
    from selfcal.solver import covariance, scaled_rank

    rng = np.random.default_rng(seed)
    prob = _problem(rng)
    # a covariance is that of an identified problem: some draws leave a point seen by one row
    # (seed 9725: J^T J singular, both paths raise LinAlgError)
    assume(scaled_rank(prob.jacobian(prob.x0))[0] > 1e-6)
    blocks = ["a", ("p", np.array([14, 15])), ("x", np.arange(6))]  # p: 16 free
    whole = covariance(prob, prob.x0, blocks, sigma2=2.0)
    schur = covariance(prob, prob.x0, blocks, sigma2=2.0, eliminate="p")
    np.testing.assert_allclose(schur, whole, rtol=1e-8, atol=1e-10 * np.abs(whole).max())
    mixed = ["a", ("p", np.array([0, 14]))]
    np.testing.assert_array_equal(
        covariance(prob, prob.x0, mixed, eliminate="p"), covariance(prob, prob.x0, mixed)
    )


@settings(max_examples=examples(10), deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_normal_matrix_assembled_in_schur_form_is_that_of_the_sparse_jacobian(seed):
    """schur_normal_matrix (the joint refinement's rank check without a sparse Jacobian of
    every row) is J^T J of Problem.jacobian, and gives the same scaled rank."""
    from selfcal.solver import scaled_rank, scaled_rank_of_normal, schur_normal_matrix
    from selfcal.solver.covariance import normal_matrix

    rng = np.random.default_rng(seed)
    prob = _problem(rng)
    want = normal_matrix(prob.jacobian(prob.x0)).toarray()
    got = schur_normal_matrix(prob, prob.x0, "p").toarray()
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())
    ratio, rank = scaled_rank_of_normal(schur_normal_matrix(prob, prob.x0, "p"))
    ratio0, rank0 = scaled_rank(prob.jacobian(prob.x0))
    if ratio0 > 1e-7:
        assert rank == rank0 and abs(ratio - ratio0) <= 1e-9 * ratio0
    else:  # J^T J squares the ratio: below ~1e-7 it is rounding (25 of 3000 seeds draw such a J)
        assert ratio <= 1e-7


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_scaled_rank_by_lanczos_on_the_schur_parts_is_that_of_the_normal_matrix(
    seed, monkeypatch
):
    """schur_scaled_rank above DENSE_MAX unknowns (lowered here to this small problem's size):
    Lanczos on the Schur parts, the shift-invert through the Schur complement, gives the ratio
    and rank of the dense eigenvalues of the whole normal matrix."""
    import importlib

    from selfcal.solver import scaled_rank, schur_scaled_rank

    cov = importlib.import_module("selfcal.solver.covariance")  # the module, not the function

    rng = np.random.default_rng(seed)
    prob = _problem(rng)
    ratio0, rank0 = scaled_rank(prob.jacobian(prob.x0))  # dense: every eigenvalue
    monkeypatch.setattr(cov, "DENSE_MAX", 5)

    def no_fallback(*args, **kwargs):
        raise AssertionError("the dense eigenvalues, not Lanczos")

    monkeypatch.setattr(cov, "scaled_rank_of_normal", no_fallback)  # Lanczos must answer
    ratio, rank = schur_scaled_rank(prob, prob.x0, "p")
    assert rank == rank0 == prob.n and abs(ratio - ratio0) <= 1e-9 * ratio0


def test_the_sparse_matrices_built_in_chunks_are_those_built_at_once(monkeypatch):
    """Problem.sparse_jacobian (chunks of residual rows), schur_normal_matrix (chunks of
    columns) and the Schur assembly (batches of groups of rows) give the same arrays, bit for
    bit, with chunks of a few rows, columns or groups as with one chunk (the chunks bound
    their memory, not their result)."""
    import importlib

    from selfcal.solver import problem as problem_module
    from selfcal.solver import schur as schur_module
    from selfcal.solver import schur_normal_matrix

    cov = importlib.import_module("selfcal.solver.covariance")
    rng = np.random.default_rng(11)
    prob = _problem(rng)
    evals = prob.evaluate(prob.x0, jacobian=True)
    w = _weights(rng, evals)
    parts = []
    for batch in (1 << 30, 8):
        monkeypatch.setattr(schur_module, "BATCH_ENTRIES", batch)
        ne = assemble(prob, evals, w, "schur", prob.instance_of_columns("p"))
        parts.append([ne.g, *ne.schur_parts[:3]])
    for whole, batched in zip(*parts):
        np.testing.assert_array_equal(whole, batched)

    def arrays(M):
        return [M.indptr, M.indices, M.data, np.asarray(M.shape)]

    mats = []
    for rows, entries in ((1 << 30, 1 << 30), (7, 40)):
        monkeypatch.setattr(problem_module, "JACOBIAN_CHUNK", rows)
        monkeypatch.setattr(cov, "_MATRIX_CHUNK", entries)
        mats.append((prob.jacobian(prob.x0), prob.sparsity(),
                     schur_normal_matrix(prob, prob.x0, "p")))  # fmt: skip
    for whole, chunked in zip(*mats):
        for a, b in zip(arrays(whole), arrays(chunked)):
            np.testing.assert_array_equal(a, b)


def test_reduced_system_solve_by_cholesky_and_its_lu_fallback():
    """The reduced matrix is solved by its Cholesky factor, and by LU when it is not positive
    definite (an indefinite symmetric matrix here): both give the solution."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(40, 12))
    b = rng.normal(size=12)
    spd = A.T @ A + 0.1 * np.eye(12)
    np.testing.assert_allclose(spd @ _spd_solve(spd, b), b, rtol=0, atol=2e-15)  # 6.7e-16
    indefinite = spd - 2.0 * np.linalg.eigvalsh(spd).max() * np.eye(12) * (np.arange(12) < 3)
    assert np.linalg.eigvalsh(indefinite).min() < 0
    np.testing.assert_allclose(indefinite @ _spd_solve(indefinite, b), b, rtol=0, atol=2e-15)
