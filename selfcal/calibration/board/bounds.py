"""Cramer-Rao bounds of the known-board route (:func:`selfcal.calibration.board.robot.calibrate_robot_with_board`).

The bound is the Fisher information of that route's one-step refinement, evaluated at given
values (the truth in a Monte Carlo, the estimate in a report): every camera's free parameters,
every minimal MCPC parameter of the chain in the board frame (tool = the first camera), each
further camera's pose in the first camera's frame, and -- with ``joint_sigma`` -- every frame's
joint corrections under their zero-mean Gaussian prior (the read-back's errors); the board's
points are known (no scale gauge, no known distance). Corner noise: Gaussian, ``pixel_sigma_px``
per coordinate. The kinematic parameters free are those the calibration estimated (the chosen
candidate of :mod:`selfcal.calibration.board.param_selection`: flat MCPC parameters and joint
offsets; every minimal parameter when none is given); their covariance is carried to the
minimal parameters of the stored model (the MCPC gauge with the nominal's joint offsets,
:func:`selfcal.calibration.board.nominal_fit.standard_gauge`) to first order. A minimal
parameter no estimated one moves was held: it has no bound.

The tool tip's bound is the RMS over postures after the best rigid alignment, as the report
measures it (:func:`selfcal.estimation.joint_report.aligned_tool_rms_bound`). Units: SI inside;
camera parameters in px (or unitless) by OpenCV name.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.held import held_error, held_response
from selfcal.calibration.board.misfit import board_view, misfit_covariance, unit_rows
from selfcal.calibration.board.problem import board_problem
from selfcal.camera import CameraModel
from selfcal.camera.camera_set import std_by_name
from selfcal.errors import UsageError
from selfcal.estimation.joint_report import aligned_tool_rms_bound
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.io.board_calibration import BoardBounds, BoardCalibrationResult, CameraBounds
from selfcal.io.calibration_bounds import BoundParameter, ToolTipBound
from selfcal.kinematics.alignment import regauge
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import (
    MCPCModel,
    chain_transforms,
    minimal_indices,
    param_is_angle,
    param_names,
)
from selfcal.solver import block_columns, covariance, inverse_columns
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = [
    "MOVES",
    "BoardCramerRao",
    "board_bounds",
    "board_cramer_rao",
    "estimated_parameters",
    "to_minimal",
]

MOVES = 1e-4
"""A minimal parameter counts as estimated when an estimated parameter moves it by more than
this per unit (rad per rad, m per m, ...): the gauge carries a freed joint offset or base
rotation into the rows after it by amounts of the order of the chain's deviation from the
drawing, and by 1e-9 and less where the axes are not involved (those are held)."""


@dataclass(frozen=True, eq=False)
class BoardCramerRao:
    """The bounds of :func:`board_cramer_rao`: ``model`` (the chain they were evaluated at,
    world = board frame), ``covariance`` (k, k) of its minimal parameters (SI, the order of
    :func:`selfcal.kinematics.mcpc.minimal_indices`; zero for a held one), ``camera_std`` every camera's free parameters' bound
    (px or unitless, by name), the noise level and the counts; ``estimated`` (k,) which
    minimal parameters the estimate moves (the others were held; all when None);
    ``camera_covariance`` (c, c) the first camera's free parameters' covariance and
    ``camera_cross`` (k, c) its covariance with the minimal parameters (zero rows for held
    ones), for what the camera's errors do to a prediction (:mod:`selfcal.calibration.board.accuracy`)."""

    model: MCPCModel
    covariance: np.ndarray
    camera_std: tuple[dict[str, float], ...]
    pixel_sigma_px: float
    observations: int
    unknowns: int
    estimated: np.ndarray | None = None
    camera_covariance: np.ndarray | None = None
    camera_cross: np.ndarray | None = None
    misfit: np.ndarray | None = None
    """(k + c, k + c) the covariance a model error of unit size (1 m per tool-point coordinate)
    in every frame gives the minimal parameters and the first camera's
    (:mod:`selfcal.calibration.board.misfit`'s ``G``; zero rows for held ones), None when not
    asked for (no ``T_tool_point``)."""
    held: np.ndarray | None = None
    """(k + c, k) the error of the minimal parameters and the first camera's per unit deviation
    of each minimal parameter from the drawing, the fit's response to it included
    (:mod:`selfcal.calibration.board.held`: zero in the directions the estimate spans), None
    when not asked for (no ``T_tool_point``)."""

    def aligned_tool_rms(self, q: np.ndarray, T_cam_tip: np.ndarray) -> float:
        """The bound (m) of the RMS error of the point ``T_cam_tip`` (first camera -> tip, m)
        over the postures ``q`` (k, n) rad after the best rigid alignment."""
        return aligned_tool_rms_bound(self, np.asarray(q, dtype=float), T_cam_tip)  # type: ignore[arg-type]

    def parameter_std(self) -> dict[str, float]:
        """Every minimal parameter's bound by name (m or rad)."""
        names = param_names(minimal_indices(self.model.joint_types))
        std = np.sqrt(np.clip(np.diag(self.covariance), 0, None)).tolist()
        est = np.ones(len(names), bool) if self.estimated is None else self.estimated
        return {n: s for n, s, e in zip(names, std, est, strict=True) if e}


def board_cramer_rao(
    board: Board,
    cameras: Sequence[CameraModel],
    model: MCPCModel,
    q: np.ndarray,
    features: Sequence[Sequence[Features]],
    pixel_sigma_px: float,
    *,
    joint_sigma: float | np.ndarray | None = None,
    T_first_cam: np.ndarray | None = None,
    free_idx: np.ndarray | None = None,
    offset_joints: np.ndarray | Sequence[int] = (),
    eye_to_hand: bool = False,
    T_tool_point: np.ndarray | None = None,
) -> BoardCramerRao:
    """The bounds of the board refinement (module docstring) with ``cameras`` (the first is the
    chain's tool; each with its ``free`` parameters), the chain ``model`` (world = board frame)
    at the joints ``q`` (m, n) rad, ``features[c][i]`` camera ``c``'s board features in frame
    ``i`` (px), ``T_first_cam`` (N, 4, 4) every camera's pose in the first camera's frame (m;
    None for one camera) and ``joint_sigma`` (rad / m, scalar or (n,); None: exact read-back);
    ``free_idx`` (flat MCPC indices) and ``offset_joints`` (revolute joints, 0 based): the
    kinematic parameters estimated (default every minimal parameter, no offset);
    ``eye_to_hand``: the cameras static and the board on the flange (``model``'s world the first
    camera, its tool the board, :class:`selfcal.estimation.kinematic_poses.KinematicPoses`).

    Raises:
        ValueError: the feature lists do not match the cameras or the frames.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n_cams, m = len(cameras), len(q)
    if len(features) != n_cams or any(len(f) != m for f in features):
        raise UsageError(f"give one feature list of {m} frames per camera ({n_cams} cameras)")
    T_rigs = np.zeros((0, 4, 4)) if n_cams == 1 else inv_pose(np.asarray(T_first_cam)[1:])
    idx = minimal_indices(model.joint_types) if free_idx is None else np.asarray(free_idx, int)
    poses = KinematicPoses(model, q, idx, T_rigs, np.ones(m, bool),
                           joint_corrections=joint_sigma is not None,
                           offset_joints=np.asarray(offset_joints, dtype=np.int64),
                           eye_to_hand=eye_to_hand)  # fmt: skip
    obs = []
    for c, fc in enumerate(features):
        frame = np.concatenate([np.full(len(f), i) for i, f in enumerate(fc)]).astype(int)
        obs.append((poses.layout.view(frame, c), np.concatenate([f.ids for f in fc]),
                    np.concatenate([f.uv for f in fc]).reshape(-1, 2)))  # fmt: skip
    prob = board_problem(cameras, poses, obs, board, pixel_sigma_px=pixel_sigma_px,
                         joint_sigma=joint_sigma, n_frames=m)  # fmt: skip
    blocks: list = ["intrinsics", *(f"intrinsics{c}" for c in range(1, n_cams))]
    blocks.append(("poses", np.arange(poses.n_kin)))
    C = covariance(prob.problem, prob.problem.x0, blocks, sigma2=pixel_sigma_px**2)
    stds, at = [], 0
    for cam in cameras:
        block = slice(at, at + cam.n_free)
        stds.append(std_by_name(cam, C[block, block]))  # with fy = mu fx by OpenCV's name
        at += cam.n_free
    n_obs = sum(len(o[1]) for o in obs)
    n0 = cameras[0].n_free
    M = to_minimal(poses) if free_idx is not None or poses.n_kin != poses.k else None
    C_kin, cross, estimated = _kinematic_part(C, at, n0, M)
    misfit = held_err = None
    if T_tool_point is not None:
        J = prob.problem.jacobian(prob.problem.x0)
        cols = block_columns(prob.problem, blocks)
        Z = inverse_columns(J, cols)
        rows, K, D = _unit_rows(cameras[0], model, q, features[0], board, T_tool_point,
                                eye_to_hand)  # fmt: skip
        G = misfit_covariance(J, rows, K, cols, Z=Z)
        G_kin, G_cross, _ = _kinematic_part(G, at, n0, M)
        misfit = np.block([[G_kin, G_cross], [G_cross.T, G[:n0, :n0]]])
        held_err = held_error(held_response(J, Z, rows, D), M, at, n0)
    assert C_kin.shape == (minimal_indices(model.joint_types).size,) * 2
    return BoardCramerRao(model, C_kin, tuple(stds), float(pixel_sigma_px), int(n_obs),
                          int(prob.problem.n), estimated, C[:n0, :n0], cross, misfit,
                          held_err)  # fmt: skip


def _kinematic_part(C: np.ndarray, at: int, n0: int,
                    M: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:  # fmt: skip
    """The minimal parameters' block of ``C`` (the cameras' ``at`` columns first, then the
    estimated kinematic parameters), its cross block with the first camera's ``n0`` and which
    minimal parameters are estimated (None: all), through ``M`` (:func:`to_minimal`, None when
    the estimated ones are the minimal ones)."""
    C_kin, cross = C[at:, at:], C[at:, :n0]
    if M is None:
        return C_kin, cross, None
    C_kin, cross = M @ C_kin @ M.T, M @ cross
    estimated = np.abs(M).max(axis=1, initial=0.0) > MOVES
    C_kin[~estimated] = 0.0
    C_kin[:, ~estimated] = 0.0
    cross[~estimated] = 0.0
    return C_kin, cross, estimated


def _unit_rows(camera: CameraModel, model: MCPCModel, q: np.ndarray, features: Sequence[Features],
               board: Board, T_tool_point: np.ndarray,
               eye_to_hand: bool) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:  # fmt: skip
    """Every frame's residual rows of the first camera (the problem's first block, two per
    corner in order), their :func:`selfcal.calibration.board.misfit.unit_rows` and their
    derivative by every minimal parameter (:mod:`selfcal.calibration.board.held`)."""
    T = fk_tool(model, q)
    t = np.asarray(T_tool_point, float)[:3, 3]
    J_id = identification_jacobian(model, q)[:, :, minimal_indices(model.joint_types)]
    rows, K, D, at = [], [], [], 0
    for i, f in enumerate(features):
        if not len(f):
            continue
        x, _, A, _ = board_view(camera, T[i], board.points(f.ids), eye_to_hand)
        rows.append(np.arange(2 * at, 2 * (at + len(f))))
        K.append(unit_rows(A, x, T[i], t, eye_to_hand)[0])
        D.append(A @ J_id[i])
        at += len(f)
    return rows, K, D


def to_minimal(poses: KinematicPoses) -> np.ndarray:
    """(k_min, n_kin) the derivative of the stored model's minimal parameters (the MCPC gauge
    with the start's joint offsets and base offset) by the estimated kinematic parameters, by
    central differences (angles differenced on the circle)."""
    model = poses.model
    minimal = minimal_indices(model.joint_types)
    angle = param_is_angle(minimal)
    p0 = poses.initial_params()

    def stored(p: np.ndarray) -> np.ndarray:
        m = poses.kinematic_model(p)
        g = regauge(chain_transforms(m), m.joint_types, model.joint_offsets, model.base_offset)
        return g.params.reshape(-1)[minimal]

    M = np.zeros((minimal.size, poses.n_kin))
    h = 1e-6
    for j in range(poses.n_kin):
        e = np.zeros_like(p0)
        e[j] = h
        d = stored(p0 + e) - stored(p0 - e)
        d[angle] = np.angle(np.exp(1j * d[angle]))
        M[:, j] = d / (2 * h)
    return M


def board_bounds(
    board: Board,
    cal: BoardCalibrationResult,
    features: Sequence[Sequence[Features]],
    q: np.ndarray,
    q_valid: np.ndarray,
    T_cam_tip: np.ndarray,
    *,
    joint_sigma: np.ndarray | None,
    pixel_sigma_px: float | None = None,
    misfit: bool = False,
) -> tuple[BoardBounds, BoardCramerRao]:
    """``calibration.json``'s ``bounds`` of the board calibration ``cal`` and the
    :class:`BoardCramerRao` they come from: :func:`board_cramer_rao`
    at its estimate (cameras, chain, extrinsics) for the features ``features[c][i]`` of the
    frames it used at their read-back joints ``q`` (m, n) rad; the tool tip ``T_cam_tip`` over
    the postures ``q_valid`` (k, n) rad (the calibration's own when none). ``pixel_sigma_px``:
    the corner noise (None: from the final fit's reprojection RMS, dof-corrected); ``misfit``:
    also what a model error does to the estimate at the tip (:attr:`BoardCramerRao.misfit`,
    for the predicted accuracy). Eye-to-hand
    (``cal.setup``) the chain's tool is the board, and ``T_cam_tip`` the tip in the board frame.

    Raises:
        numpy.linalg.LinAlgError: the Fisher information cannot be inverted.
    """
    n_cams = len(cal.cameras)
    free_idx, offset_joints = estimated_parameters(cal)
    if pixel_sigma_px is None:
        n_obs = sum(len(f) for fc in features for f in fc)
        p = sum(c.n_free for c in cal.cameras) + len(free_idx) + len(offset_joints)
        p += 6 * (n_cams - 1)
        dof = max(2 * n_obs - p, 1)
        pixel_sigma_px = float(cal.reprojection_rms_px * np.sqrt(n_obs / dof))
    b = board_cramer_rao(board, cal.cameras, cal.model, q, features, pixel_sigma_px,
                         joint_sigma=joint_sigma, T_first_cam=cal.T_first_cam,
                         free_idx=free_idx, offset_joints=offset_joints,
                         eye_to_hand=cal.eye_to_hand,
                         T_tool_point=T_cam_tip if misfit else None)  # fmt: skip
    qv = np.atleast_2d(np.asarray(q_valid, dtype=float))
    if qv.size == 0:  # an imported dataset plans no validation postures: the calibration's own
        qv = q
    idx = minimal_indices(cal.model.joint_types)
    ang = param_is_angle(idx)
    std = np.sqrt(np.clip(np.diag(b.covariance), 0, None))
    est = np.ones(idx.size, bool) if b.estimated is None else b.estimated
    params = tuple(
        BoundParameter(
            name=n,
            unit="deg" if a else "mm",
            estimate=float(cal.model.params.reshape(-1)[k] * (180.0 / np.pi if a else 1000.0)),
            std=None,
            bound=float(s * (180.0 / np.pi if a else 1000.0)) if e else None,
            held=n in cal.held,
        )  # fmt: skip
        for n, k, a, s, e in zip(param_names(idx), idx, ang, std, est, strict=True)
    )
    js = None if joint_sigma is None else np.broadcast_to(joint_sigma, (cal.model.n,))
    bounds = BoardBounds(
        pixel_sigma_px=pixel_sigma_px,
        joint_sigma_deg=None if js is None else tuple(float(x) for x in np.degrees(js)),
        observations=b.observations,
        unknowns=b.unknowns,
        tool_tip_rms_mm=ToolTipBound(1000.0 * b.aligned_tool_rms(qv, T_cam_tip), int(len(qv))),
        cameras=tuple(
            CameraBounds(n, d) for n, d in zip(cal.camera_names, b.camera_std, strict=True)
        ),
        parameters=params,
    )
    return bounds, b


def estimated_parameters(cal: BoardCalibrationResult) -> tuple[np.ndarray, np.ndarray]:
    """The kinematic parameters ``cal`` estimated: flat MCPC indices and joint offsets (0
    based), from its selection's ``identified`` names (every minimal parameter, no offset, for
    a result without a selection)."""
    types = cal.model.joint_types
    if not cal.selection or "identified" not in cal.selection:
        return minimal_indices(types), np.zeros(0, np.int64)
    flat = np.arange(6 * (len(types) + 1))
    by_name = dict(zip(param_names(flat), flat.tolist(), strict=True))
    names = [str(x) for x in cal.selection["identified"]]
    offsets = [int(x.removeprefix("offset_j")) - 1 for x in names if x.startswith("offset_j")]
    idx = [by_name[x] for x in names if not x.startswith("offset_j")]
    return np.array(idx, np.int64), np.array(offsets, np.int64)
