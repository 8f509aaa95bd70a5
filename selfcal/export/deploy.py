"""A calibrated robot users can deploy: the identified chain in the robot's base frame.

``calibration.json`` describes the robot as :attr:`selfcal.io.calibration.CalibrationResult.model`:
an MCPC chain whose *world* is the reconstruction frame (the left camera at one frame of the
trajectory) and whose *tool* is the left camera (OpenCV frame). Neither is what a user commands.
:func:`deploy` re-expresses the same physical chain as

- world = the robot's **base frame**, built on the *identified* joint axes 1 and 2
  (:func:`selfcal.kinematics.dh_table.canonical_base`): the frame on their common normal, placed relative to it
  as the nominal base frame is on the nominal axes. For a DH robot that is DH frame 0: z along
  joint 1's axis, the origin on that axis at the nominal height ``d_1`` below the common normal
  of axes 1 and 2, x such that DH row 1 has the nominal ``offset_1`` at joint reading 0; for a
  modified-DH or URDF robot its own base frame. For the nominal robot this IS the nominal base
  frame; for the identified robot it is the same construction on the measured axes. It is fixed by the arm alone (no scene, no camera), so every calibration of
  the same arm gives the same frame up to estimation error. What it cannot carry is exactly what a
  camera looking at an unknown scene cannot observe: where the base sits on the user's table
  (azimuth of joint 1's zero and base height relative to a workcell) -- register that separately;
- tool = the **tool tip** with the nominal flange orientation (z = tool axis): the identified
  camera frame composed with the known rigid ``T_cam_tip = inv(robot.T_flange_cam)`` of the
  camera/gripper assembly, exactly as :mod:`selfcal.pipeline.run` and :mod:`selfcal.kinematics.accuracy` do.

Joint values are the controller's joint readings ``q`` (rad inside, deg at the edges); constant
joint offsets of the MCPC chain are imposed equal to the nominal camera chain's
(:func:`nominal_offsets`), so the link frames are the nominal MJCF's body frames and the deployed
parameters are directly comparable with the nominal ones (:func:`nominal_deployed_params`).

Exports of a :class:`DeployedModel` (pure functions returning text; MJCF is in
:mod:`selfcal.sim.export_mjcf` because it needs MuJoCo):

- :func:`selfcal.export.robot_toml.to_toml` / :func:`selfcal.export.robot_toml.from_toml`: parameter table
  (mm / deg) that round-trips to the model, with standard deviations from the calibration and the
  DH table in the robot's own convention (standard or modified DH; none for a URDF robot) where
  one exists;
- :func:`selfcal.export.urdf.to_urdf`: links ``base_link``, ``link1..link<n>``, ``tool_tip``,
  the camera (``camera_optical_frame`` alone, ``cam_left`` and ``cam_right`` a pair), revolute
  joints named like the robot's joints (the MJCF's), full float precision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from selfcal.camera import Intrinsics
from selfcal.errors import InputError
from selfcal.io.calibration import CalibrationResult
from selfcal.kinematics.alignment import regauge
from selfcal.kinematics.dh_table import DHTable, canonical_base, dh_table
from selfcal.kinematics.forward import fk_frames
from selfcal.kinematics.mcpc import MCPCModel, chain_transforms, nominal_mcpc, shape_matrices
from selfcal.robot.definition import RobotDef, RobotDefinitionError, load_robot
from selfcal.transforms import inv_pose, make_pose, rot_z

__all__ = [
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
]

FIXED_BY_BASE_FRAME = ("alpha0", "beta0", "lx0", "ly0", "beta1", "ly1")
"""Minimal parameters that the base-frame construction sets (zero, or ``ly1 = d1 sin(alpha1)`` with
the nominal ``d1``) for a robot whose first two joints are revolute: they carry no information."""

BASE_FRAME = (
    "robot base = the nominal base frame rebuilt on the identified joint axes 1 and 2 "
    "(selfcal.kinematics.dh_table.canonical_base); for a standard-DH robot DH frame 0: z along joint 1's axis, "
    "origin on it at the nominal d1 below the common normal of axes 1 and 2, x such that DH row 1 "
    "has the nominal offset at joint reading 0"
)
TOOL_FRAME = (
    "tool tip: the identified camera (a stereo pair's left, a rig's first) composed with the "
    "known T_cam_tip = inv(robot.T_flange_cam) of the robot file's [camera_mount]; orientation "
    "of the nominal flange (z = tool axis); a robot file without [camera_mount] (a URDF never "
    "has one) puts the camera at the flange, so the tool tip is then the calibrated camera's "
    "optical frame (z along its view), not the flange"
)


class DeployError(InputError):
    """A calibration or parameter file that cannot be turned into a deployable model."""


def calibration_robot_model(name: str) -> RobotDef:
    """The robot a calibration's ``robot_model`` ``name`` names (a shipped robot's name).

    Raises:
        DeployError: no robot of that name (the caller prefixes the calibration file).
    """
    try:
        return load_robot(name)
    except RobotDefinitionError as exc:
        raise DeployError(
            f"robot_model {name!r} is not a robot this installation knows ({exc.message})",
            fix="calibrate again with this version, or pass the robot file the calibration was "
            "made with (its dataset folder's robot/ copy)",
        ) from None


@dataclass(frozen=True, eq=False)
class DeployedModel:
    """The calibrated robot in its base frame (see the module docstring). SI units.

    Attributes:
        robot_name: the robot definition (``models/<folder>/<name>.toml``).
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
        intrinsics: calibrated left intrinsics (the right's too unless ``intrinsics_right``),
            or None.
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
    intrinsics_right: Intrinsics | None = None
    """The right camera's own calibrated intrinsics (a rig whose cameras have their own), or
    None: ``intrinsics`` for both."""

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
        """``(DHTable, None)`` for this chain in the robot's own convention (standard or modified
        DH), or ``(None, reason)`` when no sound table exists (nearly parallel consecutive axes)
        or the robot comes from a URDF (:func:`selfcal.kinematics.dh_table.dh_table`)."""
        return dh_table(self.model, robot)


# --------------------------------------------------------------------------------------------
# Building the deployed model
# --------------------------------------------------------------------------------------------


def as_rigid(T, what: str) -> np.ndarray:
    """``T`` as a float 4x4 with its rotation re-orthonormalised (JSON rounds to 9 digits)."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise DeployError(
            f"{what} must be a finite 4x4 transform, got shape {T.shape}"
            + ("" if T.shape != (4, 4) else " with entries that are not finite")
        )
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
    except InputError as exc:
        raise DeployError(f"cannot build the robot base frame: {exc.message}", fix=exc.fix) from exc
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
    chain ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)``, so the link frames are the nominal
    MJCF's body frames (``selfcal.sim.robot_mjcf``) and the camera's shape matrix stays far from the Euler
    singularity."""
    return nominal_mcpc(robot).with_tool(robot.T_flange_cam).joint_offsets


def nominal_deployed_params(robot: RobotDef) -> np.ndarray:
    """MCPC parameters (n + 1, 6) of the NOMINAL robot, base frame -> tool tip (= last DH frame),
    in the offset convention of :func:`nominal_offsets`: the reference for deviations."""
    G = chain_transforms(nominal_mcpc(robot))
    return regauge(G, robot.joint_types, nominal_offsets(robot)).params


def deploy(
    calibration: CalibrationResult, robot: RobotDef | None = None, source: str = ""
) -> DeployedModel:
    """The deployable model of a calibration result (``calibration.json`` read by
    :func:`selfcal.io.calibration.read_calibration`; see :func:`deploy_chain`).

    ``robot`` defaults to the calibration's ``robot_model``. The calibrated stereo intrinsics
    and the rig, and the parameters' standard deviations, are carried along.

    Raises:
        DeployError: a robot that does not match the calibration, or a rig that is not rigid.
    """
    if robot is None:
        robot = calibration_robot_model(calibration.robot_model)
    elif calibration.robot_model != robot.name:
        raise DeployError(
            f"the calibration is of robot {calibration.robot_model!r}, not {robot.name!r}"
        )
    T = calibration.rig.T_left_right_m
    T_lr = None if np.isnan(T).all() else as_rigid(T, "rig.T_left_right_m")  # NaN: one camera
    return deploy_chain(
        calibration.model,
        robot,
        std=calibration.std_si(),
        intrinsics=calibration.pinhole,
        T_left_right=T_lr,
        source=source,
        intrinsics_right=calibration.intrinsics_of(1).pinhole() if calibration.cameras else None,
    )


def as_deployed(calibration, robot: RobotDef | None = None) -> DeployedModel:
    """Accept a :class:`DeployedModel`, a :class:`selfcal.io.calibration.CalibrationResult`, or an
    :class:`MCPCModel` that is ALREADY base frame -> tool tip (e.g. ``nominal_mcpc(robot)`` for
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
    out[0] = rot_z(model.base_offset) @ out[0]
    return out


def float_text(x: float) -> str:
    """Shortest text that reads back as exactly ``x`` (TOML and URDF: ``nan``, ``inf``)."""
    x = float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(x + 0.0)
