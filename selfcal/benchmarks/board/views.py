"""A board of known geometry projected into a *field* scenario's truth (no board scenario needed).

The truth is a marker-field scenario's (default ``scenarios/mono.toml``: one camera with the
issue's lens), acquired on the analytic path; :func:`board_pose` lays a ChArUco board (11 x 8
inner corners, 20 mm squares) where the marker field lies and :func:`board_views` projects its
corners with the true camera at the true poses, plus Gaussian noise. Used by the hand-eye
benchmark (:mod:`selfcal.benchmarks.handeye`) and ``tests/integration/test_board_robot.py``.
A board *scenario* (``[target] board``) is simulated by the backends themselves
(:func:`selfcal.sim.analytic.project_board`), and its Monte Carlo is ``selfcal montecarlo``.
"""

from __future__ import annotations

import numpy as np

from selfcal.camera import CameraModel
from selfcal.config.scenario import scenarios_dir
from selfcal.sim.actual import marker_field_of
from selfcal.target import Charuco, Features
from selfcal.transforms import inv_pose, make_pose

__all__ = ["BOARD", "MONO", "board_pose", "board_views"]

BOARD = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")
MONO = scenarios_dir() / "mono.toml"


def board_pose(truth, board: Charuco = BOARD) -> np.ndarray:
    """``T_world_board``: the board printed face up (board z down), centred on the marker
    field of ``truth`` (:class:`selfcal.io.truth.Truth`; world, m)."""
    centre = marker_field_of(truth).T_world_marker[:, :3, 3].mean(axis=0)
    _, pts = board.layout()
    size = pts.max(axis=0) + pts.min(axis=0)  # the corners' extent plus one square each side
    return make_pose(
        np.diag([1.0, -1.0, -1.0]), [centre[0] - size[0] / 2, centre[1] + size[1] / 2, 0.0]
    )


def board_views(
    truth,
    indices,
    camera: CameraModel,
    T_world_board: np.ndarray,
    sigma_px: float,
    seed: int,
    board: Charuco = BOARD,
) -> tuple[list[Features], np.ndarray]:
    """The board's corners seen by the left camera in the frames ``indices`` of ``truth``
    (true poses, ``camera`` the true model), in the image, plus Gaussian noise of ``sigma_px``
    px; and the frames' true joints (m, n) rad."""
    ids, pts = board.layout()
    rng = np.random.default_rng(seed)
    feats, q = [], []
    for i in indices:
        fr = truth.frame(int(i))
        assert fr is not None
        T = inv_pose(fr.T_world_cam_left) @ T_world_board
        Xc = pts @ T[:3, :3].T + T[:3, 3]
        uv = camera.project(Xc)
        ok = camera.in_image(uv, 2.0) & camera.valid(Xc)
        feats.append(Features(ids[ok], uv[ok] + rng.normal(0, sigma_px, (int(ok.sum()), 2))))
        q.append(fr.joints_rad)
    return feats, np.asarray(q)
