"""The robot chain a bag carries as transforms (``selfcal export DATASET --bag``): the calibrated
chain when the dataset folder holds a ``calibration.json`` (field or board), else the nominal
one, in the frames of the exported URDF (:func:`selfcal.export.urdf.to_urdf`, base frame =
``base_link``): ``/tf_static`` holds its fixed edges (the last link -> ``tool_tip``, the last link
-> the first camera, ``cam_left`` -> ``cam_right``) and ``/tf`` the moving ones (``base_link`` ->
``link1`` -> ... at every joint state). The images' ``frame_id`` is the camera's frame in that
tree, the URDF's link (:func:`selfcal.export.urdf.camera_frame_names`): ``camera_optical_frame``
for a dataset of one camera, ``cam_left`` and ``cam_right`` for a rig's first two (OpenCV/ROS
optical frames); a further camera keeps its name and has no transform. Metres,
``T_parent_child``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.export.deploy import DeployedModel, as_rigid, body_poses, deploy, deploy_chain
from selfcal.export.urdf import camera_frame_names
from selfcal.io.board_calibration import calibration_kind, read_board_calibration
from selfcal.io.calibration import read_calibration
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import RobotDef
from selfcal.transforms import rot_z, trans

__all__ = ["camera_frames", "bag_chain", "static_edges", "moving_edges"]

Edge = tuple[str, str, np.ndarray]
"""``(parent, child, T_parent_child)`` (4, 4), metres."""


def camera_frames(cameras: tuple[str, ...]) -> dict[str, str]:
    """Each camera's ``frame_id`` (in the dataset's camera order): its URDF link for the first
    two (:func:`selfcal.export.urdf.camera_frame_names`), else its own name."""
    links = camera_frame_names(len(cameras))
    return {c: links[k] if k < len(links) else c for k, c in enumerate(cameras)}


def bag_chain(root: Path, robot: RobotDef) -> tuple[DeployedModel, bool]:
    """The chain of the dataset folder ``root`` in the robot's base frame, and whether it is
    calibrated (``root/calibration.json``) or the nominal one."""
    cal = Path(root) / "calibration.json"
    if not cal.is_file():
        nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
        return deploy_chain(nominal, robot, source="nominal robot model"), False
    if calibration_kind(cal) == "board":
        res = read_board_calibration(cal)
        T_lr = None if res.T_first_cam is None else as_rigid(res.T_first_cam[1], "T_first_camera")
        return deploy_chain(res.model, robot, T_left_right=T_lr, source=str(cal)), True
    return deploy(read_calibration(cal), robot, source=str(cal)), True


def _links(n: int) -> list[str]:
    return ["base_link"] + [f"link{k + 1}" for k in range(n)]


def static_edges(dep: DeployedModel, cameras: tuple[str, ...]) -> list[Edge]:
    """The chain's fixed edges (``/tf_static``) in the frames of the dataset's ``cameras``
    (:func:`camera_frames`)."""
    n = dep.model.n
    tip = body_poses(dep.model)[n]
    last = _links(n)[-1]
    links = list(camera_frames(cameras).values())
    edges = [(last, "tool_tip", tip), (last, links[0], tip @ dep.T_tip_cam)]
    if len(links) > 1 and dep.T_left_right is not None and np.isfinite(dep.T_left_right).all():
        edges.append((links[0], links[1], np.asarray(dep.T_left_right, float)))
    return edges


def moving_edges(dep: DeployedModel, q: np.ndarray) -> list[Edge]:
    """The chain's joint edges at the joint readings ``q`` (n,) rad / m (``/tf``)."""
    poses, links = body_poses(dep.model), _links(dep.model.n)
    out = []
    for k, kind in enumerate(dep.model.joint_types):
        move = rot_z(q[k]) if kind == "revolute" else trans(np.array([0.0, 0.0, q[k]]))
        out.append((links[k], links[k + 1], poses[k] @ move))
    return out
