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


def board_residuals(poses, fs: list[Features], pixel_sigma_px: float = 0.2):
    """The board refinement's problem (the lab's camera and board, the chain ``poses``, a
    :class:`selfcal.estimation.kinematic_poses.KinematicPoses`) on the features ``fs`` of its
    frames, exact joint readings: its residuals (px) at its start and the problem."""
    from selfcal.calibration.board.problem import board_problem

    frame = np.concatenate([np.full(len(f), i) for i, f in enumerate(fs)]).astype(int)
    rows = [(poses.layout.view(frame, 0), np.concatenate([f.ids for f in fs]),
             np.concatenate([f.uv for f in fs]))]  # fmt: skip
    prob = board_problem([CAMERA], poses, rows, BOARD, pixel_sigma_px=pixel_sigma_px,
                         joint_sigma=None, n_frames=len(fs))  # fmt: skip
    return prob.problem.residual_vector(prob.problem.x0), prob
