"""A URDF of a deployed model (kinematics only): :func:`to_urdf`. Frames and units: :mod:`selfcal.export.deploy`."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.export.deploy import BASE_FRAME, TOOL_FRAME, DeployedModel, body_poses
from selfcal.export.deploy import float_text as _f

__all__ = ["to_urdf"]


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
    dep: DeployedModel, *, effort: float = 10.0, velocity: float = 1.0, calibrated: bool = True
) -> str:
    """A URDF of the calibrated chain (kinematics only: no visuals, no inertias).

    ``base_link`` is the base frame; joint ``k`` (named like the robot's joint, e.g. ``shoulder``)
    moves ``link<k>`` about (revolute) or along (prismatic) its z-axis, with its ``<origin>`` = the
    link's frame in its parent's at reading 0, so URDF joint positions = the controller's joint
    readings (rad / m) and the link frames are the MCPC link frames (= the exported MJCF's bodies).
    Fixed joints add ``tool_tip`` (on the last link), ``cam_left`` (the left camera's optical frame,
    OpenCV/ROS optical convention: z forward, x right, y down; on the last link) and, when the
    calibration has the rig, ``cam_right`` (on ``cam_left``). ``effort`` (N m) and ``velocity``
    (rad/s) are placeholders the URDF format requires; the controller enforces the real ones.
    ``calibrated=False``: ``dep`` is the nominal robot (named so, robot name without suffix).
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
    _fixed(root, "cam_left_joint", links[-1], "cam_left", poses[n] @ dep.T_tip_cam)
    ET.SubElement(root, "link", name="cam_left")
    if dep.T_left_right is not None:
        _fixed(root, "cam_right_joint", "cam_left", "cam_right", dep.T_left_right)
        ET.SubElement(root, "link", name="cam_right")
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
