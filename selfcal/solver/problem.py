"""Parameter blocks, residual blocks and the problem that lays them out as one unknown vector.

A *parameter block* is a named flat array (e.g. ``"intrinsics"`` = ``[fx, mu]``, ``"points"`` =
``(P, 3)`` raveled); some coordinates may be *held* at their initial values (gauge, fixed
intrinsics) and are then not unknowns, and some may be *bounded* (``lower`` <= value <=
``upper``, e.g. joint ranges): the solver projects every step onto the box. A coordinate may belong to an *instance* (e.g. the six
coordinates of one camera pose): the linear solver can eliminate all instances of one block by a
Schur complement when no residual row touches two of them.

A *residual block* is a batch of ``k`` homogeneous residual rows of dimension ``d`` (e.g. all image
observations, ``d = 2``) with one robust :class:`~selfcal.solver.losses.Loss` on each row's norm. It
is evaluated in one vectorised call and returns the residuals ``(k, d)`` and, when asked, its
Jacobian as *pieces*: per parameter block a dense ``(k, d, c)`` array and the ``(k, c)`` block
coordinates each column belongs to (``-1`` = no column). A new measurement kind is a new residual
block; the engine does not change.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from selfcal.errors import SolverError, UsageError
from selfcal.solver.losses import Loss

__all__ = [
    "ParameterBlock",
    "JacobianPiece",
    "Evaluation",
    "ResidualBlock",
    "Problem",
    "JACOBIAN_CHUNK",
]

JACOBIAN_CHUNK = 8192
"""Residual rows of a block per chunk of :meth:`Problem.sparse_jacobian` (bounds the memory of
its triplets; the matrix does not depend on it)."""


@dataclass(frozen=True)
class ParameterBlock:
    """A named parameter array (flattened, SI units of the caller's choosing).

    ``held``: bool mask (size,) of coordinates fixed at ``value`` (None: all free).
    ``instance``: int (size,) instance index of each coordinate for Schur elimination, ``-1`` for
    coordinates shared by all rows (None: no instances).
    ``lower``, ``upper``: bounds of the coordinates (scalar or (size,); None: -inf / inf); a
    start outside them is moved onto them.

    Raises :class:`selfcal.errors.UsageError` for arrays of another size or a lower bound above its upper bound.
    """

    name: str
    value: np.ndarray
    held: np.ndarray | None = None
    instance: np.ndarray | None = None
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    def __post_init__(self) -> None:
        v = np.asarray(self.value, dtype=float).reshape(-1).copy()
        object.__setattr__(self, "value", v)
        for key in ("held", "instance"):
            a = getattr(self, key)
            if a is None:
                continue
            a = np.asarray(a, dtype=bool if key == "held" else np.int64).reshape(-1)
            if a.shape != v.shape:
                raise UsageError(
                    f"parameter block {self.name!r}: {key} has {a.size} entries for "
                    f"{v.size} coordinates"
                )
            object.__setattr__(self, key, a)
        if self.lower is not None or self.upper is not None:
            lo = np.broadcast_to(-np.inf if self.lower is None else self.lower, v.shape)
            hi = np.broadcast_to(np.inf if self.upper is None else self.upper, v.shape)
            lo, hi = np.asarray(lo, dtype=float).copy(), np.asarray(hi, dtype=float).copy()
            if np.any(lo > hi) or np.isnan(lo).any() or np.isnan(hi).any():
                raise UsageError(f"parameter block {self.name!r}: a lower bound above its upper")
            object.__setattr__(self, "lower", lo)
            object.__setattr__(self, "upper", hi)
            object.__setattr__(self, "value", np.clip(v, lo, hi))

    @property
    def size(self) -> int:
        return int(self.value.size)


@dataclass(frozen=True)
class JacobianPiece:
    """Derivative of a residual block's rows w.r.t. one parameter block.

    ``J`` (k, d, c); ``cols`` (k, c) int coordinates of parameter block ``block`` (``-1``: the
    entry is ignored)."""

    block: str
    J: np.ndarray
    cols: np.ndarray


@dataclass(frozen=True)
class Evaluation:
    """Residuals (k, d) of one residual block and, if requested, its Jacobian pieces."""

    residuals: np.ndarray
    pieces: tuple[JacobianPiece, ...] = field(default=())


@runtime_checkable
class ResidualBlock(Protocol):
    """A batch of residual rows (see the module docstring)."""

    name: str
    dim: int
    loss: Loss

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (and Jacobian pieces when ``jacobian``) at the full parameter arrays
        ``values`` (block name -> flat array, held coordinates included)."""


class Problem:
    """Parameter blocks laid out as one unknown vector ``x`` (free coordinates, block order) and
    the residual blocks evaluated over it.

    Raises ``ValueError`` for duplicate names or residual blocks whose dimension is not >= 1.
    """

    def __init__(
        self, parameters: Sequence[ParameterBlock], residuals: Sequence[ResidualBlock]
    ) -> None:
        self.parameters = {p.name: p for p in parameters}
        self.residuals = list(residuals)
        if len(self.parameters) != len(parameters):
            raise UsageError("parameter block names must be unique")
        if len({r.name for r in self.residuals}) != len(self.residuals):
            raise UsageError("residual block names must be unique")
        self.colmap: dict[str, np.ndarray] = {}
        start = 0
        for p in parameters:
            free = np.ones(p.size, bool) if p.held is None else ~p.held
            cm = -np.ones(p.size, np.int64)
            cm[free] = start + np.arange(int(free.sum()))
            start += int(free.sum())
            self.colmap[p.name] = cm
        self.n = start
        self.x0 = np.concatenate(
            [p.value[self.colmap[p.name] >= 0] for p in parameters] or [np.zeros(0)]
        )
        self.lower = np.full(self.n, -np.inf)
        self.upper = np.full(self.n, np.inf)
        for p in parameters:
            cm = self.colmap[p.name]
            if p.lower is not None and p.upper is not None:
                self.lower[cm[cm >= 0]] = p.lower[cm >= 0]
                self.upper[cm[cm >= 0]] = p.upper[cm >= 0]
        self.bounded = bool(np.isfinite(self.lower).any() or np.isfinite(self.upper).any())
        """Whether any unknown has a finite bound (the solver then projects its steps)."""

    # ------------------------------------------------------------------- layout
    def values(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Full parameter arrays (block name -> flat array) for unknowns ``x``."""
        out = {}
        for name, p in self.parameters.items():
            cm = self.colmap[name]
            v = p.value.copy()
            free = cm >= 0
            v[free] = x[cm[free]]
            out[name] = v
        return out

    def columns(self, block: str) -> np.ndarray:
        """Indices into ``x`` of the free coordinates of parameter block ``block``."""
        cm = self.colmap[block]
        return cm[cm >= 0]

    def instance_of_columns(self, block: str) -> np.ndarray:
        """(n,) instance index of every unknown that belongs to ``block``'s instances, else -1.
        Raises ``ValueError`` if ``block`` declares no instances."""
        p = self.parameters[block]
        if p.instance is None:
            raise UsageError(f"parameter block {block!r} declares no instances to eliminate")
        out = -np.ones(self.n, np.int64)
        cm = self.colmap[block]
        free = cm >= 0
        out[cm[free]] = p.instance[free]
        return out

    def global_cols(self, piece: JacobianPiece) -> np.ndarray:
        """(k, c) indices into ``x`` of a piece's columns (``-1``: ignored or held)."""
        return self._global_cols(piece, slice(None))

    def _global_cols(self, piece: JacobianPiece, rows: slice) -> np.ndarray:
        """:meth:`global_cols` of the residual rows ``rows`` only."""
        cm = self.colmap[piece.block]
        cols = np.broadcast_to(np.asarray(piece.cols, dtype=np.int64), piece.J.shape[::2])[rows]
        return np.where(cols >= 0, cm[np.maximum(cols, 0)], -1)

    # --------------------------------------------------------------- evaluation
    def evaluate(self, x: np.ndarray, jacobian: bool = False) -> list[Evaluation]:
        """Every residual block at ``x`` (no finiteness check; see :meth:`check_finite`)."""
        vals = self.values(np.asarray(x, dtype=float))
        return [r.evaluate(vals, jacobian) for r in self.residuals]

    def nonfinite_block(self, evals: Sequence[Evaluation]) -> str | None:
        """Name of the first residual block with a NaN/inf residual, or None."""
        for blk, ev in zip(self.residuals, evals):
            if not np.isfinite(ev.residuals).all():
                return blk.name
        return None

    def check_finite(self, evals: Sequence[Evaluation], where: str) -> None:
        """Raise :class:`SolverError` naming the residual block (and the parameter block of a
        Jacobian piece) that holds a NaN/inf; ``where`` says at which point (e.g. "start")."""
        for blk, ev in zip(self.residuals, evals):
            r = np.asarray(ev.residuals)
            if not np.isfinite(r).all():
                rows = np.flatnonzero(~np.isfinite(r.reshape(len(r), -1)).all(axis=1))
                raise SolverError(
                    f"residual block {blk.name!r} has NaN/inf residuals at {where} "
                    f"({rows.size} of {len(r)} rows, first row {rows[0]})",
                    fix="check the data and the initial values of the parameters it uses",
                )
            for pc in ev.pieces:
                if np.isfinite(pc.J).all():  # the usual case: no mask of ignored columns needed
                    continue
                ok = np.isfinite(pc.J) | (np.asarray(pc.cols) < 0)[..., None, :]
                if not ok.all():
                    rows = np.flatnonzero(~ok.all(axis=(1, 2)))
                    raise SolverError(
                        f"residual block {blk.name!r}: NaN/inf in its Jacobian w.r.t. parameter "
                        f"block {pc.block!r} at {where} ({rows.size} rows, first row {rows[0]})",
                        fix="check the parameter values (e.g. a point at zero depth)",
                    )

    def row_counts(self) -> list[int]:
        """Residual rows (k) of each block at ``x0``."""
        return [len(ev.residuals) for ev in self.evaluate(self.x0)]

    def residual_vector(self, x: np.ndarray) -> np.ndarray:
        """All residuals raveled, blocks in order (for ``scipy.optimize.least_squares``)."""
        return np.concatenate([ev.residuals.ravel() for ev in self.evaluate(x)])

    def jacobian(self, x: np.ndarray) -> sp.csr_matrix:
        """Unweighted sparse Jacobian of :meth:`residual_vector` (rows, n)."""
        return self.sparse_jacobian(self.evaluate(x, jacobian=True), pattern=False)

    def sparsity(self) -> sp.csr_matrix:
        """Jacobian sparsity pattern (ones) at ``x0``."""
        return self.sparse_jacobian(self.evaluate(self.x0, jacobian=True), pattern=True)

    def sparse_jacobian(self, evals: Sequence[Evaluation], pattern: bool = False) -> sp.csr_matrix:
        """Unweighted sparse Jacobian (rows, n) from evaluations with pieces (ones if
        ``pattern``). Built in chunks of at most :data:`JACOBIAN_CHUNK` residual rows of a block
        (each chunk's triplets to CSR, the chunks stacked): the same matrix as from all
        triplets at once, without the triplets of every row in memory."""
        parts: list[sp.csr_matrix] = []
        for ev in evals:
            k, d = ev.residuals.shape
            for a in range(0, k, JACOBIAN_CHUNK):
                sl = slice(a, min(a + JACOBIAN_CHUNK, k))
                parts.append(self._jacobian_rows(ev, sl, d, pattern))
        if not parts:
            return sp.csr_matrix((0, self.n))
        return parts[0] if len(parts) == 1 else sp.vstack(parts, format="csr")

    def _jacobian_rows(self, ev: Evaluation, sl: slice, d: int, pattern: bool) -> sp.csr_matrix:
        """The CSR rows of residual rows ``sl`` of one evaluation (``d`` coordinates each)."""
        k = sl.stop - sl.start
        rows, cols, data = [], [], []
        for pc in ev.pieces:
            J = pc.J[sl]
            g = self._global_cols(pc, sl)
            rr = d * np.arange(k)[:, None, None] + np.arange(d)[None, :, None]
            rr = np.broadcast_to(rr, J.shape)
            cc = np.broadcast_to(g[:, None, :], J.shape)
            m = cc >= 0
            rows.append(rr[m])
            cols.append(cc[m])
            data.append(np.ones(int(m.sum())) if pattern else J[m])
        cat = (lambda a: np.concatenate(a)) if rows else (lambda a: np.zeros(0))
        return sp.csr_matrix((cat(data), (cat(rows), cat(cols))), shape=(k * d, self.n))
