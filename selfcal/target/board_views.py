"""Camera poses that look at a board: the views of a simulated or planned board calibration."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.target.boards import Board
from selfcal.transforms import make_pose

__all__ = ["random_board_poses"]


def random_board_poses(
    board: Board,
    n: int,
    seed: int,
    *,
    distance_m: tuple[float, float] = (0.35, 0.55),
    tilt_deg: float = 35.0,
    offset_m: float = 0.02,
) -> list[np.ndarray]:
    """``n`` poses ``T_cam_board`` (4, 4; board -> OpenCV camera, m) of a camera in front of the
    printed side of ``board``: its optical axis through the board's centre (shifted by a
    Gaussian ``offset_m`` in x and y), at a depth uniform in ``distance_m``, tilted uniformly up
    to ``tilt_deg`` about the camera's x and y axes and turned uniformly about its optical axis
    (random generator seeded with ``seed``)."""
    rng = np.random.default_rng(seed)
    c = board.layout()[1].mean(axis=0)
    out = []
    for _ in range(n):
        ang = [rng.uniform(-tilt_deg, tilt_deg), rng.uniform(-tilt_deg, tilt_deg)]
        R = Rotation.from_euler("xyz", [*ang, rng.uniform(-180, 180)], degrees=True).as_matrix()
        t = np.array([*rng.normal(0, offset_m, 2), rng.uniform(*distance_m)]) - R @ c
        out.append(make_pose(R, t))
    return out
