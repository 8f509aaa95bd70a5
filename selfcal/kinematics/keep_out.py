"""Keep-out boxes: axis-aligned regions of the base frame no part of the arm may enter (the table
top beside the robot, a fixture, the cell's walls), checked on the capsule chain of
:class:`selfcal.kinematics.self_collision.CapsuleChain`.

Each segment of the chain (from the first joint's frame on: the base itself stands where the user
put it) is sampled at :data:`SAMPLES` points; a posture enters a box when one of those points lies
inside the box grown by the capsule radius plus the clearance, or the camera centre inside the
box grown by the clearance. Coarse like the chain itself. Units: m, base frame.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_frames
from selfcal.kinematics.self_collision import CapsuleChain

__all__ = ["SAMPLES", "check_boxes", "collision_free", "outside_boxes", "chain_samples"]

SAMPLES = 9
"""Points per segment of the chain (ends included): the gap between two is at most a ninth of
the longest link, below the capsule radius plus clearance for links shorter than about 0.3 m."""


def check_boxes(boxes: np.ndarray) -> np.ndarray:
    """``boxes`` as (b, 6) ``xmin, ymin, zmin, xmax, ymax, zmax`` (m), each min below its max."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 6)
    bad = np.flatnonzero(~np.all(b[:, :3] < b[:, 3:], axis=1) | ~np.isfinite(b).all(axis=1))
    if bad.size:
        raise InputError(
            f"keep-out box {int(bad[0]) + 1} {np.round(b[bad[0]] * 1000, 3).tolist()} mm: each "
            "minimum must be below its maximum",
            fix="give xmin,ymin,zmin,xmax,ymax,zmax in mm in the base frame",
        )
    return b


def chain_samples(chain: CapsuleChain, q: np.ndarray) -> np.ndarray:
    """(m, s, 3) points along the chain's segments from the first joint's frame on (m)."""
    P = chain.points(np.atleast_2d(q))[:, 1:]  # F_1 .. tool
    t = np.linspace(0.0, 1.0, SAMPLES)[:, None]
    seg = P[:, :-1, None, :] * (1 - t) + P[:, 1:, None, :] * t  # (m, n_seg, s, 3)
    return seg.reshape(len(P), -1, 3)


def outside_boxes(chain: CapsuleChain, q: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(m,) bool: which postures ``q`` (m, n) keep the chain and the camera out of every box of
    ``boxes`` (b, 6) m (module docstring)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    good = np.ones(len(q), bool)
    b = check_boxes(boxes)
    if not len(b):
        return good
    pts = chain_samples(chain, q)
    grow = chain.radius_m + chain.clearance_m
    for box in b:
        inside = np.all((pts > box[:3] - grow) & (pts < box[3:] + grow), axis=-1)
        good &= ~inside.any(axis=1)
    if chain.T_tool_cam is not None:
        cam = (fk_frames(chain.model, q)[:, -1] @ chain.T_tool_cam)[:, :3, 3]
        c = chain.clearance_m
        for box in b:
            good &= ~np.all((cam > box[:3] - c) & (cam < box[3:] + c), axis=-1)
    return good


def collision_free(chain: CapsuleChain, q: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(m,) bool: which postures ``q`` (m, n) rad are free of self-collision and the table
    (:meth:`CapsuleChain.ok`) and keep out of every box of ``boxes`` (b, 6) m: the planners'
    one collision filter (a field plan's candidates, every plan's workspace sample)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    ok = chain.ok(q)
    ok[ok] = outside_boxes(chain, q[ok], boxes)
    return ok
