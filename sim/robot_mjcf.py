"""The robot's MuJoCo model, built with ``mujoco.MjSpec`` from an MCPC chain (no hand-typed geometry).

Layout (like a MuJoCo Menagerie arm):

- default classes ``visual`` (no contacts, group 2, no mass) and ``collision`` (group 3, simple
  shapes carrying the mass); visual and collision geometry never mix;
- a fixed body ``base`` at the world origin, then bodies ``link1`` .. ``link<n>`` whose body frames
  ARE the MCPC link frames ``F_k`` of :func:`calib.kinematics.fk_frames`: body ``link_k`` sits at
  ``V_{k-1} Rz(o_k)`` in its parent (``o_k`` the joint's constant offset) and carries a hinge
  about its z axis (a slide along z for a prismatic joint), so ``qpos`` = the joint readings ``q``;
- a body ``rig`` on the last link at the last shape matrix ``V_n``: the MCPC tool frame, which is
  the LEFT camera's OpenCV frame because the model passed in carries the camera as its tool
  (``dh_to_mcpc(robot).with_tool(robot.T_flange_cam)``, possibly perturbed). It holds the cameras
  ``cam_left`` (at the rig origin) and ``cam_right`` (at ``RigConfig.T_left_right``), and the site
  ``tool_tip`` at the known rig-to-tip transform ``T_cam_tip = inv(robot.T_flange_cam)``, so at
  nominal the tool tip is the flange (last DH frame origin, the point of the paper's Table II);
- a site ``flange`` on the last link: the nominal last DH frame (where the nominal hand-eye puts
  it relative to the last link); under injected errors the rig (camera + tip) moves relative to it;
- position actuators ``<joint name>`` (ctrlrange = joint range) and a keyframe ``home``.

The visual shapes (base, turret, upper arm, forearm, wrist, two-finger gripper, camera rig; SCORBOT
orange and greys) are laid out from the chain itself: every link tube runs from its joint to the
next joint's origin, the fingers end at the tool tip. Self-collisions are off (collision geoms have
``contype=2, conaffinity=1``: they touch the table but not each other); inertias come from the
collision shapes at a nominal density (approximate).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from calib.camera import Intrinsics
from calib.mcpc import MCPCModel, dh_to_mcpc, shape_matrices
from calib.robot_def import RobotDef
from calib.transforms import inv_pose, rot_z, trans
from sim.markers import MarkerField
from sim.mj_camera import add_camera
from sim.scene import scene_spec

__all__ = [
    "RigConfig",
    "nominal_camera_model",
    "robot_spec",
    "add_robot",
    "scene_with_robot",
    "link_body_poses",
    "flange_in_last_link",
    "link_body_names",
    "RIG_BODY",
    "CAMERA_NAMES",
    "TOOL_SITE",
    "FLANGE_SITE",
]

RIG_BODY = "rig"
CAMERA_NAMES = ("cam_left", "cam_right")
TOOL_SITE = "tool_tip"
FLANGE_SITE = "flange"


def link_body_names(n: int) -> tuple[str, ...]:
    """Body names of an n-joint arm's links: ``link1`` ... ``link<n>``."""
    return tuple(f"link{k + 1}" for k in range(n))


_ORANGE = (0.93, 0.45, 0.06, 1.0)
_GREY = (0.55, 0.56, 0.58, 1.0)
_DARK = (0.22, 0.22, 0.24, 1.0)
_BLACK = (0.05, 0.05, 0.06, 1.0)
_STEEL = (0.70, 0.72, 0.75, 1.0)

_DENSITY = 600.0  # kg/m^3 on the solid collision shapes (hollow aluminium/plastic links)


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
            raise ValueError("T_left_right must be a rigid 4x4 transform (OpenCV frames, m)")
        object.__setattr__(self, "T_left_right", T)

    @property
    def right(self) -> Intrinsics:
        """Intrinsics of the right camera."""
        return self.intrinsics if self.intrinsics_right is None else self.intrinsics_right

    @property
    def baseline_m(self) -> float:
        """Distance between the two camera centres (m)."""
        return float(np.linalg.norm(self.T_left_right[:3, 3]))


# --------------------------------------------------------------------------- kinematics -> bodies


def _motion_offset(model: MCPCModel, k: int) -> np.ndarray:
    """``Rz(o_k)`` for revolute joint index k (0-based); identity for a prismatic joint."""
    if model.joint_types[k] == "revolute":
        return rot_z(model.joint_offsets[k])
    return np.eye(4)


def nominal_camera_model(robot: RobotDef) -> MCPCModel:
    """The nominal MCPC chain with the left camera (OpenCV frame) as its tool:
    ``dh_to_mcpc(robot).with_tool(robot.T_flange_cam)``."""
    return dh_to_mcpc(robot).with_tool(robot.T_flange_cam)


def link_body_poses(model: MCPCModel) -> np.ndarray:
    """Body poses relative to their parents, (n + 1, 4, 4): ``V_{k-1} Rz(o_k)`` for ``link_k``
    (k = 1..n, the first relative to the fixed base = world) and ``V_n`` for the rig."""
    V = shape_matrices(model.params)
    out = np.empty((model.n + 1, 4, 4))
    for k in range(model.n):
        out[k] = V[k] @ _motion_offset(model, k)
    out[model.n] = V[model.n]
    return out


def flange_in_last_link(robot: RobotDef, model: MCPCModel) -> np.ndarray:
    """Pose (4, 4) of the nominal flange (last DH frame) in the last link's body frame.

    The nominal camera chain ``dh_to_mcpc(robot).with_tool(robot.T_flange_cam)`` puts the camera at
    ``V_n`` and so the flange at ``V_n inv(T_flange_cam)``; a different constant offset of the last
    joint in ``model`` (from the gauge fix) rotates the link frame about its axis.
    """
    nominal = nominal_camera_model(robot)
    n = robot.n
    V_n = shape_matrices(nominal.params[n])
    corr = np.eye(4)
    if robot.joint_types[n - 1] == "revolute":
        corr = rot_z(nominal.joint_offsets[n - 1] - model.joint_offsets[n - 1])
    return corr @ V_n @ inv_pose(robot.T_flange_cam)


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(-1))
    return q


def _set_pose(elem, T: np.ndarray) -> None:
    elem.pos = np.asarray(T[:3, 3], dtype=float).copy()
    elem.quat = _quat(T[:3, :3])


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _perp(v: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """Unit vector perpendicular to ``v``, as close to ``hint`` as possible."""
    v = _unit(v)
    for h in (np.asarray(hint, float), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        w = h - (h @ v) * v
        if np.linalg.norm(w) > 1e-6:
            return _unit(w)
    raise AssertionError("unreachable")


def _box_frame(x_dir: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    """Rotation whose x axis is ``x_dir`` and whose z axis is as close to ``z_hint`` as possible."""
    x = _unit(x_dir)
    z = _perp(x, z_hint)
    return np.column_stack([x, np.cross(z, x), z])


# --------------------------------------------------------------------------- geometry helpers


class _Builder:
    """Adds visual / collision geoms with the right default classes."""

    def __init__(self, spec: mujoco.MjSpec) -> None:
        self.spec = spec
        self.visual = spec.find_default("visual")
        self.collision = spec.find_default("collision")

    def _geom(self, body, cls, gtype, size, material=None, **kw) -> mujoco.MjsGeom:
        g = body.add_geom(cls)
        g.type = gtype
        g.size = list(size) + [0.0] * (3 - len(size))
        if material is not None:
            g.material = material
        for key, val in kw.items():
            setattr(g, key, val)
        return g

    def capsule(self, body, p0, p1, r, material=None, collision=False):
        cls = self.collision if collision else self.visual
        ft = np.concatenate([np.asarray(p0, float), np.asarray(p1, float)])
        return self._geom(body, cls, mujoco.mjtGeom.mjGEOM_CAPSULE, [r], material, fromto=ft)

    def cylinder(self, body, p0, p1, r, material=None, collision=False):
        cls = self.collision if collision else self.visual
        ft = np.concatenate([np.asarray(p0, float), np.asarray(p1, float)])
        return self._geom(body, cls, mujoco.mjtGeom.mjGEOM_CYLINDER, [r], material, fromto=ft)

    def box(self, body, center, R, half, material=None, collision=False):
        cls = self.collision if collision else self.visual
        return self._geom(
            body,
            cls,
            mujoco.mjtGeom.mjGEOM_BOX,
            list(half),
            material,
            pos=np.asarray(center, float).copy(),
            quat=_quat(R),
        )

    def box_between(self, body, p0, p1, half_w, half_h, z_hint, material=None, collision=False):
        """A box from ``p0`` to ``p1`` (x along the segment), half sizes ``half_w`` (y), ``half_h``
        (z, as close to ``z_hint`` as possible)."""
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        d = p1 - p0
        L = float(np.linalg.norm(d))
        return self.box(
            body, (p0 + p1) / 2, _box_frame(d, z_hint), [L / 2, half_w, half_h], material, collision
        )

    def sphere(self, body, center, r, material=None, collision=False):
        cls = self.collision if collision else self.visual
        return self._geom(
            body,
            cls,
            mujoco.mjtGeom.mjGEOM_SPHERE,
            [r],
            material,
            pos=np.asarray(center, float).copy(),
        )


def _add_defaults_and_materials(spec: mujoco.MjSpec) -> None:
    vis = spec.add_default("visual", spec.default)
    vis.geom.contype = 0
    vis.geom.conaffinity = 0
    vis.geom.group = 2
    vis.geom.density = 0.0
    col = spec.add_default("collision", spec.default)
    col.geom.group = 3
    col.geom.contype = 2  # touches the table (contype 1) but not other robot geoms
    col.geom.conaffinity = 1
    col.geom.density = _DENSITY
    col.geom.rgba = [0.6, 0.2, 0.2, 0.5]
    for name, rgba, spec_ in (
        ("orange", _ORANGE, 0.3),
        ("grey", _GREY, 0.3),
        ("dark", _DARK, 0.2),
        ("black", _BLACK, 0.1),
        ("steel", _STEEL, 0.6),
    ):
        m = spec.add_material()
        m.name = name
        m.rgba = list(rgba)
        m.specular = spec_
        m.shininess = 0.3
        m.reflectance = 0.0


# --------------------------------------------------------------------------- the links' shapes


def _next_joint(model: MCPCModel, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Origin and axis of joint k + 2's frame (1-based k + 1 is this link) in link k + 1's frame."""
    T = shape_matrices(model.params[k + 1]) @ _motion_offset(model, k + 1)
    return T[:3, 3].copy(), T[:3, 2].copy()


def _shape_base(b: _Builder, body, model: MCPCModel, h_base: float) -> None:
    """Grey pedestal around joint 1's axis (placed by ``V_0``), from the floor up to ``h_base``."""
    V0 = shape_matrices(model.params[0])
    o, z = V0[:3, 3], V0[:3, 2]
    b.box(body, o + z * 0.006, V0[:3, :3], [0.13, 0.13, 0.006], "dark")
    b.cylinder(body, o + z * 0.012, o + z * h_base, 0.105, "grey")
    b.cylinder(body, o + z * 0.012, o + z * h_base, 0.105, collision=True)


def _shape_turret(b: _Builder, body, model: MCPCModel, h_base: float) -> None:
    """Orange body rotating about z from the pedestal to the shoulder axis (+ shoulder motor)."""
    p, a = _next_joint(model, 0)
    h = float(p[2])
    col_top = max(h - 0.06, h_base + 0.02)
    b.cylinder(body, [0, 0, h_base + 0.002], [0, 0, h_base + 0.02], 0.10, "dark")
    b.cylinder(body, [0, 0, h_base + 0.02], [0, 0, col_top], 0.075, "orange")
    # yoke from the column top out to the shoulder axis, and the shoulder housing along it
    radial = np.array([p[0], p[1], 0.0])
    if np.linalg.norm(radial) > 1e-3:  # shoulder axis offset from the turret axis (DH a_1)
        r = _unit(radial)
        b.box_between(body, [0, 0, h] - 0.035 * r, p + 0.04 * r, 0.06, 0.05, [0, 0, 1], "orange")
    b.cylinder(body, [0, 0, col_top - 0.01], [0, 0, h], 0.065, "orange")
    b.cylinder(body, p - 0.075 * a, p + 0.075 * a, 0.055, "grey")
    b.cylinder(body, p + 0.075 * a, p + 0.085 * a, 0.035, "dark")
    b.cylinder(body, [0, 0, h_base + 0.02], [0, 0, h], 0.075, collision=True)
    b.cylinder(body, p - 0.075 * a, p + 0.075 * a, 0.055, collision=True)


def _shape_arm(
    b: _Builder, body, model: MCPCModel, k: int, width: float, height: float, r_joint: float
) -> None:
    """Upper arm / forearm: an orange beam from this joint to the next, grey joint housings."""
    p, a = _next_joint(model, k)
    b.cylinder(body, [0, 0, -width - 0.012], [0, 0, width + 0.012], r_joint, "grey")
    if np.linalg.norm(p) < 1e-3:  # next joint at this origin (e.g. before a prismatic joint)
        b.sphere(body, [0, 0, 0], r_joint, collision=True)
        return
    b.box_between(body, [0, 0, 0], p, height, width, [0, 0, 1], "orange")
    b.cylinder(body, p - (width + 0.008) * a, p + (width + 0.008) * a, r_joint * 0.85, "grey")
    b.capsule(body, [0, 0, 0], p, max(width, height), collision=True)


def _shape_wrist(b: _Builder, body, model: MCPCModel, k: int) -> None:
    """Wrist pitch link: a dark gearbox about the pitch axis, a stub along the roll axis."""
    p, a = _next_joint(model, k)
    b.cylinder(body, [0, 0, -0.042], [0, 0, 0.042], 0.034, "dark")
    b.cylinder(body, p + 0.0 * a, p + 0.035 * a, 0.03, "grey")
    b.sphere(body, [0, 0, 0], 0.045, collision=True)


def _shape_hand(b: _Builder, body, tip: np.ndarray, cam: np.ndarray) -> None:
    """Roll link: roll housing along z up to the gripper palm, two fingers ending at ``tip``.

    The fingers open along the direction perpendicular to the tool axis and to the camera's
    offset from it, so they stay out of the camera's view.
    """
    z = np.array([0.0, 0.0, 1.0])
    tip = np.asarray(tip, float)
    L = float(tip[2])
    axis_pt = np.array([tip[0], tip[1], 0.0])  # the gripper's centre line, parallel to z
    off = np.asarray(cam, float) - tip
    off[2] = 0.0
    u = _unit(np.cross(z, off)) if np.linalg.norm(off) > 1e-3 else np.array([1.0, 0.0, 0.0])
    v = np.cross(z, u)
    finger_len = min(0.045, 0.35 * L)
    palm_len = min(0.02, 0.15 * L)
    z_f = L - finger_len  # finger root
    z_p = z_f - palm_len  # palm root
    R_hand = np.column_stack([u, v, z])
    b.cylinder(body, [0, 0, 0.035], axis_pt + z * (z_p - 0.004), 0.028, "grey")
    b.cylinder(body, axis_pt + z * (z_p - 0.004), axis_pt + z * z_p, 0.032, "steel")
    b.box(body, axis_pt + z * (z_p + palm_len / 2), R_hand, [0.03, 0.016, palm_len / 2], "dark")
    for s in (-1.0, 1.0):
        root = axis_pt + z * z_f + s * 0.016 * u
        b.box(
            body,
            root + z * (finger_len / 2 - 0.001),
            R_hand,
            [0.004, 0.003, finger_len / 2 + 0.001],
            "black",
        )
        # a finger pad, ending exactly at the tool tip
        b.box(
            body,
            axis_pt + s * 0.0105 * u + z * (L - 0.009),
            R_hand,
            [0.0015, 0.003, 0.009],
            "steel",
        )
    b.capsule(body, [0, 0, 0.035], axis_pt + z * z_p, 0.028, collision=True)
    b.box(
        body,
        axis_pt + z * (z_f + finger_len / 2 - palm_len / 2),
        R_hand,
        [0.022, 0.012, (finger_len + palm_len) / 2],
        collision=True,
    )


def _shape_rig(b: _Builder, body, T_left_right: np.ndarray, T_cam_link: np.ndarray) -> None:
    """Stereo camera bar behind both camera centres (z_cam < 0: never in view), a bracket towards
    the last link's axis. ``T_cam_link``: last link frame in the rig (camera) frame."""
    c_r = T_left_right[:3, 3]
    centre = c_r / 2.0
    x_dir = c_r if np.linalg.norm(c_r) > 1e-6 else np.array([1.0, 0.0, 0.0])
    R = _box_frame(x_dir, [0, 0, 1])
    half_len = float(np.linalg.norm(c_r)) / 2.0 + 0.02
    back = np.array([0.0, 0.0, -0.021])
    b.box(body, centre + back, R, [half_len, 0.017, 0.016], "dark")
    b.box(body, centre + back, R, [half_len, 0.017, 0.016], collision=True)
    for c in (np.zeros(3), c_r):
        b.cylinder(body, c + [0, 0, -0.0052], c + [0, 0, -0.0047], 0.011, "steel")
        b.cylinder(body, c + [0, 0, -0.0047], c + [0, 0, -0.0042], 0.008, "black")
    # bracket: from the bar to the nearest point of the last link's axis, kept behind the cameras
    o, a = T_cam_link[:3, 3], T_cam_link[:3, 2]
    start = centre + back
    foot = o + ((start - o) @ a) * a
    foot[2] = min(foot[2], back[2])
    if np.linalg.norm(foot - start) > 0.01:
        b.box_between(body, start, foot, 0.012, 0.006, [0, 0, 1], "grey")


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
        raise ValueError(
            f"model joint types {model.joint_types} do not match {robot.name}'s {robot.joint_types}"
        )
    if any(b.name == "base" for b in spec.bodies):
        raise ValueError("spec already contains a robot (body 'base'); add it once")
    spec.compiler.degree = False  # all angles below are radians
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.timestep = 0.002
    _add_defaults_and_materials(spec)
    b = _Builder(spec)
    n = model.n
    poses = link_body_poses(model)

    base = spec.worldbody.add_body(name="base")
    p1, _ = _next_joint(model, 0)
    h_base = float(np.clip(0.3 * p1[2], 0.04, 0.12))
    _shape_base(b, base, model, h_base)

    parent = base
    links = []
    for k in range(n):
        body = parent.add_body(name=link_body_names(n)[k])
        _set_pose(body, poses[k])
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
    _shape_turret(b, links[0], model, h_base)
    if n >= 2:
        _shape_arm(b, links[1], model, 1, width=0.036, height=0.03, r_joint=0.048)
    if n >= 3:
        _shape_arm(b, links[2], model, 2, width=0.03, height=0.026, r_joint=0.042)
    if n >= 4:
        _shape_wrist(b, links[3], model, 3)

    T_cam_tip = inv_pose(robot.T_flange_cam)
    V_n = poses[n]
    tip_in_link = (V_n @ T_cam_tip)[:3, 3]
    _shape_hand(b, links[-1], tip_in_link, V_n[:3, 3])

    flange = links[-1].add_site(name=FLANGE_SITE)
    _set_pose(flange, flange_in_last_link(robot, model))
    flange.size = [0.004, 0.0, 0.0]
    flange.group = 4

    rig_body = links[-1].add_body(name=RIG_BODY)
    _set_pose(rig_body, V_n)
    _shape_rig(b, rig_body, rig.T_left_right, inv_pose(V_n))
    add_camera(rig_body, CAMERA_NAMES[0], rig.intrinsics, np.eye(4))
    add_camera(rig_body, CAMERA_NAMES[1], rig.right, rig.T_left_right)
    tip = rig_body.add_site(name=TOOL_SITE)
    _set_pose(tip, T_cam_tip)
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
    g.offwidth = max(int(g.offwidth), rig.intrinsics.width, rig.right.width)
    g.offheight = max(int(g.offheight), rig.intrinsics.height, rig.right.height)


def robot_spec(robot: RobotDef, model: MCPCModel, rig: RigConfig | None = None) -> mujoco.MjSpec:
    """A new ``MjSpec`` holding only the robot (and its stereo rig) for the MCPC chain ``model``.

    ``model``'s tool must be the left camera's OpenCV frame, e.g.
    ``dh_to_mcpc(robot).with_tool(robot.T_flange_cam)`` (possibly perturbed).
    """
    spec = mujoco.MjSpec()
    spec.modelname = robot.name
    add_robot(spec, robot, model, RigConfig() if rig is None else rig)
    spec.stat.extent = 1.0
    spec.stat.center = [0.2, 0.1, 0.3]
    return spec


def scene_with_robot(
    robot: RobotDef, model: MCPCModel, rig: RigConfig | None, field: MarkerField, **scene_kw
) -> mujoco.MjSpec:
    """The scene of ``sim.scene.scene_spec(field)`` (table, lights, markers; rendered at the rig's
    image size) with the robot added; names stay unprefixed (``cam_left``, ``tool_tip``, ...)."""
    rig = RigConfig() if rig is None else rig
    spec = scene_spec(field, width=rig.intrinsics.width, height=rig.intrinsics.height, **scene_kw)
    spec.modelname = f"{robot.name}_scene"
    add_robot(spec, robot, model, rig)
    return spec
