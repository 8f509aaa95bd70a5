"""A simple self-collision and floor check for planning postures of any serial arm.

The arm is a chain of capsules (segments with a radius) through the origins of its frames, from
the nominal MCPC chain (:func:`selfcal.kinematics.forward.fk_frames`): the world origin (base), each link
frame ``F_k`` (on joint k's axis) and the tool frame. Coincident points (a spherical wrist) are
merged. The wrist camera is a point (its centre), checked against the floor only: its mount is
light and sits beside the tool. A posture is rejected when

- two capsules that are not neighbours come closer than ``2 * radius + clearance`` (surface gap
  below ``clearance``). Capsules are neighbours when the chain between them is shorter than that
  distance (a short wrist link makes its two neighbours one rigid body), so the check never
  flags the joints themselves;
- a point of the chain beyond the second joint is below ``floor_z_m + radius + clearance``, or
  the camera centre below ``floor_z_m + clearance``: the arm or its camera would touch the table
  the robot stands on (the world's z = ``floor_z_m`` plane; the base sits on it).

This is conservative and coarse (no link shapes, one radius for all links): it keeps a planned
trajectory away from the arm folding onto itself and from the table, not a certified collision
test. Units: metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.kinematics.forward import fk_frames
from selfcal.kinematics.mcpc import MCPCModel

__all__ = ["CapsuleChain", "segment_distances"]

_MERGE_M = 1e-6  # points of the chain closer than this are one point


def segment_distances(a0, a1, b0, b1) -> np.ndarray:
    """Shortest distances (...,) between segments ``[a0, a1]`` and ``[b0, b1]`` (..., 3).

    Clamped closest points of the two lines (Ericson, Real-Time Collision Detection, 5.1.9),
    robust to zero-length segments.
    """
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a = np.sum(d1 * d1, -1)
    e = np.sum(d2 * d2, -1)
    f = np.sum(d2 * r, -1)
    c = np.sum(d1 * r, -1)
    b = np.sum(d1 * d2, -1)
    tiny = 1e-300
    a_ = np.maximum(a, tiny)
    e_ = np.maximum(e, tiny)
    denom = a * e - b * b
    # general case: closest points of the lines, s clamped, then t for that s, clamped; lines
    # closer to parallel than the rounding of ``denom`` (relative 1e-14) take s = 0, the
    # endpoint candidates below then give the minimum
    skew = denom > 1e-14 * a * e
    s = np.where(skew, np.clip((b * f - c * e) / np.where(skew, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e_
    s = np.where(
        t < 0.0, np.clip(-c / a_, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_, 0, 1), s)
    )
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments (points)
    s = np.where(e <= tiny, np.clip(-c / a_, 0.0, 1.0), s)
    t = np.where(e <= tiny, 0.0, t)
    s = np.where(a <= tiny, 0.0, s)
    t = np.where(a <= tiny, np.where(e <= tiny, 0.0, np.clip(f / e_, 0.0, 1.0)), t)
    p = a0 + s[..., None] * d1
    q = b0 + t[..., None] * d2
    d = np.linalg.norm(p - q, axis=-1)
    # every endpoint against the other segment: each candidate is a distance between points of
    # the two segments, so the minimum never undercuts the true one, and it is exact where the
    # closed form above is ill-conditioned (near-parallel or nearly point-like segments)
    for x, y0, dy, ee in ((a0, b0, d2, e_), (a1, b0, d2, e_), (b0, a0, d1, a_), (b1, a0, d1, a_)):
        u = np.clip(np.sum((x - y0) * dy, -1) / ee, 0.0, 1.0)
        d = np.minimum(d, np.linalg.norm(x - (y0 + u[..., None] * dy), axis=-1))
    return d


@dataclass(frozen=True)
class CapsuleChain:
    """The check of the module docstring for one arm.

    Attributes:
        model: nominal MCPC chain, world (base) -> flange or tool.
        T_tool_cam: the camera in ``model``'s tool frame (4, 4), or None (no camera point).
        radius_m: capsule radius of every link (m).
        clearance_m: required surface gap between non-neighbouring capsules and to the floor (m).
        floor_z_m: the table plane's height in the world frame (m).
    """

    model: MCPCModel
    T_tool_cam: np.ndarray | None = None
    radius_m: float = 0.03
    clearance_m: float = 0.01
    floor_z_m: float = 0.0

    def points(self, q: np.ndarray) -> np.ndarray:
        """Chain points (m, n + 2, 3): base, ``F_1..F_n``, tool (world, m)."""
        F = fk_frames(self.model, np.atleast_2d(q))
        return np.concatenate([np.zeros((F.shape[0], 1, 3)), F[:, :, :3, 3]], axis=1)

    def ok(self, q: np.ndarray) -> np.ndarray:
        """Boolean (m,): which postures ``q`` (m, n) pass both checks."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        P = self.points(q)
        good = np.ones(len(q), dtype=bool)
        if self.T_tool_cam is not None:
            cam = fk_frames(self.model, q)[:, -1] @ self.T_tool_cam
            good &= cam[:, 2, 3] >= self.floor_z_m + self.clearance_m
        # merge coincident points (same for every posture: rigid zero-length links)
        keep = [0]
        for k in range(1, P.shape[1]):
            if np.max(np.linalg.norm(P[:, k] - P[:, keep[-1]], axis=-1)) > _MERGE_M:
                keep.append(k)
        P = P[:, keep]
        n_seg = P.shape[1] - 1
        lengths = np.min(np.linalg.norm(np.diff(P, axis=1), axis=-1), axis=0)
        need = 2 * self.radius_m + self.clearance_m
        for i in range(n_seg):
            for j in range(i + 2, n_seg):
                if np.sum(lengths[i + 1 : j]) <= need:
                    continue  # neighbours through a short rigid piece
                d = segment_distances(P[:, i], P[:, i + 1], P[:, j], P[:, j + 1])
                good &= d >= need
        # points beyond the second joint (index 2 onwards of the merged chain) above the floor
        floor = self.floor_z_m + self.radius_m + self.clearance_m
        good &= np.all(P[:, 2:, 2] >= floor, axis=1)
        return good
