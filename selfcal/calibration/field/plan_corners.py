"""A field plan's tool-point criterion with the markers' corners unknown, as the field route
estimates them (``selfcal plan --target FIELD.toml``, issue #30; docs/plan.md "What limits a
field plan of 12"): the field route's Cramer-Rao bound of the tool point, the plan's forecast
(:func:`selfcal.calibration.field.plan.field_forecast`), computed for candidate sets fast enough
to exchange postures on it.

:mod:`selfcal.calibration.field.plan_information` takes the corners as known, and a plan chosen
so sees each marker in few views, which leaves the corners' positions to absorb the arm's error.
With the corners unknown the information is not a sum over the postures' parameter blocks: each
posture's read-back errors meet every corner it sees, so eliminating them couples those corners
(dropping that coupling, session 25's criterion, rated the UR5e's plan of 12 ahead of the random
30 where the forecast rates it behind). Here the unknowns ``z`` are the camera's free
parameters, the free kinematic parameters, the rig and every marker corner; posture ``i``'s
read-back errors are eliminated from its own rows exactly (the Schur complement over its rows
and their prior: ``M_i = I - Q_i (Q_i^T Q_i + P)^-1 Q_i^T``), which leaves its information over
``z`` as ``V_i V_i^T`` (``V_i = R_i^T chol(M_i)``, nonzero on the columns it sees), and a set
``S`` of postures has the information ``Lambda(S) = prior + sum_i V_i V_i^T`` (the prior: the
known distance's row). The criterion is ``sqrt(trace(G C))``, ``C`` the free kinematic block of
``Lambda(S)^-1`` (the board plan's, :mod:`selfcal.calibration.board.plan.greedy`): the forecast
itself. A candidate added to a set updates the inverse by its rank (the Woodbury identity), so
one inverse per set ranks every candidate (or, where it would leave less than :data:`CANCEL`
of the set's criterion, a difference of large numbers, that candidate's own inverse).
A corner no posture of the set sees twice is held by a regulariser of :data:`EPS` of its
scale (the forecast drops it), which passes on none of its information. SI units, px.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from selfcal.calibration.field.plan_information import PostureRows
from selfcal.errors import UsageError

__all__ = ["CornerBlocks", "corner_blocks", "corner_criterion", "corner_exchange", "corner_grow"]

EPS = 1e-9
"""Every unknown's information is regularised by this share of its scale (the mean information
of one candidate): a corner seen in one view only (singular) then passes on none of its
information, as the bound drops it."""
CANCEL = 0.5
"""A candidate whose addition would leave less than this share of the held set's squared
criterion is costed directly, not by the update (module docstring)."""
PASSES = 50
"""The exchange's rounds of the chosen postures at most (each swap lowers the criterion, so it
ends anyway)."""


@dataclass(frozen=True)
class CornerBlocks:
    """Every candidate's piece of the criterion (module docstring), in scaled unknowns ``z s``:
    ``cols[i]`` the unknowns candidate ``i``'s rows touch (indices into ``z``), ``R[i]``
    (r, len(cols[i])) its whitened rows over them (csr; no rows: it adds nothing, its view not
    registered), ``E[i]`` (r, r) ``I + Q_i P^-1 Q_i^T`` (the identity with exact joints), so that
    its information is ``R_i^T E_i^-1 R_i``; ``prior`` (z, z) the information without postures (the known distance's, and the
    regulariser); ``kin`` the indices into ``z`` of the free kinematic parameters (the tool
    weight's order); ``scale`` (z,) ``s``: the root of each unknown's mean information per
    candidate (the joints exact)."""

    R: tuple[sparse.csr_matrix, ...]
    E: tuple[np.ndarray, ...]
    cols: tuple[np.ndarray, ...]
    prior: np.ndarray
    kin: np.ndarray
    scale: np.ndarray


def corner_blocks(pr: PostureRows) -> CornerBlocks:
    """The pieces of the criterion for the candidate postures of ``pr``
    (:func:`selfcal.calibration.field.plan_information.posture_rows` of the field route's setup
    at the nominal chain: the markers the cameras see, the corner noise and the read-back
    noise). A candidate whose camera sees fewer than
    :data:`selfcal.estimation.epipolar.MIN_SHARED` corners adds nothing (the route does not
    register it)."""
    J, m = pr.J, len(pr.registered)
    n = pr.fs.model.n
    dq_all = pr.lay.n_camera + np.asarray(pr.lay.pose_model.dq_cols, dtype=np.int64)
    z = np.setdiff1d(np.arange(J.shape[1]), dq_all)  # every unknown but the read-back errors
    Rz = pr.R[:, z].tocsr()
    sq = Rz.multiply(Rz)
    scale = np.sqrt(np.asarray(sq[: int(pr.ends[-1])].sum(axis=0)).ravel() / m)
    scale = np.where(scale > 0, scale, 1.0)
    Rz = (Rz @ sparse.diags(1.0 / scale)).tocsr()
    shared = np.arange(len(pr.lay.kin_cols))  # the camera and kinematics: always touched
    R: list[sparse.csr_matrix] = []
    E: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    cov = None if pr.prior is None else np.linalg.inv(pr.prior)
    for i in range(m):
        at = pr.rows(i) if pr.registered[i] else slice(0, 0)
        Ri = Rz[at]
        c = np.union1d(shared, Ri.indices) if Ri.shape[0] else np.zeros(0, np.int64)
        R.append(Ri[:, c].tocsr())
        cols.append(c)
        if cov is None:
            E.append(np.eye(Ri.shape[0]))
            continue
        Q = pr.R[at][:, dq_all[n * i : n * (i + 1)]].toarray()
        E.append(np.eye(len(Q)) + Q @ cov @ Q.T)
    extra = J[pr.R.shape[0] :][:, z].toarray() / scale  # the known distance's row (no joints)
    prior = extra.T @ extra + EPS * np.eye(len(z))
    kin = np.arange(pr.lay.n_camera, len(pr.lay.kin_cols))
    return CornerBlocks(tuple(R), tuple(E), tuple(cols), prior, kin, scale)


def _inverse(cb: CornerBlocks, held: np.ndarray) -> np.ndarray:
    """``Lambda(held)^-1`` in the scaled unknowns (module docstring)."""
    L = cb.prior.copy()
    for i in map(int, held):
        c = cb.cols[i]
        A = cb.R[i].toarray()
        L[np.ix_(c, c)] += A.T @ np.linalg.solve(cb.E[i], A)
    return np.linalg.inv(L)


def _weight(cb: CornerBlocks, G: np.ndarray) -> np.ndarray:
    """(k, g) a factor ``F F^T`` of the tool weight ``G`` in the scaled kinematic unknowns."""
    s = cb.scale[cb.kin]
    if G.shape != (len(s), len(s)):
        raise UsageError(f"the tool weight is {G.shape}, not ({len(s)}, {len(s)}): "
                         "the free kinematic parameters of the same chain")  # fmt: skip
    w, U = np.linalg.eigh(G / np.outer(s, s))
    keep = w > 0
    return U[:, keep] * np.sqrt(w[keep])


def _costs(cb: CornerBlocks, Fw: np.ndarray, held: np.ndarray, add: bool) -> np.ndarray:
    """``trace(G C)`` (squared criterion, m^2) of the postures ``held`` plus, with ``add``, each
    candidate in turn ((m,); a candidate that adds nothing: the held set's), else of ``held``
    alone ((1,)). A candidate ``j`` adds its rows ``R_j`` with its read-back errors (prior
    ``P``) as unknowns of their own: with ``S = Lambda(held)^-1``,
    ``K = E_j + R_j S R_j^T`` and ``Z = R_j S_kin F`` (``G = F F^T``) it lowers ``trace(G C)``
    by ``trace(Z^T K^-1 Z)`` (the Woodbury identity)."""
    S = _inverse(cb, held)
    SF = S[:, cb.kin] @ Fw  # (z, g)
    base = float(np.sum(Fw * (S[np.ix_(cb.kin, cb.kin)] @ Fw)))
    if not add:
        return np.array([base])
    out = np.full(len(cb.R), base)
    for j, (Rj, Ej, c) in enumerate(zip(cb.R, cb.E, cb.cols, strict=True)):
        if not Rj.shape[0]:
            continue
        T = Rj @ S[np.ix_(c, c)]  # (r, c)
        K = Ej + np.asarray(Rj @ T.T)
        Z = np.asarray(Rj @ SF[c])  # (r, g)
        out[j] = base - float(np.sum(Z * np.linalg.solve(K, Z)))
    # a drop of more than half is a difference of large numbers (a held set that leaves some
    # unknown to the regulariser): those candidates' costs directly
    for low in map(int, np.flatnonzero(out < CANCEL * base)):
        out[low] = _costs(cb, Fw, np.append(held, low), add=False)[0]
    return out


def corner_criterion(cb: CornerBlocks, G: np.ndarray, chosen: np.ndarray) -> float:
    """The criterion (m, module docstring) of the candidates ``chosen`` (indices), ``G`` the
    aligned tool weight of the free kinematic parameters
    (:func:`selfcal.calibration.field.plan_information.tool_weight`)."""
    got = _costs(cb, _weight(cb, G), np.asarray(chosen, dtype=np.int64), add=False)[0]
    return float(np.sqrt(max(got, 0.0)))


def corner_exchange(cb: CornerBlocks, G: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """``chosen`` (count,) indices improved by swaps on :func:`corner_criterion` (Fedorov's
    exchange): each chosen candidate in turn, cyclically, is swapped for the candidate that
    lowers the criterion most when that lowers it by more than a millionth, until every place
    has been tried once since the last swap (at most :data:`PASSES` times round); each swap
    keeps its place."""
    chosen = np.asarray(chosen, dtype=np.int64).copy()
    Fw = _weight(cb, G)
    cost = _costs(cb, Fw, chosen, add=False)[0]
    since = 0
    for step in range(PASSES * len(chosen)):
        if since == len(chosen):
            break
        k = step % len(chosen)
        c = _costs(cb, Fw, np.delete(chosen, k), add=True)
        c[chosen] = np.inf
        j = int(np.argmin(c))
        since += 1
        if c[j] < cost * (1.0 - 1e-6):
            cost, chosen[k], since = float(c[j]), j, 0
    return chosen


def corner_grow(cb: CornerBlocks, G: np.ndarray, chosen: np.ndarray, total: int) -> np.ndarray:
    """(total,) indices: ``chosen`` (count,) first, then one candidate at a time the one whose
    addition lowers :func:`corner_criterion` most (the greedy choice on it, started from
    ``chosen``); nested plans of every size from ``count`` to ``total``. ``total`` at most the
    candidates (:class:`selfcal.errors.UsageError` else)."""
    held = np.asarray(chosen, dtype=np.int64)
    if not len(held) <= total <= len(cb.R):
        raise UsageError(
            f"corner_grow: total {total}, not from {len(held)} (the postures given) to "
            f"{len(cb.R)} (the candidates)"
        )
    Fw = _weight(cb, G)
    while len(held) < total:
        c = _costs(cb, Fw, held, add=True)
        c[held] = np.inf
        held = np.append(held, int(np.argmin(c)))
    return held
