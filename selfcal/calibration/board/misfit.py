"""What a model error does to a board calibration's pixels and to its estimate (issue #29).

The board route's model error (:mod:`selfcal.calibration.board.accuracy`) is an error of every
frame's tool pose the chain cannot express: ``m`` per tool-point coordinate and ``m / L`` per
rotation coordinate (``L`` the tool point's mean distance to the board points in view), drawn
afresh per frame. It moves a frame's pixels (:func:`unit_rows`: their derivative by it, the
frame's ``K``), and, in the frames a calibration was fitted on, it moves the estimate: the least
squares fit takes it as data, so its estimate errs by ``(J^T J)^-1 J^T K eps`` on top of what
the pixel noise gives (:func:`misfit_covariance`: the covariance of that error per unit ``m^2``,
``G``). A prediction from the fit then errs by ``m^2 (u + w)`` in squared pixels beyond the
noise's share: ``u`` the frame's own (``tr K K^T``), ``w`` what ``G`` carries to it. Counting
``w`` is what keeps a fold that extrapolates (a configuration far from the others, whose
prediction the training frames' model error throws far) from being read as a large model error
everywhere: the folds' excess is split by ``u + w``, and the calibration on every frame, whose
``G`` is smaller where it interpolates, is predicted with its own ``w``.

Taken as independent per frame; the same error shared by a configuration's frames (its wrist
moves only) gives the real sets' folds about the same ``w`` (photoneo's predicted held-out RMS
1.317 against 1.319 px), so the simpler one is kept. The pixel noise is the fit's own residual
level, which holds what of the model error the fit could not absorb: that part is counted
twice (small where the folds' excess is large against the noise).

Frames: the camera frame for the pixels' points, the chain's tool pose ``T_tool`` (eye-in-hand
the camera in the board frame, eye-to-hand the board in the camera frame); SI; pixels px.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from selfcal.solver import inverse_columns
from selfcal.transforms import inv_pose, skew

if TYPE_CHECKING:
    from selfcal.camera import CameraModel

__all__ = ["CHUNK", "board_view", "misfit_covariance", "pose_jacobian", "tip_map", "unit_rows"]

CHUNK = 256
"""Frames per product in :func:`misfit_covariance` (its memory: their rows times the unknowns
kept, not every row's)."""


def pose_jacobian(Jx: np.ndarray, x: np.ndarray, T_tool: np.ndarray,
                  eye_to_hand: bool) -> np.ndarray:  # fmt: skip
    """(2k, 6) the derivative of the pixels of the board points ``x`` (k, 3) (camera frame, m)
    by a body twist ``[v; w]`` (m, rad) of the chain's tool pose ``T_tool`` (4, 4) (the camera
    in the board frame, eye-to-hand the board in the camera frame); ``Jx`` (k, 2, 3) the
    projection's derivative by the point (px per m)."""
    if eye_to_hand:  # camera <- board = the tool pose; the twist moves the board
        R = T_tool[:3, :3]
        dX = np.concatenate([np.broadcast_to(R, (len(x), 3, 3)), -skew(x - T_tool[:3, 3]) @ R], 2)
    else:  # camera <- board = inv(tool pose); the twist moves the camera
        dX = np.concatenate([np.broadcast_to(-np.eye(3), (len(x), 3, 3)), skew(x)], 2)
    return (Jx @ dX).reshape(-1, 6)


def board_view(camera: CameraModel, T_tool: np.ndarray, X: np.ndarray,
               eye_to_hand: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The board points ``X`` (k, 3) (board frame, m) seen by ``camera`` at the chain's tool
    pose ``T_tool`` (4, 4) (eye-in-hand the camera in the board frame, eye-to-hand the board in
    the camera frame): their points ``x`` (k, 3) in the camera frame (m), predicted pixels
    (k, 2), derivative by a body twist of the tool pose ``A`` (2k, 6) (:func:`pose_jacobian`)
    and by the camera's free parameters (k, 2, c)."""
    T_cam_board = T_tool if eye_to_hand else inv_pose(T_tool)
    x = np.asarray(X, float) @ T_cam_board[:3, :3].T + T_cam_board[:3, 3]
    uv, Jx, Jc = camera.project_free(x)
    return x, uv, pose_jacobian(Jx, x, T_tool, eye_to_hand), Jc


def tip_map(T_tool: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(6, 6) the map of a body twist ``[v; w]`` of the tool pose ``T_tool`` to the move of the
    tool point ``t`` (3,) (tool frame, m) and the rotation, both in the world frame."""
    R = T_tool[:3, :3]
    B = np.zeros((6, 6))
    B[:3, :3], B[:3, 3:], B[3:, 3:] = R, -R @ skew(np.asarray(t, float)), R
    return B


def unit_rows(A: np.ndarray, x: np.ndarray, T_tool: np.ndarray, t: np.ndarray,
              eye_to_hand: bool) -> tuple[np.ndarray, float]:  # fmt: skip
    """A frame's ``K`` (2k, 6): its pixels' derivative by the model error in units of ``m``
    (module docstring), from ``A`` (2k, 6) their derivative by the tool pose's body twist
    (:func:`pose_jacobian`) of the board points ``x`` (k, 3) (camera frame, m), the tool pose
    ``T_tool`` and the tool point ``t`` (3,) (tool frame, m); and the lever ``L`` (m)."""
    tip_cam = T_tool[:3, :3] @ t + T_tool[:3, 3] if eye_to_hand else t  # camera frame
    lever = float(np.mean(np.linalg.norm(x - tip_cam, axis=1)))
    D_half = np.linalg.inv(tip_map(T_tool, t)) @ np.diag(np.r_[np.ones(3), np.full(3, 1 / lever)])
    return A @ D_half, lever


def misfit_covariance(J: sp.spmatrix, rows: list[np.ndarray], K: list[np.ndarray],
                      cols: np.ndarray, Z: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """``G`` (len(cols), len(cols)): the covariance of the unknowns ``cols`` a model error of
    unit ``m`` in every frame gives the least-squares estimate of the Jacobian ``J`` (its
    residuals in px, the estimate at ``(J^T J)^-1 J^T`` of the data), frame ``i``'s pixels the
    residual rows ``rows[i]`` (2k,) moved by ``K[i]`` (2k, 6) (:func:`unit_rows`), independently
    per frame (module docstring). Only the columns ``cols`` of ``(J^T J)^-1`` are solved for
    (:func:`selfcal.solver.inverse_columns`; ``Z`` when given), then carried through ``J^T K``
    frame by frame."""
    Jr = sp.csr_matrix(J)
    Z = inverse_columns(J, cols) if Z is None else Z
    G = np.zeros((len(cols), len(cols)))
    for a in range(0, len(rows), CHUNK):  # J (J^T J)^-1 restricted, a chunk of frames at a time
        part = rows[a : a + CHUNK]
        W = Jr[np.concatenate(part)] @ Z
        at = 0
        for r, k in zip(part, K[a : a + CHUNK], strict=True):
            X = W[at : at + len(r)].T @ k  # (len(cols), 6): the estimate's move per unit error
            G += X @ X.T
            at += len(r)
    return G
