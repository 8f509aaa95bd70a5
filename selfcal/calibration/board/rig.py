"""A rig of N >= 2 cameras calibrated from a board: every camera its own model, the extrinsics.

Route (:func:`calibrate_board_rig`):

1. every camera alone: :func:`selfcal.calibration.board.calibrate.calibrate_board` (OpenCV's calibration, then
   the bundle adjustment with the board held) with *its own* model and free parameters;
2. the extrinsics ``T_first_cam[c]`` (camera ``c`` in the first camera's frame) from the frames
   both cameras see the board in: ``T_cam0_board inv(T_camc_board)``, averaged (rotations by
   their chordal mean, translations by their mean); an error when they share none;
3. one adjustment of every camera's free parameters (one ``intrinsics`` block per camera), the
   first camera's board pose per frame and the extrinsics (:class:`BoardRigPoses`) against the
   pixels of every camera, the board's points held: the board frame is the world and its
   geometry gives the scale, so nothing is held for a gauge.

Frames and units: ``T_cam_board`` maps board coordinates to a camera's OpenCV frame (m); views
follow :class:`selfcal.estimation.observations.ViewLayout` (frame ``i``, camera ``c``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.calibrate import BoardCalibration, calibrate_board
from selfcal.camera import CameraModel, Pinhole
from selfcal.errors import EstimationError, InputError
from selfcal.estimation.observations import ViewLayout
from selfcal.estimation.pose_models import RigPoses, _LocalPoseBlock
from selfcal.estimation.reprojection import ReprojectionBlock
from selfcal.solver import Loss, ParameterBlock, Problem, SolverOptions, covariance, solve
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose, make_pose

__all__ = ["BoardRigPoses", "BoardRigCalibration", "calibrate_board_rig"]


class BoardRigPoses(RigPoses):
    """Poses of a rig before a board: per registered frame the first camera's ``T_first_board``
    and per further camera ``T_cam_first``, ``T_cam_board = T_cam_first T_first_board``. No
    gauge (the board's known points fix frame and scale), unlike :class:`RigPoses` whose
    products and Jacobians it shares. Parameter layout: ``[w, v]`` of each registered frame,
    then ``[w, v]`` of each further camera."""

    def __init__(self, T0_first_board: np.ndarray, T0_cam_first: np.ndarray, registered):
        self.T0 = np.asarray(T0_first_board, dtype=float).copy()
        self.rigs0 = np.asarray(T0_cam_first, dtype=float).reshape(-1, 4, 4).copy()
        self.registered = np.asarray(registered, dtype=bool).copy()
        self.n_configs = len(self.T0)
        self.layout = ViewLayout(self.n_configs, 1 + len(self.rigs0))
        self.n_views = self.layout.n_views
        self.cfg_idx = np.flatnonzero(self.registered)
        n_first = 6 * len(self.cfg_idx)
        self.rig_cols_all = [n_first + 6 * c + np.arange(6) for c in range(len(self.rigs0))]
        self.n_params = n_first + 6 * len(self.rigs0)
        cols = -np.ones((self.n_views, 12), dtype=np.int64)
        by = self.layout.by_frame(cols)
        for j, cfg in enumerate(self.cfg_idx):
            by[cfg, :, :6] = np.arange(6 * j, 6 * j + 6)
        for c, rc in enumerate(self.rig_cols_all, start=1):
            by[self.registered, c, 6:] = rc
        # the first camera's views name the second camera's extrinsics too (zero derivative):
        # every view then has 12 real columns (with -1 slots in some rows of the piece the
        # engine's adjustment crawled, 400+ iterations, where Gauss-Newton on the same
        # Jacobian converges in 3 steps)
        by[self.registered, 0, 6:] = self.rig_cols_all[0]
        self._cols = cols

    def _first(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        T = np.full((self.n_configs, 4, 4), np.nan)
        J = np.zeros((self.n_configs, 6, 6))
        q = p[: 6 * len(self.cfg_idx)].reshape(-1, 6)
        T[self.cfg_idx], J[self.cfg_idx] = _LocalPoseBlock.evaluate(
            self.T0[self.cfg_idx], q[:, :3], q[:, 3:]
        )
        return T, J

    def _rig(self, p: np.ndarray, c: int = 0) -> tuple[np.ndarray, np.ndarray]:
        q = p[self.rig_cols_all[c]]
        T, J = _LocalPoseBlock.evaluate(self.rigs0[c][None], q[None, :3], q[None, 3:])
        return T[0], J[0]

    def first(self, p: np.ndarray) -> np.ndarray:
        """``T_first_board`` (m, 4, 4) of every frame (NaN where not registered)."""
        return self._first(p)[0]


@dataclass
class BoardRigCalibration:
    """Result of :func:`calibrate_board_rig`: ``cameras`` (each its own model, the free
    parameters adjusted) and their ``std``; ``T_first_cam`` (N, 4, 4) m (the first the
    identity) with ``T_first_cam_std`` (N, 6) (rotation rad, translation m, of the extrinsics'
    local parameters); ``T_first_board`` (m, 4, 4) per frame (NaN where no camera sees the
    board); ``rms_px`` the 2-D RMS of every camera's inliers; ``single``: each camera's own
    calibration (step 1)."""

    cameras: tuple[CameraModel, ...]
    std: tuple[dict[str, float], ...]
    T_first_cam: np.ndarray
    T_first_cam_std: np.ndarray
    T_first_board: np.ndarray
    rms_px: float
    single: tuple[BoardCalibration, ...]


def _mean_pose(T: np.ndarray) -> np.ndarray:
    """The mean (4, 4) of rigid transforms (k, 4, 4): chordal mean rotation, mean translation."""
    R = Rotation.from_matrix(T[:, :3, :3]).mean().as_matrix()
    return make_pose(R, T[:, :3, 3].mean(axis=0))


def calibrate_board_rig(
    board: Board,
    features: Sequence[Sequence[Features]],
    sizes: Sequence[tuple[int, int]],
    models: Sequence[str],
    frees: Sequence[Sequence[str]],
    *,
    names: Sequence[Sequence[str]] | None = None,
    max_iter: int = 100,
    initials: Sequence[Pinhole | None] | None = None,
) -> BoardRigCalibration:
    """Calibrate N cameras (``features[c]``: one :class:`Features` per frame, the frames in the
    same order for every camera; ``sizes[c]`` (width, height) px; ``models[c]``, ``frees[c]``
    its model and free parameters; ``initials[c]``: a camera to start from, as
    :func:`selfcal.calibration.board.calibrate.calibrate_board`'s ``initial``) and their extrinsics to the first
    (module docstring).

    Raises:
        InputError: fewer than two cameras, unequal frame counts, or a camera that never sees
            the board together with the first.
        selfcal.calibration.board.calibrate.BoardInputError / BoardMismatchError: as ``calibrate_board``.
        EstimationError: the joint adjustment did not converge.
    """
    n = len(features)
    m = len(features[0]) if n else 0
    if n < 2 or any(len(f) != m for f in features):
        raise InputError(
            f"a board rig needs two or more cameras with one image each per frame; got {n} "
            f"camera(s) with {[len(f) for f in features]} frames",
            fix="give every camera the same frames (one image per camera and frame)",
        )
    single = tuple(
        calibrate_board(
            board,
            features[c],
            *sizes[c],
            free=frees[c],
            model=models[c],
            names=None if names is None else names[c],
            initial=None if initials is None else initials[c],
        )  # fmt: skip
        for c in range(n)
    )
    T0 = single[0].T_cam_board
    rigs0 = []
    for c in range(1, n):
        both = single[0].used & single[c].used
        if not both.any():
            raise InputError(
                f"camera {c} never sees the board in a frame the first camera sees it in; its "
                "extrinsics cannot be found",
                fix="add frames in which both cameras see the board",
            )
        rigs0.append(_mean_pose(single[c].T_cam_board[both] @ inv_pose(T0[both])))
    T_cam_first = np.stack(rigs0)
    reg = np.zeros(m, bool)
    T_first = np.full((m, 4, 4), np.nan)
    for c in reversed(range(n)):  # the first camera's own pose where it has one
        use = single[c].used
        R = np.eye(4) if c == 0 else inv_pose(T_cam_first[c - 1])
        T_first[use] = R @ single[c].T_cam_board[use]
        reg |= use
    poses = BoardRigPoses(T_first, T_cam_first, reg)
    blocks, params = [], []
    ids_all = np.unique(np.concatenate([f.ids for fc in features for f in fc]))
    ids_all = ids_all[~np.isnan(board.points(ids_all)).any(axis=1)]
    for c, sc in enumerate(single):
        keep = sc.inlier
        view = poses.layout.view(sc.view[keep], np.full(int(keep.sum()), c))
        pidx = np.searchsorted(ids_all, sc.feature[keep])
        uv = np.concatenate([features[c][i].uv for i in np.flatnonzero(sc.used).tolist()])[keep]
        blocks.append(ReprojectionBlock(sc.camera, poses, view, pidx, uv, Loss("linear"),
                                        name=f"reprojection{c}", intrinsics=f"intrinsics{c}"))  # fmt: skip
        params.append(ParameterBlock(f"intrinsics{c}", sc.camera.free_values()))
    params += [
        ParameterBlock("poses", poses.initial_params(), instance=poses.param_instances()),
        ParameterBlock(
            "points", board.points(ids_all).ravel(), held=np.ones(3 * len(ids_all), bool)
        ),
    ]
    prob = Problem(params, blocks)
    sol = solve(prob, SolverOptions(tol=1e-12, max_iterations=max_iter, eliminate="poses"))
    if sol.status <= 0:
        raise EstimationError(
            f"the adjustment of the board rig did not converge within {max_iter} iterations "
            f"({sol.message})",
            fix="check that every camera's images belong to the same frames (file order)",
        )
    r = np.concatenate([sol.residuals[b.name] for b in blocks])
    dof = max(r.size - prob.n, 1)
    sigma2 = float(np.sum(r**2)) / dof
    cams, stds = [], []
    for c, sc in enumerate(single):
        cam = sc.camera.with_free_values(sol.values[f"intrinsics{c}"])
        C = covariance(prob, sol.x, [f"intrinsics{c}"], sigma2=sigma2)
        cams.append(cam)
        stds.append(
            dict(zip(cam.free, np.sqrt(np.clip(np.diag(C), 0, None)).tolist(), strict=True))
        )
    p = sol.values["poses"]
    n_first = 6 * len(poses.cfg_idx)
    C_rig = covariance(prob, sol.x, [("poses", np.arange(n_first, poses.n_params))], sigma2=sigma2)
    rig_std = np.sqrt(np.clip(np.diag(C_rig), 0, None)).reshape(-1, 6)
    T_first_cam = np.concatenate([np.eye(4)[None], inv_pose(poses.rigs(p))])
    return BoardRigCalibration(
        cameras=tuple(cams), std=tuple(stds), T_first_cam=T_first_cam,
        T_first_cam_std=np.concatenate([np.zeros((1, 6)), rig_std]),
        T_first_board=poses.first(p), rms_px=float(np.sqrt(np.mean(np.sum(r**2, axis=1)))),
        single=single,
    )  # fmt: skip
