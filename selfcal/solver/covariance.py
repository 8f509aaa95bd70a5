"""Covariance of selected parameter blocks after a solve: blocks of ``(J^T J)^-1``.

The caller supplies the noise level: ``sigma^2 (J^T J)^-1`` with ``J`` the unweighted Jacobian of
the residuals at the solution (each residual in units of its own standard deviation, or scaled
by ``sigma^2`` when all rows share one unknown noise level). Nuisance unknowns (points, poses)
are marginalised by the inverse.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.linalg import ArpackError, LinearOperator, eigsh, splu

from selfcal.errors import UsageError
from selfcal.solver.linear import DENSE_MAX
from selfcal.solver.problem import Problem
from selfcal.solver.schur import SchurAssembler, SchurLayout, SchurPlans

__all__ = [
    "block_columns",
    "inverse_block",
    "inverse_columns",
    "covariance",
    "scaled_rank",
    "scaled_rank_of_normal",
    "schur_scaled_rank",
    "normal_matrix",
    "psd_sqrt",
    "schur_normal_matrix",
]


_DENSE_COLUMN = 0.125  # a column in more than this fraction of the rows is multiplied densely
NORMAL_CHUNK = 1 << 16
"""Rows of ``J`` per chunk of :func:`normal_matrix` (one chunk: the product at once)."""


def psd_sqrt(C: np.ndarray) -> np.ndarray:
    """The symmetric positive semi-definite square root ``S`` (p, p) of the symmetric positive
    semi-definite ``C`` (p, p), any units: ``S S = S S^T = C`` (``V diag(sqrt(w)) V^T`` from the
    eigen-decomposition of ``(C + C^T) / 2``, round-off's negative eigenvalues taken as 0).
    Unlike ``V diag(sqrt(w))`` it is a function of ``C`` alone, not of the signs and order of the
    eigenvectors the decomposition happens to return: ``S z`` (``z`` standard normal) is a draw
    of ``N(0, C)`` that a small change of ``C`` changes little (the forecast draws of
    ``selfcal plan``, issue #30). How little depends on the rank: at full rank ``S`` is
    Lipschitz in ``C``, a relative change ``e`` moving it by at most about ``cond(C) * e``
    (1e-12: ~6e-11 of the root, its last digits); with zero eigenvalues it is not, the change
    moves it by up to about ``sqrt(e)`` (1e-12 moves a rank 6 of 8 root by up to ~1.6e-6
    relative, its 6th digit), and the draws move as much."""
    C = np.asarray(C, dtype=float)
    if C.ndim != 2 or C.shape[0] != C.shape[1] or not np.all(np.isfinite(C)):
        raise UsageError(f"psd_sqrt needs a finite square matrix, got shape {C.shape}")
    w, V = np.linalg.eigh((C + C.T) / 2.0)
    S = (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T
    return (S + S.T) / 2.0


def normal_matrix(J: sp.spmatrix | np.ndarray) -> sp.csc_matrix:
    """``J^T J`` (CSC) of a sparse Jacobian. The columns that most rows use (a camera's
    intrinsics, a kinematic chain: more than 1/8 of the rows) are multiplied densely (BLAS) with
    themselves and with the rest, only the sparse remainder (poses, points) by a sparse product:
    the same matrix as ``J.T @ J`` (to rounding), several times faster when a few columns are
    dense (measured: 77 -> ~15 ms for the joint refinement at 300 postures). A Jacobian of more
    than :data:`NORMAL_CHUNK` rows with dense columns is multiplied a chunk of rows at a time
    and the products added (the same matrix to rounding, without a column-major copy of ``J``
    and the dense columns of every row in memory: 0.26 GB at 3000 postures); without dense
    columns (or with only dense ones) it is one sparse product."""
    Jr_ = sp.csr_matrix(J)
    m, n = Jr_.shape
    dense = np.bincount(Jr_.indices, minlength=n) > _DENSE_COLUMN * m
    if not dense.any() or dense.all():  # one sparse product (the chunks are for dense columns)
        Jc = sp.csc_matrix(J)
        return (Jc.T @ Jc).tocsc()
    d, r = np.flatnonzero(dense), np.flatnonzero(~dense)
    nd, nr = len(d), len(r)
    Dd = np.zeros((nd, nd))
    Rd = np.zeros((nr, nd))
    Rr_sum: sp.spmatrix | None = None
    for a in range(0, m, NORMAL_CHUNK):
        Jc = sp.csc_matrix(Jr_[a : a + NORMAL_CHUNK]) if m > NORMAL_CHUNK else sp.csc_matrix(J)
        Jd = Jc[:, d].toarray()
        Jr = Jc[:, r]
        Dd += Jd.T @ Jd  # (nd, nd)
        Rd += np.asarray(Jr.T @ Jd)  # (nr, nd)
        RrI = Jr.T @ Jr
        Rr_sum = RrI if Rr_sum is None else Rr_sum + RrI
    assert Rr_sum is not None  # m >= 1: a column is dense
    Rr = Rr_sum.tocoo()
    rows = np.concatenate([np.repeat(d, nd), np.repeat(r, nd), np.tile(d, nr), r[Rr.row]])
    cols = np.concatenate([np.tile(d, nd), np.tile(d, nr), np.repeat(r, nd), r[Rr.col]])
    vals = np.concatenate([Dd.ravel(), Rd.ravel(), Rd.ravel(), Rr.data])
    return sp.csc_matrix((vals, (rows, cols)), shape=(n, n))


def inverse_columns(J: sp.spmatrix | np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The columns ``cols`` of ``(J^T J)^-1`` (n, len(cols)).

    Diagonally scaled exact solve: dense LU up to :data:`selfcal.solver.linear.DENSE_MAX`
    unknowns, SuperLU (COLAMD) above. Raises ``RuntimeError``/``LinAlgError`` when ``J^T J`` is
    singular (an unknown the residuals do not determine)."""
    cols = np.asarray(cols, dtype=np.int64)
    JtJ = normal_matrix(J)
    dg = np.sqrt(np.maximum(JtJ.diagonal(), 1e-300))
    e = np.zeros((JtJ.shape[0], len(cols)))
    e[cols, np.arange(len(cols))] = 1.0
    if JtJ.shape[0] <= DENSE_MAX:  # dense LU: faster than SuperLU at this size
        M = JtJ.toarray() / dg[:, None] / dg[None, :]
        return np.linalg.solve(M, e / dg[:, None]) / dg[:, None]
    Dinv = sp.diags(1.0 / dg)
    lu = splu((Dinv @ JtJ @ Dinv).tocsc(), permc_spec="COLAMD")
    return lu.solve(e / dg[:, None]) / dg[:, None]


def inverse_block(J: sp.spmatrix | np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1`` restricted to the unknowns ``cols`` (len(cols), len(cols)), symmetrised
    (:func:`inverse_columns`' solve)."""
    out = inverse_columns(J, cols)[np.asarray(cols, dtype=np.int64)]
    return 0.5 * (out + out.T)


def block_columns(problem: Problem,
                  blocks: Sequence[str | tuple[str, np.ndarray]]) -> np.ndarray:  # fmt: skip
    """The unknowns' columns of parameter ``blocks`` in that order (each block's free
    coordinates in order; ``(name, idx)`` selects the free coordinates ``idx`` of a block)."""
    cols = []
    for b in blocks:
        name, idx = (b, None) if isinstance(b, str) else b
        c = problem.columns(name)
        cols.append(c if idx is None else c[np.asarray(idx, dtype=np.int64)])
    return np.concatenate(cols)


def covariance(
    problem: Problem,
    x: np.ndarray,
    blocks: Sequence[str | tuple[str, np.ndarray]],
    *,
    sigma2: float = 1.0,
    eliminate: str | None = None,
    plans: SchurPlans | None = None,
) -> np.ndarray:
    """``sigma2 (J^T J)^-1`` over the free coordinates of parameter ``blocks`` (in that order,
    each block's coordinates in order; ``(name, idx)`` selects the free coordinates ``idx`` of a
    block) at unknowns ``x`` (e.g. ``SolverResult.x``).

    ``eliminate``: a parameter block with instances (as :class:`selfcal.solver.SolverOptions`'s):
    when none of the selected coordinates is one of its instances', the inverse is that of the
    Schur complement of the instances in ``J^T J`` assembled as the solver assembles it (dense,
    the kept unknowns only), instead of a sparse factorisation of the whole of ``J^T J``;
    ``plans`` the Schur form's structures kept from the solve (:class:`SchurPlans`)."""
    cols = block_columns(problem, blocks)
    if eliminate is not None:
        kept = _kept_inverse(problem, x, cols, eliminate, plans)
        if kept is not None:
            return sigma2 * kept
    return sigma2 * inverse_block(problem.jacobian(x), cols)


def schur_normal_matrix(problem: Problem, x: np.ndarray, eliminate: str) -> sp.csc_matrix:
    """``J^T J`` (unweighted, CSC) at ``x`` assembled as the solver assembles its Schur form
    (block ``eliminate``'s instances eliminated): the same matrix as :func:`normal_matrix` of
    :meth:`Problem.jacobian` (to rounding) without the sparse Jacobian of every row."""
    U, W, V, elim, kept = _schur_parts(problem, x, eliminate)
    return _normal_of_parts(U, W, V, elim, kept, problem.n)


def _schur_parts(
    problem: Problem, x: np.ndarray, eliminate: str, plans: SchurPlans | None = None
) -> tuple[np.ndarray, ...]:
    """``(U, W, V, elim, kept)`` of the unweighted ``J^T J`` at ``x`` in the solver's Schur form
    (:class:`selfcal.solver.linear.NormalEquations`)."""
    inst = problem.instance_of_columns(eliminate)
    if plans is not None:
        parts = plans.normal_at(problem, x, inst)
        if parts is not None:
            return parts
    evals = problem.evaluate(x, jacobian=True)
    asm = SchurAssembler(problem, inst, plans)
    _, U, W, V = asm.assemble(evals, [np.ones(len(ev.residuals)) for ev in evals])
    parts = (U, W, V, asm.layout.elim, asm.layout.kept)
    if plans is not None:
        plans.keep_normal(problem, x, inst, parts)
    return parts


_MATRIX_CHUNK = 1 << 20  # entries per column chunk of _normal_of_parts


def _normal_of_parts(
    U: np.ndarray, W: np.ndarray, V: np.ndarray, elim: np.ndarray, kept: np.ndarray, n: int
) -> sp.csc_matrix:
    """The (n, n) CSC matrix ``[[U, W], [W^T, V]]`` of the Schur form's parts (``U`` (I, s, s),
    ``W`` (I, s, nk), ``V`` (nk, nk), ``elim`` (I, s) the unknown of each instance slot, ``-1``
    padding, ``kept`` (nk,)), every entry of the parts stored (zeros too), indices sorted.
    Built in chunks of columns of at most about :data:`_MATRIX_CHUNK` entries (each chunk's
    triplets to CSC, the chunks side by side): the same matrix as from all triplets at once,
    without the triplets of the coupling ``W`` (dense in the kept unknowns) in memory."""
    e = elim >= 0
    ia, a, b = np.nonzero(e[:, :, None] & e[:, None, :])
    u_row, u_col, u_val = elim[ia, a], elim[ia, b], U[ia, a, b]
    iw, aw = np.nonzero(e)
    e_unk = elim[iw, aw]  # the eliminated unknowns, rows of W (ne,)
    nk, ne = len(kept), len(e_unk)
    count = np.zeros(n, np.int64)  # entries of each column
    np.add.at(count, u_col, 1)
    count[e_unk] += nk
    count[kept] += ne + nk
    cum = np.cumsum(count)
    cuts = np.searchsorted(cum, np.arange(_MATRIX_CHUNK, cum[-1] if n else 0, _MATRIX_CHUNK))
    cuts = np.unique(np.r_[0, cuts, n])
    parts = []
    for c0, c1 in zip(cuts[:-1], cuts[1:]):
        su = np.flatnonzero((u_col >= c0) & (u_col < c1))
        se = np.flatnonzero((e_unk >= c0) & (e_unk < c1))  # W^T: kept rows, these columns
        sk = np.flatnonzero((kept >= c0) & (kept < c1))  # W and V: these kept columns
        rows = [u_row[su], np.tile(kept, len(se)), np.tile(e_unk, len(sk)),
                np.tile(kept, len(sk))]  # fmt: skip
        cols = [u_col[su], np.repeat(e_unk[se], nk), np.repeat(kept[sk], ne),
                np.repeat(kept[sk], nk)]  # fmt: skip
        vals = [u_val[su], W[iw[se], aw[se]].ravel(), W[iw[None, :], aw[None, :], sk[:, None]].ravel(),
                V[:, sk].T.ravel()]  # fmt: skip
        cc = np.concatenate(cols) - c0
        parts.append(sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), cc)),
                                   shape=(n, c1 - c0)))  # fmt: skip
    if not parts:
        return sp.csc_matrix((n, n))
    return parts[0] if len(parts) == 1 else sp.hstack(parts, format="csc")


def _kept_inverse(
    problem: Problem, x: np.ndarray, cols: np.ndarray, eliminate: str,
    plans: SchurPlans | None = None,
) -> np.ndarray | None:  # fmt: skip
    """``(J^T J)^-1`` restricted to ``cols`` through the Schur complement of the instances of
    block ``eliminate`` (diagonally scaled like :func:`inverse_block`), or None when a column
    is one of theirs, there are none, or an instance's block is not positive definite."""
    inst = problem.instance_of_columns(eliminate)
    if not np.any(inst >= 0) or np.any(inst[cols] >= 0):
        return None
    U, W, V, elim, _ = _schur_parts(problem, x, eliminate, plans)
    lay = SchurLayout.of(inst)
    Us, Ws, Vs, dV = _unit_diagonal(U, W, V, elim >= 0)
    try:
        Li = np.linalg.inv(np.linalg.cholesky(Us))
    except np.linalg.LinAlgError:
        return None
    Y = np.matmul(Li, Ws).reshape(-1, lay.nk)
    S = Vs - Y.T @ Y
    k = lay.kid[cols]
    rhs = np.zeros((lay.nk, len(k)))
    rhs[k, np.arange(len(k))] = 1.0
    out = np.linalg.solve(S, rhs)[k] / dV[k][:, None] / dV[k][None, :]
    return 0.5 * (out + out.T)


def scaled_rank(J: sp.spmatrix | np.ndarray, rtol: float = 1e-9) -> tuple[float, int]:
    """``(s_min / s_max, rank)`` of the unit-column-scaled ``J``: the smallest relative singular
    value and the numerical rank (singular values above ``rtol s_max``), from the eigenvalues of
    ``J^T J``: all of them densely up to :data:`selfcal.solver.linear.DENSE_MAX` unknowns; above,
    only the largest and (shift-invert Lanczos on the sparse matrix, linear in the postures of a
    bundle adjustment) the smallest, and all densely only when that one is below the rank
    threshold (a rank-deficient problem, which the callers refuse)."""
    return scaled_rank_of_normal(normal_matrix(J), rtol)


def _unit_diagonal(U, W, V, e: np.ndarray) -> tuple[np.ndarray, ...]:
    """The Schur parts of ``J^T J`` scaled to a unit diagonal (as :func:`inverse_block` scales
    it; ``e`` (I, s) the instances' used slots, an unused one decoupled) and the kept unknowns'
    scales: ``(Us, Ws, Vs, dV)``."""
    dU = np.sqrt(np.where(e, np.maximum(np.einsum("iaa->ia", U), 1e-300), 1.0))
    dV = np.sqrt(np.maximum(np.diag(V), 1e-300))
    Us = U / dU[:, :, None] / dU[:, None, :]
    i, a = np.nonzero(~e)
    Us[i, a, a] = 1.0  # an instance's unused slot: decoupled
    Ws = W / dU[:, :, None] / dV[None, None, :]
    return Us, Ws, V / dV[:, None] / dV[None, :], dV


def schur_scaled_rank(
    problem: Problem, x: np.ndarray, eliminate: str, rtol: float = 1e-9,
    plans: SchurPlans | None = None,
) -> tuple[float, int]:  # fmt: skip
    """:func:`scaled_rank_of_normal` of :func:`schur_normal_matrix` ``(problem, x, eliminate)``;
    above :data:`selfcal.solver.linear.DENSE_MAX` unknowns without forming it: Lanczos on the
    Schur parts (products per instance), the smallest eigenvalue by shift-invert through the
    Schur complement of the instances (a dense factorisation of the kept unknowns) instead of a
    sparse factorisation of every unknown. The same numbers to rounding; a matrix that is not
    positive definite (rank deficient) goes to :func:`scaled_rank_of_normal`. ``plans``: the
    Schur form's structures to share with the solve (:class:`SchurPlans`)."""
    U, W, V, elim, kept = _schur_parts(problem, x, eliminate, plans)
    n, e = problem.n, elim >= 0
    if n <= DENSE_MAX or not e.any():
        return scaled_rank_of_normal(_normal_of_parts(U, W, V, elim, kept, n), rtol)
    ni, s, nk = W.shape
    safe = np.maximum(elim, 0)
    Us, Ws, Vs, _ = _unit_diagonal(U, W, V, e)

    def place(ye: np.ndarray, yk: np.ndarray) -> np.ndarray:
        y = np.empty(n)
        y[elim[e]] = ye[e]
        y[kept] = yk
        return y

    def matvec(v: np.ndarray) -> np.ndarray:
        v = np.ravel(v)
        ve, vk = np.where(e, v[safe], 0.0), v[kept]
        ye = np.einsum("iab,ib->ia", Us, ve) + np.einsum("iab,b->ia", Ws, vk)
        return place(ye, np.einsum("iab,ia->b", Ws, ve) + Vs @ vk)

    try:
        Li = np.linalg.inv(np.linalg.cholesky(Us))
        Y = np.matmul(Li, Ws).reshape(ni * s, nk)
        cS = scipy.linalg.cho_factor(Vs - Y.T @ Y)
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        return scaled_rank_of_normal(_normal_of_parts(U, W, V, elim, kept, n), rtol)

    def solve(b: np.ndarray) -> np.ndarray:
        b = np.ravel(b)
        lb = np.einsum("iab,ib->ia", Li, np.where(e, b[safe], 0.0)).ravel()
        yk = scipy.linalg.cho_solve(cS, b[kept] - Y.T @ lb)
        return place(np.einsum("iba,ib->ia", Li, (lb - Y @ yk).reshape(ni, s)), yk)

    M = LinearOperator((n, n), matvec=matvec, dtype=float)
    try:
        top = eigsh(M, k=1, which="LA", return_eigenvectors=False)[0]
        low = eigsh(M, k=1, sigma=0.0, which="LM", return_eigenvectors=False,
                    OPinv=LinearOperator((n, n), matvec=solve, dtype=float))[0]  # fmt: skip
    except (RuntimeError, ArpackError):
        top = low = 0.0
    if top > 0 and low > (rtol**2) * top:
        return float(np.sqrt(low / top)), n
    return scaled_rank_of_normal(_normal_of_parts(U, W, V, elim, kept, n), rtol)


def scaled_rank_of_normal(JtJ: sp.spmatrix, rtol: float = 1e-9) -> tuple[float, int]:
    """:func:`scaled_rank` from ``J^T J`` (e.g. :func:`schur_normal_matrix`'s)."""
    JtJ = sp.csc_matrix(JtJ)
    dg = np.sqrt(np.maximum(JtJ.diagonal(), 1e-300))
    if JtJ.shape[0] > DENSE_MAX:
        Dinv = sp.diags(1.0 / dg)
        M = (Dinv @ JtJ @ Dinv).tocsc()
        try:
            top = eigsh(M, k=1, which="LA", return_eigenvectors=False)[0]
            low = eigsh(M, k=1, sigma=0.0, which="LM", return_eigenvectors=False)[0]
        except (RuntimeError, ArpackError):  # singular at the shift: rank deficient
            top = low = 0.0
        if top > 0 and low > (rtol**2) * top:
            return float(np.sqrt(low / top)), int(JtJ.shape[0])
    ev = np.linalg.eigvalsh(JtJ.toarray() / np.outer(dg, dg))
    s = np.sqrt(np.clip(ev, 0.0, None))[::-1]
    return float(s[-1] / s[0]), int(np.sum(s > rtol * s[0]))
