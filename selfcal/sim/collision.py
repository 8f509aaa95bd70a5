"""Self-collision and table contact of the robot, from its MuJoCo collision shapes.

The MuJoCo side of :mod:`selfcal.calibration.field.optimal_poses` (which takes the check as a callback and stays
MuJoCo-free).
"""

from __future__ import annotations

import mujoco
import numpy as np

from selfcal.robot.definition import load_robot
from selfcal.sim.link_frames import link_body_names, nominal_camera_model
from selfcal.sim.robot_mjcf import robot_spec

__all__ = ["SHORT_LINK_M", "collision_checker", "collision_free"]

SHORT_LINK_M = 0.05
"""A link whose frame origins lie closer than this (m) joins its two neighbours into one rigid
piece: their collision shapes meet at the joint by construction."""


def collision_checker(robot_name: str, *, table: bool = True, tolerance_m: float = 0.01):
    """A callback ``ok(q (m, n) rad) -> (m,) bool`` for :mod:`selfcal.calibration.field.optimal_poses`: False where
    the nominal robot's MuJoCo collision shapes (:mod:`selfcal.sim.robot_mjcf`, group 3) of two
    non-adjacent links penetrate by more than ``tolerance_m`` (the shapes are coarse), or, with
    ``table``, where a link beyond the turret (arm, wrist, hand, camera rig) goes below the table
    plane z = 0.

    Adjacent (never checked): parent and child bodies, and two links joined through a link shorter
    than :data:`SHORT_LINK_M` (the SCORBOT wrist: joints 4 and 5 share their origin, so the
    forearm's capsule and the hand overlap by construction; the KR 6 R900's 35 mm elbow offset
    between the upper arm and the forearm roll). Bodies without a joint (the camera rig) belong to the
    link they are fixed to. So the shapes cannot tell a camera touching the forearm near the
    wrist (they overlap there at every posture); what is checked is arm against base, turret and
    the other arm links, and everything against the table.
    """
    robot = load_robot(robot_name)
    spec = robot_spec(robot, nominal_camera_model(robot))
    if table:
        g = spec.worldbody.add_geom()
        g.name = "collision_table"
        g.type = mujoco.mjtGeom.mjGEOM_PLANE
        g.size = [2.0, 2.0, 0.01]
    for g in spec.geoms:  # collision shapes collide with each other (and the table) only
        on = g.group == 3 or g.name == "collision_table"
        g.contype, g.conaffinity = (1, 1) if on else (0, 0)
    m = spec.compile()
    m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)  # parent-child: skip
    d = mujoco.MjData(m)
    d.qpos[: robot.n] = robot.home
    mujoco.mj_forward(m, d)
    links = [m.body(nm).id for nm in link_body_names(robot.n)]
    origin = d.xpos[links]
    skip = set()
    for k in range(1, robot.n - 1):  # a short link k+1 (0-based k) joins links k and k+2
        if np.linalg.norm(origin[k + 1] - origin[k]) < SHORT_LINK_M:
            skip.add(frozenset((links[k - 1], links[k + 1])))

    def link_of(b: int) -> int:  # bodies fixed to a link (no joint) belong to it
        while b > 0 and m.body_jntnum[b] == 0 and m.body_parentid[b] > 0:
            b = int(m.body_parentid[b])
        return b

    owner = np.array([link_of(b) for b in range(m.nbody)])
    ground = {m.body("base").id, links[0]}  # the pedestal and turret stand on the table
    table_id = m.geom("collision_table").id if table else -1
    nq = robot.n

    def ok(q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        res = np.ones(len(q), bool)
        for i, qi in enumerate(q):
            d.qpos[:nq] = qi
            mujoco.mj_forward(m, d)
            for c in d.contact[: d.ncon]:
                g1, g2 = int(c.geom1), int(c.geom2)
                b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
                if table_id in (g1, g2):
                    if (b2 if g1 == table_id else b1) in ground or c.dist >= 0:
                        continue
                elif (
                    c.dist >= -tolerance_m
                    or owner[b1] == owner[b2]
                    or frozenset((int(owner[b1]), int(owner[b2]))) in skip
                    or m.body_parentid[owner[b1]] == owner[b2]
                    or m.body_parentid[owner[b2]] == owner[b1]
                ):
                    continue
                res[i] = False
                break
        return res

    return ok


def collision_free(robot_name: str, q: np.ndarray) -> np.ndarray:
    """(m,) bool: postures ``q`` (m, n) rad free of self-collision and table contact (see
    :func:`collision_checker`; builds the checker each call -- keep one for many calls)."""
    return collision_checker(robot_name)(q)
