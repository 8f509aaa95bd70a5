"""The robot's MuJoCo model, built with ``mujoco.MjSpec`` from an MCPC chain (no hand-typed geometry).

Layout (like a MuJoCo Menagerie arm):

- default classes ``visual`` (no contacts, group 2, no mass) and ``collision`` (group 3, simple
  shapes carrying the mass); visual and collision geometry never mix;
- a fixed body ``base`` at the world origin, then bodies ``link1`` .. ``link<n>`` whose body frames
  ARE the MCPC link frames ``F_k`` of :func:`selfcal.kinematics.forward.fk_frames`: body ``link_k`` sits at
  ``V_{k-1} Rz(o_k)`` in its parent (``o_k`` the joint's constant offset) and carries a hinge
  about its z axis (a slide along z for a prismatic joint), so ``qpos`` = the joint readings ``q``;
- a body ``rig`` on the last link at the last shape matrix ``V_n``: the MCPC tool frame, which is
  the LEFT camera's OpenCV frame because the model passed in carries the camera as its tool
  (``nominal_mcpc(robot).with_tool(robot.T_flange_cam)``, possibly perturbed). It holds the cameras
  ``cam_left`` (at the rig origin) and ``cam_right`` (at ``RigConfig.T_left_right``), and the site
  ``tool_tip`` at the known rig-to-tip transform ``T_cam_tip = inv(robot.T_flange_cam)``, so at
  nominal the tool tip is the flange (last DH frame origin, the point of the paper's Table II);
- a site ``flange`` on the last link: the nominal last DH frame (where the nominal hand-eye puts
  it relative to the last link); under injected errors the rig (camera + tip) moves relative to it;
- position actuators ``<joint name>`` (ctrlrange = joint range) and a keyframe ``home``.

The shapes are laid out from the chain itself (geoms through ``selfcal.sim.mjcf_geoms``): the robot
file's ``[mjcf] shapes`` picks the SCORBOT's hand-made layout (``"turret"``, ``selfcal.sim.robot_shapes``)
or simple capsules between the joint frames for any arm (``"capsules"``, the default,
``selfcal.sim.capsule_shapes``); the body poses come from ``selfcal.sim.link_frames``. Self-collisions are off
(collision geoms have ``contype=2, conaffinity=1``: they touch the table but not each other);
inertias come from the collision shapes at a nominal density (approximate).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from selfcal.camera import Intrinsics
from selfcal.errors import InputError, UsageError
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.robot.definition import RobotDef
from selfcal.sim.capsule_shapes import link_radius, shape_capsule_base, shape_capsule_links
from selfcal.sim.lens import source_pinhole
from selfcal.sim.link_frames import (
    flange_in_last_link,
    link_body_names,
    link_body_poses,
    next_joint,
)
from selfcal.sim.markers import MarkerField
from selfcal.sim.mj_camera import add_camera
from selfcal.sim.mjcf_geoms import GeomBuilder, add_defaults_and_materials, set_pose
from selfcal.sim.robot_shapes import (
    shape_arm,
    shape_base,
    shape_hand,
    shape_rig,
    shape_turret,
    shape_wrist,
)
from selfcal.sim.scene import scene_spec
from selfcal.transforms import inv_pose, trans

__all__ = [
    "RigConfig",
    "robot_spec",
    "add_robot",
    "scene_with_robot",
    "RIG_BODY",
    "CAMERA_NAMES",
    "TOOL_SITE",
    "FLANGE_SITE",
]

RIG_BODY = "rig"
CAMERA_NAMES = ("cam_left", "cam_right")
TOOL_SITE = "tool_tip"
FLANGE_SITE = "flange"


def _default_intrinsics() -> Intrinsics:
    return Intrinsics.centered(fx=800.0, mu=1.0, width=640, height=480)


def _default_baseline() -> np.ndarray:
    return trans(np.array([0.06, 0.0, 0.0]))


@dataclass(frozen=True, eq=False)
class RigConfig:
    """The wrist stereo rig: left intrinsics, the right camera's pose in the left camera's frame
    (OpenCV convention, m) and optionally different right intrinsics (default: same as left)."""

    intrinsics: Intrinsics = field(default_factory=_default_intrinsics)
    T_left_right: np.ndarray = field(default_factory=_default_baseline)
    intrinsics_right: Intrinsics | None = None

    def __post_init__(self) -> None:
        T = np.asarray(self.T_left_right, dtype=float)
        if T.shape != (4, 4) or not np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-9):
            raise InputError("T_left_right must be a rigid 4x4 transform (OpenCV frames, m)")
        object.__setattr__(self, "T_left_right", T)

    @property
    def right(self) -> Intrinsics:
        """Intrinsics of the right camera."""
        return self.intrinsics if self.intrinsics_right is None else self.intrinsics_right

    @property
    def baseline_m(self) -> float:
        """Distance between the two camera centres (m)."""
        return float(np.linalg.norm(self.T_left_right[:3, 3]))


# --------------------------------------------------------------------------- public API


def add_robot(spec: mujoco.MjSpec, robot: RobotDef, model: MCPCModel, rig: RigConfig) -> None:
    """Add the robot (defaults, materials, bodies, joints, actuators, sites, cameras, ``home``
    keyframe) to ``spec``; element names are unprefixed (``link1``, ``cam_left``, ``tool_tip``).

    ``model`` is the MCPC chain to realise (its tool = the left camera's OpenCV frame); ``robot``
    supplies joint names, ranges, home posture and the known rig-to-tip transform.

    Raises ``ValueError`` if ``model`` and ``robot`` disagree on the joints, or if ``spec`` already
    holds a robot.
    """
    if model.joint_types != robot.joint_types:
        raise UsageError(
            f"model joint types {model.joint_types} do not match {robot.name}'s {robot.joint_types}"
        )
    if any(b.name == "base" for b in spec.bodies):
        raise UsageError("spec already contains a robot (body 'base'); add it once")
    spec.compiler.degree = False  # all angles below are radians
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.timestep = 0.002
    add_defaults_and_materials(spec)
    b = GeomBuilder(spec)
    n = model.n
    poses = link_body_poses(model)

    base = spec.worldbody.add_body(name="base")
    turret = robot.mjcf is not None and robot.mjcf.shapes == "turret"
    T_link_flange = flange_in_last_link(robot, model)
    r_link = link_radius(model, T_link_flange)
    if turret:
        p1, _ = next_joint(model, 0)
        h_base = float(np.clip(0.3 * p1[2], 0.04, 0.12))
        shape_base(b, base, model, h_base)
    else:
        shape_capsule_base(b, base, model, r_link)

    parent = base
    links = []
    for k in range(n):
        body = parent.add_body(name=link_body_names(n)[k])
        set_pose(body, poses[k])
        j = body.add_joint()
        j.name = robot.joint_names[k]
        j.type = (
            mujoco.mjtJoint.mjJNT_HINGE
            if robot.joint_types[k] == "revolute"
            else mujoco.mjtJoint.mjJNT_SLIDE
        )
        j.axis = [0.0, 0.0, 1.0]
        j.pos = [0.0, 0.0, 0.0]
        j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        j.range = [float(v) for v in robot.limits[k]]
        j.armature = float(robot.simulation.armature[k])
        links.append(body)
        parent = body

    # shapes, from the kinematics
    T_cam_tip = inv_pose(robot.T_flange_cam)
    V_n = poses[n]
    if turret:
        shape_turret(b, links[0], model, h_base)
        if n >= 2:
            shape_arm(b, links[1], model, 1, width=0.036, height=0.03, r_joint=0.048)
        if n >= 3:
            shape_arm(b, links[2], model, 2, width=0.03, height=0.026, r_joint=0.042)
        if n >= 4:
            shape_wrist(b, links[3], model, 3)
        tip_in_link = (V_n @ T_cam_tip)[:3, 3]
        shape_hand(b, links[-1], tip_in_link, V_n[:3, 3])
    else:
        shape_capsule_links(b, links, model, T_link_flange, r_link)

    flange = links[-1].add_site(name=FLANGE_SITE)
    set_pose(flange, T_link_flange)
    flange.size = [0.004, 0.0, 0.0]
    flange.group = 4

    rig_body = links[-1].add_body(name=RIG_BODY)
    set_pose(rig_body, V_n)
    shape_rig(b, rig_body, rig.T_left_right, inv_pose(V_n))
    add_camera(rig_body, CAMERA_NAMES[0], rig.intrinsics, np.eye(4))
    add_camera(rig_body, CAMERA_NAMES[1], rig.right, rig.T_left_right)
    tip = rig_body.add_site(name=TOOL_SITE)
    set_pose(tip, T_cam_tip)
    tip.size = [0.003, 0.0, 0.0]
    tip.rgba = [0.1, 0.8, 0.2, 1.0]
    tip.group = 4

    for k in range(n):
        a = spec.add_actuator()
        a.name = robot.joint_names[k]
        a.target = robot.joint_names[k]
        a.trntype = mujoco.mjtTrn.mjTRN_JOINT
        a.set_to_position(kp=float(robot.simulation.kp[k]), kv=float(robot.simulation.kv[k]))
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.ctrlrange = [float(v) for v in robot.limits[k]]

    key = spec.add_key()
    key.name = "home"
    key.qpos = [float(v) for v in robot.home]
    key.ctrl = [float(v) for v in robot.home]

    g = spec.visual.global_
    rendered = (source_pinhole(rig.intrinsics), source_pinhole(rig.right))  # lens: larger
    g.offwidth = max(int(g.offwidth), *(c.width for c in rendered))
    g.offheight = max(int(g.offheight), *(c.height for c in rendered))


def robot_spec(robot: RobotDef, model: MCPCModel, rig: RigConfig | None = None) -> mujoco.MjSpec:
    """A new ``MjSpec`` holding only the robot (and its stereo rig) for the MCPC chain ``model``.

    ``model``'s tool must be the left camera's OpenCV frame, e.g.
    ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)`` (possibly perturbed).
    """
    spec = mujoco.MjSpec()
    spec.modelname = robot.name
    add_robot(spec, robot, model, RigConfig() if rig is None else rig)
    spec.stat.extent = 1.0
    spec.stat.center = [0.2, 0.1, 0.3]
    return spec


def scene_with_robot(
    robot: RobotDef,
    model: MCPCModel,
    rig: RigConfig | None,
    field: MarkerField | None,
    **scene_kw,
) -> mujoco.MjSpec:
    """The scene of ``selfcal.sim.scene.scene_spec(field)`` (table, lights, markers; rendered at the rig's
    image size; no ``field``: table and lights) with the robot added; names stay unprefixed
    (``cam_left``, ``tool_tip``, ...)."""
    rig = RigConfig() if rig is None else rig
    spec = scene_spec(field, width=rig.intrinsics.width, height=rig.intrinsics.height, **scene_kw)
    spec.modelname = f"{robot.name}_scene"
    add_robot(spec, robot, model, rig)
    return spec
