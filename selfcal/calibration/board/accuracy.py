"""Predicted tool-point accuracy of a board calibration over the workspace (issue #29).

The tool point is the flange (the robot file's flange -> camera mount seen from the camera;
eye-to-hand the calibrated flange -> board mount seen from the board), predicted in the chain's
world frame: the board frame (eye-to-hand: the first camera's frame). Its error has the two
parts of :mod:`selfcal.calibration.accuracy`:

- the estimation error: the Cramer-Rao covariance of the estimated minimal parameters at the
  estimate with the fit's own pixel noise (:mod:`selfcal.calibration.board.bounds`: the cameras,
  the joint read-back corrections and, for a rig, the extrinsics marginalised) carried through
  the chain (:class:`selfcal.kinematics.tool_error.ToolErrorModel`);
- the model error, from the parameter selection's own leave-one-configuration-out folds
  (:mod:`selfcal.calibration.board.param_selection`: the chosen candidate fitted without each
  fold): every held-out frame's first-camera pixels, predicted from its joints alone, are
  explained by the one correction ``xi`` (a body twist) of the predicted tool pose that fits
  them best (linear least squares on the projection's Jacobian), so that ``B xi`` is the
  frame's tool-point error (position m, orientation rad; ``B`` carries the twist to the tool
  point in the world frame). What the fold's covariance explains there (``tr S``) and what the
  pixel noise and the joint read-back noise explain (``tr N``: ``B sigma^2 (A^T A)^-1 B^T`` with
  ``A`` that Jacobian, plus the joint twists weighted by the joint sigma) are taken out as the
  tracker route does (:func:`selfcal.calibration.accuracy.model_error_of`).

What this cannot see: the fold's camera errors move its prediction and its pose correction
alike (the correlation is not modelled: the held-out errors then read a little smaller than
``S + N``, and a small model error is not counted); a model error the same in every frame is
absorbed by the placement (board pose, hand-eye) and is not seen.

Beside it, the cross-validated reprojection (``accuracy.cross_validation``): every fold's
held-out frames predicted by the chosen candidate and by the fair nominal (the first candidate,
:mod:`selfcal.calibration.board.nominal_fit`'s objective on the same training frames), as the
2-D RMS in px and in mm at the board (the detected pixel's ray met with the board's plane at the
predicted pose, against the predicted corner). Nothing here reads truth.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.accuracy import (
    SAMPLE_COUNT,
    Accuracy,
    ModelError,
    error_model_from_json,
    model_error_of,
    postures_from_json,
)
from selfcal.calibration.board.bounds import BoardCramerRao, board_cramer_rao
from selfcal.calibration.board.nominal_fit import standard_gauge
from selfcal.calibration.board.param_selection import Selection
from selfcal.calibration.board.refine import BoardObservations, Refinement, predicted_points
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.kinematics.tool_error import (
    EDGE_FRACTION,
    ToolErrorModel,
    workspace_sample,
    workspace_summary,
)

__all__ = [
    "board_accuracy",
    "board_error_model",
    "board_error_model_from_json",
    "board_postures_from_json",
    "cross_validated_reprojection",
    "held_out_pose_errors",
    "model_error",
    "pose_jacobian",
]

_FIX = "re-run `selfcal calibrate` to write the block again"


def _what(eye_to_hand: bool) -> str:
    frame = "the first camera's frame" if eye_to_hand else "the board frame"
    return (
        "predicted error of the calibrated tool point (the flange) and tool orientation against "
        f"the true ones, in {frame}: the Cramer-Rao covariance at the estimate carried through "
        "the chain plus a model error estimated from the leave-one-configuration-out folds "
        "(docs/tool-accuracy.md); 95 % bounds of the error's norm per joint vector, summarised "
        "per region: inside = joint vectors within the calibration postures' joint ranges, edge "
        f"= beyond them by up to {EDGE_FRACTION:.0%} of each joint's range, workspace = within "
        "the joint limits"
    )


def _skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the cross-product matrices of ``v`` (..., 3)."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)  # fmt: skip


def board_error_model(cr: BoardCramerRao, T_tool_point: np.ndarray, position_m: float = 0.0,
                      rotation_rad: float = 0.0) -> tuple[ToolErrorModel, tuple[str, ...]]:  # fmt: skip
    """The :class:`ToolErrorModel` of the bounds ``cr`` (world = the chain's, the tool point
    ``T_tool_point`` in the chain's tool frame) with the model error ``position_m`` /
    ``rotation_rad`` per coordinate, and the names of the parameters its covariance covers (the
    minimal parameters the estimate moved)."""
    idx = minimal_indices(cr.model.joint_types)
    est = np.ones(idx.size, bool) if cr.estimated is None else np.asarray(cr.estimated, bool)
    cov = cr.covariance[np.ix_(est, est)]
    em = ToolErrorModel(cr.model, np.eye(4), idx[est], cov, position_m, rotation_rad,
                        np.asarray(T_tool_point, float))  # fmt: skip
    return em, tuple(param_names(idx[est]))


def pose_jacobian(Jx: np.ndarray, x: np.ndarray, T_tool: np.ndarray,
                  eye_to_hand: bool) -> np.ndarray:  # fmt: skip
    """(2k, 6) the derivative of the pixels of the board points ``x`` (k, 3) (camera frame, m)
    by a body twist ``[v; w]`` (m, rad) of the chain's tool pose ``T_tool`` (4, 4) (the camera
    in the board frame, eye-to-hand the board in the camera frame); ``Jx`` (k, 2, 3) the
    projection's derivative by the point (px per m)."""
    if eye_to_hand:  # camera <- board = the tool pose; the twist moves the board
        R = T_tool[:3, :3]
        dX = np.concatenate([np.broadcast_to(R, (len(x), 3, 3)), -_skew(x - T_tool[:3, 3]) @ R], 2)
    else:  # camera <- board = inv(tool pose); the twist moves the camera
        dX = np.concatenate([np.broadcast_to(-np.eye(3), (len(x), 3, 3)), _skew(x)], 2)
    return (Jx @ dX).reshape(-1, 6)


def held_out_pose_errors(obs: BoardObservations, fit: Refinement, frames: np.ndarray,
                         T_tool_point: np.ndarray, cr: BoardCramerRao) -> tuple[np.ndarray, ...]:  # fmt: skip
    """For every frame of ``frames`` (m,) bool with first-camera rows: the tool-point error of
    ``fit``'s prediction from the joints alone, as the best pose correction of the frame's
    pixels (module docstring), and what explains it. ``cr``: ``fit``'s bounds (its covariance
    and the pixel noise). Returns the frames (k,), the errors (k, 6) (position m, orientation
    rad, world frame), the covariance (k, 6, 6) the estimate's errors give them (the kinematics'
    and the first camera's, with their correlation) and that of the noise (k, 6, 6) (the pixel
    noise and the joint read-back noise)."""
    cam, v, Xc, uv, _ = predicted_points(obs, fit, frames)[0]
    t = np.asarray(T_tool_point, float)[:3, 3]
    js = obs.joint_sigma
    idx = minimal_indices(cr.model.joint_types)
    est = np.ones(idx.size, bool) if cr.estimated is None else np.asarray(cr.estimated, bool)
    n0 = 0 if cr.camera_covariance is None else len(cr.camera_covariance)
    C = np.zeros((est.sum() + n0, est.sum() + n0))
    C[: est.sum(), : est.sum()] = cr.covariance[np.ix_(est, est)]
    if n0:
        assert cr.camera_cross is not None
        C[est.sum() :, est.sum() :] = cr.camera_covariance
        C[: est.sum(), est.sum() :] = cr.camera_cross[est]
        C[est.sum() :, : est.sum()] = cr.camera_cross[est].T
    out: list[list] = [[], [], [], []]
    for i in np.unique(v).tolist():
        rows = v == i
        T = fk_tool(cr.model, obs.q[i][None])[0]
        x = Xc[rows]
        uv_hat, Jx, Jc = cam.project_free(x)  # px, px per m (k, 2, 3), px per parameter
        r = (uv_hat - uv[rows]).reshape(-1)
        A = pose_jacobian(Jx, x, T, obs.eye_to_hand)
        AtA_inv = np.linalg.inv(A.T @ A)
        xi = -AtA_inv @ A.T @ r
        B = np.zeros((6, 6))
        B[:3, :3], B[:3, 3:], B[3:, 3:] = T[:3, :3], -T[:3, :3] @ _skew(t), T[:3, :3]
        Jb = identification_jacobian(cr.model, obs.q[i][None])[0][:, idx[est]]
        G = B @ np.concatenate([Jb, AtA_inv @ A.T @ Jc.reshape(-1, n0)], axis=1)
        N = cr.pixel_sigma_px**2 * B @ AtA_inv @ B.T
        if js is not None:
            tw = B @ joint_twists(cr.model, obs.q[i][None])[0]  # (6, n)
            N = N + tw @ np.diag(np.broadcast_to(np.asarray(js, float) ** 2, (tw.shape[1],))) @ tw.T
        for lst, val in zip(out, (i, B @ xi, G @ C @ G.T, N), strict=True):
            lst.append(val)
    if not out[0]:
        return np.zeros(0, int), np.zeros((0, 6)), np.zeros((0, 6, 6)), np.zeros((0, 6, 6))
    return tuple(np.array(o) for o in out)


def _features(obs: BoardObservations, frames: np.ndarray) -> list[list]:
    """Every camera's features of the frames ``frames`` (m,) bool, in order."""
    k = np.flatnonzero(frames).tolist()
    return [[fc[i] for i in k] for fc in (obs.features, *obs.rig_features)]


def model_error(obs: BoardObservations, selection: Selection, offsets: np.ndarray,
                T_tool_point: np.ndarray, pixel_sigma_px: float) -> ModelError | None:  # fmt: skip
    """The model error (module docstring) from the chosen candidate's fold fits; None without
    folds (one configuration) or when no fold was fitted."""
    fits = selection.candidates[selection.chosen].fold_fits
    if selection.fold_of is None or not fits:
        return None
    r2, s2, n2, r2r, s2r, n2r, v2, v2r = [], [], [], [], [], [], [], []
    for f, (fit, free_idx, offset_joints) in sorted(fits.items()):
        out = selection.fold_of == f
        train = obs.used & ~out
        model = standard_gauge(fit.model, offsets)
        cr = board_cramer_rao(
            obs.board, fit.cameras, model, obs.q[train], _features(obs, train), pixel_sigma_px,
            joint_sigma=obs.joint_sigma, T_first_cam=None if obs.rig is None else fit.T_first_cam,
            free_idx=free_idx, offset_joints=offset_joints, eye_to_hand=obs.eye_to_hand,
        )  # fmt: skip
        frames, e, S, N = held_out_pose_errors(obs, fit, out, T_tool_point, cr)
        if not len(frames):
            continue
        r2.append(np.sum(e[:, :3] ** 2, axis=1))
        r2r.append(np.sum(e[:, 3:] ** 2, axis=1))
        s2.append(np.trace(S[:, :3, :3], axis1=1, axis2=2))
        s2r.append(np.trace(S[:, 3:, 3:], axis1=1, axis2=2))
        n2.append(np.trace(N[:, :3, :3], axis1=1, axis2=2))
        n2r.append(np.trace(N[:, 3:, 3:], axis1=1, axis2=2))
        tot = S + N  # the variance of a squared norm: 2 tr Sigma^2 (anisotropic here)
        v2.append(2.0 * np.einsum("kij,kji->k", tot[:, :3, :3], tot[:, :3, :3]))
        v2r.append(2.0 * np.einsum("kij,kji->k", tot[:, 3:, 3:], tot[:, 3:, 3:]))
    return model_error_of(r2, s2, n2, (r2r, s2r, n2r), folds=len(r2),
                          failed=selection.folds - len(r2),
                          noise_what="the pixel and joint read-back noise",
                          var2=(v2, v2r))  # fmt: skip


def _errors_px_mm(obs: BoardObservations, fit: Refinement,
                  frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Every camera's inlier rows of ``frames`` predicted by ``fit``: the 2-D error (k,) px and
    mm at the board (the detected pixel's ray met with the board plane at the predicted pose,
    against the predicted corner)."""
    px, mm = [], []
    for cam, _, Xc, uv, normal in predicted_points(obs, fit, frames):
        px.append(np.linalg.norm(cam.project(Xc) - uv, axis=1))
        d = np.concatenate([cam.unproject(uv), np.ones((len(uv), 1))], axis=1)
        s = np.sum(normal * Xc, axis=1) / np.sum(normal * d, axis=1)
        mm.append(1e3 * np.linalg.norm(s[:, None] * d - Xc, axis=1))
    return (np.concatenate(px), np.concatenate(mm)) if px else (np.zeros(0), np.zeros(0))


def cross_validated_reprojection(obs: BoardObservations, selection: Selection) -> dict | None:
    """The cross-validated reprojection of the chosen candidate and of the fair nominal (module
    docstring): per model its 2-D RMS in px and mm at the board over every held-out row; None
    without folds."""
    if selection.fold_of is None:
        return None
    chosen = selection.candidates[selection.chosen]
    out: dict = {
        "what": "every fold's frames predicted from their joints alone by the model fitted "
        "without them (leave-one-configuration-out): 2-D RMS over the held-out corners in px and "
        "in mm at the board",
        "configurations": selection.configurations,
        "folds": selection.folds,
    }
    for key, cand in (("calibrated", chosen), ("nominal", selection.candidates[0])):
        px, mm = [], []
        for f, (fit, _, _) in sorted(cand.fold_fits.items()):
            e_px, e_mm = _errors_px_mm(obs, fit, selection.fold_of == f)
            px.append(e_px)
            mm.append(e_mm)
        if not px or len(cand.fold_fits) < selection.folds:
            out[key] = None
            continue
        p, m = np.concatenate(px), np.concatenate(mm)
        out[key] = {
            "label": cand.label,
            "corners": int(p.size),
            "reprojection_rms_px": float(np.sqrt(np.mean(p**2))),
            "at_board_rms_mm": float(np.sqrt(np.mean(m**2))),
        }
    return out


def board_accuracy(obs: BoardObservations, selection: Selection, cr: BoardCramerRao,
                   offsets: np.ndarray, T_tool_point: np.ndarray, limits: np.ndarray, *,
                   pixel_sigma_px: float, count: int = SAMPLE_COUNT) -> Accuracy:  # fmt: skip
    """The predicted accuracy of a board calibration (module docstring): ``cr`` its bounds at
    the estimate (the stored model, :func:`selfcal.calibration.board.bounds.board_bounds`),
    ``selection`` its parameter selection (the fold fits), ``offsets`` (n,) rad the joint
    offsets of the stored model's gauge, ``T_tool_point`` the flange in the chain's tool frame,
    ``limits`` (n, 2) rad / m the joint limits, ``pixel_sigma_px`` the corner noise the bounds
    used; ``count`` joint vectors per region."""
    me = model_error(obs, selection, offsets, T_tool_point, pixel_sigma_px)
    pos = 0.0 if me is None else me.position_m
    rot = 0.0 if me is None or me.rotation_rad is None else me.rotation_rad
    em, names = board_error_model(cr, T_tool_point, pos, rot)
    q_cal = np.asarray(obs.q[obs.used], dtype=float)
    sample = workspace_sample(q_cal, limits, count=count)
    note = ("no cross-validation (the frames show one arm configuration): the covariance alone, "
            "which is optimistic when the model misfits")  # fmt: skip
    extra = {
        "tool_point": "the flange",
        "T_tool_point_si": np.asarray(T_tool_point, float).tolist(),
        "joint_limits_si": np.asarray(limits, float).tolist(),
        "cross_validation": cross_validated_reprojection(obs, selection),
    }
    return Accuracy(em, names, me, workspace_summary(em, sample, q_cal), sample, q_cal,
                    _what(obs.eye_to_hand), note, extra)  # fmt: skip


def board_error_model_from_json(block: dict, model: MCPCModel, where: str) -> ToolErrorModel:
    """The :class:`ToolErrorModel` of a board ``calibration.json``'s ``accuracy`` block.

    Raises:
        InputError: the block is malformed (named).
    """
    names = tuple(param_names(minimal_indices(model.joint_types)))
    tip = np.asarray(block.get("T_tool_point_si", np.eye(4)), dtype=float)
    return error_model_from_json(block, model, np.eye(4), names, True, where, fix=_FIX,
                                 T_tool_point=tip)  # fmt: skip


def board_postures_from_json(block: dict, n: int, where: str) -> np.ndarray:
    """The calibration postures (m, n) rad / m of a board ``accuracy`` block."""
    return postures_from_json(block, n, where, fix=_FIX)
