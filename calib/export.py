"""A calibrated robot users can deploy: the identified chain in the robot's base frame.

``calibration.json`` describes the robot as :attr:`calib.io.calibration.CalibrationResult.model`:
an MCPC chain whose *world* is the reconstruction frame (the left camera at one frame of the
trajectory) and whose *tool* is the left camera (OpenCV frame). Neither is what a user commands.
:func:`deploy` re-expresses the same physical chain as

- world = the robot's **base frame**: DH frame 0 of the *identified* joint axes 1 and 2
  (:func:`calib.identify.canonical_base`): z along joint 1's axis (pointing like the nominal
  base z), the origin on that axis at the nominal height ``d_1`` below the common normal of axes 1
  and 2, x such that DH row 1 has the nominal ``offset_1`` at joint reading 0. For the nominal
  robot this IS the nominal base frame; for the identified robot it is the same construction on
  the measured axes. It is fixed by the arm alone (no scene, no camera), so every calibration of
  the same arm gives the same frame up to estimation error. What it cannot carry is exactly what a
  camera looking at an unknown scene cannot observe: where the base sits on the user's table
  (azimuth of joint 1's zero and base height relative to a workcell) -- register that separately;
- tool = the **tool tip** with the nominal flange orientation (z = tool axis): the identified
  camera frame composed with the known rigid ``T_cam_tip = inv(robot.T_flange_cam)`` of the
  camera/gripper assembly, exactly as :mod:`scenarios.pipeline` and :mod:`calib.report` do.

Joint values are the controller's joint readings ``q`` (rad inside, deg at the edges); constant
joint offsets of the MCPC chain are imposed equal to the nominal camera chain's
(:func:`nominal_offsets`), so the link frames are the nominal MJCF's body frames and the deployed
parameters are directly comparable with the nominal ones (:func:`nominal_deployed_params`).

Exports (pure functions returning text; MJCF is in :mod:`sim.export_mjcf` because it needs MuJoCo):

- :func:`to_toml` / :func:`from_toml`: parameter table (mm / deg) that round-trips to the model,
  with standard deviations from the calibration and the DH table where one exists;
- :func:`to_urdf`: links ``base_link``, ``link1..link<n>``, ``tool_tip``, ``cam_left``,
  ``cam_right``, revolute joints named like the robot's joints (the MJCF's), full float precision.
"""

from __future__ import annotations

import math
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from calib.camera import Intrinsics
from calib.errors import InputError
from calib.identify import DHTable, canonical_base, dh_table, regauge
from calib.io.calibration import CalibrationResult
from calib.kinematics import fk_frames
from calib.mcpc import (
    MCPCModel,
    chain_transforms,
    dh_to_mcpc,
    minimal_indices,
    param_is_angle,
    param_names,
    shape_matrices,
)
from calib.robot_def import RobotDef, load_robot
from calib.transforms import inv_pose, make_pose, rot_z

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "DEPLOY_FORMAT",
    "BASE_FRAME",
    "FIXED_BY_BASE_FRAME",
    "TOOL_FRAME",
    "DeployError",
    "DeployedModel",
    "deploy_chain",
    "deploy",
    "as_deployed",
    "nominal_offsets",
    "nominal_deployed_params",
    "body_poses",
    "float_text",
    "as_rigid",
    "to_toml",
    "from_toml",
    "to_urdf",
]

DEPLOY_FORMAT = "scorbot-selfcal-deployed"

FIXED_BY_BASE_FRAME = ("alpha0", "beta0", "lx0", "ly0", "beta1", "ly1")
"""Minimal parameters that the base-frame construction sets (zero, or ``ly1 = d1 sin(alpha1)`` with
the nominal ``d1``) for a robot whose first two joints are revolute: they carry no information."""

BASE_FRAME = (
    "robot base = DH frame 0 of the identified joint axes 1 and 2 (calib.identify.canonical_base): "
    "z along joint 1's axis, origin on it at the nominal d1 below the common normal of axes 1 and "
    "2, x such that DH row 1 has the nominal offset at joint reading 0"
)
TOOL_FRAME = (
    "tool tip: the identified left camera composed with the known T_cam_tip = "
    "inv(robot.T_flange_cam); orientation of the nominal flange (z = tool axis)"
)


class DeployError(InputError):
    """A calibration or parameter file that cannot be turned into a deployable model."""


@dataclass(frozen=True, eq=False)
class DeployedModel:
    """The calibrated robot in its base frame (see the module docstring). SI units.

    Attributes:
        robot_name: the robot definition (``models/robots/<name>.toml``).
        joint_names, joint_types: per joint.
        limits: (n, 2) joint ranges (rad or m), from the robot definition.
        home: (n,) home posture (rad or m).
        model: MCPC chain base frame -> tool tip, joint readings ``q``.
        T_tip_cam: the left camera (OpenCV frame) in the tool-tip frame: the known rigid
            camera/gripper assembly ``inv(T_cam_tip)`` (= ``robot.T_flange_cam`` by default). The
            calibrated hand-eye is not here but in the last shape matrix (where the assembly sits
            on the last link).
        T_world_base: the base frame in the source model's world (for a calibration: the
            reconstruction frame), for traceability.
        std: minimal parameter name -> one-sigma (rad, m) of the same-named parameter as identified
            in the reconstruction frame (``calibration.json``); empty when unknown.
        intrinsics: calibrated left intrinsics (right assumed equal), or None.
        T_left_right: calibrated right camera in the left camera's frame, or None.
        source: where the model came from (file name or description).
    """

    robot_name: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    limits: np.ndarray
    home: np.ndarray
    model: MCPCModel
    T_tip_cam: np.ndarray
    T_world_base: np.ndarray = field(default_factory=lambda: np.eye(4))
    std: dict[str, float] = field(default_factory=dict)
    intrinsics: Intrinsics | None = None
    T_left_right: np.ndarray | None = None
    source: str = ""

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.model.n

    def camera_model(self) -> MCPCModel:
        """The chain base frame -> left camera, with the same joint offsets (same link frames)."""
        G = chain_transforms(self.model)
        return regauge(
            [*G[:-1], G[-1] @ self.T_tip_cam], self.model.joint_types, self.model.joint_offsets
        )

    def frames(self, q: np.ndarray) -> np.ndarray:
        """Link frames ``F_1..F_n`` and the tool tip, (m, n + 1, 4, 4), in the base frame (m)."""
        return fk_frames(self.model, q)

    def tool_tip(self, q: np.ndarray) -> np.ndarray:
        """Tool-tip poses ``T_base_tip`` (m, 4, 4) for joint readings ``q`` (m, n) rad."""
        return fk_frames(self.model, q)[:, -1]

    def dh(self, robot: RobotDef) -> tuple[DHTable | None, str | None]:
        """``(DHTable, None)`` for this chain, or ``(None, reason)`` when no sound DH table exists
        (nearly parallel consecutive axes; :func:`calib.identify.dh_table`)."""
        return dh_table(self.model, robot)


# --------------------------------------------------------------------------------------------
# Building the deployed model
# --------------------------------------------------------------------------------------------


def as_rigid(T, what: str) -> np.ndarray:
    """``T`` as a float 4x4 with its rotation re-orthonormalised (JSON rounds to 9 digits)."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise DeployError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    U, s, Vt = np.linalg.svd(T[:3, :3])
    if np.max(np.abs(s - 1.0)) > 1e-6 or np.linalg.det(U @ Vt) < 0:
        raise DeployError(f"{what} is not a rigid transform (singular values {s})")
    return make_pose(U @ Vt, T[:3, 3])


def deploy_chain(
    model_cam: MCPCModel,
    robot: RobotDef,
    T_cam_tip: np.ndarray | None = None,
    **extra,
) -> DeployedModel:
    """The chain ``model_cam`` (any world frame, tool = left camera) in the robot's base frame with
    the tool tip as tool (module docstring). Works for an identified model and for the simulator's
    truth alike, so both can be compared in the same, physically defined frame.

    ``T_cam_tip`` (default ``inv(robot.T_flange_cam)``): the tool tip in the camera frame.
    ``extra``: further :class:`DeployedModel` fields (std, intrinsics, T_left_right, source).

    Raises:
        DeployError: joints differ from ``robot``'s, or axes 1 and 2 are nearly parallel (no base
            frame can be built from them).
    """
    if model_cam.joint_types != robot.joint_types:
        raise DeployError(
            f"model joint types {model_cam.joint_types} do not match {robot.name}'s "
            f"{robot.joint_types}: wrong robot model for this calibration?"
        )
    T_cam_tip = (
        inv_pose(robot.T_flange_cam) if T_cam_tip is None else as_rigid(T_cam_tip, "T_cam_tip")
    )
    try:
        T_world_base = canonical_base(model_cam, robot)
    except ValueError as exc:
        raise DeployError(f"cannot build the robot base frame: {exc}") from exc
    G = chain_transforms(model_cam)
    offsets = nominal_offsets(robot)
    chain = [inv_pose(T_world_base) @ G[0], *G[1:-1], G[-1] @ T_cam_tip]
    model = regauge(chain, robot.joint_types, offsets)
    return DeployedModel(
        robot_name=robot.name,
        joint_names=tuple(robot.joint_names),
        joint_types=tuple(robot.joint_types),
        limits=np.array(robot.limits, dtype=float),
        home=np.array(robot.home, dtype=float),
        model=model,
        T_tip_cam=inv_pose(T_cam_tip),
        T_world_base=T_world_base,
        **extra,
    )


def nominal_offsets(robot: RobotDef) -> np.ndarray:
    """The constant joint offsets (n,) rad of the deployed chains: those of the nominal camera
    chain ``dh_to_mcpc(robot).with_tool(robot.T_flange_cam)``, so the link frames are the nominal
    MJCF's body frames (``sim.robot_mjcf``) and the camera's shape matrix stays far from the Euler
    singularity."""
    return dh_to_mcpc(robot).with_tool(robot.T_flange_cam).joint_offsets


def nominal_deployed_params(robot: RobotDef) -> np.ndarray:
    """MCPC parameters (n + 1, 6) of the NOMINAL robot, base frame -> tool tip (= last DH frame),
    in the offset convention of :func:`nominal_offsets`: the reference for deviations."""
    G = chain_transforms(dh_to_mcpc(robot))
    return regauge(G, robot.joint_types, nominal_offsets(robot)).params


def deploy(
    calibration: CalibrationResult, robot: RobotDef | None = None, source: str = ""
) -> DeployedModel:
    """The deployable model of a calibration result (``calibration.json`` read by
    :func:`calib.io.calibration.read_calibration`; see :func:`deploy_chain`).

    ``robot`` defaults to the calibration's ``robot_model``. The calibrated stereo intrinsics
    and the rig, and the parameters' standard deviations, are carried along.

    Raises:
        DeployError: a robot that does not match the calibration, or a rig that is not rigid.
    """
    if robot is None:
        robot = load_robot(calibration.robot_model)
    elif calibration.robot_model != robot.name:
        raise DeployError(
            f"the calibration is of robot {calibration.robot_model!r}, not {robot.name!r}"
        )
    T_lr = as_rigid(calibration.T_left_right_m, "rig.T_left_right_m")
    return deploy_chain(
        calibration.model,
        robot,
        std=calibration.std_si(),
        intrinsics=calibration.pinhole,
        T_left_right=T_lr,
        source=source,
    )


def as_deployed(calibration, robot: RobotDef | None = None) -> DeployedModel:
    """Accept a :class:`DeployedModel`, a :class:`calib.io.calibration.CalibrationResult`, or an
    :class:`MCPCModel` that is ALREADY base frame -> tool tip (e.g. ``dh_to_mcpc(robot)`` for
    the nominal robot).

    Raises:
        DeployError: anything else, or an MCPC model without ``robot``.
    """
    if isinstance(calibration, DeployedModel):
        return calibration
    if isinstance(calibration, CalibrationResult):
        return deploy(calibration, robot)
    if isinstance(calibration, MCPCModel):
        if robot is None:
            raise DeployError("an MCPCModel needs the robot definition (joint names and ranges)")
        if calibration.joint_types != robot.joint_types:
            raise DeployError(f"model joint types do not match {robot.name}'s")
        return DeployedModel(
            robot.name, tuple(robot.joint_names), tuple(robot.joint_types),
            np.array(robot.limits, float), np.array(robot.home, float), calibration,
            np.array(robot.T_flange_cam, float),
        )  # fmt: skip
    raise DeployError(
        f"expected a CalibrationResult (read_calibration), a DeployedModel or an MCPCModel, got "
        f"{type(calibration).__name__}"
    )


def body_poses(model: MCPCModel) -> np.ndarray:
    """Each link frame in its parent's at joint reading 0, (n + 1, 4, 4): ``V_{k-1} Rz(o_k)`` for
    link k (the first relative to the base), then ``V_n`` (the tool) relative to link n. These are
    the MJCF body poses and the URDF joint origins; the joint then turns about / slides along z."""
    V = shape_matrices(model.params)
    out = V.copy()
    for k, kind in enumerate(model.joint_types):
        if kind == "revolute":
            out[k] = V[k] @ rot_z(model.joint_offsets[k])
    return out


def float_text(x: float) -> str:
    """Shortest text that reads back as exactly ``x`` (TOML and URDF: ``nan``, ``inf``)."""
    x = float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(x + 0.0)


# --------------------------------------------------------------------------------------------
# TOML
# --------------------------------------------------------------------------------------------


_f = float_text


def _arr(v) -> str:
    return "[" + ", ".join(_f(x) for x in np.asarray(v, dtype=float).reshape(-1)) + "]"


def _mat(R) -> str:
    return "[" + ", ".join(_arr(r) for r in np.asarray(R, dtype=float)) + "]"


def _s(text: str) -> str:
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"') + '"'


def _pose_lines(T: np.ndarray) -> list[str]:
    return [f"R = {_mat(T[:3, :3])}", f"xyz_mm = {_arr(T[:3, 3] * 1000.0)}"]


def to_toml(dep: DeployedModel, robot: RobotDef | None = None) -> str:
    """The parameter table of ``dep`` as TOML text (mm / deg), readable by :func:`from_toml`.

    Sections: ``[joints]`` (names, types, constant offsets, ranges, home), ``[[mcpc]]`` (one row
    per shape matrix ``V_i = Rx(alpha) Ry(beta) Rz(gamma) Trans(lx, ly, lz)``, i = 0..n, full
    precision: these define the model), ``[[parameters]]`` (the minimal identifiable set with the
    nominal value, the deviation and the calibration's std), ``[tool_camera]`` (left camera in the
    tool-tip frame), ``[base_in_reconstruction]``, ``[camera]`` (intrinsics, rig) and ``[dh]`` (the
    DH table, or a note why there is none).
    """
    robot = load_robot(dep.robot_name) if robot is None else robot
    m = dep.model
    n = m.n
    deg = 180.0 / math.pi
    unit = [deg, deg, deg, 1000.0, 1000.0, 1000.0]
    names_u = ["alpha_deg", "beta_deg", "gamma_deg", "lx_mm", "ly_mm", "lz_mm"]
    rev = [t == "revolute" for t in dep.joint_types]
    L = [
        f"# Calibrated kinematics of {dep.robot_name}, written by scorbot-selfcal (calib.export).",
        f"# Source: {dep.source or 'n/a'}",
        "# Units: mm and deg. Model: T_base_tip(q) = V_0 Q_1(q_1) V_1 ... Q_n(q_n) V_n with",
        "# V_i = Rx(alpha_i) Ry(beta_i) Rz(gamma_i) Trans(lx_i, ly_i, lz_i) and Q_k = Rz(q_k + offset_k)",
        "# (revolute) or Tz(q_k) (prismatic); q = the controller's joint readings.",
        f'format = "{DEPLOY_FORMAT}"',
        "version = 1",
        f"robot_model = {_s(dep.robot_name)}",
        f"source = {_s(dep.source)}",
        f"base_frame = {_s(BASE_FRAME)}",
        f"tool_frame = {_s(TOOL_FRAME)}",
        "",
        "[joints]",
        "names = [" + ", ".join(_s(x) for x in dep.joint_names) + "]",
        "types = [" + ", ".join(_s(x) for x in dep.joint_types) + "]",
        f"offset_deg = {_arr(m.joint_offsets * deg)}",
        "# ranges and home: deg for revolute joints, mm for prismatic ones",
        "range = " + _mat([lim * (deg if r else 1000.0) for lim, r in zip(dep.limits, rev)]),
        f"home = {_arr([h * (deg if r else 1000.0) for h, r in zip(dep.home, rev)])}",
        "",
    ]
    for i in range(n + 1):
        L.append("[[mcpc]]")
        L.append(f"frame = {i}")
        L += [f"{nm} = {_f(m.params[i, c] * unit[c])}" for c, nm in enumerate(names_u)]
        L.append("")
    nominal = nominal_deployed_params(robot)
    idx = minimal_indices(m.joint_types)
    ang = param_is_angle(idx)
    L.append(
        "# The minimal identifiable set (Zhuang's eq. 10) in the base frame. std: one sigma of the "
        "same-named parameter as identified in the reconstruction frame (calibration.json), which "
        "carries over to first order. alpha0, beta0, lx0, ly0, beta1 are zero and ly1 = d1 "
        "sin(alpha1) with the nominal d1 by the choice of the base frame (fixed_by_base_frame)."
    )
    for name, k, a in zip(param_names(idx), idx, ang):
        s = deg if a else 1000.0
        v, v0 = m.params.reshape(-1)[k] * s, nominal.reshape(-1)[k] * s
        d = v - v0
        if a:
            d = (d + 180.0) % 360.0 - 180.0
        L += [
            "[[parameters]]",
            f"name = {_s(name)}",
            f'unit = "{"deg" if a else "mm"}"',
            f"value = {_f(v)}",
            f"nominal = {_f(v0)}",
            f"deviation = {_f(d)}",
        ]
        if name in FIXED_BY_BASE_FRAME:
            L.append("fixed_by_base_frame = true")
        elif name in dep.std:
            L.append(f"std = {_f(dep.std[name] * s)}")
        L.append("")
    L += ["[tool_camera]  # the left camera (OpenCV frame) in the tool-tip frame (rigid assembly)"]
    L += _pose_lines(dep.T_tip_cam) + [""]
    L += ["[base_in_reconstruction]  # the base frame in the calibration's world frame"]
    L += _pose_lines(dep.T_world_base) + [""]
    if dep.intrinsics is not None:
        i = dep.intrinsics
        L += [
            "[camera]  # calibrated pinhole intrinsics (px, OpenCV), both cameras",
            f"fx = {_f(i.fx)}",
            f"mu = {_f(i.mu)}",
            f"cx = {_f(i.cx)}",
            f"cy = {_f(i.cy)}",
            f"width = {int(i.width)}",
            f"height = {int(i.height)}",
            "",
        ]
        if dep.T_left_right is not None:
            L += ["[camera.T_left_right]  # right camera in the left camera's frame"]
            L += _pose_lines(dep.T_left_right) + [""]
    dh, note = dep.dh(robot)
    L.append("[dh]  # standard DH, A_i = Rz(q_i + theta_offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)")
    if dh is None:
        L.append(f"note = {_s('no DH table: ' + note)}")
        L.append("")
    else:
        L.append("note = " + _s("DH frame 0 = the base frame; T_flange_tool = tool tip in frame n"))
        rows = ", ".join(
            f"{{theta_offset_deg = {_f(o * deg)}, d_mm = {_f(d * 1000)}, a_mm = {_f(a * 1000)}, "
            f"alpha_deg = {_f(al * deg)}}}"
            for o, d, a, al in dh.rows()
        )
        L.append(f"rows = [{rows}]")
        L.append("")
        L.append("[dh.T_flange_tool]")
        L += _pose_lines(dh.T_flange_tool) + [""]
    return "\n".join(L)


def _pose_from(t: dict, what: str) -> np.ndarray:
    try:
        return as_rigid(
            make_pose(np.asarray(t["R"], float), np.asarray(t["xyz_mm"], float) / 1000), what
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise DeployError(f"{what}: needs R (3x3) and xyz_mm (3): {exc}") from exc


def from_toml(text: str) -> DeployedModel:
    """Read a parameter table written by :func:`to_toml` back into a :class:`DeployedModel`.

    Raises:
        DeployError: not valid TOML, another format, or missing / malformed keys (named).
    """
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DeployError(f"not valid TOML: {exc}") from exc
    if d.get("format") != DEPLOY_FORMAT:
        raise DeployError(f"not a {DEPLOY_FORMAT} file (format = {d.get('format')!r})")
    deg = math.pi / 180.0
    try:
        j = d["joints"]
        types = tuple(j["types"])
        rev = np.array([t == "revolute" for t in types])
        to_si = np.where(rev, deg, 1e-3)
        n = len(types)
        rows = sorted(d["mcpc"], key=lambda r: r["frame"])
        if [r["frame"] for r in rows] != list(range(n + 1)):
            raise DeployError(f"[[mcpc]] must hold frames 0..{n} once each")
        scale = np.array([deg, deg, deg, 1e-3, 1e-3, 1e-3])
        cols = ["alpha_deg", "beta_deg", "gamma_deg", "lx_mm", "ly_mm", "lz_mm"]
        params = np.array([[float(r[c]) for c in cols] for r in rows]) * scale
        model = MCPCModel(params, types, np.asarray(j["offset_deg"], float) * deg)
        std = {}
        for p in d.get("parameters", []):
            if "std" in p:
                std[p["name"]] = float(p["std"]) * (deg if p["unit"] == "deg" else 1e-3)
        intr, T_lr = None, None
        if "camera" in d:
            c = d["camera"]
            intr = Intrinsics(
                float(c["fx"]), float(c["mu"]), float(c["cx"]), float(c["cy"]), int(c["width"]),
                int(c["height"]),
            )  # fmt: skip
            if "T_left_right" in c:
                T_lr = _pose_from(c["T_left_right"], "[camera.T_left_right]")
        return DeployedModel(
            robot_name=str(d["robot_model"]),
            joint_names=tuple(j["names"]),
            joint_types=types,
            limits=np.asarray(j["range"], float) * to_si[:, None],
            home=np.asarray(j["home"], float) * to_si,
            model=model,
            T_tip_cam=_pose_from(d["tool_camera"], "[tool_camera]"),
            T_world_base=_pose_from(d["base_in_reconstruction"], "[base_in_reconstruction]"),
            std=std,
            intrinsics=intr,
            T_left_right=T_lr,
            source=str(d.get("source", "")),
        )
    except KeyError as exc:
        raise DeployError(f"parameter file lacks key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, DeployError):
            raise
        raise DeployError(f"malformed parameter file: {exc}") from exc


# --------------------------------------------------------------------------------------------
# URDF
# --------------------------------------------------------------------------------------------


def _xyz_rpy(T: np.ndarray) -> tuple[str, str]:
    """URDF ``xyz`` and ``rpy`` (fixed-axis roll, pitch, yaw: R = Rz(y) Ry(p) Rx(r)), full precision."""
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
    return " ".join(_f(v) for v in T[:3, 3]), " ".join(_f(v) for v in rpy)


def _origin(parent: ET.Element, T: np.ndarray) -> None:
    xyz, rpy = _xyz_rpy(T)
    ET.SubElement(parent, "origin", xyz=xyz, rpy=rpy)


def _fixed(root: ET.Element, name: str, parent: str, child: str, T: np.ndarray) -> None:
    j = ET.SubElement(root, "joint", name=name, type="fixed")
    ET.SubElement(j, "parent", link=parent)
    ET.SubElement(j, "child", link=child)
    _origin(j, T)


def to_urdf(dep: DeployedModel, *, effort: float = 10.0, velocity: float = 1.0) -> str:
    """A URDF of the calibrated chain (kinematics only: no visuals, no inertias).

    ``base_link`` is the base frame; joint ``k`` (named like the robot's joint, e.g. ``shoulder``)
    moves ``link<k>`` about (revolute) or along (prismatic) its z-axis, with its ``<origin>`` = the
    link's frame in its parent's at reading 0, so URDF joint positions = the controller's joint
    readings (rad / m) and the link frames are the MCPC link frames (= the exported MJCF's bodies).
    Fixed joints add ``tool_tip`` (on the last link), ``cam_left`` (the left camera's optical frame,
    OpenCV/ROS optical convention: z forward, x right, y down; on the last link) and, when the
    calibration has the rig, ``cam_right`` (on ``cam_left``). ``effort`` (N m) and ``velocity``
    (rad/s) are placeholders the URDF format requires; the controller enforces the real ones.
    """
    m = dep.model
    n = m.n
    root = ET.Element("robot", name=f"{dep.robot_name}_calibrated")
    root.append(
        ET.Comment(
            f" Calibrated {dep.robot_name} (scorbot-selfcal calib.export; source: "
            f"{dep.source or 'n/a'}). base_link = {BASE_FRAME}. tool_tip = {TOOL_FRAME}. "
            "Metres and radians. "
        )
    )
    poses = body_poses(m)
    links = ["base_link"] + [f"link{k + 1}" for k in range(n)]
    ET.SubElement(root, "link", name=links[0])
    for k in range(n):
        kind = m.joint_types[k]
        j = ET.SubElement(root, "joint", name=dep.joint_names[k], type=kind)
        ET.SubElement(j, "parent", link=links[k])
        ET.SubElement(j, "child", link=links[k + 1])
        _origin(j, poses[k])
        ET.SubElement(j, "axis", xyz="0 0 1")
        lo, hi = dep.limits[k]
        ET.SubElement(
            j, "limit", lower=_f(lo), upper=_f(hi), effort=_f(effort), velocity=_f(velocity)
        )
        ET.SubElement(root, "link", name=links[k + 1])
    _fixed(root, "tool_tip_joint", links[-1], "tool_tip", poses[n])
    ET.SubElement(root, "link", name="tool_tip")
    _fixed(root, "cam_left_joint", links[-1], "cam_left", poses[n] @ dep.T_tip_cam)
    ET.SubElement(root, "link", name="cam_left")
    if dep.T_left_right is not None:
        _fixed(root, "cam_right_joint", "cam_left", "cam_right", dep.T_left_right)
        ET.SubElement(root, "link", name="cam_right")
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
