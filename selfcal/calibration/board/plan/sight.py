"""Lines of sight of a planned view: no part of the arm and no keep-out box stands between the
camera and the board (the candidate pool of :mod:`selfcal.calibration.board.plan.views`).

The arm is the capsule chain of :class:`selfcal.kinematics.self_collision.CapsuleChain` (the
self-collision check's shapes: segments through the chain's frame origins, one radius). A view's
lines of sight run from the camera's centre to a grid of points over the board's printed image
(its quiet zone included) whose spacing is at most the capsule radius plus clearance, so that a
link whose axis crosses the pyramid from the camera to the printed board comes within that
distance of one of them. Each line stops that distance and 1 cm before the board (a link
touching the board is the collision checks' business). A posture is refused when

- a segment of the chain but its last (the link the flange is on, which holds the camera
  eye-in-hand and the board eye-to-hand) comes within the capsule radius plus clearance of a
  line of sight. Another link near the camera counts: the ER-4u's forearm, with the camera 3.9 cm
  from its axis, hid half the board in a rendered view (docs/plan.md);
- a line of sight crosses a keep-out box grown by the clearance, but a box that holds the
  camera's centre (the camera's own stand or housing).

Units: m, base frame. Vectorised over postures (in chunks of :data:`CHUNK`).
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.self_collision import CapsuleChain, segment_distances

__all__ = ["CHUNK", "LINE_STOP_M", "sight_grid", "sight_lines", "sight_clear"]

CHUNK = 256
"""Postures per vectorised chunk (lines x segments x chunk distances at a time)."""
LINE_STOP_M = 0.01
"""Each line of sight stops this much (beyond the capsule radius plus clearance) before the
board (m)."""


def sight_grid(extent_m: tuple[float, float, float, float], spacing_m: float) -> np.ndarray:
    """(g, 3) points over the rectangle ``extent_m = (x0, y0, x1, y1)`` (board frame, m) on the
    board's plane: its corners, edges and inside, at most ``spacing_m`` apart along each axis."""
    x0, y0, x1, y1 = extent_m
    nx = max(2, int(np.ceil((x1 - x0) / spacing_m)) + 1)
    ny = max(2, int(np.ceil((y1 - y0) / spacing_m)) + 1)
    x, y = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny), indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)


def sight_lines(C: np.ndarray, P: np.ndarray, stop_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The lines of sight from the camera centres ``C`` (m, 3) to the board points ``P``
    (m, g, 3) (m, base frame), each stopped ``stop_m`` before its point (none shorter than a
    point at the camera): their starts and ends (m, g, 3)."""
    v = P - C[:, None]
    d = np.linalg.norm(v, axis=-1, keepdims=True)
    end = C[:, None] + v * np.maximum(1.0 - stop_m / np.maximum(d, 1e-12), 0.0)
    return np.broadcast_to(C[:, None], end.shape), end


def _segment_hits_box(a: np.ndarray, b: np.ndarray, box: np.ndarray) -> np.ndarray:
    """(...) bool: the segments ``[a, b]`` (..., 3) cross the axis-aligned ``box`` (6,) (the
    slab test; touching counts)."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (box[:3] - a) / d
        t1 = (box[3:] - a) / d
    lo, hi = np.minimum(t0, t1), np.maximum(t0, t1)
    # an axis the segment does not move along: inside the slab or never
    still = np.abs(d) < 1e-15
    inside = (a >= box[:3]) & (a <= box[3:])
    lo = np.where(still, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(still, np.where(inside, np.inf, -np.inf), hi)
    enter = np.maximum(lo.max(axis=-1), 0.0)
    leave = np.minimum(hi.min(axis=-1), 1.0)
    return enter <= leave


def sight_clear(
    chain: CapsuleChain,
    q: np.ndarray,
    C: np.ndarray,
    P: np.ndarray,
    boxes: np.ndarray,
) -> np.ndarray:
    """(m,) bool: which postures ``q`` (m, n) rad keep every line of sight from the camera
    centre ``C`` (m, 3) or (3,) to the board points ``P`` (m, g, 3) (base frame, m) clear of the
    arm's capsules and of the keep-out ``boxes`` (b, 6) (module docstring); either mount, the
    last link holds the camera or the board and is left out."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m = len(q)
    C = np.broadcast_to(np.asarray(C, dtype=float), (m, 3))
    P = np.asarray(P, dtype=float)
    gap = chain.radius_m + chain.clearance_m
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 6)
    ok = np.ones(m, dtype=bool)
    for s in range(0, m, CHUNK):
        k = slice(s, min(s + CHUNK, m))
        a, b = sight_lines(C[k], P[k], gap + LINE_STOP_M)  # (c, g, 3)
        pts = chain.points(q[k])[:, 1:]  # F_1 .. tool: the base stands below the first joint
        # the segments but the last (the camera's or the board's link): (c, n_seg - 1, 3)
        s0, s1 = pts[:, :-2], pts[:, 1:-1]
        d = segment_distances(a[:, :, None], b[:, :, None], s0[:, None], s1[:, None])
        ok[k] = np.all(d > gap, axis=(1, 2))
        for box in boxes:
            grown = box + np.r_[-1.0, -1.0, -1.0, 1.0, 1.0, 1.0] * chain.clearance_m
            holds_camera = np.all((C[k] >= grown[:3]) & (C[k] <= grown[3:]), axis=-1)
            hit = _segment_hits_box(a, b, grown).any(axis=1)
            ok[k] &= holds_camera | ~hit
    return ok
