"""Measurement terms on the board route: the context a term joins and its blocks on the chain.

The board refinement (:func:`selfcal.calibration.board.refine.refine_on_board`) estimates the
chain in a :class:`selfcal.estimation.kinematic_poses.KinematicPoses` block (``poses``): the
absolute values of the flat MCPC parameters ``free_idx``, then changes of the zero offsets of
``offset_joints``, then the rig's extrinsics and the joint corrections of the images' frames. A
term (:mod:`selfcal.terms`) knows flat MCPC parameters only, so it is given the whole chain as
one *virtual* block, :data:`CHAIN_BLOCK` (every flat parameter, ``model.params.reshape(-1)``
order), which :func:`chain_values` computes from ``poses`` at every evaluation, and its blocks
are wrapped (:class:`ChainTermBlock`) so that their Jacobian reaches ``poses`` by the chain rule.
A zero offset ``o`` of joint ``j`` (0-based) is a turn of the shape matrix before it about its
z-axis, exactly: ``V_j Rz(o) = Rx(alpha) Ry(beta) Rz(gamma + o) Trans(Rz(-o) l)``; so the
offset moves ``gamma_j`` by ``o`` and turns ``(lx_j, ly_j)`` by ``-o``.

The term's context (:class:`selfcal.terms.base.TermContext`) on the board route:

- ``model``: the fit's start chain; world and tool are the board route's: eye-in-hand the world
  is the board frame (its declared points, m) and the tool the first camera (OpenCV frame);
  eye-to-hand the world is the first camera (OpenCV frame) and the tool the board frame;
- ``free_idx``: every flat MCPC parameter, in block :data:`CHAIN_BLOCK` (the fit's own held
  parameters do not move in it: :func:`chain_values` holds them);
- ``unit_sigma``: the camera stage's pixel noise (px per coordinate), the unit of the images'
  residuals and of the joint prior, at least :data:`MIN_UNIT_SIGMA_PX` (noise-free images fit to
  1e-13 px, which would weigh a term's rows to nothing: the solver then stops before the term's
  own unknowns move).

The terms' rows enter every fit of the route: the fair nominal (the kinematics held, the terms'
own unknowns fitted), every candidate of the parameter selection and each of its
cross-validation folds (the folds leave out images, never a term's rows: the held-out error is
the images'), and the calibration; the selection's pool of parameters takes their rows too
(:func:`identification_rows`). SI units.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.solver import Evaluation, JacobianPiece, ResidualBlock
from selfcal.terms.base import (
    Term,
    TermBlocks,
    TermContext,
    TermReport,
    TermSolution,
    term_blocks,
)

__all__ = [
    "CHAIN_BLOCK",
    "MIN_UNIT_SIGMA_PX",
    "BuiltTerms",
    "ChainTermBlock",
    "build_terms",
    "chain_values",
]

CHAIN_BLOCK = "board_chain"
"""The virtual block of every flat MCPC parameter a term on the board route is built on (it is
no parameter block of the problem: :class:`ChainTermBlock` fills it from ``poses``)."""

MIN_UNIT_SIGMA_PX = 0.01
"""Floor of the terms' unit (px), as the field's ``min_pixel_sigma_px``: board detectors give
0.02-0.3 px."""

POSES = "poses"
"""The board adjustment's block of the chain (:class:`KinematicPoses`' parameters)."""


def chain_values(poses: KinematicPoses, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The flat MCPC parameters (6 (n + 1),) of the chain ``poses`` gives at its parameters
    ``p`` (zero offsets folded into the shape matrices, module docstring; the joint offsets
    those of ``poses.model``) and their derivative (6 (n + 1), n_kin) by ``p[:n_kin]``."""
    model = poses.model
    k, n_kin = poses.k, poses.n_kin
    flat = model.params.reshape(-1).copy()
    flat[poses.free_idx] = p[:k]
    D = np.zeros((flat.size, n_kin))
    D[poses.free_idx, np.arange(k)] = 1.0
    for i, j in enumerate(poses.offset_joints.tolist()):
        o = float(p[k + i])
        c, s = np.cos(o), np.sin(o)
        turn = np.array([[c, s], [-s, c]])  # Rz(-o) on (lx, ly)
        rows = [6 * j + 3, 6 * j + 4]
        lx, ly = turn @ flat[rows]
        D[rows] = turn @ D[rows]
        flat[6 * j + 2] += o
        flat[rows] = lx, ly
        D[6 * j + 2, k + i] = 1.0
        D[rows, k + i] = ly, -lx  # d(Rz(-o) l)/do = (ly', -lx')
    return flat, D


class ChainTermBlock:
    """A term's residual block over :data:`CHAIN_BLOCK` evaluated on the ``poses`` block: the
    same rows (name, dimension, loss), its chain piece turned into a piece of ``poses``."""

    def __init__(self, inner: ResidualBlock, poses: KinematicPoses) -> None:
        self.inner, self.poses = inner, poses
        self.name, self.dim, self.loss = inner.name, inner.dim, inner.loss

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals of the wrapped block; its chain Jacobian by the chain rule."""
        flat, D = chain_values(self.poses, values[POSES])
        ev = self.inner.evaluate({**values, CHAIN_BLOCK: flat}, jacobian)
        if not jacobian:
            return Evaluation(ev.residuals)
        pieces = []
        for pc in ev.pieces:
            if pc.block != CHAIN_BLOCK:
                pieces.append(pc)
                continue
            k, d, c = pc.J.shape
            dense = np.zeros((k, flat.size, d))
            ok = pc.cols >= 0
            rows = np.broadcast_to(np.arange(k)[:, None], pc.cols.shape)
            np.add.at(dense, (rows[ok], pc.cols[ok]), np.moveaxis(pc.J, 2, 1)[ok])
            if D.shape[1]:
                J = np.einsum("kfd,fc->kdc", dense, D)
                cols = np.broadcast_to(np.arange(D.shape[1]), (k, D.shape[1]))
                pieces.append(JacobianPiece(POSES, J, cols))
        return Evaluation(ev.residuals, tuple(pieces))


@dataclass(frozen=True)
class BuiltTerms:
    """The terms of one board fit: each term's blocks (``built``), the context they were built
    in, and the wrapped residual blocks and new parameter blocks for the problem."""

    terms: tuple[Term, ...]
    built: tuple[TermBlocks, ...]
    context: TermContext
    residuals: tuple[ResidualBlock, ...]
    parameters: tuple

    def reports(self, values: Mapping[str, np.ndarray], residuals: Mapping[str, np.ndarray],
                poses: KinematicPoses, model: MCPCModel) -> list[TermReport]:  # fmt: skip
        """Every term's report at the solution (``values``, ``residuals`` the solver's; ``model``
        the solved chain, world and tool the route's)."""
        flat, _ = chain_values(poses, values[POSES])
        solved = TermSolution({**values, CHAIN_BLOCK: flat}, residuals, model, model,
                              self.context)  # fmt: skip
        return [t.report(b, solved) for t, b in zip(self.terms, self.built, strict=True)]


def build_terms(terms: Sequence[Term], poses: KinematicPoses, unit_sigma: float) -> BuiltTerms:
    """The blocks of ``terms`` over the chain of ``poses`` (module docstring), residuals in the
    unit ``unit_sigma`` (px; at least :data:`MIN_UNIT_SIGMA_PX`).

    Raises:
        InputError: a term's data that do not fit the chain (the term's own check).
    """
    n_flat = poses.model.params.size
    unit = max(float(unit_sigma), MIN_UNIT_SIGMA_PX)
    ctx = TermContext(poses.model, np.arange(n_flat), CHAIN_BLOCK, unit)
    built = tuple(t.build(ctx) for t in terms)
    res, params = term_blocks(built)
    wrapped = tuple(ChainTermBlock(r, poses) for r in res)
    return BuiltTerms(tuple(terms), built, ctx, wrapped, tuple(params))


def identification_rows(terms: Sequence[Term], model: MCPCModel, free_idx: np.ndarray,
                        offset_joints: np.ndarray) -> np.ndarray:  # fmt: skip
    """The terms' rows of an identification Jacobian at ``model``: their residuals' derivative
    (each error over its own standard deviation) by the flat MCPC parameters ``free_idx`` and
    then the zero offsets of ``offset_joints``, with the part the terms' own unknowns (a fixture
    frame, a tip ...) can absorb projected out -- what the terms tell of the chain. (r, k) with
    ``k = len(free_idx) + len(offset_joints)``; (0, k) without terms.

    Raises:
        InputError: a term's data that do not fit the chain (the term's own check).
    """
    free_idx = np.asarray(free_idx, dtype=np.int64)
    offset_joints = np.asarray(offset_joints, dtype=np.int64)
    k = len(free_idx) + len(offset_joints)
    if not terms:
        return np.zeros((0, k))
    poses = KinematicPoses(model, np.zeros((1, model.n)), free_idx, np.zeros((0, 4, 4)),
                           offset_joints=offset_joints)  # fmt: skip
    built = build_terms(terms, poses, 1.0)  # rows in standard deviations
    sizes = {POSES: poses.n_params, **{b.name: b.value.size for b in built.parameters}}
    start = np.cumsum([0, *sizes.values()])
    at = dict(zip(sizes, start[:-1].tolist(), strict=True))
    values = {POSES: poses.initial_params(), **{b.name: b.value for b in built.parameters}}
    rows = []
    for block in built.residuals:
        ev = block.evaluate(values, True)
        n_rows, d = ev.residuals.shape
        J = np.zeros((n_rows, d, int(start[-1])))
        for pc in ev.pieces:
            ok = pc.cols >= 0
            r = np.broadcast_to(np.arange(n_rows)[:, None], pc.cols.shape)
            np.add.at(np.moveaxis(J, 2, 1), (r[ok], at[pc.block] + pc.cols[ok]),
                      np.moveaxis(pc.J, 2, 1)[ok])  # fmt: skip
        rows.append(J.reshape(n_rows * d, -1))
    A = np.concatenate(rows)
    chain, own = A[:, :k], A[:, poses.n_params :]
    if own.shape[1]:  # the complement of what the terms' own unknowns absorb
        Q, s, _ = np.linalg.svd(own, full_matrices=False)
        Q = Q[:, s > 1e-12 * max(float(s.max(initial=0.0)), 1e-300)]
        chain = chain - Q @ (Q.T @ chain)
    return chain
