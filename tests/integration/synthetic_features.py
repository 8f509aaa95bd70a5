"""Board features of the synthetic lab (tests/integration/synthetic_board.py) projected
analytically: the true chain's camera poses, the lens camera, Gaussian pixel noise, and only the
corners inside the image (no images drawn)."""

from __future__ import annotations

import numpy as np
from synthetic_board import BOARD, CAMERA, H, W

from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.target.base import Features
from selfcal.transforms import inv_pose


def board_features(
    model: MCPCModel, T_world_board: np.ndarray, q: np.ndarray, px: float, seed: int
) -> list[Features]:
    """The board's corners seen at the joints ``q`` (m, n) rad through ``model`` (tool = camera)
    with ``px`` pixel noise per coordinate."""
    rng = np.random.default_rng(seed)
    ids, pts = BOARD.layout()
    out = []
    for T_world_cam in fk_tool(model, np.atleast_2d(q)):
        T = inv_pose(T_world_cam) @ T_world_board
        Xc = pts @ T[:3, :3].T + T[:3, 3]
        uv = CAMERA.project(Xc) + rng.normal(0, px, (len(pts), 2))
        ok = (
            (uv[:, 0] > 0)
            & (uv[:, 0] < W - 1)
            & (uv[:, 1] > 0)
            & (uv[:, 1] < H - 1)
            & (Xc[:, 2] > 0)
        )
        out.append(Features(np.asarray(ids)[ok], uv[ok]))
    return out
