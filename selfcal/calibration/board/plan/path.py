"""The order a plan's postures are recorded in: a short joint-space path from home (nearest
neighbour, then 2-opt; a step's cost is its largest joint move, which sets the travel time when
the joints move together). ``selfcal plan``, issue #30. Units: rad (m for a prismatic joint).
"""

from __future__ import annotations

import numpy as np

__all__ = ["order_path", "path_length"]


def _step(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.max(np.abs(a - b), axis=-1)


def path_length(q: np.ndarray, start: np.ndarray) -> float:
    """The joint path from ``start`` through ``q`` (m, n) in order: the sum of every step's
    largest joint move (rad)."""
    pts = np.concatenate([np.asarray(start, dtype=float)[None], np.asarray(q, dtype=float)])
    return float(_step(pts[1:], pts[:-1]).sum())


def order_path(q: np.ndarray, start: np.ndarray) -> np.ndarray:
    """An order (m,) of postures ``q`` (m, n) for a short path from ``start`` (n,): nearest
    neighbour, then 2-opt (reversing a stretch while that shortens the open path)."""
    q = np.asarray(q, dtype=float)
    m = len(q)
    pts = np.concatenate([np.asarray(start, dtype=float)[None], q])
    D = _step(pts[:, None], pts[None])
    tour, left = [0], set(range(1, m + 1))
    while left:
        nxt = min(left, key=lambda j: D[tour[-1], j])
        tour.append(nxt)
        left.remove(nxt)
    improved = True
    while improved:
        improved = False
        for i in range(1, m):
            for j in range(i + 1, m + 1):
                a, b = tour[i - 1], tour[i]
                c = tour[j]
                e = tour[j + 1] if j < m else None
                old = D[a, b] + (D[c, e] if e is not None else 0.0)
                new = D[a, c] + (D[b, e] if e is not None else 0.0)
                if new < old - 1e-12:
                    tour[i : j + 1] = tour[i : j + 1][::-1]
                    improved = True
    return np.asarray(tour[1:]) - 1
