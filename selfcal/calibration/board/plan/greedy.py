"""The greedy choice of a plan's postures: one candidate at a time, the one that lowers the
predicted tool-point error most (``selfcal plan``, issue #30; :mod:`selfcal.calibration.board.plan.planner`,
the tracker plan :mod:`selfcal.calibration.tracker.plan` and ``--add``
:mod:`selfcal.calibration.board.plan.add` share it), and the exchange that improves a choice
by swapping one chosen posture for one not chosen (:func:`exchange`; a greedy choice is not the
best set of its size: the UR5e example's plan of 12 for 0.04 px, docs/plan.md). The error is
``sqrt(trace(G C))``, ``C`` the kinematic block of the inverse information and ``G`` the
aligned tool weight. Units: m.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import InputError

__all__ = ["EXCHANGE_GAIN", "REG", "exchange", "predicted_error", "select_greedy"]

REG = 1e-6
"""The greedy start's information: this times the identity in parameters scaled to unit mean
information per candidate (it only matters while fewer frames than parameters are chosen)."""
EXCHANGE_GAIN = 1e-6
"""The exchange takes a swap when it lowers the criterion by more than this share."""
EXCHANGE_PASSES = 200
"""... and stops after this many swaps at most (each lowers the criterion, so it ends anyway)."""


def predicted_error(F: np.ndarray, G: np.ndarray, n_cam: int) -> float:
    """The predicted RMS tool-point error (m): ``sqrt(trace(G C))``, ``C`` the kinematic block
    of ``F^-1`` (``F`` (p, p) the information, the first ``n_cam`` parameters the camera's);
    infinite when ``F`` is singular."""
    try:
        C = np.linalg.inv(F)
    except np.linalg.LinAlgError:
        return float("inf")
    if not np.all(np.isfinite(C)) or np.linalg.cond(F) > 1e14:
        return float("inf")
    return float(np.sqrt(max(np.trace(G @ C[n_cam:, n_cam:]), 0.0)))


def select_greedy(
    F: np.ndarray, G: np.ndarray, n_cam: int, count: int, start: np.ndarray | None = None
) -> np.ndarray:
    """Indices (count,) into the candidates' informations ``F`` (m, p, p), chosen one by one to
    lower ``trace(W (F_0 + sum F_i)^-1)`` most, ``W`` = ``G`` (k, k) on the kinematic block
    (module docstring); ``F_0`` the information ``start`` (p, p) already held (the prior of
    the deviation from the drawing, a dataset's frames) plus a slight regularisation. A stack
    ``start`` (s, p, p) of several: the sum of their ``s`` costs is lowered (the added postures
    serve each)."""
    m, p, _ = F.shape
    if count > m:
        raise InputError(f"cannot choose {count} postures from {m} candidates",
                         fix="lower --count or widen the candidate pool (--candidates)")  # fmt: skip
    Fs, Ws, total = _scaled(F, G, n_cam, start)
    free = np.ones(m, bool)
    chosen: list[int] = []
    for _ in range(count):
        cost = _costs(total, Fs, Ws)
        cost[~free] = np.inf
        b = int(np.argmin(cost))
        chosen.append(b)
        free[b] = False
        total = total + Fs[b]
    return np.asarray(chosen)


def exchange(
    F: np.ndarray, G: np.ndarray, n_cam: int, chosen: np.ndarray, start: np.ndarray | None = None
) -> np.ndarray:
    """``chosen`` (count,) indices into the candidates' informations ``F`` (m, p, p) improved by
    swaps: while some chosen candidate and some other one, swapped, lower
    :func:`select_greedy`'s criterion (the same ``G``, ``n_cam`` and ``start``) by more than
    :data:`EXCHANGE_GAIN` of it, the swap that lowers it most is made (at most
    :data:`EXCHANGE_PASSES`); each swap keeps its place in ``chosen``, so the result is
    ``chosen`` when no swap helps. Fedorov's exchange, steepest descent: it ends at a choice
    no single swap improves (a local optimum), never above where it started."""
    chosen = np.asarray(chosen, dtype=np.int64).copy()
    m = len(F)
    if len(chosen) == 0 or len(chosen) == m:
        return chosen
    Fs, Ws, start_total = _scaled(F, G, n_cam, start)
    total = start_total + Fs[chosen].sum(axis=0)
    cost = _costs(total, np.zeros((1,) + Fs.shape[1:]), Ws)[0]
    for _ in range(EXCHANGE_PASSES):
        free = np.ones(m, bool)
        free[chosen] = False
        best = (cost, -1, -1)
        for k, i in enumerate(chosen):
            c = _costs(total - Fs[i], Fs, Ws)
            c[~free] = np.inf
            j = int(np.argmin(c))
            if c[j] < best[0]:
                best = (float(c[j]), k, j)
        if best[1] < 0 or best[0] >= cost * (1.0 - EXCHANGE_GAIN):
            break
        cost, k, j = best
        total = total - Fs[chosen[k]] + Fs[j]
        chosen[k] = j
    return chosen


def pool_sets(size: int, count: int) -> list[tuple[str, np.ndarray]]:
    """The pool's disjoint sets of ``count`` candidates in draw order, each with its name
    (``"random set k of s"``; the first is the random plan of that size): the rivals a plan is
    judged against when its criterion may not be what the calibration reaches (the camera
    planner with few postures, the tracker planner always). Indices into the pool of ``size``."""
    sets = size // count
    return [
        (f"random set {k + 1} of {sets}", np.arange(k * count, (k + 1) * count))
        for k in range(sets)
    ]


def _scaled(
    F: np.ndarray, G: np.ndarray, n_cam: int, start: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The candidates' informations, the weight and the start(s) (s, p, p) with the
    regularisation, in parameters scaled to unit mean information per candidate."""
    m, p, _ = F.shape
    d = np.sqrt(np.maximum(np.einsum("mii->i", F) / m, 1e-300))
    Fs = F / np.outer(d, d)
    W = np.zeros((p, p))
    W[n_cam:, n_cam:] = G
    Ws = W / np.outer(d, d)
    starts = np.zeros((1, p, p)) if start is None else np.asarray(start, dtype=float)
    total = REG * np.eye(p) + starts.reshape(-1, p, p) / np.outer(d, d)
    return Fs, Ws, total


def _costs(total: np.ndarray, Fs: np.ndarray, Ws: np.ndarray) -> np.ndarray:
    """(m,) the criterion with each candidate of ``Fs`` added to the held ``total`` (s, p, p):
    the sum over the starts of ``trace(Ws (total + F)^-1)``."""
    cost = np.zeros(len(Fs))
    for t in total:
        cost += np.einsum("ij,mji->m", Ws, np.linalg.inv(t + Fs))
    return cost
