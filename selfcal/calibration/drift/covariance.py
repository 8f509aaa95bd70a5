"""The covariance of the drift check's stacked new views (``Sigma`` of
:mod:`selfcal.calibration.drift.images`' docstring, px^2): what the calibration's estimate
error, its frames' noise shared with paired views and each view's own noise give their
residuals, and what the views tell of a change (its information, ``G^T Sigma^-1 G``)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

from selfcal.calibration.drift.views import ViewJacobians
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.kinematics.tool_error import ToolErrorModel

__all__ = ["change_information", "estimate_covariance", "view_covariance"]


def view_covariance(C: np.ndarray, views: list[ViewJacobians],
                C_noise: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """``Sigma`` (module docstring) of the stacked views, ``C`` the estimate's covariance,
    ``C_noise`` its part from the calibration frames' noise (None: a file written before it,
    the paired views' cross term left out)."""
    H = np.concatenate([np.concatenate([v.kin, v.cam], axis=1) * (not v.paired) for v in views])
    sigma = H @ C @ H.T  # a paired view's estimate cancels (selfcal.calibration.drift.paired)
    if C_noise is not None:  # but its frame's noise moved the estimate the others hold
        Y = np.concatenate([np.zeros((len(v.r), H.shape[1])) if v.frame_H is None else v.frame_H
                            for v in views])  # fmt: skip
        cross = Y @ C_noise @ H.T
        sigma += cross + cross.T
    at = np.cumsum([0] + [len(v.r) for v in views])
    for i, v in enumerate(views):
        sigma[at[i] : at[i + 1], at[i] : at[i + 1]] += v.local
        for j, w in enumerate(views[:i]):  # views paired with one frame share its noise
            if v.frame is not None and w.frame is not None and w.frame[0] == v.frame[0]:
                shared = v.frame[2][np.ix_(v.frame[1], w.frame[1])]
                sigma[at[i] : at[i + 1], at[j] : at[j + 1]] += shared
                sigma[at[j] : at[j + 1], at[i] : at[i + 1]] += shared.T
    return sigma


def change_information(C: np.ndarray, views: list[ViewJacobians], G: np.ndarray,
                       C_noise: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """(d, d) ``G^T Sigma^-1 G``: what the stacked ``views`` (``Sigma`` their covariance in the
    check, ``C`` and ``C_noise`` as in :func:`selfcal.calibration.drift.images.image_drift_check`) tell of a change whose pixels
    move by ``G`` (2k, d) per unit of its d parameters (e.g. a mount's translation, px per m):
    ``x^T (G^T Sigma^-1 G) x`` is the noncentrality of the change ``x``
    (:func:`selfcal.calibration.drift.p_value.known_change_power`)."""
    L = np.linalg.cholesky(view_covariance(C, views, C_noise))
    Gw = solve_triangular(L, np.asarray(G, float), lower=True)
    return Gw.T @ Gw


def estimate_covariance(cal: BoardCalibrationResult, em: ToolErrorModel) -> np.ndarray:
    """(p + c, p + c) the covariance of the calibration's estimated kinematic parameters (``em``,
    its ``accuracy`` block) and its first camera's free parameters with their correlation (the
    block's ``camera_covariance_si`` and ``camera_cross_si``); a file written before them: the
    camera's standard deviations alone, taken as independent of the kinematics."""
    p, camera = len(em.covariance), cal.cameras[0]
    c = len(camera.free)
    C = np.zeros((p + c, p + c))
    C[:p, :p] = em.covariance
    block = cal.accuracy or {}
    cam = np.asarray(block.get("camera_covariance_si", []), float)
    cross = np.asarray(block.get("camera_cross_si", []), float)
    if cam.shape == (c, c) and cross.shape == (p, c):
        C[p:, p:], C[:p, p:], C[p:, :p] = cam, cross, cross.T
    else:
        std = cal.camera_std[0]
        C[p:, p:] = np.diag(np.array([std.get(k, 0.0) for k in camera.free], float) ** 2)
    return C
