"""Where a board is: its pose in the robot's base frame from a user's six numbers.

The user states the centre of the board's printed image (:meth:`selfcal.target.boards.Board.image`'s
extent) in the base frame and a rotation that turns the board from lying printed face up with its
columns along the base's x axis (rotations about the base's fixed x, y, z axes, in that order:
``R = Rz Ry Rx``, the ``rpy`` of ``selfcal fk``). The board frame itself
(:mod:`selfcal.target.boards`) has z into the board, so the face-up board's frame is the base frame
turned by 180 degrees about x. Units: m and rad.
"""

from __future__ import annotations

import numpy as np

from selfcal.target.boards import Board
from selfcal.transforms import make_pose, rot_x, rot_y, rot_z

__all__ = ["FACE_UP", "board_pose", "board_centre", "board_pose_values"]

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
