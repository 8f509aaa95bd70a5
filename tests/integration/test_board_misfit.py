"""What a model error in the calibration frames does to the board route's estimate
(selfcal/calibration/board/misfit.py, issue #29): the bounds' ``misfit`` covariance against
the least-squares response to pixels drawn through tool poses moved by the model error, found
without the module's derivatives (exact re-projection, the problem's residuals for the data)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm
from synthetic_board import BOARD, CAMERA, ROBOT, make_lab
from synthetic_features import board_features, board_residuals

from selfcal.calibration.board import misfit
from selfcal.calibration.board.bounds import board_cramer_rao
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices
from selfcal.robot.definition import load_robot
from selfcal.target.base import Features
from selfcal.transforms import inv_pose, make_pose, skew


def test_the_misfit_covariance_is_the_fits_response_to_moved_tool_poses(monkeypatch):
    """Per frame a model error of 1 m per tool-point coordinate (the tool point moved in the
    board frame) and 1 m / L rad per rotation coordinate (the tool turned about the tool point,
    L the tool point's mean distance to the board points in view): the covariance of the
    linearised fit's answer to the pixels it moves, summed over independent frames, is the
    bounds' ``misfit`` (kinematic parameters, then the camera's); the frames taken a few at a
    time (``CHUNK``)."""
    monkeypatch.setattr(misfit, "CHUNK", 4)
    lab = make_lab(0)
    q = load_robot(ROBOT).home + np.random.default_rng(3).normal(0, np.radians(3.0), (6, 6))
    feats = board_features(lab.true_model, lab.T_world_board, q, 0.0, 0)
    model = lab.true_model.with_base(inv_pose(lab.T_world_board))  # world = the board
    T_tip = make_pose(np.eye(3), [0.01, -0.02, -0.08])  # a point behind the camera
    cr = board_cramer_rao(BOARD, [CAMERA], model, q, [feats], 0.2, T_tool_point=T_tip)
    assert cr.misfit is not None

    poses = KinematicPoses(model, q, minimal_indices(model.joint_types), np.zeros((0, 4, 4)),
                           np.ones(len(q), bool))  # fmt: skip

    def residuals(fs: list[Features]):
        return board_residuals(poses, fs, 0.2)

    r0, prob = residuals(feats)
    J = prob.problem.jacobian(prob.problem.x0).toarray()
    t = T_tip[:3, 3]
    h = 1e-6
    moved = []
    for i, (T, f) in enumerate(zip(fk_tool(model, q), feats, strict=True)):
        X = BOARD.points(f.ids)
        x = (X - T[:3, 3]) @ T[:3, :3]  # camera frame
        lever = np.mean(np.linalg.norm(x - t, axis=1))
        p = T[:3, :3] @ t + T[:3, 3]  # the tool point in the board frame

        def pixels(d: np.ndarray, T=T, X=X, lever=lever, p=p) -> np.ndarray:
            R = expm(skew(d[3:] / lever))
            T2 = T.copy()
            T2[:3, :3] = R @ T[:3, :3]
            T2[:3, 3] = R @ (T[:3, 3] - p) + p + d[:3]
            Tc = inv_pose(T2)
            return CAMERA.project(X @ Tc[:3, :3].T + Tc[:3, 3])

        for e in np.eye(6):
            fs = list(feats)
            fs[i] = Features(f.ids, f.uv + (pixels(h * e) - pixels(-h * e)) / (2 * h))
            moved.append(residuals(fs)[0] - r0)
    X = np.linalg.lstsq(J, np.stack(moved, axis=1), rcond=None)[0]
    cols = np.concatenate([prob.problem.columns("intrinsics"), prob.problem.columns("poses")])
    X = X[cols]
    n0 = CAMERA.n_free
    X = np.concatenate([X[n0:], X[:n0]])  # the bounds' order: kinematics, then the camera
    G = X @ X.T
    assert np.abs(cr.misfit - G).max() < 1e-4 * np.abs(G).max()
    assert np.abs(G).max() > 0
