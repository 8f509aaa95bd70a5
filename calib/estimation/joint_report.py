"""What the one-step refinement reports: calibration-document fields and covariance propagation.

Works on a :class:`calib.estimation.joint_result.JointRefinementResult` (SI units, world = the
left camera of the reference configuration): the tool-point covariance and its aligned-RMS
bound, the robot's encoder noise, and the calibration document with the joint result as the
final one.
"""

from __future__ import annotations

import copy
import warnings

import numpy as np

from calib.estimation.joint_result import JointRefinementResult
from calib.identify import express_in_frame, minimal_difference, to_dh
from calib.kinematics import fk_tool, identification_jacobian
from calib.mcpc import MCPCModel, dh_to_mcpc, minimal_indices, param_is_angle, shape_matrices
from calib.transforms import inv_pose, rot_z, skew

__all__ = [
    "express_in_reference",
    "tool_point_covariance",
    "encoder_sigma",
    "method_summary",
    "joint_document",
    "aligned_tool_rms_bound",
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
    parameters of that frame (central differences, step ``h``). SI units."""
    theta0 = model_g.params.reshape(-1)[free_idx]

    def to_ref_frame(theta: np.ndarray) -> MCPCModel:
        flat = model_g.params.reshape(-1).copy()
        flat[free_idx] = theta
        mg = model_g.with_params(flat)
        return express_in_frame(mg, inv_pose(fk_tool(mg, q_ref)[0]), like=like)

    model_ref = to_ref_frame(theta0)
    k = len(free_idx)
    Hm = np.empty((minimal_indices(like.joint_types).size, k))
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
    """Standard deviation (n,) rad / m of a read-back rounded to the nearest encoder count,
    ``1 / (counts_per_unit sqrt(12))``; None if the robot has no finite encoder resolution."""
    cpu = np.asarray(getattr(robot, "counts_per_unit", np.full(robot.n, np.inf)), dtype=float)
    if not np.all(np.isfinite(cpu) & (cpu > 0)):
        return None
    return 1.0 / (cpu * np.sqrt(12.0))


def method_summary(doc: dict) -> dict:
    """The method-specific part of a calibration document (for ``document["methods"]``)."""
    keys = ("intrinsics", "rig", "reprojection_rms_px", "observations", "hand_eye", "parameters")
    out = {k: doc[k] for k in keys if k in doc}
    out["mcpc_params_si"] = doc["mcpc"]["params_si"]
    return out


def _round(T: np.ndarray, digits: int = 9) -> list:
    return np.round(np.asarray(T, dtype=float), digits).tolist()


def joint_document(doc: dict, res: JointRefinementResult, robot) -> dict:
    """A copy of the two-stage calibration document with the joint result as the final one.

    Replaced: intrinsics, rig, reprojection RMS, observations, hand-eye, parameters (estimate,
    std in the reference-camera frame), mcpc, dh, camera poses. Added: ``joint`` (gauge, rank,
    iterations, time, noise levels). ``identification`` still describes the two-stage start.
    """
    out = copy.deepcopy(doc)
    model = res.model
    out["intrinsics"].update(
        {
            "fx": res.fx,
            "fy": res.fx * res.mu,
            "mu": res.mu,
            "fx_std": res.fx_std,
            "mu_std": res.mu_std,
        }
    )
    out["rig"] = {"T_left_right_m": _round(res.T_left_right)}
    out["reprojection_rms_px"] = res.rms_px
    out["observations"] = {"inliers": res.n_inliers, "outliers": res.n_outliers}
    idx = minimal_indices(model.joint_types)
    ang = param_is_angle(idx)
    params = []
    for j, (name, k, a) in enumerate(zip(res.names, idx, ang)):
        s = 180.0 / np.pi if a else 1000.0
        params.append(
            {
                "name": name,
                "unit": "deg" if a else "mm",
                "estimate": float(model.params.reshape(-1)[k] * s),
                "std": float(res.std[j] * s) if np.isfinite(res.std[j]) else None,
                "held": name in res.held_reason and not res.held_reason[name].startswith("gauge"),
            }
        )
    out["parameters"] = params

    def last_link_to_tool(mdl: MCPCModel) -> np.ndarray:
        return rot_z(mdl.joint_offsets[-1]) @ shape_matrices(mdl.params[-1])

    T_flange_cam = inv_pose(last_link_to_tool(dh_to_mcpc(robot))) @ last_link_to_tool(model)
    out["hand_eye"] = {"T_flange_cam_m": _round(T_flange_cam)}
    out["mcpc"].update(
        {"joint_offsets_rad": model.joint_offsets.tolist(), "params_si": model.params.tolist()}
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dh = to_dh(model, robot)
    if dh is None:
        out["dh"] = None
        out["dh_note"] = "; ".join(str(w.message) for w in caught) or "not representable"
    else:
        out["dh"] = {
            "rows": [
                {
                    "theta_offset_deg": np.degrees(o),
                    "d_mm": d * 1000,
                    "a_mm": a_ * 1000,
                    "alpha_deg": np.degrees(al),
                }
                for o, d, a_, al in dh.rows()
            ]
        }
        out["dh_note"] = None
    frames = np.asarray(out["camera_poses"]["frame_index"])
    used = res.diagnostics.get("used_configs")
    if used is not None and len(used) == len(frames):
        out["camera_poses"]["T_world_cam_left_m"] = [_round(T) for T in res.T_world_cam[used, 0]]
    out["joint"] = {
        "gauge_held": list(res.gauge.held),
        "gauge_method": res.gauge.method,
        "gauge_condition_number": res.gauge.condition_number,
        "held": {n: r for n, r in res.held_reason.items()},
        "rank": res.rank,
        "n_unknowns": res.n_unknowns,
        "rank_min_singular_scaled": res.rank_min_singular,
        "iterations": res.iterations,
        "rounds": res.rounds,
        "converged": res.converged,
        "sigma_px": res.sigma_px,
        "pixel_sigma_prior_px": res.diagnostics.get("pixel_sigma_px"),
        "joint_sigma": res.diagnostics.get("joint_sigma"),
        "joint_correction_rms": res.diagnostics.get("joint_correction_rms"),
        "scale_residual_m": res.diagnostics.get("scale_residual_m"),
        "note": (
            "one-step maximum-likelihood refinement (calib.joint_refine) started from the "
            "two-stage result; parameters and std are in the reference-camera frame like the "
            "two-stage ones; 'identification' describes the two-stage start"
        ),
    }
    return out


def aligned_tool_rms_bound(
    res: JointRefinementResult, q: np.ndarray, T_cam_point: np.ndarray
) -> float:
    """Predicted RMS (m) of a camera-attached point's error over postures ``q`` (k, n) *after*
    the best rigid alignment (the validation metric of :mod:`calib.report`), from the parameter
    covariance (first order): ``sqrt(trace(P S P) / k)`` with ``S`` the (3k, 3k) covariance of
    the stacked points (:func:`tool_point_covariance` with cross terms) and ``P`` the projector
    removing rigid motions. With the a-posteriori noise level this is the Cramer-Rao bound of
    the metric for an unbiased estimator."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(res.model.joint_types)
    T = fk_tool(res.model, q)
    Jb = identification_jacobian(res.model, q)[:, :, idx]
    pt = np.asarray(T_cam_point, dtype=float)[:3, 3]
    Jp = (T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])).reshape(-1, idx.size)
    S = Jp @ np.nan_to_num(res.covariance) @ Jp.T
    P_world = (T @ np.asarray(T_cam_point, dtype=float))[:, :3, 3]
    c = P_world - P_world.mean(axis=0)
    rigid = np.concatenate(
        [np.tile(np.eye(3), (len(q), 1)), -skew(c).reshape(-1, 3)], axis=1
    )  # (3k, 6): translation, rotation about the centroid
    Q, _ = np.linalg.qr(rigid)
    P = np.eye(len(S)) - Q @ Q.T
    return float(np.sqrt(max(np.trace(P @ S @ P), 0.0) / len(q)))
