"""The Schur form of the normal equations, assembled through a symbolic structure built once.

The unknowns of one parameter block's *instances* (e.g. the camera poses, or the joint
corrections of each configuration) are eliminated: ``A = J^T W J`` is assembled as
``[[U, W], [W^T, V]]`` with ``U`` block diagonal, one ``(s, s)`` block per instance (no residual
row touches two instances), the coupling ``W`` ``(I, s, nk)`` and the dense kept block ``V``
``(nk, nk)`` (intrinsics, rig, kinematics, points).

:class:`SchurAssembler` sorts, once per problem, every Jacobian column of every residual block
into one of three kinds by the unknowns it touches over the rows:

- *eliminated* (``E``): an instance's unknown; the rows are grouped by instance (and slot layout);
- *constant kept* (``C``): the same kept unknown in every row that uses it (intrinsics, rig,
  kinematic parameters): their block ``Xc^T Xc`` is one BLAS product over all rows;
- *varying kept* (``P``): a kept unknown that changes from row to row (a point's coordinates);
  the rows are grouped by the unknowns they touch.

Each group's rows are cut into chunks of at most :data:`CHUNK_ROWS` (zero-padded), and the sums
``X_a^T X_b`` over a group are batched matrix products of the chunks added by ``reduceat`` (no
Python loop over instances or points); only the ``E x P`` products are formed per row. The
scatter indices of every product into ``U``, ``W`` and ``V`` are computed once and reused in
every iteration while the Jacobian's column pattern stays the same (checked on each call; a
changed pattern rebuilds that residual block's structure). ``X = sqrt(w) J`` with the IRLS row
weights ``w >= 0``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.errors import UsageError
from selfcal.solver.problem import Evaluation, Problem

__all__ = ["BATCH_ENTRIES", "CHUNK_ROWS", "SchurLayout", "SchurAssembler", "SchurPlans"]

CHUNK_ROWS = 32
"""Rows per chunk of a group in the batched products (a group is padded to whole chunks)."""

BATCH_ENTRIES = 1 << 18
"""Gathered Jacobian entries per batch of chunks in :meth:`_Groups.products` (bounds its
memory; the sums do not depend on it)."""


@dataclass(frozen=True)
class SchurLayout:
    """Where each unknown goes: ``slot`` (n + 1,) its slot in its instance, ``inst`` (n + 1,)
    its instance (0 .. ni-1; ``ni`` for a kept unknown), ``kid`` (n + 1,) its kept index
    (``nk`` for an eliminated one); the extra last entry answers index ``-1`` (no column).
    ``elim`` (ni, s) the unknown of each instance slot (``-1`` padding), ``kept`` (nk,)."""

    slot: np.ndarray
    inst: np.ndarray
    kid: np.ndarray
    elim: np.ndarray
    kept: np.ndarray
    ni: int
    s: int
    nk: int

    @classmethod
    def of(cls, instance: np.ndarray) -> SchurLayout:
        """From the instance of every unknown (-1 = kept), e.g.
        :meth:`selfcal.solver.Problem.instance_of_columns`."""
        n = len(instance)
        kept = np.flatnonzero(instance < 0)
        e = np.flatnonzero(instance >= 0)
        ids, inv = np.unique(instance[e], return_inverse=True)
        inv = inv.reshape(-1)
        counts = np.bincount(inv, minlength=len(ids))
        s = int(counts.max()) if len(ids) else 1
        order = np.argsort(inv, kind="stable")
        slot = np.empty(len(e), np.int64)
        starts = np.cumsum(counts) - counts
        slot[order] = np.arange(len(e)) - np.repeat(starts, counts)
        elim = -np.ones((len(ids), s), np.int64)
        elim[inv, slot] = e
        slot_of = np.full(n + 1, s, np.int64)
        slot_of[e] = slot
        inst_of = np.full(n + 1, len(ids), np.int64)
        inst_of[e] = inv
        kid = np.full(n + 1, len(kept), np.int64)
        kid[kept] = np.arange(len(kept))
        return cls(slot_of, inst_of, kid, elim, kept, len(ids), s, len(kept))


class _Groups:
    """Rows grouped by an id (``-1``: in no group), each group cut into chunks of at most ``M``
    rows: ``rows`` (chunks, M) row indices (padding: row ``k``, the zero row every ``X`` has),
    ``starts`` the first chunk of each group (``reduceat``), ``first`` a row of each group."""

    def __init__(self, group: np.ndarray, k: int) -> None:
        sel = np.flatnonzero(group >= 0)
        order = sel[np.argsort(group[sel], kind="stable")]
        _, first, counts = np.unique(group[order], return_index=True, return_counts=True)
        self.n = len(counts)
        m = int(min(CHUNK_ROWS, max(1, np.median(counts)))) if self.n else 1
        per = -(-counts // m)
        self.starts = np.cumsum(per) - per
        local = np.arange(len(order)) - np.repeat(first, counts)
        self.rows = np.full((int(per.sum()), m), k, np.int64)
        self.rows[np.repeat(self.starts, counts) + local // m, local % m] = order
        self.first = order[first]

    def products(self, A: np.ndarray, B: np.ndarray | None = None) -> np.ndarray:
        """``sum_{rows r of the group} A_r^T B_r`` (groups, a, b) for ``A`` (k + 1, d, a) and
        ``B`` (k + 1, d, b) (``B`` None: ``A``). The chunks' products are formed for a batch of
        whole groups at a time (about :data:`BATCH_ENTRIES` gathered entries, at least one
        group) and summed over each group by ``reduceat``: the sums over all chunks at once,
        bit for bit, without the gathered rows of every chunk in memory."""
        c, m = self.rows.shape
        d, a = A.shape[1], A.shape[2]
        b = a if B is None else B.shape[2]
        out = np.empty((self.n, a, b))
        per = max(1, BATCH_ENTRIES // (m * d * (a + b)))  # chunks per batch
        ends = np.r_[self.starts[1:], c]
        g0 = 0
        while g0 < self.n:  # groups g0 .. g1 - 1: their chunks, and at least one group
            g1 = max(g0 + 1, int(np.searchsorted(ends, self.starts[g0] + per, "right")))
            c0, c1 = self.starts[g0], ends[g1 - 1]
            rows = self.rows[c0:c1]
            Ap = A[rows].reshape(c1 - c0, m * d, a)
            Bp = Ap if B is None else B[rows].reshape(c1 - c0, m * d, b)
            P = np.matmul(Ap.transpose(0, 2, 1), Bp)
            out[g0:g1] = np.add.reduceat(P, self.starts[g0:g1] - c0, axis=0)
            g0 = g1
        return out


class _Columns:
    """One kind of Jacobian column of a residual block, gathered from the pieces into
    ``X`` (k + 1, d, c) = ``sqrt(w) J`` with the entries of rows that do not use the column
    zeroed and a zero last row. ``G`` (k, c) the unknown of each entry (``n``: none)."""

    def __init__(self, k: int, d: int) -> None:
        self.k, self.d = k, d
        self.src: list[tuple[int, int]] = []  # (piece, column)
        self.G: list[np.ndarray] = []
        self.used: list[np.ndarray] = []

    def add(self, piece: int, cols: np.ndarray, GT: np.ndarray, used: np.ndarray, n: int) -> None:
        """The columns ``cols`` of piece ``piece``: their unknowns ``GT`` (c, k) and which rows
        use them ``used`` (c, k), a column a row."""
        self.src += [(piece, int(c)) for c in cols]
        self.G.append(np.where(used, GT, n))
        self.used.append(used)

    def freeze(self) -> None:
        """Cut the sources into runs of consecutive columns of one piece (copied as slices) and
        list the zero entries."""
        self.c = len(self.src)
        k = self.k
        GmT = np.concatenate(self.G) if self.G else np.zeros((0, k), np.int64)
        self.Gm = np.ascontiguousarray(GmT.T)
        self.runs: list[tuple[int, slice, slice]] = []
        for dst, (p, col) in enumerate(self.src):
            if self.runs and self.runs[-1][0] == p and self.runs[-1][1].stop == col:
                _, a, b = self.runs.pop()
                self.runs.append((p, slice(a.start, col + 1), slice(b.start, dst + 1)))
            else:
                self.runs.append((p, slice(col, col + 1), slice(dst, dst + 1)))
        used = np.concatenate(self.used) if self.used else np.ones((0, k), bool)
        zc, zr = np.nonzero(~used)
        # the unused entries' flat positions in X (every row of a residual's d components)
        self.zero = ((zr[:, None] * self.d + np.arange(self.d)) * self.c + zc[:, None]).ravel()
        self.G, self.used = [], []  # in Gm and zero now (a plan lives as long as its solve)

    def gather(self, Js: Sequence[np.ndarray], sw: np.ndarray | None) -> np.ndarray:
        """``X`` (class docstring); ``sw`` (k, 1) the rows' square-root weights, None when
        every weight is 1. The pieces' columns are copied first and then weighted in place:
        one contiguous product, where a product into strided slices of ``X`` took 1.5x as
        long (the same numbers)."""
        X = np.empty((self.k + 1, self.d, self.c))
        X[self.k] = 0.0
        for p, src, dst in self.runs:
            X[: self.k, :, dst] = Js[p][:, :, src]
        if sw is not None:
            Xk = X[: self.k].reshape(self.k, -1)
            np.multiply(Xk, sw, out=Xk)
        if len(self.zero):
            X.reshape(-1)[self.zero] = 0.0
        return X


class _BlockPlan:
    """The structure of one residual block's contribution (see the module docstring)."""

    def __init__(self, Gs: Sequence[np.ndarray], k: int, d: int, lay: SchurLayout, n: int):
        self.k, self.d, self.n = k, d, n
        inst_x, kid = lay.inst, lay.kid
        E, C, P = _Columns(k, d), _Columns(k, d), _Columns(k, d)
        for p, G in enumerate(Gs):  # every column of a piece at once, a column a row of GT
            GT = np.ascontiguousarray(G.T)
            valid = GT >= 0
            is_e = valid & (inst_x[GT] < lay.ni)  # inst_x[-1]: no instance
            is_k = valid & ~is_e
            # a kept column is constant when its used rows' smallest and largest unknown agree
            const = np.where(is_k, GT, n).min(axis=1) == np.where(is_k, GT, -1).max(axis=1)
            any_e, any_k = is_e.any(axis=1), is_k.any(axis=1)
            for cols, used, on in ((E, is_e, any_e), (C, is_k, any_k & const),
                                   (P, is_k, any_k & ~const)):  # fmt: skip
                j = np.flatnonzero(on)
                if len(j):
                    cols.add(p, j, GT[j], used[j], n)
        for cols in (E, C, P):
            cols.freeze()
        self.E, self.C, self.P = E, C, P
        ni, s, nk = lay.ni, lay.s, lay.nk
        # eliminated: one instance per row, grouped by (instance, slot layout)
        inst_e = lay.inst[E.Gm]  # ni where unused
        row_inst = np.where(inst_e < ni, inst_e, -1).max(axis=1, initial=-1)
        if np.any((inst_e < ni) & (inst_e != row_inst[:, None])):
            raise UsageError(
                "a residual block couples two instances of the eliminated parameter block; "
                "the Schur elimination does not apply"
            )
        slot_e = np.where(inst_e < ni, lay.slot[E.Gm], -1)
        self.ge = self._grouping(np.concatenate([row_inst[:, None], slot_e], axis=1), row_inst)
        gi = row_inst[self.ge.first]  # (groups,) instance
        gs = np.maximum(slot_e[self.ge.first], 0)  # (groups, ce) slots (unused entries add 0)
        self.U_idx = ((gi[:, None, None] * s + gs[:, :, None]) * s + gs[:, None, :]).ravel()
        # a constant column's unknown: the one of its used rows
        self.gc = np.where(C.Gm < n, C.Gm, -1).max(axis=0, initial=-1)
        self.kc = kc = kid[self.gc]
        self.kc_unique = len(np.unique(kc)) == len(kc)
        self.W_idx_c = ((gi[:, None, None] * s + gs[:, :, None]) * nk + kc[None, None, :]).ravel()
        # varying kept: rows grouped by the unknowns they touch
        kp = np.where(P.Gm < n, kid[np.minimum(P.Gm, n)], -1)  # (k, cp)
        self.gp = self._grouping(kp, np.where((kp >= 0).any(axis=1), 0, -1))
        gp = np.maximum(kp[self.gp.first], 0)  # (groups, cp)
        self.V_idx_cp = (kc[None, :, None] * nk + gp[:, None, :]).ravel()
        self.V_idx_pp = (gp[:, :, None] * nk + gp[:, None, :]).ravel()
        # eliminated x varying kept, per row (rows that have both)
        both = (row_inst >= 0) & (kp >= 0).any(axis=1) if E.c and P.c else np.zeros(k, bool)
        self.ep_rows = np.flatnonzero(both)
        r = self.ep_rows
        se = np.maximum(slot_e[r], 0)
        self.W_idx_p = (
            (row_inst[r, None, None] * s + se[:, :, None]) * nk + np.maximum(kp[r], 0)[:, None, :]
        ).ravel()

    @staticmethod
    def _grouping(key: np.ndarray, member: np.ndarray) -> _Groups:
        """Groups of the rows with ``member >= 0`` by equal ``key`` rows."""
        group = -np.ones(len(key), np.int64)
        sel = np.flatnonzero(member >= 0)
        if len(sel):
            group[sel] = _row_ids(key[sel])
        return _Groups(group, len(key))

    def contribute(self, ev: Evaluation, w: np.ndarray, out: _Sums) -> None:
        """Adds this block's products (``ev``'s pieces, row weights ``w``) to ``out``."""
        Js = [pc.J for pc in ev.pieces]
        unit = bool(np.all(w == 1.0))  # plain least squares: X is J (no products by 1)
        sw = None if unit else np.sqrt(w)[:, None]
        y = np.zeros((self.k + 1, self.d))
        res = ev.residuals.reshape(self.k, self.d)
        if sw is None:
            y[: self.k] = res
        else:
            np.multiply(res, sw, out=y[: self.k])
        Xe = self.E.gather(Js, sw) if self.E.c else None
        Xc = self.C.gather(Js, sw) if self.C.c else None
        Xp = self.P.gather(Js, sw) if self.P.c else None
        for X, cols in ((Xe, self.E), (Xp, self.P)):
            if X is not None:
                out.g_idx.append(cols.Gm.ravel())
                out.g_val.append(np.einsum("kda,kd->ka", X[: self.k], y[: self.k]).ravel())
        if Xc is not None:
            Xf = Xc.reshape(-1, self.C.c)
            out.g_idx.append(self.gc)
            out.g_val.append(Xf.T @ y.ravel())
            out.add_V(self.kc, Xf.T @ Xf, self.kc_unique)
        if Xe is not None and self.ge.n:
            out.U.append((self.U_idx, self.ge.products(Xe).ravel()))
            if Xc is not None:
                out.W.append((self.W_idx_c, self.ge.products(Xe, Xc).ravel()))
        if Xp is not None and self.gp.n:
            out.Vl.append((self.V_idx_pp, self.gp.products(Xp).ravel()))
            if Xc is not None:
                out.Vsym.append((self.V_idx_cp, self.gp.products(Xc, Xp).ravel()))
        if len(self.ep_rows):
            assert Xe is not None and Xp is not None
            r = self.ep_rows
            L = np.matmul(Xe[r].transpose(0, 2, 1), Xp[r])
            out.W.append((self.W_idx_p, L.ravel()))


class _Sums:
    """The products of one assembly, scattered at the end (one ``bincount`` per matrix)."""

    def __init__(self, lay: SchurLayout, n: int) -> None:
        self.lay, self.n = lay, n
        self.V = np.zeros((lay.nk, lay.nk))
        self.g_idx: list[np.ndarray] = []
        self.g_val: list[np.ndarray] = []
        self.U: list[tuple[np.ndarray, np.ndarray]] = []
        self.W: list[tuple[np.ndarray, np.ndarray]] = []
        self.Vsym: list[tuple[np.ndarray, np.ndarray]] = []  # added with their transpose
        self.Vl: list[tuple[np.ndarray, np.ndarray]] = []  # kept x kept, scattered

    def add_V(self, kc: np.ndarray, M: np.ndarray, unique: bool) -> None:
        if unique:
            self.V[np.ix_(kc, kc)] += M
        else:
            np.add.at(self.V, (kc[:, None], kc[None, :]), M)

    @staticmethod
    def scatter(parts: list[tuple[np.ndarray, np.ndarray]], size: int) -> np.ndarray | None:
        if not parts:
            return None
        if len(parts) == 1:
            return np.bincount(parts[0][0], parts[0][1], size)
        idx = np.concatenate([p[0] for p in parts])
        return np.bincount(idx, np.concatenate([p[1] for p in parts]), size)

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``g`` (n,), ``U`` (ni, s, s), ``W`` (ni, s, nk), ``V`` (nk, nk)."""
        lay, n = self.lay, self.n
        ni, s, nk = lay.ni, lay.s, lay.nk
        g = self.scatter(list(zip(self.g_idx, self.g_val)), n + 1)
        U = self.scatter(self.U, ni * s * s)
        W = self.scatter(self.W, ni * s * nk)
        V = self.V
        Vl = self.scatter(self.Vl, nk * nk)
        if Vl is not None:
            V += Vl.reshape(nk, nk)
        Vs = self.scatter(self.Vsym, nk * nk)
        if Vs is not None:
            Vs = Vs.reshape(nk, nk)
            V += Vs + Vs.T
        return (
            np.zeros(n) if g is None else g[:n],
            np.zeros((ni, s, s)) if U is None else U.reshape(ni, s, s),
            np.zeros((ni, s, nk)) if W is None else W.reshape(ni, s, nk),
            V,
        )


class SchurPlans:
    """The residual blocks' assembly structures kept from one :class:`SchurAssembler` to the
    next: for a sequence of solves and checks of problems with the same structure (the robust
    rounds of an adjustment that keep their rows and its final plain pass, its rank check at
    the start and covariance at the solution), each builds a block's structure only when no
    kept one has the same eliminated unknowns and the same global columns in every row
    (compared, never assumed: a copy of those columns, 4 bytes an entry, is kept beside the
    structure). A caller holds one for as long as such a sequence runs; it keeps the last
    structure of each residual block name.

    ``normal=True``: it also keeps the last unweighted ``J^T J`` a check assembled (the Schur
    parts of :mod:`selfcal.solver.covariance`) for one more use at the same point by the same
    problem (a rank check, then a covariance: one Jacobian and one assembly instead of two);
    taken, it is dropped (it is as large as the coupling block ``W``)."""

    def __init__(self, normal: bool = False) -> None:
        self._kept: dict[str, tuple[np.ndarray, list[np.ndarray], int, _BlockPlan]] = {}
        self._normal_on = normal
        self._normal: tuple[Problem, np.ndarray, np.ndarray, tuple] | None = None

    def keep_normal(self, problem: Problem, x: np.ndarray, instance: np.ndarray, parts: tuple):
        """Keep ``parts`` of ``problem`` at ``x`` (instances ``instance``) when ``normal``."""
        if self._normal_on:
            self._normal = (problem, np.array(x, dtype=float), instance.copy(), parts)

    def normal_at(self, problem: Problem, x: np.ndarray, instance: np.ndarray) -> tuple | None:
        """The kept parts if they are ``problem``'s (the same object) at ``x`` with these
        instances (then dropped), else None."""
        kept, self._normal = self._normal, None
        if kept is None or kept[0] is not problem:
            return None
        if not (np.array_equal(kept[1], x) and np.array_equal(kept[2], instance)):
            return None
        return kept[3]

    def find(
        self, name: str, instance: np.ndarray, Gs: Sequence[np.ndarray], d: int
    ) -> _BlockPlan | None:
        """The kept structure of block ``name`` if it was built for these instances (n,), the
        pieces' global columns ``Gs`` (k, c) each and ``d`` residuals a row, else None."""
        kept = self._kept.get(name)
        if kept is None or kept[2] != d or not np.array_equal(kept[0], instance):
            return None
        if len(kept[1]) != len(Gs) or any(
            a.shape != b.shape or not np.array_equal(a, b) for a, b in zip(kept[1], Gs)
        ):
            return None
        return kept[3]

    def keep(
        self, name: str, instance: np.ndarray, Gs: Sequence[np.ndarray], d: int, plan: _BlockPlan
    ) -> None:
        small = np.int32 if len(instance) < 2**31 else np.int64
        self._kept[name] = (instance.copy(), [G.astype(small) for G in Gs], d, plan)


class SchurAssembler:
    """Assembles the Schur-form normal equations of ``problem`` for the instances ``instance``
    (n,) (-1 kept; :meth:`selfcal.solver.Problem.instance_of_columns`); the structure of each
    residual block is built on the first call and reused while its column pattern is the same,
    or taken from ``plans`` (:class:`SchurPlans`) when an earlier assembler of the same
    structure built it.

    Raises ``ValueError`` (on the first assembly) when a residual row couples two instances.
    """

    def __init__(
        self, problem: Problem, instance: np.ndarray, plans: SchurPlans | None = None
    ) -> None:
        self.problem = problem
        self.instance = np.asarray(instance, dtype=np.int64)
        self.layout = SchurLayout.of(self.instance)
        self.plans = plans
        self._plans: list[tuple[tuple, _BlockPlan] | None] = [None] * len(problem.residuals)

    def _plan(self, i: int, ev: Evaluation) -> _BlockPlan:
        k = len(ev.residuals)
        key = tuple((pc.block, pc.cols, pc.J.shape) for pc in ev.pieces)
        cached = self._plans[i]
        if cached is not None and _same(cached[0], key):
            return cached[1]
        d = int(np.prod(ev.residuals.shape[1:], dtype=np.int64)) if k else 1
        Gs = [self.problem.global_cols(pc) for pc in ev.pieces]
        name = self.problem.residuals[i].name
        plan = self.plans.find(name, self.instance, Gs, d) if self.plans is not None else None
        if plan is None:
            plan = _BlockPlan(Gs, k, d, self.layout, self.problem.n)
            if self.plans is not None:
                self.plans.keep(name, self.instance, Gs, d, plan)
        self._plans[i] = (key, plan)
        return plan

    def assemble(
        self, evals: Sequence[Evaluation], weights: Sequence[np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(g, U, W, V)`` of ``J^T W J`` and ``J^T W r`` (see the module docstring) from the
        Jacobian evaluations and the IRLS row weights (k,) of each residual block."""
        out = _Sums(self.layout, self.problem.n)
        for i, (ev, w) in enumerate(zip(evals, weights)):
            if len(ev.residuals) and ev.pieces:
                self._plan(i, ev).contribute(ev, np.asarray(w, dtype=float), out)
        return out.result()


def _row_ids(key: np.ndarray) -> np.ndarray:
    """An id per row of ``key`` (m, c) ints >= -1, equal for equal rows (one integer code per
    row when the value ranges allow, else ``np.unique`` over the rows)."""
    k = key + 1
    radix = k.max(axis=0, initial=0) + 1
    if np.sum(np.log2(radix.astype(float))) < 62:
        code = np.zeros(len(k), np.int64)
        for j in range(k.shape[1]):
            code = code * radix[j] + k[:, j]
        return np.unique(code, return_inverse=True)[1].reshape(-1)
    return np.unique(k, axis=0, return_inverse=True)[1].reshape(-1)


def _same(a: tuple, b: tuple) -> bool:
    """Two column patterns (block, cols, J shape per piece) are the same."""
    if len(a) != len(b):
        return False
    for (ba, ca, sa), (bb, cb, sb) in zip(a, b):
        if ba != bb or sa != sb:
            return False
        if ca is not cb and not np.array_equal(ca, cb):
            return False
    return True
