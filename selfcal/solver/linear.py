"""The normal equations of a weighted problem and their damped, Marquardt-scaled solution.

Three forms of ``A = J^T W J``, ``g = J^T W r`` (``W`` the per-row IRLS weights):

- ``dense``: one (n, n) array, solved by LU; assembled from the products of each residual
  block's Jacobian pieces, by ``bincount`` or by one dense product per pair of pieces (small
  problems, up to :data:`DENSE_MAX` unknowns);
- ``sparse``: a CSC matrix from the sparse Jacobian, solved by SuperLU with COLAMD ordering;
- ``schur``: the unknowns of one parameter block's *instances* (e.g. the camera poses) are
  eliminated: ``A`` is assembled straight from the Jacobian pieces as ``[[U, W], [W^T, V]]``
  with ``U`` block diagonal (one small block per instance, since no residual row touches two
  instances; :mod:`selfcal.solver.schur`, its structure built once per solve), so each solve
  factors the instance blocks (Cholesky) and the dense reduced ``V - W^T U^-1 W`` (the kept
  unknowns, e.g. intrinsics, rig and points) only: assembly and solve linear in the number of
  instances.

Every form solves ``(S A S + lam I) y = S g`` with ``S = diag(A)^-1/2`` and returns ``S y``
(Marquardt scaling, the damping of :mod:`selfcal.solver.lm`). Singular systems raise
:class:`SingularSystem`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from selfcal.errors import SolverError, UsageError
from selfcal.solver.problem import Evaluation, Problem
from selfcal.solver.schur import SchurAssembler

__all__ = ["DENSE_MAX", "SingularSystem", "NormalEquations", "assemble", "DampedSystem"]

DENSE_MAX = 1500
"""Unknowns up to which the normal equations are formed and factored densely (LU); larger
problems use sparse matrices and SuperLU (or the Schur form when an elimination is asked for)."""

_CHUNK = 8192  # residual rows per bincount pass (bounds the memory of the index arrays)


class SingularSystem(SolverError):
    """The damped normal equations could not be factored or gave a non-finite step (a
    :class:`~selfcal.errors.SolverError`, so a ``RuntimeError``)."""


@dataclass
class NormalEquations:
    """``A`` and ``g`` in one of the three forms (see the module docstring); ``n`` unknowns.

    dense: ``A`` (n, n). sparse: ``A`` CSC. schur: ``U`` (I, s, s), ``W`` (I, s, nk), ``V``
    (nk, nk), ``elim`` (I, s) unknown index per instance slot (``-1`` padding), ``kept`` (nk,)."""

    kind: str
    n: int
    g: np.ndarray
    A: np.ndarray | sp.csc_matrix | None = None
    U: np.ndarray | None = None
    W: np.ndarray | None = None
    V: np.ndarray | None = None
    elim: np.ndarray | None = None
    kept: np.ndarray | None = None

    def is_finite(self) -> bool:
        """True when ``A`` and ``g`` hold no NaN/inf."""
        if not np.isfinite(self.g).all():
            return False
        if self.kind == "sparse":
            return bool(np.isfinite(self.sparse_A.data).all())
        if self.kind == "dense":
            return bool(np.isfinite(self.dense_A).all())
        U, W, V, _, _ = self.schur_parts
        return bool(np.isfinite(U).all() and np.isfinite(W).all() and np.isfinite(V).all())

    @property
    def dense_A(self) -> np.ndarray:
        """``A`` of the dense form."""
        assert self.kind == "dense" and isinstance(self.A, np.ndarray)
        return self.A

    @property
    def sparse_A(self) -> sp.csc_matrix:
        """``A`` of the sparse form."""
        assert self.kind == "sparse" and sp.issparse(self.A)
        return self.A

    @property
    def schur_parts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(U, W, V, elim, kept)`` of the Schur form."""
        U, W, V, elim, kept = self.U, self.W, self.V, self.elim, self.kept
        assert U is not None and W is not None and V is not None
        assert elim is not None and kept is not None
        return U, W, V, elim, kept

    def quadratic(self, x: np.ndarray) -> float:
        """``x^T A x``."""
        if self.kind != "schur":
            assert self.A is not None
            return float(x @ (self.A @ x))
        U, W, V, elim, kept = self.schur_parts
        xe = np.where(elim >= 0, x[np.maximum(elim, 0)], 0.0)
        xk = x[kept]
        Ux = np.einsum("iab,ib->ia", U, xe)
        Wx = np.einsum("iab,b->ia", W, xk)
        return float(np.sum(xe * Ux) + 2.0 * np.sum(xe * Wx) + xk @ (V @ xk))


def _chunks(k: int):
    for a in range(0, k, _CHUNK):
        yield slice(a, min(a + _CHUNK, k))


def _sparse_normal(
    problem: Problem, evals: Sequence[Evaluation], weights: Sequence[np.ndarray]
) -> NormalEquations:
    J = problem.sparse_jacobian(evals)
    wr = np.concatenate([np.repeat(w, ev.residuals.shape[1]) for w, ev in zip(weights, evals)])
    r = np.concatenate([ev.residuals.ravel() for ev in evals])
    JtW = (J.T @ sp.diags(wr)).tocsr()
    return NormalEquations("sparse", problem.n, JtW @ r, A=(JtW @ J).tocsc())


class _Piece:
    """One Jacobian piece of a chunk of rows: ``J`` (k, d, c) with the entries of unused columns
    zeroed, weighted ``wJ``, unknown indices ``G`` (k, c) (unused -> a used one; ``G_raw`` keeps
    the ``-1``), its distinct unknowns ``U`` (a slice when contiguous)."""

    def __init__(self, J: np.ndarray, w: np.ndarray, G: np.ndarray, n: int) -> None:
        self.G_raw = G  # with its -1 slots, for merging
        unused = G < 0
        self.unused = unused if unused.any() else None
        if self.unused is not None:
            J = np.where(unused[:, None, :], 0.0, J)
            G = np.where(unused, G.max(), G)
        self.J, self.wJ, self.G, self.w = J, J * w[:, None, None], G, w
        seen = np.zeros(n, bool)
        seen[G] = True
        U = np.flatnonzero(seen)
        self.nu = len(U)
        self.U = slice(U[0], U[-1] + 1) if U[-1] - U[0] + 1 == len(U) else U
        self.local = (np.cumsum(seen) - 1)[G]
        self.shared = self.nu**2 <= 40 * J.shape[2] ** 2  # most columns in every row

    def gram(self) -> np.ndarray:
        """``J^T W J`` over ``U`` by a symmetric rank-k update of the (k d, len(U)) dense form
        of ``sqrt(w) J`` (half a product's work)."""
        k, d, _ = self.J.shape
        X3 = np.zeros((k, d, self.nu))
        sJ = self.J * np.sqrt(self.w)[:, None, None]
        if self.unused is None:
            rows = (np.arange(k)[:, None, None], np.arange(d)[None, :, None])
            idx = (*rows, self.local[:, None, :])  # a tuple index (no star in [] before 3.11)
            X3[idx] = sJ
        else:
            # an unused slot points at a used column (maybe of the same row): writing its zero
            # there could overwrite that column's entry, so only the used slots are written
            kk, cc = np.nonzero(~self.unused)
            X3[kk, :, self.local[kk, cc]] = sJ[kk, :, cc]
        X = X3.reshape(k * d, -1)
        return X.T @ X  # numpy runs X^T X as a symmetric rank-k update (its own BLAS)


def _block(a: _Piece, b: _Piece) -> tuple:
    """Index of the (U_a, U_b) block of a matrix: two slices (a view) or ``np.ix_``."""
    if isinstance(a.U, slice) and isinstance(b.U, slice):
        return a.U, b.U
    ua = np.arange(a.U.start, a.U.stop) if isinstance(a.U, slice) else a.U
    ub = np.arange(b.U.start, b.U.stop) if isinstance(b.U, slice) else b.U
    return np.ix_(ua, ub)


def _pair_products(M: np.ndarray, a: _Piece, b: _Piece) -> None:
    """``M[a.G, b.G] += sum_rows a.wJ^T b.J``. A piece with few distinct unknowns shared by
    many rows (a kinematic chain: 28 of its 31 columns in every row) with itself: one symmetric
    dense product; otherwise a scatter of the per-row products (measured: faster for poses,
    points and every pair of different pieces)."""
    if a is b and a.shared:
        M[_block(a, a)] += a.gram()
    else:
        L = np.matmul(a.wJ.transpose(0, 2, 1), b.J)
        idx = (a.local[:, :, None] * b.nu + b.local[:, None, :]).ravel()
        M[_block(a, b)] += np.bincount(idx, L.ravel(), a.nu * b.nu).reshape(a.nu, b.nu)


def _grouped(ps: list[_Piece], w: np.ndarray, n: int) -> list[_Piece]:
    """At most two pieces: the shared ones side by side (if one of them is wide and they are
    still shared together) and the others side by side (their columns are disjoint: different
    parameter blocks)."""

    def merged(group: list[_Piece]) -> list[_Piece]:
        if len(group) < 2:
            return group
        J = np.concatenate([p.J for p in group], axis=2)
        return [_Piece(J, w, np.concatenate([p.G_raw for p in group], axis=1), n)]

    if not any(p.shared and p.J.shape[2] >= 8 for p in ps):  # nothing wide: one scatter
        return merged(ps)
    shared = merged([p for p in ps if p.shared])
    if not shared[0].shared:
        return merged(ps)
    return shared + merged([p for p in ps if not p.shared])


def _accumulate(A: np.ndarray, B: np.ndarray | None, pieces: list[_Piece]) -> np.ndarray | None:
    """Adds the products of ``pieces`` (one chunk of rows) to ``A`` (pairs of a piece with
    itself) and ``B`` (pairs a < b, allocated on first use; the caller adds ``B + B^T``)."""
    for i, a in enumerate(pieces):
        for b in pieces[i:]:
            if b is a:
                _pair_products(A, a, b)
                continue
            if B is None:
                B = np.zeros_like(A)
            _pair_products(B, a, b)
    return B


def _dense_normal(
    problem: Problem, evals: Sequence[Evaluation], weights: Sequence[np.ndarray]
) -> NormalEquations:
    """Dense ``A`` from the products of the Jacobian pieces (a piece's columns in one row are
    distinct): a wide piece whose columns are shared by most rows (a kinematic chain) with
    itself by a dense product, all other pieces together by one scatter, the cross pairs by
    scatters; rows in chunks of :data:`_CHUNK`."""
    n = problem.n
    A = np.zeros((n, n))  # diagonal piece pairs
    B: np.ndarray | None = None  # pairs a < b, added with their transpose
    g = np.zeros(n)
    for ev, w in zip(evals, weights):
        Gs = [problem.global_cols(pc) for pc in ev.pieces]
        for sl in _chunks(len(ev.residuals)):
            ps = [
                _Piece(pc.J[sl], w[sl], G[sl], n)
                for pc, G in zip(ev.pieces, Gs)
                if G[sl].max() >= 0
            ]
            ps = _grouped(ps, w[sl], n)
            for a in ps:
                gr = np.einsum("kda,kd->ka", a.wJ, ev.residuals[sl])
                g += np.bincount(a.G.ravel(), gr.ravel(), n)
            B = _accumulate(A, B, ps)
    if B is not None:
        A += B + B.T
    return NormalEquations("dense", n, g, A=A)


def assemble(
    problem: Problem,
    evals: Sequence[Evaluation],
    weights: Sequence[np.ndarray],
    kind: str,
    instances: np.ndarray | None = None,
    schur: SchurAssembler | None = None,
) -> NormalEquations:
    """Normal equations of ``problem`` from Jacobian evaluations and per-row weights (k,) per
    residual block. ``kind``: "dense", "sparse" or "schur" (``instances`` (n,) int: instance of
    every unknown to eliminate, -1 kept; see :meth:`Problem.instance_of_columns`; or ``schur``,
    an assembler of the problem that keeps its structure from one call to the next)."""
    if kind == "dense":
        return _dense_normal(problem, evals, weights)
    if kind == "sparse":
        return _sparse_normal(problem, evals, weights)
    if kind == "schur":
        if schur is None:
            if instances is None:
                raise UsageError("the Schur form needs the instances of the eliminated unknowns")
            schur = SchurAssembler(problem, instances)
        g, U, W, V = schur.assemble(evals, weights)
        lay = schur.layout
        return NormalEquations("schur", problem.n, g, U=U, W=W, V=V, elim=lay.elim, kept=lay.kept)
    raise UsageError(f"unknown linear solver {kind!r}; use dense, sparse or schur")


class DampedSystem:
    """Solves ``(S A S + lam I) y = S g`` for the Marquardt-scaled normal equations
    (``S = diag(A)^-1/2``, tiny diagonals lifted to ``1e-12 max diag``) and returns ``S y``."""

    def __init__(self, ne: NormalEquations):
        self.ne = ne
        if ne.kind == "schur":
            U, W, V, elim, kept = ne.schur_parts
            diag = np.zeros(ne.n)
            e = elim >= 0
            diag[elim[e]] = np.einsum("iaa->ia", U)[e]
            diag[kept] = np.diag(V)
        else:
            diag = np.diag(ne.dense_A) if ne.kind == "dense" else ne.sparse_A.diagonal()
        d = np.maximum(diag, 1e-12 * max(diag.max(initial=0.0), 1e-300))
        self.s = 1.0 / np.sqrt(d)
        self.As: np.ndarray | sp.csc_matrix
        if ne.kind == "dense":
            self.As = ne.dense_A * self.s[:, None] * self.s[None, :]
        elif ne.kind == "sparse":
            S = sp.diags(self.s)
            self.As = (S @ ne.sparse_A @ S).tocsc()
        else:
            se = np.where(e, self.s[np.maximum(elim, 0)], 1.0)
            sk = self.s[kept]
            self.Us = U * se[:, :, None] * se[:, None, :]
            self.Ws = W * se[:, :, None]  # then by sk in place: no second (ni, s, nk) temporary
            self.Ws *= sk[None, None, :]
            self.Vs = V * sk[:, None] * sk[None, :]
            self.se = se

    def scaled_gradient(self) -> np.ndarray:
        """``S g`` (n,)."""
        return self.s * self.ne.g

    def solve(self, lam: float) -> np.ndarray:
        """The step ``x = S y`` for damping ``lam`` (not negated). Raises
        :class:`SingularSystem` when the damped matrix cannot be factored."""
        gs = self.s * self.ne.g
        try:
            if self.ne.kind == "dense":
                assert isinstance(self.As, np.ndarray)
                M = self.As.copy()
                M[np.diag_indices_from(M)] += lam
                y = np.linalg.solve(M, gs)
            elif self.ne.kind == "sparse":
                Ms = (self.As + lam * sp.eye(len(gs), format="csc")).tocsc()
                y = splu(Ms, permc_spec="COLAMD").solve(gs)
            else:
                y = self._solve_schur(gs, lam)
        except (np.linalg.LinAlgError, RuntimeError) as exc:
            raise SingularSystem(str(exc)) from None
        if not np.isfinite(y).all():
            raise SingularSystem("singular damped normal equations (non-finite step)")
        return self.s * y

    def _solve_schur(self, gs: np.ndarray, lam: float) -> np.ndarray:
        _, _, _, elim, kept = self.ne.schur_parts
        ni, s, nk = self.Ws.shape
        if ni == 0:  # nothing eliminated: the kept block alone
            y = np.empty_like(gs)
            y[kept] = np.linalg.solve(self.Vs + lam * np.eye(nk), gs[kept])
            return y
        Ud = self.Us + lam * np.eye(s)
        e = elim >= 0
        ge = np.where(e, gs[np.maximum(elim, 0)], 0.0)
        try:  # U_i = L_i L_i^T: the reduced matrix by a symmetric product of L_i^-1 W_i
            Li = np.linalg.inv(np.linalg.cholesky(Ud))
        except np.linalg.LinAlgError:  # not positive definite in floating point: LU
            Li = None
        if Li is not None:
            Y = np.matmul(Li, self.Ws).reshape(ni * s, -1)
            S = self.Vs - Y.T @ Y
            lge = np.einsum("iab,ib->ia", Li, ge).ravel()
            S[np.diag_indices_from(S)] += lam
            yk = _spd_solve(S, gs[kept] - Y.T @ lge)
            t = lge - Y @ yk
            ye = np.einsum("iba,ib->ia", Li, t.reshape(ni, s))
        else:
            Ui = np.linalg.inv(Ud)
            Z = np.matmul(Ui, self.Ws).reshape(ni * s, -1)
            Wf = self.Ws.reshape(ni * s, -1)
            S = self.Vs - Wf.T @ Z
            S[np.diag_indices_from(S)] += lam
            uge = np.einsum("iab,ib->ia", Ui, ge)
            yk = np.linalg.solve(S, gs[kept] - Wf.T @ uge.ravel())
            ye = uge - np.einsum("iab,b->ia", Z.reshape(ni, s, -1), yk)
        y = np.empty_like(gs)
        y[kept] = yk
        y[elim[e]] = ye[e]
        return y


def _spd_solve(S: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``S^-1 b`` for the damped reduced matrix ``S`` (symmetric, positive definite: the Schur
    complement of a positive definite matrix) by its Cholesky factor, half the work of LU; by
    LU when floating point makes it not positive definite."""
    try:
        factor = scipy.linalg.cho_factor(S, check_finite=False)
    except np.linalg.LinAlgError:
        return np.linalg.solve(S, b)
    return scipy.linalg.cho_solve(factor, b, check_finite=False)
