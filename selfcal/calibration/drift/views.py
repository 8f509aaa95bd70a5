"""One new view of the board linearised at a board calibration (the drift check, issue #29).

The pixels the calibration predicts for it from the joints alone, their derivatives by every
change the check considers (the estimated parameters, the camera, the chain's tool and world,
each joint's offset) and the view's own covariance (the model error, the joint read-back and
the corner noise): :mod:`selfcal.calibration.drift.images` stacks them, tests them and
:mod:`selfcal.calibration.drift.attribution` fits the changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.misfit import board_view, tip_map
from selfcal.calibration.board.view_jitter import camera_directions
from selfcal.camera import CameraModel
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.transforms import adjoint, inv_pose

__all__ = ["ViewJacobians", "view_jacobians"]


@dataclass(frozen=True)
class ViewJacobians:
    """One view linearised at the calibration (px; derivatives per m and rad).

    Attributes:
        r: (2k,) detected - predicted pixels.
        local: (2k, 2k) its own covariance (model error, per-view misfit in the pose span and
            the camera's directions, joint read-back and corner noise).
        kin: (2k, p) derivative by the estimated kinematic parameters; cam: (2k, c) by the
            camera's free parameters.
        tool: (2k, 6) by a body twist of the chain's tool (eye-in-hand the camera on the
            flange, eye-to-hand the board on it); world: (2k, 6) by a twist of the chain's
            world frame (the board, eye-to-hand the camera); joints: (2k, n) by each joint's
            offset.
        B: (6, 6) the map of a body twist of the chain's tool to the move of the tool point
            (the flange) and the rotation, world frame; Ad: (6, 6) of a world twist to a body
            twist; tw: (6, n) every joint's body twist.
        paired: ``r`` is the difference from the calibration's own frame at the same posture
            (:mod:`selfcal.calibration.drift.paired`): the calibration's estimate cancels in
            it (no ``H C H^T`` term) and ``local`` is both views' noise.
    """

    r: np.ndarray
    local: np.ndarray
    kin: np.ndarray
    cam: np.ndarray
    tool: np.ndarray
    world: np.ndarray
    joints: np.ndarray
    B: np.ndarray
    Ad: np.ndarray
    tw: np.ndarray
    paired: bool = False


def view_jacobians(em: ToolErrorModel, camera: CameraModel, q: np.ndarray, X: np.ndarray,
                   uv: np.ndarray, *, eye_to_hand: bool, pixel_sigma_px: float,
                   joint_sigma_rad: np.ndarray | None,
                   jitter: np.ndarray | None = None, camera_misfit_px: float = 0.0,
                   pose_misfit_px: float = 0.0) -> ViewJacobians:  # fmt: skip
    """The view of board points ``X`` (k, 3) (board frame, m) detected at ``uv`` (k, 2) px by
    ``camera`` at the joints ``q`` (n,) rad / m, linearised at the calibration ``em`` (its
    chain, estimated columns and model error) with the corner noise ``pixel_sigma_px``, the
    joint read-back noise ``joint_sigma_rad`` (n,) or None and the per-view jitter ``jitter``
    (6, 6) of the chain's tool pose (body twist, m and rad;
    :mod:`selfcal.calibration.board.view_jitter`) or None, with its per-view misfit
    ``camera_misfit_px`` (px) in each of the camera's directions the pose cannot mimic, and
    ``pose_misfit_px`` (px) in each direction of the view's pose span (orthonormal, in pixels:
    what the calibration's frames carry there when it is known, in place of ``jitter``)."""
    model = em.model
    T = fk_tool(model, q[None])[0]
    _, uv_hat, A, Jc = board_view(camera, T, X, eye_to_hand)
    t = np.zeros(3) if em.T_tool_point is None else np.asarray(em.T_tool_point)[:3, 3]
    B = tip_map(T, t)
    tip = A @ np.linalg.inv(B)  # pixels by a move of the tool point and a rotation (world)
    rot = 0.0 if em.model_error_rad is None else em.model_error_rad
    m2 = np.r_[np.full(3, em.model_error_m**2), np.full(3, rot**2)] * em.model_error_factor(q)[0]
    tw = joint_twists(model, q[None])[0]
    joints = A @ tw
    Ad = adjoint(inv_pose(T))
    local = (tip * m2) @ tip.T + pixel_sigma_px**2 * np.eye(len(A))
    if jitter is not None:
        local += A @ np.asarray(jitter, float) @ A.T
    if pose_misfit_px > 0.0:
        local += pose_misfit_px**2 * (A @ np.linalg.pinv(A))
    if camera_misfit_px > 0.0:
        U = camera_directions(A, Jc.reshape(len(A), -1))
        local += camera_misfit_px**2 * (U @ U.T)
    if joint_sigma_rad is not None:
        local += (joints * np.asarray(joint_sigma_rad, float) ** 2) @ joints.T
    return ViewJacobians(
        r=(np.asarray(uv, float) - uv_hat).reshape(-1),
        local=local,
        kin=A @ identification_jacobian(model, q[None])[0][:, em.columns],
        cam=Jc.reshape(len(A), -1),
        tool=A,
        world=A @ Ad,
        joints=joints,
        B=B,
        Ad=Ad,
        tw=tw,
    )
