"""What the one-step refinement reports: covariance propagation.

Works on a :class:`selfcal.estimation.joint_result.JointRefinementResult` (SI units, world = the
left camera of the reference configuration): the parameters re-expressed in the reference-camera
frame, the tool-point covariance and its aligned-RMS bound, the robot's encoder noise. The
calibration result is built from it in :func:`selfcal.calibration.field.results.with_joint`.
"""

from __future__ import annotations

import numpy as np

from selfcal.estimation.joint_result import JointRefinementResult
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices
from selfcal.transforms import inv_pose, skew

__all__ = [
    "express_in_reference",
    "tool_point_covariance",
    "encoder_sigma",
    "aligned_tool_rms_bound",
    "aligned_tool_weight",
]


def express_in_reference(
    model_g: MCPCModel,
    free_idx: np.ndarray,
    q_ref: np.ndarray,
    like: MCPCModel,
    cov_free: np.ndarray,
    h: float = 1e-7,
) -> tuple[MCPCModel, np.ndarray]:
    """The chain ``model_g`` (optimisation gauge) re-expressed with the world at its tool (left
    camera) at joints ``q_ref`` (1, n), in ``like``'s joint-offset convention, and the
    covariance ``cov_free`` of its free flat parameters ``free_idx`` propagated to all minimal
    parameters of that frame (central differences, step ``h``). SI units. A ``cov_free``
    without a finite entry (no covariance computed: the fair nominal's refinement) gives the
    all-NaN covariance it propagates to, without the differences (2 chains re-expressed per
    free parameter)."""
    theta0 = model_g.params.reshape(-1)[free_idx]

    def to_ref_frame(theta: np.ndarray) -> MCPCModel:
        flat = model_g.params.reshape(-1).copy()
        flat[free_idx] = theta
        mg = model_g.with_params(flat)
        return express_in_frame(mg, inv_pose(fk_tool(mg, q_ref)[0]), like=like)

    model_ref = to_ref_frame(theta0)
    k = len(free_idx)
    n_min = minimal_indices(like.joint_types).size
    if k and not np.isfinite(cov_free).any():
        return model_ref, np.full((n_min, n_min), np.nan)
    Hm = np.empty((n_min, k))
    for j in range(k):
        e_ = np.zeros(k)
        e_[j] = h
        Hm[:, j] = (
            minimal_difference(to_ref_frame(theta0 + e_), model_ref)
            - minimal_difference(to_ref_frame(theta0 - e_), model_ref)
        ) / (2 * h)
    return model_ref, Hm @ cov_free @ Hm.T


def tool_point_covariance(
    res: JointRefinementResult, q: np.ndarray, T_cam_point: np.ndarray
) -> np.ndarray:
    """Covariance (k, 3, 3) m^2 of a point rigidly attached to the camera (e.g. the tool tip,
    ``T_cam_point`` (4, 4)) at joints ``q`` (k, n), from the parameter covariance (first order,
    reference-camera frame). The Cramer-Rao bound of the predicted tool tip when the noise model
    is right."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(res.model.joint_types)
    T = fk_tool(res.model, q)
    Jb = identification_jacobian(res.model, q)[:, :, idx]  # body twist of the camera
    pt = np.asarray(T_cam_point, dtype=float)[:3, 3]
    # point in world: T p; d = R (dv + dw x p) = R (dv - p x dw)
    Jp = T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])  # (k, 3, P)
    cov = np.nan_to_num(res.covariance)
    return Jp @ cov @ np.swapaxes(Jp, -1, -2)


def encoder_sigma(robot) -> np.ndarray | None:
    """Standard deviation (n,) rad / m of the joint read-back, the motors' counts rounded:
    the robot file's encoder table's (:attr:`selfcal.robot.encoder.EncoderSpec.read_back_sigma`,
    ``1 / (c sqrt 12)``, ``sqrt 2`` that of the half-count on a differential wrist); None if the
    robot has no finite encoder resolution (its joints are taken as exact)."""
    enc = getattr(robot, "encoder", None)
    return None if enc is None else np.array(enc.read_back_sigma)


def aligned_tool_weight(model: MCPCModel, q: np.ndarray, T_cam_point: np.ndarray) -> np.ndarray:
    """(k, k) the weight ``G`` of the minimal parameters' covariance ``C`` (SI, the order of
    :func:`selfcal.kinematics.mcpc.minimal_indices`) whose ``trace(G C)`` is the squared RMS of
    a camera-attached point's error over postures ``q`` (m, n) after the best rigid alignment
    (:func:`aligned_tool_rms_bound`): ``G = Jp^T P Jp / m`` with ``Jp`` (3m, k) the stacked
    points' Jacobian and ``P`` the projector removing rigid motions (m^2 per unit^2)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(model.joint_types)
    T = fk_tool(model, q)
    Jb = identification_jacobian(model, q)[:, :, idx]
    pt = np.asarray(T_cam_point, dtype=float)[:3, 3]
    Jp = (T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])).reshape(-1, idx.size)
    P_world = (T @ np.asarray(T_cam_point, dtype=float))[:, :3, 3]
    c = P_world - P_world.mean(axis=0)
    rigid = np.concatenate(
        [np.tile(np.eye(3), (len(q), 1)), -skew(c).reshape(-1, 3)], axis=1
    )  # (3m, 6): translation, rotation about the centroid
    Q, _ = np.linalg.qr(rigid)
    PJ = Jp - Q @ (Q.T @ Jp)
    return PJ.T @ PJ / len(q)


def aligned_tool_rms_bound(
    res: JointRefinementResult, q: np.ndarray, T_cam_point: np.ndarray
) -> float:
    """Predicted RMS (m) of a camera-attached point's error over postures ``q`` (k, n) *after*
    the best rigid alignment (the validation metric of :mod:`selfcal.kinematics.accuracy`), from the parameter
    covariance (first order): ``sqrt(trace(P S P) / k)`` with ``S`` the (3k, 3k) covariance of
    the stacked points (:func:`tool_point_covariance` with cross terms) and ``P`` the projector
    removing rigid motions (computed as ``trace(G C)``, :func:`aligned_tool_weight`). With the
    a-posteriori noise level this is the Cramer-Rao bound of the metric for an unbiased
    estimator."""
    G = aligned_tool_weight(res.model, q, T_cam_point)
    return float(np.sqrt(max(np.trace(G @ np.nan_to_num(res.covariance)), 0.0)))
