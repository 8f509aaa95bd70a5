"""A field plan's tool-point criterion with the markers' corners unknown, as the field route
estimates them (``selfcal plan --target FIELD.toml``, issue #30; docs/plan.md "What limits a
field plan of 12").

:mod:`selfcal.calibration.field.plan_information` takes the corners as known, and a plan chosen
so sees each marker in few views (the docs example's plan of 12: 6.5 on the mean, the random 30
11.0), which leaves the corners' positions to absorb the arm's error. With the corners unknown
the information is not a sum over the postures, but each marker's 12 corner coordinates (the two
scale markers' 24 together: the known distance joins them) meet the other unknowns only through
the postures that see it, so their Schur complement is one small block per marker: for a set
``S`` of postures, ``H(S) = sum_i F_i - sum_k B_k D_k^-1 B_k^T`` with ``B_k = sum_i B_ik``
(parameters x the marker's corners) and ``D_k = sum_i D_ik`` (its corners), and the criterion is
``sqrt(trace(G C))``, ``C`` the kinematic block of ``H(S)^-1`` (the board plan's criterion,
:mod:`selfcal.calibration.board.plan.greedy`). With exact joints this is the field route's
Cramer-Rao bound of the tool point (the forecast,
:func:`selfcal.calibration.field.plan.field_forecast`); with the joints' read-back errors each
posture's are eliminated within its own rows of a marker, the coupling they make between two
markers' corners dropped, so it approximates the forecast, and the plan is judged by the
forecast. SI units, px.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.field.plan_information import PostureRows
from selfcal.errors import UsageError
from selfcal.target import CORNERS_PER_MARKER

__all__ = ["CornerBlocks", "corner_blocks", "corner_criterion", "corner_exchange", "corner_grow"]

EPS = 1e-9
"""A marker's corner block is regularised by this share of its trace: a marker seen in one view
only (singular block) then passes on none of its information, as the bound drops it."""
PASSES = 200
"""The exchange's swaps at most (each lowers the criterion, so it ends anyway)."""


@dataclass(frozen=True)
class CornerBlocks:
    """Every candidate's pieces of the criterion (module docstring): ``F`` (m, p, p) its
    information about ``[camera's free parameters, free kinematic parameters]`` with its
    read-back errors eliminated, ``B`` and ``D`` one (m, p, c) and (m, c, c) array per marker
    group (c its corner coordinates, 12 or 24), ``prior`` (c, c) each group's information
    without postures (the known distance's, zeros elsewhere), ``scale`` (p,) the parameters'
    scaling (the root of their mean information per candidate)."""

    F: np.ndarray
    B: tuple[np.ndarray, ...]
    D: tuple[np.ndarray, ...]
    prior: tuple[np.ndarray, ...]
    scale: np.ndarray


def corner_blocks(pr: PostureRows) -> CornerBlocks:
    """The pieces of the criterion for the candidate postures of ``pr``
    (:func:`selfcal.calibration.field.plan_information.posture_rows` of the field route's setup
    at the nominal chain: the markers the one camera sees, the corner noise and the read-back
    noise). A candidate whose camera sees fewer than
    :data:`selfcal.estimation.epipolar.MIN_SHARED` corners adds nothing (the route does not
    register it)."""
    fs, J, m = pr.fs, pr.J, len(pr.registered)
    n_points = len(fs.X_world)
    x0 = J.shape[1] - 3 * n_points  # the points' columns come last
    group = np.arange(n_points) // CORNERS_PER_MARKER
    sa, sb = (np.asarray(s) for s in fs.scale_points)
    group[sb] = group[sa[0]]  # the known distance joins the scale markers
    names, group = np.unique(group, return_inverse=True)
    cols = [(x0 + 3 * np.flatnonzero(group == g)[:, None] + np.arange(3)).ravel()
            for g in range(len(names))]  # fmt: skip
    th = pr.lay.kin_cols
    p = len(th)
    F = np.zeros((m, p, p))
    B = [np.zeros((m, p, len(c))) for c in cols]
    D = [np.zeros((m, len(c), len(c))) for c in cols]
    for i in map(int, np.flatnonzero(pr.registered)):  # unregistered: nothing
        at = pr.rows(i)
        Ri = pr.R[at]
        A = Ri[:, th].toarray()
        dq = None  # the posture's read-back errors' columns and their elimination
        if pr.prior is not None:
            Bq = Ri[:, pr.dq_cols(i)].toarray()
            dq = (Bq, np.linalg.solve(Bq.T @ Bq + pr.prior, Bq.T))
        MA = _eliminated(A, dq)
        F[i] = A.T @ MA
        for g in np.unique(group[pr.point[at]]):
            X = Ri[:, cols[g]].toarray()
            B[g][i] = MA.T @ X
            D[g][i] = X.T @ _eliminated(X, dq)
    extra = J[
        pr.R.shape[0] :
    ].tocsc()  # the known distance's row (and the joints' prior: no corners)
    pri = []
    for c in cols:
        S = extra[:, c].toarray()
        pri.append(S.T @ S)
    scale = np.sqrt(np.maximum(np.einsum("mii->i", F) / m, 1e-300))
    return CornerBlocks(F, tuple(B), tuple(D), tuple(pri), scale)


def _eliminated(X: np.ndarray, dq: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """``M X`` with ``M = I - Bq (Bq^T Bq + prior)^-1 Bq^T`` (``dq = (Bq, that inverse times
    Bq^T)``): the posture's read-back errors eliminated from the rows ``X``; ``X`` when exact."""
    return X if dq is None else X - dq[0] @ (dq[1] @ X)


def _costs(cb: CornerBlocks, W: np.ndarray, held: np.ndarray, add: bool) -> np.ndarray:
    """``trace(W C)`` (squared criterion, m^2) of the postures ``held`` plus, with ``add``, each
    candidate in turn ((m,)), else of ``held`` alone ((1,))."""
    H = cb.F[held].sum(axis=0)[None] + (cb.F if add else 0.0)
    for Bg, Dg, Pg in zip(cb.B, cb.D, cb.prior, strict=True):
        b = Bg[held].sum(axis=0)[None]
        d = Dg[held].sum(axis=0)[None]  # the views' (not the prior's)
        if not add:
            H = H - _corner_term(b, d, Pg)
            continue
        # a candidate that does not see the group adds zeros to b and d: its term is the held
        # set's, computed once (the same numbers as adding its zeros, at a share of the solves)
        sees = np.flatnonzero(Bg.any(axis=(1, 2)) | Dg.any(axis=(1, 2)))
        term = np.repeat(_corner_term(b, d, Pg), len(Bg), axis=0)
        term[sees] = _corner_term(b + Bg[sees], d + Dg[sees], Pg)
        H = H - term
    s = cb.scale
    C = np.linalg.inv(H / np.outer(s, s) + EPS * np.eye(len(s)))
    return np.einsum("ij,mji->m", W / np.outer(s, s), C)


def _corner_term(b: np.ndarray, d: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """(m, p, p) ``b (d + prior)^-1 b^T`` of a marker group's (m, p, c) ``b`` and (m, c, c) views'
    ``d``, each ``d`` regularised by :data:`EPS` of its trace (unseen: ``b = 0``)."""
    eps = EPS * np.maximum(np.einsum("mii->m", d), 1.0)[:, None, None]
    d = d + prior + eps * np.eye(d.shape[-1])
    return b @ np.linalg.solve(d, np.swapaxes(b, 1, 2))


def _weight(cb: CornerBlocks, G: np.ndarray) -> np.ndarray:
    p = cb.F.shape[1]
    W = np.zeros((p, p))
    W[p - len(G) :, p - len(G) :] = G
    return W


def corner_criterion(cb: CornerBlocks, G: np.ndarray, chosen: np.ndarray) -> float:
    """The criterion (m, module docstring) of the candidates ``chosen`` (indices), ``G`` the
    aligned tool weight of the free kinematic parameters
    (:func:`selfcal.calibration.field.plan_information.tool_weight`)."""
    got = _costs(cb, _weight(cb, G), np.asarray(chosen, dtype=np.int64), add=False)[0]
    return float(np.sqrt(max(got, 0.0)))


def corner_exchange(cb: CornerBlocks, G: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """``chosen`` (count,) indices improved by swaps on :func:`corner_criterion`: while a chosen
    candidate swapped for another lowers it by more than a millionth, the swap that lowers it most
    is made (at most :data:`PASSES`; Fedorov's exchange, steepest descent, as
    :func:`selfcal.calibration.board.plan.greedy.exchange`); each swap keeps its place."""
    chosen = np.asarray(chosen, dtype=np.int64).copy()
    W = _weight(cb, G)
    cost = _costs(cb, W, chosen, add=False)[0]
    for _ in range(PASSES):
        best = (cost, -1, -1)
        for k in range(len(chosen)):
            c = _costs(cb, W, np.delete(chosen, k), add=True)
            c[chosen] = np.inf
            j = int(np.argmin(c))
            if c[j] < best[0]:
                best = (float(c[j]), k, j)
        if best[1] < 0 or best[0] >= cost * (1.0 - 1e-6):
            break
        cost, k, j = best
        chosen[k] = j
    return chosen


def corner_grow(cb: CornerBlocks, G: np.ndarray, chosen: np.ndarray, total: int) -> np.ndarray:
    """(total,) indices: ``chosen`` (count,) first, then one candidate at a time the one whose
    addition lowers :func:`corner_criterion` most (the greedy choice on it, started from
    ``chosen``); nested plans of every size from ``count`` to ``total``, each one greedy step
    (a single pass of :func:`corner_exchange`'s search per added posture). ``total`` at most the
    candidates (:class:`selfcal.errors.UsageError` else)."""
    held = np.asarray(chosen, dtype=np.int64)
    if not len(held) <= total <= len(cb.F):
        raise UsageError(
            f"corner_grow: total {total}, not from {len(held)} (the postures given) to "
            f"{len(cb.F)} (the candidates)"
        )
    W = _weight(cb, G)
    while len(held) < total:
        c = _costs(cb, W, held, add=True)
        c[held] = np.inf
        held = np.append(held, int(np.argmin(c)))
    return held
