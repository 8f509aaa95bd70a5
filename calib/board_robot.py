"""Robot calibration with a board of known geometry: camera, hand-eye and kinematics.

The known-board counterpart of the self-calibration route (one camera on the flange, a board
somewhere in the scene):

1. :func:`calib.board_calibrate.calibrate_board` -- the camera and the board pose of every frame
   (Zhang via ``cv2.calibrateCamera``, then the bundle adjustment with the board held);
2. :func:`calib.identify.identify` -- the minimal MCPC parameters (tool = camera) fitted to the
   camera poses in the board frame (the two-stage method of the paper; ``place_base`` finds the
   robot's base in the board frame);
3. the one-step refinement: the same bundle adjustment (:func:`calib.bundle_adjust.bundle_adjust`)
   with the camera poses taken from the kinematic chain
   (:class:`calib.estimation.kinematic_poses.KinematicPoses`) and the board's points held at
   their declared positions. The board fixes the world frame (the board frame) and the scale, so
   no parameter is held for a gauge and no known distance is needed; only the parameters the
   identification found unidentifiable stay held. With a rig of N >= 2 cameras
   (:func:`calib.board_rig.calibrate_board_rig` gives its start) every further camera's pixels
   join the same adjustment: its own model and free parameters, its pose in the first camera's
   frame (``T_first_cam``) estimated with the kinematics, so that the cameras, the extrinsics
   and the chain belong together (the robot's tool is the first camera). With ``joint_sigma`` (e.g. the encoder
   quantisation, :func:`calib.estimation.joint_report.encoder_sigma`) every frame gets joint
   corrections with a zero-mean Gaussian prior (errors in variables, as
   :mod:`calib.joint_refine` explains); without, the read-back is taken as exact.

Frames: the world is the board frame (m); the model's tool is the OpenCV camera frame. SI units.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from calib.board_calibrate import BoardCalibration, calibrate_board
from calib.board_rig import BoardRigCalibration
from calib.bundle_adjust import _Problem as _AdjustmentProblem
from calib.camera import CameraModel, Pinhole
from calib.camera.camera_set import std_by_name
from calib.errors import EstimationError
from calib.estimation.kinematic_poses import KinematicPoses
from calib.estimation.reprojection import ReprojectionBlock
from calib.estimation.residuals import GaussianPriorBlock
from calib.identify import IdentificationResult, identify
from calib.mcpc import MCPCModel, minimal_indices, param_names
from calib.solver import Loss, ParameterBlock, ResidualBlock, SolverOptions, covariance, solve
from calib.target.base import Features
from calib.target.boards import Board
from calib.transforms import inv_pose

__all__ = ["BoardRobotCalibration", "calibrate_robot_with_board"]


@dataclass
class BoardRobotCalibration:
    """Result of :func:`calibrate_robot_with_board`: the refined kinematic ``model`` (world =
    board frame, tool = camera) and ``camera``; ``camera_std`` of its free parameters; the stages
    it started from (``board``: the camera stage, ``identification``: the two-stage model);
    ``used`` (m,) the frames in the adjustment; ``rms_px`` the final reprojection RMS (2-D,
    every camera's inliers); ``held``: minimal parameters held (unidentifiable from the frames).
    ``cameras``, ``cameras_std``: every camera of the rig (the first is ``camera``);
    ``T_first_cam`` (N, 4, 4): every camera's pose in the first camera's frame (m; the first
    the identity)."""

    model: MCPCModel
    camera: CameraModel
    camera_std: dict[str, float]
    board: BoardCalibration
    identification: IdentificationResult
    used: np.ndarray
    rms_px: float
    held: tuple[str, ...]
    cameras: tuple[CameraModel, ...] = ()
    cameras_std: tuple[dict[str, float], ...] = ()
    T_first_cam: np.ndarray = field(default_factory=lambda: np.eye(4)[None])


def calibrate_robot_with_board(
    board: Board,
    features: Sequence[Features],
    q: np.ndarray,
    nominal: MCPCModel,
    width: int,
    height: int,
    *,
    free: Sequence[str] = ("fx", "mu", "cx", "cy"),
    model: str = "pinhole",
    names: Sequence[str] | None = None,
    joint_sigma: float | np.ndarray | None = None,
    rig: BoardRigCalibration | None = None,
    rig_features: Sequence[Sequence[Features]] = (),
    max_iter: int = 100,
    initial: Pinhole | None = None,
) -> BoardRobotCalibration:
    """Calibrate the camera and the robot from the board ``features`` of one camera image per
    frame and the joint read-backs ``q`` (m, n) rad; ``model``, ``free``: the camera model
    (:data:`calib.camera.MODELS`) and its parameters to estimate (OpenCV names; with a lens the
    refinement adjusts its coefficients too); ``nominal``: the nominal MCPC model with the
    camera as tool (its world frame need not be the board's); ``joint_sigma`` (rad / m, scalar
    or (n,)): the read-back's standard deviation, or None for exact read-back; ``initial``: a
    camera to start from (:func:`calib.board_calibrate.calibrate_board`). ``rig``: the board
    calibration of a rig of N >= 2 cameras whose first camera took ``features`` (the start of
    every further camera and its extrinsics), ``rig_features[c - 1]`` camera ``c``'s features,
    one per frame in the frames' order. See the module docstring.

    Raises:
        calib.board_calibrate.BoardInputError / BoardMismatchError: as :func:`calibrate_board`.
        calib.identify.IdentificationError: too few frames for the kinematics;
            calib.identify.IdentificationSolverError (a kind of it) when the two-stage
            identification's solver failed (a caller may fall back to the nominal chain).
        EstimationError: the refinement did not converge.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if len(q) != len(features):
        raise ValueError(f"{len(features)} images but {len(q)} joint rows; give one row per image")
    cam_stage = calibrate_board(board, features, width, height, free=free, model=model, names=names,
                                initial=initial)  # fmt: skip
    used = cam_stage.used.copy()
    T_board_cam = inv_pose(cam_stage.T_cam_board[used])
    ident = identify(nominal, q[used], T_board_cam)
    idx = minimal_indices(nominal.joint_types)
    held = tuple(n for n, est in zip(param_names(idx), ident.estimated, strict=True) if not est)
    free_idx = idx[ident.estimated]
    n_cams = 1 if rig is None else len(rig.cameras)
    if len(rig_features) != n_cams - 1:
        raise ValueError(f"a rig of {n_cams} cameras needs {n_cams - 1} further feature lists")
    poses = KinematicPoses(
        ident.model,
        q,
        free_idx,
        np.zeros((0, 4, 4)) if rig is None else inv_pose(rig.T_first_cam[1:]),
        used,
        joint_corrections=joint_sigma is not None,
    )
    # every camera's inlier rows (camera 0: this camera stage's), in the frames the chain poses
    rows = [(cam_stage, features)]
    if rig is not None:
        rows += list(zip(rig.single[1:], rig_features, strict=True))
    obs = []
    for c, (sc, fc) in enumerate(rows):
        keep = sc.inlier & used[sc.view]
        uv_c = np.concatenate([fc[i].uv for i in np.flatnonzero(sc.used).tolist()])[keep]
        obs.append((poses.layout.view(sc.view[keep], c), sc.feature[keep], uv_c))
    ids = np.unique(np.concatenate([o[1] for o in obs]))
    view, feat0, uv = obs[0]
    pidx = np.searchsorted(ids, feat0)
    extra: list[ResidualBlock] = []
    extra_params: list[ParameterBlock] = []
    for c in range(1, n_cams):
        assert rig is not None
        v_c, f_c, uv_c = obs[c]
        extra.append(ReprojectionBlock(rig.cameras[c], poses, v_c, np.searchsorted(ids, f_c), uv_c,
                                       Loss("linear"), name=f"reprojection{c}",
                                       intrinsics=f"intrinsics{c}"))  # fmt: skip
        extra_params.append(ParameterBlock(f"intrinsics{c}", rig.cameras[c].free_values()))
    if joint_sigma is not None:
        js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (nominal.n,))
        w = np.tile(cam_stage.sigma_px / js, int(used.sum()))  # px per rad (m) of correction
        extra.append(GaussianPriorBlock("poses", poses.dq_cols, w))
    x0 = np.concatenate([cam_stage.camera.free_values(), poses.initial_params()])
    prob = _AdjustmentProblem(
        cam_stage.camera, poses, view, pidx, uv, len(ids), loss=Loss("linear"), x0=x0,
        extra=extra, fixed_points=board.points(ids), extra_params=extra_params,
    )  # fmt: skip
    sol = solve(prob.problem, SolverOptions(tol=1e-12, max_iterations=max_iter, eliminate="poses"))
    if sol.status <= 0:
        raise EstimationError(
            f"the refinement of kinematics and camera on the board did not converge within "
            f"{max_iter} iterations ({sol.message})",
            fix="check the joint read-back (units, order of the rows) against the images",
        )
    camera, p, _ = prob.unpack(sol.x)
    r = np.concatenate([sol.residuals[prob.block.name]]
                       + [sol.residuals[f"reprojection{c}"] for c in range(1, n_cams)])  # fmt: skip
    dof = max(sum(v.size for v in sol.residuals.values()) - prob.n, 1)
    sigma2 = float(sum(np.sum(v**2) for v in sol.residuals.values())) / dof
    cams: list[CameraModel] = [camera]
    stds = []
    for c in range(n_cams):
        name = "intrinsics" if c == 0 else f"intrinsics{c}"
        if c:
            assert rig is not None
            cams.append(rig.cameras[c].with_free_values(sol.values[name]))
        cov = covariance(prob.problem, sol.x, [name], sigma2=sigma2)
        stds.append(std_by_name(cams[c], cov))  # with fy = mu fx by OpenCV's name
    return BoardRobotCalibration(
        model=poses.kinematic_model(p),
        camera=camera,
        camera_std=stds[0],
        board=cam_stage,
        identification=ident,
        used=used,
        rms_px=float(np.sqrt(np.mean(np.sum(r**2, axis=1)))),
        held=held,
        cameras=tuple(cams),
        cameras_std=tuple(stds),
        T_first_cam=np.concatenate([np.eye(4)[None], inv_pose(poses.rigs(p))]),
    )
