"""The hand-eye and the board mount for other software: ROS tf, easy_handeye, plain matrices.

A :class:`HandEyeExport` holds the static transforms of a calibration, each as the child's pose
in its parent frame (m) with its sigmas (rotation about the parent's axes, translation along
them), and the ROS frame names they go by (:data:`FRAME_NAMES`, ``--frames`` of ``selfcal
export``):

- a pose dataset's calibration (:mod:`selfcal.calibration.handeye.calibration_file`,
  :func:`from_handeye_document`): eye-in-hand flange -> camera and base -> board; eye-to-hand
  base -> camera and flange -> board. ``base`` and ``flange`` are the frames the robot's poses
  were given in (base -> flange as the controller reports it);
- a calibration with joints (:func:`from_chain`; tool = the camera): flange -> camera, where the
  flange is the nominal flange of joint n (``selfcal.calibration.field.results.hand_eye``), and for a board
  calibration base -> board, where the base is the robot's base frame rebuilt on the identified
  axes 1 and 2 (``selfcal.kinematics.dh_table.canonical_base``, the URDF export's ``base_link``);
  flange -> camera alone (and a note why) when joint 1 or 2 is prismatic or their axes parallel;
- an eye-to-hand calibration with joints (the camera static, the board on the flange;
  :func:`from_mounts`): base -> camera and flange -> board as ``calibration.json`` ``mounts``
  holds them, with the sigmas of the Cramer-Rao covariance.

Writers (pure functions returning text): :func:`to_tf_yaml` (``static_transform_publisher``
arguments for ROS 1 and ROS 2 and launch snippets), :func:`to_easy_handeye_yaml` (easy_handeye's
saved calibration: ``parameters`` and ``transformation``) and :func:`to_matrix_yaml` (4x4,
translation, quaternion xyzw, Euler angles). Quaternions are ``x, y, z, w`` with ``w >= 0``;
the camera frame is the optical frame (OpenCV = ROS optical: z forward, x right, y down).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.field.results import flange_tool
from selfcal.errors import InputError
from selfcal.export.deploy import as_rigid
from selfcal.export.deploy import float_text as _f
from selfcal.kinematics.dh_table import canonical_base
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.robot.definition import RobotDef
from selfcal.transforms import inv_pose

__all__ = [
    "FRAME_NAMES",
    "StaticTransform",
    "HandEyeExport",
    "frame_names",
    "from_handeye_document",
    "from_chain",
    "from_mounts",
    "to_tf_yaml",
    "to_easy_handeye_yaml",
    "to_matrix_yaml",
    "euler_rpy",
]

FRAME_NAMES = {"base": "base_link", "flange": "tool0", "camera": "camera_optical_frame",
               "board": "board"}  # fmt: skip
"""Default ROS frame names: ``base_link`` (the robot's base), ``tool0`` (ROS-Industrial's flange
frame without tool offset, as the controller reports it; not the ``flange`` link, whose x points
out of the flange), ``camera_optical_frame`` (z forward, x right, y down) and ``board``."""

_ROLES = {"eye-in-hand": (("flange", "camera"), ("base", "board")),
          "eye-to-hand": (("base", "camera"), ("flange", "board"))}  # fmt: skip


@dataclass(frozen=True)
class StaticTransform:
    """``T`` (4, 4) m: the ``child`` frame's pose in the ``parent`` frame (roles of
    :data:`FRAME_NAMES`), ``what`` it is in words; ``sigma_rotation_rad`` (3,) about the parent's
    axes and ``sigma_xyz_m`` (3,) along them, or None when the calibration has none."""

    what: str
    parent: str
    child: str
    T: np.ndarray
    sigma_rotation_rad: np.ndarray | None
    sigma_xyz_m: np.ndarray | None


@dataclass(frozen=True)
class HandEyeExport:
    """The ``setup``, the ``transforms`` (the hand-eye first, then the board mount when the
    calibration has one), ``source`` (the file) and ``note`` (what the calibration identified and
    how the sigmas were obtained)."""

    setup: str
    transforms: tuple[StaticTransform, ...]
    source: str
    note: str


def frame_names(text: str | None) -> dict[str, str]:
    """The frame names of ``--frames BASE,FLANGE,CAMERA,BOARD`` (None: :data:`FRAME_NAMES`).

    Raises:
        InputError: not four non-empty names without spaces.
    """
    if text is None:
        return dict(FRAME_NAMES)
    names = [n.strip() for n in text.split(",")]
    if len(names) != 4 or any(not n or " " in n for n in names):
        raise InputError(f"--frames {text!r}: give four frame names BASE,FLANGE,CAMERA,BOARD",
                         fix="e.g. --frames base,tool0,camera_color_optical_frame,board")  # fmt: skip
    return dict(zip(FRAME_NAMES, names, strict=True))


def from_handeye_document(doc: Mapping, source: str) -> HandEyeExport:
    """The export of a pose dataset's ``calibration.json`` document (as
    :func:`selfcal.calibration.handeye.calibration_file.read_handeye` returns it): its calibrated hand-eye and
    board mount with the sigmas of the fit's covariance."""
    setup = str(doc["setup"])
    out = []
    for key, (parent, child) in zip(("hand_eye", "board_mount"), _ROLES[setup], strict=True):
        t = doc[key]
        T = as_rigid(t["matrix"], f"{source}: {key}.matrix")
        out.append(StaticTransform(str(t["transform"]), parent, child, T,
                                   np.radians(np.array(t["sigma_rotation_deg"], float)),
                                   np.array(t["sigma_xyz_mm"], float) / 1000.0))  # fmt: skip
    note = ("camera, hand-eye and board mount fitted on corner reprojection from the robot's "
            "flange poses; no kinematics identified (the poses are taken as the robot reports "
            "them); sigmas from the fit's covariance")  # fmt: skip
    return HandEyeExport(setup, tuple(out), source, note)


def _last_row_sigmas(model: MCPCModel, robot: RobotDef, std: Mapping[str, float]):
    """First-order sigmas ``(rotation, translation)`` of flange -> camera from the sigmas (rad,
    m) of the last MCPC row's six parameters, taken as independent (calibration.json stores no
    covariance); a parameter without one (held) counts as exact. None without any."""
    n = model.n
    names = [f"{c}{n}" for c in ("alpha", "beta", "gamma", "lx", "ly", "lz")]
    if not any(k in std for k in names):
        return None
    s = np.array([std.get(k, 0.0) for k in names], float)
    T0 = flange_tool(model, robot)
    J = np.zeros((6, 6))
    for j in range(6):
        h = 1e-7
        p = model.params.copy()
        p[n, j] += h
        T = flange_tool(model.with_params(p), robot)
        w = Rotation.from_matrix(T[:3, :3] @ T0[:3, :3].T).as_rotvec()
        J[:, j] = np.r_[w, T[:3, 3] - T0[:3, 3]] / h
    sd = np.sqrt(np.sum((J * s) ** 2, axis=1))
    return sd[:3], sd[3:]


def from_chain(model: MCPCModel, robot: RobotDef, std: Mapping[str, float], source: str, *,
               board: bool, sigma_source: str = "standard deviations") -> HandEyeExport:  # fmt: skip
    """The export of a calibration with joints: ``model`` the identified chain whose tool is the
    camera (world: the board frame when ``board``, else any), ``std`` the minimal parameters'
    sigmas by name (rad, m), ``sigma_source`` what they are. Flange -> camera with first-order
    sigmas from the last row's parameters; with ``board`` also base -> board (no sigma: the base
    frame is rebuilt on the identified axes 1 and 2, whose covariance the calibration does not
    store) -- unless joint 1 or 2 is prismatic or their axes are parallel (an arm on a track, a
    SCARA): no base frame can be rebuilt then, flange -> camera is exported alone and ``note``
    says so."""
    sig = _last_row_sigmas(model, robot, std)
    out = [StaticTransform("flange -> camera", "flange", "camera",
                           flange_tool(model, robot),
                           None if sig is None else sig[0], None if sig is None else sig[1])]  # fmt: skip
    base = ("the base the robot's base frame rebuilt on the identified joint axes 1 and 2 (as "
            "the URDF export's base_link)")  # fmt: skip
    if board:
        try:
            T_board_base = canonical_base(model, robot)
        except ValueError as exc:
            # an arm on a track or a SCARA: its axes 1 and 2 fix no base frame
            base = (f"no base -> board: the robot's base frame cannot be rebuilt on the identified "
                    f"axes ({exc}); the calibration's chain is in the board frame "
                    "(calibration.json), flange -> camera alone is exported")  # fmt: skip
        else:
            out.append(StaticTransform("base -> board", "base", "board", inv_pose(T_board_base),
                                       None, None))  # fmt: skip
    note = (f"kinematics of {robot.name} identified with the camera; the flange is the nominal "
            f"flange of the last joint on the identified last link, {base}; "
            f"flange -> camera sigmas to first order from the {sigma_source} of the last "
            "link's six parameters taken as independent")  # fmt: skip
    return HandEyeExport("eye-in-hand", tuple(out), source, note)


def from_mounts(mounts: Sequence, source: str) -> HandEyeExport:
    """The export of an eye-to-hand board calibration with joints: its ``mounts``
    (:class:`selfcal.io.board_calibration.Mount`: base -> camera, flange -> board, sigmas from the
    Cramer-Rao covariance at the estimate)."""
    out = tuple(StaticTransform(m.what, m.parent, m.child, m.T, m.sigma_rotation_rad,
                                m.sigma_xyz_m) for m in mounts)  # fmt: skip
    note = ("camera, base -> camera, flange -> board and the kinematics the data support fitted "
            "on corner reprojection from the joint readings; base: the robot's base frame "
            "rebuilt on the identified joint axes 1 and 2, flange: the nominal flange of the last "
            "joint on the identified last link; sigmas to first order from the Cramer-Rao "
            "covariance at the estimate")  # fmt: skip
    return HandEyeExport("eye-to-hand", out, source, note)


def _quat(T: np.ndarray) -> np.ndarray:
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    return -q if q[3] < 0 else q


def _nums(v) -> str:
    return "[" + ", ".join(_f(x) for x in np.asarray(v, float).ravel()) + "]"


def _sigma_lines(t: StaticTransform, indent: str) -> list[str]:
    if t.sigma_xyz_m is None or t.sigma_rotation_rad is None:
        return [f"{indent}sigma: null  # the calibration gives no sigma for this transform"]
    return [f"{indent}sigma_xyz_mm: {_nums(t.sigma_xyz_m * 1000.0)}  # along the parent's axes",
            f"{indent}sigma_rotation_deg: {_nums(np.degrees(t.sigma_rotation_rad))}"
            "  # about the parent's axes"]  # fmt: skip


def _header(ex: HandEyeExport, frames: Mapping[str, str], what: str) -> list[str]:
    return [f"# {what}, written by scorbot-selfcal (selfcal.export.handeye).",
            f"# Source: {ex.source}; setup {ex.setup}.", f"# {ex.note}.",
            "# Each transform: the child frame's pose in the parent frame (metres); frames: "
            + ", ".join(f"{r} = {n}" for r, n in frames.items()) + ".",
            "# The camera frame is the optical frame (z forward, x right, y down); base and "
            "flange are the frames the robot reports its flange poses in."]  # fmt: skip


def _args(t: StaticTransform, frames: Mapping[str, str]) -> tuple[str, str]:
    """ROS 2 and ROS 1 ``static_transform_publisher`` arguments of ``t``."""
    x, y, z = (_f(v) for v in t.T[:3, 3])
    qx, qy, qz, qw = (_f(v) for v in _quat(t.T))
    p, c = frames[t.parent], frames[t.child]
    ros2 = (f"--x {x} --y {y} --z {z} --qx {qx} --qy {qy} --qz {qz} --qw {qw} "
            f"--frame-id {p} --child-frame-id {c}")  # fmt: skip
    return ros2, f"{x} {y} {z} {qx} {qy} {qz} {qw} {p} {c}"


def to_tf_yaml(ex: HandEyeExport, frames: Mapping[str, str] = FRAME_NAMES) -> str:
    """The transforms as ROS tf: per transform its parent and child frame, translation (m),
    quaternion, sigmas and the ``static_transform_publisher`` command lines of ROS 2 and ROS 1,
    then a ROS 2 launch XML and a ROS 1 launch file publishing all of them (YAML text)."""
    lines = _header(ex, frames, "Static transforms for ROS tf")
    lines += [f"setup: {ex.setup}", "transforms:"]
    nodes2, nodes1 = [], []
    for t in ex.transforms:
        ros2, ros1 = _args(t, frames)
        node = f"{frames[t.parent]}_to_{frames[t.child]}"
        nodes2.append(f'    <node pkg="tf2_ros" exec="static_transform_publisher" '
                      f'name="{node}" args="{ros2}"/>')  # fmt: skip
        nodes1.append(f'    <node pkg="tf2_ros" type="static_transform_publisher" '
                      f'name="{node}" args="{ros1}"/>')  # fmt: skip
        q = _quat(t.T)
        lines += [f'  - what: "{t.what}"', f"    parent: {frames[t.parent]}",
                  f"    child: {frames[t.child]}",
                  f"    translation: {{x: {_f(t.T[0, 3])}, y: {_f(t.T[1, 3])}, z: {_f(t.T[2, 3])}}}",
                  f"    rotation: {{x: {_f(q[0])}, y: {_f(q[1])}, z: {_f(q[2])}, w: {_f(q[3])}}}",
                  *_sigma_lines(t, "    "),
                  f"    ros2: ros2 run tf2_ros static_transform_publisher {ros2}",
                  f"    ros1: rosrun tf2_ros static_transform_publisher {ros1}"]  # fmt: skip
    lines += ["launch_ros2_xml: |", "  <launch>", *nodes2, "  </launch>",
              "launch_ros1: |", "  <launch>", *nodes1, "  </launch>"]  # fmt: skip
    return "\n".join(lines) + "\n"


def to_easy_handeye_yaml(ex: HandEyeExport, frames: Mapping[str, str] = FRAME_NAMES,
                         namespace: str | None = None) -> str:  # fmt: skip
    """The hand-eye as easy_handeye's saved calibration (``~/.ros/easy_handeye/NAME.yaml``:
    ``parameters`` and ``transformation`` with ``x y z qx qy qz qw``, from the effector
    (eye-on-hand) or the robot base (eye-on-base) to the tracking base frame, the camera); the
    board mount and the sigmas go under ``scorbot_selfcal``, which easy_handeye ignores."""
    he = ex.transforms[0]
    on_hand = ex.setup == "eye-in-hand"
    ns = namespace or f"/selfcal_eye_on_{'hand' if on_hand else 'base'}/"
    q = _quat(he.T)
    lines = _header(ex, frames, "easy_handeye calibration")
    lines += ["parameters:", f"  eye_on_hand: {'true' if on_hand else 'false'}",
              "  move_group: manipulator", "  move_group_namespace: /", f"  namespace: {ns}",
              f"  robot_base_frame: {frames['base']}", f"  robot_effector_frame: {frames['flange']}",
              f"  tracking_base_frame: {frames['camera']}",
              f"  tracking_marker_frame: {frames['board']}", "transformation:",
              *(f"  {k}: {_f(v)}" for k, v in zip(("x", "y", "z"), he.T[:3, 3], strict=True)),
              *(f"  {k}: {_f(v)}" for k, v in zip(("qx", "qy", "qz", "qw"), q, strict=True)),
              "scorbot_selfcal:", f'  hand_eye: "{he.what}"', *_sigma_lines(he, "  ")]  # fmt: skip
    for t in ex.transforms[1:]:
        lines += [f'  board_mount: "{t.what}"', f"  board_mount_parent: {frames[t.parent]}",
                  f"  board_mount_matrix: [{', '.join(_nums(r) for r in t.T)}]",
                  *_sigma_lines(t, "  board_mount_")]  # fmt: skip
    return "\n".join(lines) + "\n"


def euler_rpy(T: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad) of ``T``'s rotation, fixed axes X-Y-Z: ``R = Rz(yaw) Ry(pitch)
    Rx(roll)`` (URDF's ``rpy``, tf's ``getRPY``)."""
    return Rotation.from_matrix(np.asarray(T)[:3, :3]).as_euler("xyz")


def to_matrix_yaml(ex: HandEyeExport, frames: Mapping[str, str] = FRAME_NAMES) -> str:
    """Each transform as a plain 4x4 (m), translation (mm), quaternion (xyzw) and Euler angles
    (deg; roll, pitch, yaw about fixed X, Y, Z: ``R = Rz(yaw) Ry(pitch) Rx(roll)``), with its
    sigmas (YAML text, one mapping per transform)."""
    lines = _header(ex, frames, "Hand-eye transforms as matrices")
    lines += [f"setup: {ex.setup}", "transforms:"]
    for t in ex.transforms:
        lines += [f'  - what: "{t.what}"', f"    parent: {frames[t.parent]}",
                  f"    child: {frames[t.child]}", "    matrix:  # T_parent_child, metres",
                  *(f"      - {_nums(r)}" for r in t.T),
                  f"    translation_mm: {_nums(t.T[:3, 3] * 1000.0)}",
                  f"    quaternion_xyzw: {_nums(_quat(t.T))}",
                  f"    euler_rpy_deg: {_nums(np.degrees(euler_rpy(t.T)))}"
                  "  # fixed X-Y-Z: R = Rz(yaw) Ry(pitch) Rx(roll)",
                  *_sigma_lines(t, "    ")]  # fmt: skip
    return "\n".join(lines) + "\n"
