"""What the kinematic parameters a board calibration holds at the drawing do to its prediction
(selfcal/calibration/board/held.py, issue #29): the bounds' ``held`` response against the
least-squares answer to pixels drawn through an arm whose held parameter deviates, found
without the module's derivatives (the arm re-projected, the problem's residuals for the data),
and the deviation's share of the predicted tool-point error away from the postures."""

from __future__ import annotations

import numpy as np
from synthetic_board import BOARD, CAMERA, ROBOT, make_lab
from synthetic_features import board_features, board_residuals

from selfcal.calibration.board.accuracy import board_error_model
from selfcal.calibration.board.bounds import board_cramer_rao, to_minimal
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.held_prior import with_deviation
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.robot.definition import load_robot
from selfcal.target.base import Features
from selfcal.transforms import inv_pose, make_pose

HELD = ("beta2", "ly3")


def test_a_held_parameters_deviation_is_the_fits_answer_and_shows_away_from_the_postures():
    """Two inner parameters held: per unit deviation of each, the linearised fit's answer to
    the pixels the deviated arm moves (the estimate's move less the deviation, on the minimal
    parameters, then the camera's) is the bounds' ``held`` column; a deviation of an estimated
    parameter is absorbed (its column ~0). With the default deviation the predicted tool-point
    error at a posture 40 deg away gains several times the noise's share (0.02 px)."""
    lab = make_lab(0)
    robot = load_robot(ROBOT)
    rng = np.random.default_rng(3)
    q = robot.home + rng.normal(0, np.radians(5.0), (8, 6))
    model = lab.true_model.with_base(inv_pose(lab.T_world_board))  # world = the board
    types = model.joint_types
    idx = minimal_indices(types)
    names = param_names(idx)
    free = idx[[n not in HELD for n in names]]
    feats = board_features(lab.true_model, lab.T_world_board, q, 0.0, 0)
    T_tip = make_pose(np.eye(3), [0.01, -0.02, -0.08])
    cr = board_cramer_rao(BOARD, [CAMERA], model, q, [feats], 0.02, free_idx=free,
                          T_tool_point=T_tip)  # fmt: skip
    assert cr.held is not None and cr.estimated is not None
    assert [n for n, e in zip(names, cr.estimated, strict=True) if not e] == list(HELD)

    poses = KinematicPoses(model, q, free, np.zeros((0, 4, 4)), np.ones(len(q), bool))

    def residuals(fs: list[Features]):
        return board_residuals(poses, fs, 0.02)

    r0, prob = residuals(feats)
    J = prob.problem.jacobian(prob.problem.x0).toarray()
    cols = np.concatenate([prob.problem.columns("intrinsics"), prob.problem.columns("poses")])
    n0, k = CAMERA.n_free, idx.size
    M = to_minimal(poses)
    h = 1e-6
    for name in (*HELD, "lx2"):  # the held ones, and one the fit estimates
        j = names.index(name)

        def arm(step: float, j: int = j) -> MCPCModel:  # the chain in the board frame
            p = model.params.copy()
            p.reshape(-1)[idx[j]] += step
            return MCPCModel(p, types, model.joint_offsets, model.base_offset)

        moved = [residuals(board_features(arm(s), np.eye(4), q, 0.0, 0))[0] - r0
                 for s in (h, -h)]  # fmt: skip
        Y = -np.linalg.lstsq(J, (moved[0] - moved[1]) / (2 * h), rcond=None)[0][cols]
        want = np.r_[M @ Y[n0:] - np.eye(k)[j], Y[:n0]]
        scale = 1.0 if name in HELD else np.abs(cr.held[:, names.index(HELD[0])]).max()
        assert np.abs(cr.held[:, j] - want).max() < 1e-4 * scale
        if name in HELD:
            assert np.abs(want[:k]).max() > 0.5  # the held parameter itself is off by d
        else:
            assert np.abs(cr.held[:, j]).max() < 1e-4 * scale  # absorbed

    var = Deviation().variance(types)
    em0, _ = board_error_model(cr, T_tip)
    em, covered = board_error_model(with_deviation(cr, var), T_tip)
    assert set(HELD) <= set(covered)
    far = robot.home + np.radians([30.0, -40.0, 40.0, 20.0, 30.0, 0.0])

    def rms(model_: object, at: np.ndarray) -> np.ndarray:
        return np.sqrt(np.trace(model_.estimation_covariance(at)[:, :3, :3], axis1=1, axis2=2))

    held_far = np.sqrt(rms(em, far[None]) ** 2 - rms(em0, far[None]) ** 2)[0]
    assert held_far > 3.0 * rms(em0, far[None])[0]  # 2.3 mm against 0.35 mm
