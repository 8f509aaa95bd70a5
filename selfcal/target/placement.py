"""Where a board is, or a static camera: a pose in the robot's base frame from a user's six numbers.

The user states the centre of the board's printed image (:meth:`selfcal.target.boards.Board.image`'s
extent) in the base frame and a rotation that turns the board from lying printed face up with its
columns along the base's x axis (rotations about the base's fixed x, y, z axes, in that order:
``R = Rz Ry Rx``, the ``rpy`` of ``selfcal fk``). The board frame itself
(:mod:`selfcal.target.boards`) has z into the board, so the face-up board's frame is the base frame
turned by 180 degrees about x. A static camera (:func:`camera_pose`): its centre in the base frame
and the rotation of its OpenCV axes (x right, y down, z along the optical axis) from the base's
axes, the same fixed-axes ``rpy``; without a rotation it looks at a given point with its image rows
level (:func:`look_at`). A board on the flange (eye-to-hand, :func:`board_on_flange`): printed face
out along the flange's z axis, as the simulated eye-to-hand cell mounts it. Units: m and rad.
"""

from __future__ import annotations

import numpy as np

from selfcal.target.boards import Board
from selfcal.transforms import make_pose, rot_x, rot_y, rot_z

__all__ = [
    "FACE_UP",
    "board_pose",
    "board_centre",
    "board_pose_values",
    "camera_pose",
    "camera_pose_values",
    "look_at",
    "board_on_flange",
]

FACE_UP = np.diag([1.0, -1.0, -1.0])
"""The board frame's rotation in the base frame for a board lying printed face up (x along x,
rows along -y, z into the board = down)."""


def board_centre(board: Board) -> np.ndarray:
    """(3,) the centre of ``board``'s printed image in the board frame (m, z = 0)."""
    x0, y0, x1, y1 = board.image(1.0).extent_m
    return np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])


def board_pose(board: Board, centre_m: np.ndarray, rpy_rad: np.ndarray | None = None) -> np.ndarray:
    """``T_base_board`` (4, 4; board -> base, m): the printed image centred at ``centre_m`` (3,)
    m, turned by ``rpy_rad`` (3,) rad (module docstring; None: face up)."""
    r = np.zeros(3) if rpy_rad is None else np.asarray(rpy_rad, dtype=float)
    R = (rot_z(r[2]) @ rot_y(r[1]) @ rot_x(r[0]))[:3, :3] @ FACE_UP
    return make_pose(R, np.asarray(centre_m, dtype=float) - R @ board_centre(board))


def board_pose_values(board: Board, T_base_board: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of :func:`board_pose`: the printed image's centre (3,) m in the base frame
    and the rotation ``rpy`` (3,) rad from face up (fixed axes x, y, z; ``R = Rz Ry Rx``)."""
    from scipy.spatial.transform import Rotation

    T = np.asarray(T_base_board, dtype=float)
    R = T[:3, :3] @ FACE_UP  # FACE_UP is its own inverse
    rpy = Rotation.from_matrix(R).as_euler("xyz")
    return T[:3, 3] + T[:3, :3] @ board_centre(board), rpy


def camera_pose(centre_m: np.ndarray, rpy_rad: np.ndarray) -> np.ndarray:
    """``T_base_cam`` (4, 4; OpenCV camera frame -> base, m): the camera's centre ``centre_m``
    (3,) m, its axes the base's turned by ``rpy_rad`` (3,) rad (fixed axes x, y, z:
    ``R = Rz Ry Rx``; zero: the optical axis along the base's z)."""
    r = np.asarray(rpy_rad, dtype=float)
    return make_pose((rot_z(r[2]) @ rot_y(r[1]) @ rot_x(r[0]))[:3, :3], np.asarray(centre_m))


def camera_pose_values(T_base_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of :func:`camera_pose`: the centre (3,) m and ``rpy`` (3,) rad."""
    from selfcal.transforms import rpy_from_matrix

    T = np.asarray(T_base_cam, dtype=float)
    return T[:3, 3].copy(), rpy_from_matrix(T[:3, :3])


def look_at(centre_m: np.ndarray, target_m: np.ndarray) -> np.ndarray:
    """``T_base_cam`` (4, 4, m) of a camera at ``centre_m`` (3,) whose optical axis passes
    through ``target_m`` (3,), its image rows level (x axis in the base's xy plane, y pointing
    down as far as it can; straight up or down: x along the base's x).

    Raises:
        InputError: the two points coincide.
    """
    from selfcal.errors import InputError

    c, t = np.asarray(centre_m, dtype=float), np.asarray(target_m, dtype=float)
    z = t - c
    if np.linalg.norm(z) < 1e-9:
        raise InputError("the camera's centre is the point it should look at",
                         fix="give the camera's rotation (RX,RY,RZ) as well")  # fmt: skip
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])  # right of the view, level
    x = np.array([1.0, 0.0, 0.0]) if np.linalg.norm(x) < 1e-9 else x / np.linalg.norm(x)
    y = np.cross(z, x)
    return make_pose(np.stack([x, y, z], axis=1), c)


def board_on_flange(board: Board, standoff_m: float = 0.05) -> np.ndarray:
    """``T_flange_board`` (4, 4, m) of ``board`` mounted on the flange with its printed face out
    (along the flange's z) and the centre of its features on the flange's axis, ``standoff_m``
    in front of the flange: board x along flange x, board z (into the board) along -z."""
    _, pts = board.layout()
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    return make_pose(FACE_UP, np.array([0.0, 0.0, standoff_m]) - FACE_UP @ centre)
