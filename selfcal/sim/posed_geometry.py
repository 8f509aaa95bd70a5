"""The robot's and the scene's visual geoms, posed by MuJoCo at given joint angles, as plain
arrays for a viewer (``selfcal.plots.rerun_log`` turns them into Rerun archetypes).

World frame = the simulator's world, metres. Geoms come in four shape groups: ``"boxes"`` (boxes
and the table plane), ``"cylinders"``, ``"capsules"`` and ``"spheres"`` (spheres and ellipsoids).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from selfcal.kinematics.mcpc import MCPCModel
from selfcal.robot.definition import RobotDef
from selfcal.sim.markers import MarkerField
from selfcal.sim.robot_mjcf import RigConfig, scene_with_robot

__all__ = ["GeomGroup", "PosedGeometry"]

_GEOM = mujoco.mjtGeom
_PLANE = int(_GEOM.mjGEOM_PLANE)
_SHAPES = {
    int(_GEOM.mjGEOM_BOX): "boxes",
    _PLANE: "boxes",
    int(_GEOM.mjGEOM_CYLINDER): "cylinders",
    int(_GEOM.mjGEOM_CAPSULE): "capsules",
    int(_GEOM.mjGEOM_SPHERE): "spheres",
    int(_GEOM.mjGEOM_ELLIPSOID): "spheres",
}


@dataclass(frozen=True)
class GeomGroup:
    """Geoms of one shape group at the current posture (k geoms).

    ``pos`` (k, 3) centres (m); ``R`` (k, 3, 3) world-from-geom rotations; ``size`` (k, 3) MuJoCo
    geom sizes (half-extents; radius and half-length for cylinders and capsules); ``rgba`` k
    colours 0..255; ``is_plane`` (k,) planes (``size`` 0 means infinite).
    """

    pos: np.ndarray
    R: np.ndarray
    size: np.ndarray
    rgba: list[tuple[int, int, int, int]]
    is_plane: np.ndarray


class PosedGeometry:
    """The robot (kinematic chain ``model``) with its rig in the scene of ``field``, compiled.

    ``static``: geom ids fixed to the world (table, markers); ``moving``: the robot's visual geoms.
    """

    def __init__(
        self, robot: RobotDef, model: MCPCModel, rig: RigConfig, field: MarkerField | None
    ) -> None:
        self.m = scene_with_robot(robot, model, rig, field).compile()
        self.d = mujoco.MjData(self.m)
        self.n = robot.n
        m = self.m
        self.static = [i for i in range(m.ngeom) if m.geom_bodyid[i] == 0]
        self.moving = [i for i in range(m.ngeom) if m.geom_bodyid[i] != 0 and m.geom_group[i] == 2]

    def set(self, q: np.ndarray) -> None:
        """Pose the robot at joint angles ``q`` (rad)."""
        self.d.qpos[: self.n] = q
        mujoco.mj_kinematics(self.m, self.d)

    def _rgba(self, i: int) -> tuple[int, int, int, int]:
        m = self.m
        c = m.mat_rgba[m.geom_matid[i]] if m.geom_matid[i] >= 0 else m.geom_rgba[i]
        r, g, b, a = (int(round(255 * float(x))) for x in c)
        return r, g, b, a

    def groups(self, ids: list[int]) -> dict[str, GeomGroup]:
        """The geoms ``ids`` at the current posture by shape group (other shapes are left out)."""
        m, d = self.m, self.d
        members: dict[str, list[int]] = {}
        for i in ids:
            key = _SHAPES.get(int(m.geom_type[i]))
            if key is not None:
                members.setdefault(key, []).append(i)
        return {
            key: GeomGroup(
                pos=d.geom_xpos[g].copy(),
                R=d.geom_xmat[g].reshape(-1, 3, 3).copy(),
                size=m.geom_size[g].copy(),
                rgba=[self._rgba(i) for i in g],
                is_plane=np.asarray(m.geom_type[g]) == _PLANE,
            )
            for key, g in members.items()
        }
