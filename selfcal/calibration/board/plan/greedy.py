"""The greedy choice of a plan's postures: one candidate at a time, the one that lowers the
predicted tool-point error most (``selfcal plan``, issue #30; :mod:`selfcal.calibration.board.plan.planner`,
the tracker plan :mod:`selfcal.calibration.tracker.plan` and ``--add``
:mod:`selfcal.calibration.board.plan.add` share it). The error is ``sqrt(trace(G C))``, ``C``
the kinematic block of the inverse information and ``G`` the aligned tool weight. Units: m.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import InputError

__all__ = ["REG", "predicted_error", "select_greedy"]

REG = 1e-6
"""The greedy start's information: this times the identity in parameters scaled to unit mean
information per candidate (it only matters while fewer frames than parameters are chosen)."""


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
    d = np.sqrt(np.maximum(np.einsum("mii->i", F) / m, 1e-300))
    Fs = F / np.outer(d, d)
    W = np.zeros((p, p))
    W[n_cam:, n_cam:] = G
    Ws = W / np.outer(d, d)
    starts = np.zeros((1, p, p)) if start is None else np.asarray(start, dtype=float)
    total = REG * np.eye(p) + starts.reshape(-1, p, p) / np.outer(d, d)
    free = np.ones(m, bool)
    chosen: list[int] = []
    for _ in range(count):
        cost = np.zeros(m)
        for t in total:
            cost += np.einsum("ij,mji->m", Ws, np.linalg.inv(t + Fs))
        cost[~free] = np.inf
        b = int(np.argmin(cost))
        chosen.append(b)
        free[b] = False
        total = total + Fs[b]
    return np.asarray(chosen)
