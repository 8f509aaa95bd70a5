"""What one posture of a plan tells the board calibration: the Fisher information of each
candidate frame about the camera's free parameters and the chain's minimal kinematic parameters
(``selfcal plan``, issue #30; :mod:`selfcal.calibration.board.plan.planner`). The board route's problem
(:func:`selfcal.calibration.board.problem.board_problem`) at the nominal chain and camera, one
Jacobian over every frame, each frame's joint read-back corrections eliminated under their
prior (:func:`frame_information`: what a fit learns from the frame); and what a frame's
prediction from its joints alone errs by, nothing eliminated, its read-back errors beside
(:func:`prediction_information`: how the selection's cross-validation predicts a left-out
fold). Units: SI and px.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.calibration.board.problem import board_problem
from selfcal.errors import InputError, UsageError
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices

__all__ = ["board_model", "frame_information", "prediction_information"]


def board_model(setup: PlanSetup) -> MCPCModel:
    """The nominal chain the board calibration fits: eye-in-hand board frame -> camera (world =
    the board, tool = the camera), eye-to-hand camera -> board (world = the camera, tool = the
    board; :meth:`selfcal.calibration.board.plan.views.PlanSetup.calibration_model`)."""
    return setup.calibration_model()


def frame_information(
    setup: PlanSetup,
    q: np.ndarray,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None = None,
    seen: Sequence[np.ndarray] | None = None,
) -> np.ndarray:
    """(m, p, p) the Fisher information of each posture ``q`` (m, n) rad about ``[camera's free
    parameters, minimal kinematic parameters]`` (px, rad, m; the order of
    :func:`selfcal.calibration.board.bounds.board_cramer_rao`): the board features ``seen``
    in each frame (m arrays of feature ids; None: every feature) at the nominal camera's
    projection, noise ``pixel_sigma_px`` px per coordinate; with ``joint_sigma`` (n,) rad
    (m for a prismatic joint) each frame's joint read-back errors are estimated under their
    Gaussian prior and eliminated (the Schur complement of the frame's own corrections), as the
    board route does."""
    Jg, Jl, js = _frame_jacobians(setup, q, pixel_sigma_px, joint_sigma, seen)
    F = np.stack([a.T @ a for a in Jg])
    if js is not None:  # eliminate each frame's joint corrections
        prior = np.diag((pixel_sigma_px / js) ** 2)
        for f, (a, b) in enumerate(zip(Jg, Jl, strict=True)):
            B = a.T @ b
            F[f] -= B @ np.linalg.solve(b.T @ b + prior, B.T)
    return F / pixel_sigma_px**2


def prediction_information(setup: PlanSetup, q: np.ndarray, pixel_sigma_px: float,
                           joint_sigma: np.ndarray | None = None,
                           seen: Sequence[np.ndarray] | None = None) -> np.ndarray:  # fmt: skip
    """(m, p + j, p + j) what a frame's prediction from its joints alone errs by, as the
    selection's cross-validation predicts a left-out fold
    (:mod:`selfcal.calibration.board.param_selection`: nothing of the fold re-fitted): each
    frame's ``J^T J / sigma^2`` about ``[camera's free parameters, minimal kinematic
    parameters, its joints' read-back errors in units of joint_sigma]`` (the arguments as
    :func:`frame_information`'s; ``j`` = n with ``joint_sigma``, else 0), nothing eliminated.
    A parameter error ``e`` (p,) and read-back errors ``z`` (j,) (standard normal: the
    read-back's ``dq / joint_sigma``) move the frame's features by ``[e, z]^T A [e, z]
    sigma^2`` px^2 in all; the first ``p`` rows and columns are :func:`frame_information`'s
    without the joints' elimination, which the training fits do and the prediction cannot."""
    Jg, Jl, js = _frame_jacobians(setup, q, pixel_sigma_px, joint_sigma, seen)
    if js is None:
        return np.stack([a.T @ a for a in Jg]) / pixel_sigma_px**2
    J = [np.concatenate([a, b * js], axis=1) for a, b in zip(Jg, Jl, strict=True)]
    return np.stack([a.T @ a for a in J]) / pixel_sigma_px**2


def _frame_jacobians(
    setup: PlanSetup,
    q: np.ndarray,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None,
    seen: Sequence[np.ndarray] | None,
) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray | None]:
    """Per frame the Jacobian (2k, p) of its features (px) about ``[camera, minimal]`` and
    (2k, n) about its joint corrections (none without ``joint_sigma``), with the joints'
    standard deviations (n,) (None without); the arguments as :func:`frame_information`'s."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m = len(q)
    model = board_model(setup)
    ids, pts = setup.board.layout()
    if seen is None:
        feature = [np.arange(len(ids))] * m
    else:
        at = {int(i): k for k, i in enumerate(ids.tolist())}
        feature = [np.array([at[i] for i in np.asarray(s).tolist() if i in at], np.int64)
                   for s in seen]  # fmt: skip
        if len(feature) != m:
            raise UsageError(f"{len(feature)} frames of seen features for {m} postures")
    T_cb = setup.T_cam_board(q)  # board -> camera
    Xc = np.einsum("mij,kj->mki", T_cb[:, :3, :3], pts) + T_cb[:, None, :3, 3]
    uv = setup.camera.project(Xc)  # (m, k, 2)
    idx = minimal_indices(model.joint_types)
    poses = KinematicPoses(model, q, idx, np.zeros((0, 4, 4)), np.ones(m, bool),
                           joint_corrections=joint_sigma is not None,
                           eye_to_hand=setup.eye_to_hand)  # fmt: skip
    frame = np.repeat(np.arange(m), [len(f) for f in feature])
    k = np.concatenate([np.zeros(0, np.int64), *feature])
    rows = [(poses.layout.view(frame, 0), ids[k], uv[frame, k])]
    prob = board_problem([setup.camera], poses, rows, setup.board, pixel_sigma_px=pixel_sigma_px,
                         joint_sigma=joint_sigma, n_frames=m)  # fmt: skip
    P = prob.problem
    pose_cols = P.columns("poses")
    cols = np.concatenate([P.columns("intrinsics"), pose_cols[: poses.n_kin]])
    J = P.jacobian(P.x0)[: 2 * len(frame)]  # the reprojection rows (the prior's follow)
    views = poses.layout.view(np.arange(m), 0)
    of_view = np.empty(int(views.max()) + 1, np.int64)
    of_view[views] = np.arange(m)
    row_frame = np.repeat(of_view[prob.block.view], 2)
    if len(row_frame) != J.shape[0]:
        raise InputError("the board problem's residuals do not match the frames' features")
    order = np.argsort(row_frame, kind="stable")
    ends = np.cumsum(np.bincount(row_frame, minlength=m))
    parts = np.split(order, ends[:-1])
    Jg = J[:, cols].toarray()
    kin = [Jg[r] for r in parts]
    if joint_sigma is None:
        return kin, [np.zeros((len(r), 0)) for r in parts], None
    dq = pose_cols[np.asarray(poses.dq_cols)].reshape(m, -1)
    js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (dq.shape[1],)).copy()
    return kin, [J[r][:, dq[f]].toarray() for f, r in enumerate(parts)], js
