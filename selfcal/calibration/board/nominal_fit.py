"""The fair nominal of a board calibration: the nominal chain with only its placement fitted.

"Nominal" is the robot file's kinematic chain with everything but the kinematics fitted by the
same objective as the calibration: the board pose (board <- base, 6 dof), the hand-eye (flange
<- camera, 6 dof) and every camera's free parameters, fitted to the reprojection of the same
features with the same loss on the one solver (:func:`selfcal.calibration.board.refine.refine_on_board` with
the placement parameters free and every chain parameter held). A calibration is judged against
this model -- what the robot gives without calibrating its kinematics -- never against a
pose-distance proxy. The start of that fit is the closed-form placement of the nominal chain on
the camera stage's poses (:func:`place_nominal`).

Frames and units: world = board frame (m), the model's tool = the first camera (OpenCV frame);
eye-to-hand (the board on the flange) world = the first camera, tool = the board, and the
placement is base -> camera and flange -> board.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from selfcal.calibration.board.refine import BoardObservations, Refinement, refine_on_board
from selfcal.kinematics.alignment import AXIS_TIPS, fit_rigid_transform, regauge
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, chain_transforms
from selfcal.transforms import inv_pose

__all__ = ["fit_nominal", "place_nominal", "placement_indices", "standard_gauge"]


def placement_indices(n: int) -> np.ndarray:
    """Flat MCPC indices of the placement: all six parameters of ``V_0`` (world -> joint 1: the
    board pose) and of ``V_n`` (last joint -> camera: the hand-eye) of a chain of ``n`` joints;
    together they move the nominal chain rigidly in the world and the camera on the flange
    (12 dof), the chain itself held."""
    return np.r_[np.arange(6), 6 * n + np.arange(6)]


def place_nominal(nominal: MCPCModel, q: np.ndarray, T_board_cam: np.ndarray) -> MCPCModel:
    """``nominal`` (tool = the camera at its nominal mount) placed on the camera poses
    ``T_board_cam`` (m, 4, 4) at the joints ``q`` (m, n) rad (eye-to-hand: the tool the board,
    the poses the board's in the camera frame): board pose and hand-eye by
    alternating closed-form rigid fits (:func:`selfcal.kinematics.alignment.fit_rigid_transform`) from the
    nominal mount, the round whose camera positions fit best kept (with little wrist motion the
    alternation can drift off: the hand-eye is then weakly determined by the poses) -- the start
    of :func:`fit_nominal`."""
    F = fk_tool(nominal, q)

    def misfit(B: np.ndarray, C: np.ndarray) -> float:
        return float(np.sum(((B @ F @ C - T_board_cam) @ AXIS_TIPS)[:, :3] ** 2))

    C = np.eye(4)
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for _ in range(20):
        B = fit_rigid_transform(T_board_cam, F @ C)
        if best is None or misfit(B, C) < best[0]:
            best = (misfit(B, C), B, C)
        C = inv_pose(fit_rigid_transform(inv_pose(T_board_cam), inv_pose(B @ F)))
    assert best is not None
    return nominal.with_base(best[1]).with_tool(best[2])


def standard_gauge(model: MCPCModel, offsets: np.ndarray) -> MCPCModel:
    """The same chain (same tool pose at every joint vector) in the MCPC gauge
    (:func:`selfcal.kinematics.mcpc.gauge_fix`) with the joint offsets ``offsets`` (n,) rad: a fit that
    freed a whole ``V_0`` or a joint's zero offset written as the minimal parameters, so that it
    compares one to one with models in that gauge."""
    return regauge(chain_transforms(model), model.joint_types, offsets)


def fit_nominal(obs: BoardObservations, nominal: MCPCModel, *, stds: bool = True) -> Refinement:
    """The fair nominal (module docstring) from the observations ``obs`` of every frame with the
    board; its model in the MCPC gauge with ``nominal``'s joint offsets.

    Raises:
        EstimationError: the fit did not converge.
    """
    used = obs.used
    start = place_nominal(nominal, obs.q[used], obs.tool_poses()[used])
    fit = refine_on_board(obs, start, placement_indices(nominal.n), stds=stds,
                          what="the fair nominal (the nominal chain placed on the camera "
                          "stage's poses, board pose, hand-eye and cameras fitted, the chain "
                          "held)")  # fmt: skip
    return replace(fit, model=standard_gauge(fit.model, start.joint_offsets))
