"""A URDF of a deployed model (kinematics only): :func:`to_urdf`. Frames and units: :mod:`selfcal.export.deploy`."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.errors import UsageError
from selfcal.export.deploy import BASE_FRAME, TOOL_FRAME, DeployedModel, body_poses
from selfcal.export.deploy import float_text as _f

__all__ = ["MONO_FRAME", "STEREO_FRAMES", "camera_frame_names", "to_urdf"]

MONO_FRAME = "camera_optical_frame"
"""The exported URDF's link (and a bag's ``frame_id``) of a single camera: its optical frame
(REP 103's ``_optical`` suffix: z forward, x right, y down); a lone camera is not a left one."""
STEREO_FRAMES = ("cam_left", "cam_right")
"""The links of a rig's first two cameras (the ROS stereo convention: the first is the left)."""


def camera_frame_names(cameras: int) -> tuple[str, ...]:
    """The URDF links of the first ``cameras`` cameras' optical frames, at most two (a further
    camera of a rig has no link: a bag names it by its own name): :data:`MONO_FRAME` for one,
    :data:`STEREO_FRAMES` for two or more."""
    if cameras < 1:
        raise UsageError(f"cameras must be at least 1, got {cameras}")
    return (MONO_FRAME,) if cameras == 1 else STEREO_FRAMES


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


def to_urdf(
    dep: DeployedModel,
    *,
    effort: float = 10.0,
    velocity: float = 1.0,
    calibrated: bool = True,
    cameras: int | None = None,
) -> str:
    """A URDF of the calibrated chain (kinematics only: no visuals, no inertias).

    ``base_link`` is the base frame; joint ``k`` (named like the robot's joint, e.g. ``shoulder``)
    moves ``link<k>`` about (revolute) or along (prismatic) its z-axis, with its ``<origin>`` = the
    link's frame in its parent's at reading 0, so URDF joint positions = the controller's joint
    readings (rad / m) and the link frames are the MCPC link frames (= the exported MJCF's bodies).
    Fixed joints add ``tool_tip`` (on the last link) and the first camera's optical frame
    (OpenCV/ROS optical convention: z forward, x right, y down; on the last link):
    ``camera_optical_frame`` for a single camera, ``cam_left`` for a rig's first, and, when the
    calibration has the rig, ``cam_right`` (on ``cam_left``) (:func:`camera_frame_names`; each
    joint is its link's name + ``_joint``). ``cameras``: how many cameras the dataset has (a
    bag's nominal URDF of a stereo dataset names ``cam_left``); default 2 with the rig, else 1.
    ``effort`` (N m) and ``velocity`` (rad/s) are placeholders the URDF format requires; the
    controller enforces the real ones. ``calibrated=False``: ``dep`` is the nominal robot (named
    so, robot name without suffix).
    """
    m = dep.model
    n = m.n
    root = ET.Element("robot", name=dep.robot_name + ("_calibrated" if calibrated else ""))
    root.append(
        ET.Comment(
            f" {'Calibrated' if calibrated else 'Nominal'} {dep.robot_name} (scorbot-selfcal selfcal.export.deploy; source: "
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
    rig = dep.T_left_right
    names = camera_frame_names(max(cameras or 0, 1 if rig is None else 2))
    _fixed(root, f"{names[0]}_joint", links[-1], names[0], poses[n] @ dep.T_tip_cam)
    ET.SubElement(root, "link", name=names[0])
    if rig is not None:
        _fixed(root, f"{names[1]}_joint", names[0], names[1], rig)
        ET.SubElement(root, "link", name=names[1])
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
