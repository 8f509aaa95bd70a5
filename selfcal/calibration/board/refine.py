"""The one-step refinement on a board of a chosen set of kinematic parameters, and its prediction.

One bundle adjustment (:mod:`selfcal.estimation.bundle_adjust`'s problem on the one solver): the camera poses
come from the kinematic chain (:class:`selfcal.estimation.kinematic_poses.KinematicPoses`), the
board's points are held at their declared positions (the board frame is the world and gives the
scale), every camera's free parameters are estimated, and so are the chosen kinematic
parameters -- flat MCPC parameters ``free_idx`` and the zero offsets of ``offset_joints`` -- while
every other parameter stays at the start model's value. The fair nominal
(:mod:`selfcal.calibration.board.nominal_fit`), every candidate of the parameter selection
(:mod:`selfcal.calibration.board.param_selection`) and the final calibration are this one fit with other parameter
sets; a subset of the frames (``train``) gives the fits of the cross-validation, and
:func:`predict_px` predicts the others from their joints alone.

Frames and units: world = board frame (m), the model's tool = the first camera (OpenCV frame),
pixels in the OpenCV convention; joints rad (m for a prismatic joint). Eye-to-hand (the cameras
static, the board on the flange: ``BoardObservations.eye_to_hand``) the same fit runs on the
inverted chain: world = the first camera, the model's tool = the board
(:class:`selfcal.estimation.kinematic_poses.KinematicPoses`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.board.calibrate import BoardCalibration
from selfcal.calibration.board.problem import board_problem
from selfcal.calibration.board.rig import BoardRigCalibration
from selfcal.calibration.board.terms import build_terms
from selfcal.camera import CameraModel
from selfcal.camera.camera_set import std_by_name
from selfcal.errors import EstimationError
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, param_names
from selfcal.solver import SolverOptions, covariance, solve
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.terms.base import Term
from selfcal.transforms import inv_pose

__all__ = ["BoardObservations", "Refinement", "predict_px", "predicted_points", "refine_on_board"]


@dataclass(frozen=True)
class BoardObservations:
    """What every fit on one dataset shares: the ``board``, the camera stage ``cam_stage`` of
    the first camera (its inlier rows are the observations; its camera the start), the
    ``features`` of every frame, the joints ``q`` (m, n) rad, a ``rig`` of further cameras
    (their start, or None) with their features ``rig_features``, the joint read-back's
    standard deviation ``joint_sigma`` (rad / m, or None for exact read-back) and the setup:
    ``eye_to_hand`` the cameras static and the board on the flange (the chain's world is then
    the first camera and its tool the board), else the cameras on the flange (world = board,
    tool = the first camera). ``terms``: further measurements of the same robot
    (:mod:`selfcal.terms`: touch-probe points, tracker rows ...) estimated with the images in
    every fit (:mod:`selfcal.calibration.board.terms`)."""

    board: Board
    cam_stage: BoardCalibration
    features: Sequence[Features]
    q: np.ndarray
    rig: BoardRigCalibration | None = None
    rig_features: Sequence[Sequence[Features]] = ()
    joint_sigma: float | np.ndarray | None = None
    eye_to_hand: bool = False
    terms: tuple[Term, ...] = ()

    @property
    def used(self) -> np.ndarray:
        """(m,) the frames the camera stage found the board in."""
        return self.cam_stage.used

    def tool_poses(self) -> np.ndarray:
        """(m, 4, 4) the chain's tool poses in its world that the camera stage measured (NaN
        where it did not find the board): the camera in the board frame, or eye-to-hand the
        board in the first camera's frame (m)."""
        T = self.cam_stage.T_cam_board
        return T.copy() if self.eye_to_hand else inv_pose(T)

    def rows(self, frames: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per camera the inlier rows of the frames ``frames`` (m,) bool: frame index, feature
        id and pixel (k, 2)."""
        stages = [(self.cam_stage, self.features)]
        if self.rig is not None:
            stages += list(zip(self.rig.single[1:], self.rig_features, strict=True))
        out = []
        for sc, fc in stages:
            keep = sc.inlier & frames[sc.view]
            uv = np.concatenate([fc[i].uv for i in np.flatnonzero(sc.used).tolist()])[keep]
            out.append((sc.view[keep], sc.feature[keep], uv))
        return out


@dataclass(frozen=True)
class Refinement:
    """The result of :func:`refine_on_board`: the kinematic ``model``, every camera
    (``cameras``, the first is the chain's tool) with the standard deviations of its free
    parameters ``cameras_std``, every camera's pose in the first's frame ``T_first_cam`` (N, 4,
    4) m, the 2-D reprojection RMS ``rms_px`` over every camera's rows and the solver's
    ``iterations``; ``sections``: the measurement terms' ``calibration.json`` sections and
    ``term_diagnostics`` their diagnostics (SI) at the solution."""

    model: MCPCModel
    cameras: tuple[CameraModel, ...]
    cameras_std: tuple[dict[str, float], ...]
    T_first_cam: np.ndarray
    rms_px: float
    iterations: int
    sections: tuple = ()
    term_diagnostics: dict = field(default_factory=dict)


def refine_on_board(
    obs: BoardObservations,
    start: MCPCModel,
    free_idx: np.ndarray,
    offset_joints: np.ndarray | Sequence[int] = (),
    *,
    train: np.ndarray | None = None,
    cameras: Sequence[CameraModel] | None = None,
    max_iter: int = 100,
    stds: bool = True,
    converge: bool = True,
    tol: float = 1e-12,
    what: str = "kinematics and cameras",
) -> Refinement:
    """Fit the flat MCPC parameters ``free_idx`` and the zero offsets of ``offset_joints`` of
    ``start`` (every other parameter held at its value), every camera's free parameters (from
    ``cameras``, default the camera stage's and the rig's) and the further cameras' extrinsics
    to the inlier pixels of the frames ``train`` (m,) bool (default every frame with the board),
    robust to nothing (the camera stage rejected the outliers), on the one solver. ``stds``:
    compute the cameras' standard deviations (the cross-validation's fits skip them);
    ``converge=False``: take the iterate after ``max_iter`` iterations (a few Gauss-Newton
    steps from a nearby fit) instead of an error; ``tol``: the solver's relative tolerance;
    ``what``: the fit's name in the error (e.g. the fair nominal).

    Raises:
        EstimationError: the solver did not converge within ``max_iter`` iterations (with
            ``converge``) or failed: the message names the fit and what was tried, and blames
            no data (a caller's data check does that when it finds them wrong).
    """
    used = obs.used if train is None else obs.used & np.asarray(train, bool)
    rig = obs.rig
    n_cams = 1 if rig is None else len(rig.cameras)
    if cameras is None:
        cameras = [obs.cam_stage.camera] + ([] if rig is None else list(rig.cameras[1:]))
    poses = KinematicPoses(
        start,
        obs.q,
        np.asarray(free_idx, dtype=np.int64),
        np.zeros((0, 4, 4)) if rig is None else inv_pose(rig.T_first_cam[1:]),
        used,
        joint_corrections=obs.joint_sigma is not None,
        offset_joints=np.asarray(offset_joints, dtype=np.int64),
        eye_to_hand=obs.eye_to_hand,
    )
    rows = [(poses.layout.view(v, c), f, uv) for c, (v, f, uv) in enumerate(obs.rows(used))]
    terms = build_terms(obs.terms, poses, obs.cam_stage.sigma_px) if obs.terms else None
    prob = board_problem(cameras[:n_cams], poses, rows, obs.board,
                         pixel_sigma_px=obs.cam_stage.sigma_px, joint_sigma=obs.joint_sigma,
                         n_frames=int(used.sum()),
                         term_blocks=() if terms is None else terms.residuals,
                         term_params=() if terms is None else terms.parameters)  # fmt: skip
    sol = solve(prob.problem, SolverOptions(tol=tol, max_iterations=max_iter, eliminate="poses"))
    if sol.status < 0 or (sol.status == 0 and converge):
        free = [*param_names(np.asarray(free_idx, dtype=np.int64)),
                *(f"offset_j{j + 1}" for j in np.asarray(offset_joints, dtype=int).tolist())]  # fmt: skip
        listed = ", ".join(free[:8]) + (" ..." if len(free) > 8 else "")
        ended = "stopped" if sol.status < 0 else f"did not converge within {max_iter} iterations"
        raise EstimationError(
            f"the fit of {what} on the board {ended} ({sol.message}): the estimator failed; "
            f"tried: Levenberg-Marquardt from the start "
            f"model, {len(free)} kinematic parameter(s) free ({listed or 'none'}), every "
            f"camera's free parameters, {int(used.sum())} frames, tolerance {tol:g}"
            + (", joint read-back errors estimated" if obs.joint_sigma is not None else "")
            + (f", with the terms {', '.join(t.kind for t in obs.terms)}" if obs.terms else ""),
            fix="add frames from other arm configurations (move the first joints, not only the "
            "wrist) and calibrate again",
        )
    camera, p, _ = prob.unpack(sol.x)
    r = np.concatenate([sol.residuals[prob.block.name]]
                       + [sol.residuals[f"reprojection{c}"] for c in range(1, n_cams)])  # fmt: skip
    cams: list[CameraModel] = [camera]
    cams += [cameras[c].with_free_values(sol.values[f"intrinsics{c}"]) for c in range(1, n_cams)]
    std_list: list[dict[str, float]] = []
    if stds:
        dof = max(sum(v.size for v in sol.residuals.values()) - prob.n, 1)
        sigma2 = float(sum(np.sum(v**2) for v in sol.residuals.values())) / dof
        for c in range(n_cams):
            cov = covariance(prob.problem, sol.x, ["intrinsics" if c == 0 else f"intrinsics{c}"],
                             sigma2=sigma2)  # fmt: skip
            std_list.append(std_by_name(cams[c], cov))  # with fy = mu fx by OpenCV's name
    model = poses.kinematic_model(p)
    reports = [] if terms is None else terms.reports(sol.values, sol.residuals, poses, model)
    return Refinement(
        model=model,
        cameras=tuple(cams),
        cameras_std=tuple(std_list),
        T_first_cam=np.concatenate([np.eye(4)[None], inv_pose(poses.rigs(p))]),
        rms_px=float(np.sqrt(np.mean(np.sum(r**2, axis=1)))),
        iterations=int(getattr(sol, "iterations", 0)),
        sections=tuple(r.section for r in reports if r.section is not None),
        term_diagnostics={k: v for r in reports for k, v in r.diagnostics.items()},
    )


def predicted_points(
    obs: BoardObservations, fit: Refinement, frames: np.ndarray
) -> list[tuple[CameraModel, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Per camera, the inlier rows of the frames ``frames`` (m,) bool as ``fit`` predicts them
    from the joints alone: the camera's model, the rows' frame index (k,), the board points in
    the camera's frame (k, 3) m, the detected pixels (k, 2) and the board's normal in the
    camera's frame (k, 3)."""
    frames = obs.used & np.asarray(frames, bool)
    T_tool = fk_tool(fit.model, obs.q)
    T_cam0_board = T_tool if obs.eye_to_hand else inv_pose(T_tool)
    out = []
    for c, (v, f, uv) in enumerate(obs.rows(frames)):
        T = inv_pose(fit.T_first_cam[c]) @ T_cam0_board[v]
        X = obs.board.points(f)
        Xc = np.einsum("kij,kj->ki", T[:, :3, :3], X) + T[:, :3, 3]
        out.append((fit.cameras[c], v, Xc, uv, T[:, :3, 2]))
    return out


def predict_px(obs: BoardObservations, fit: Refinement, frames: np.ndarray) -> np.ndarray:
    """The residuals (k, 2) px (predicted - detected) of every camera's inlier rows in the frames
    ``frames`` (m,) bool, predicted from the joints alone with ``fit`` (nothing re-fitted)."""
    out = [cam.project(Xc) - uv for cam, _, Xc, uv, _ in predicted_points(obs, fit, frames)]
    return np.concatenate(out) if out else np.zeros((0, 2))
