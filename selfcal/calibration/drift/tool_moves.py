"""Where a candidate change of the drift check moves the tool (issue #29): the tool point's (the
flange's) move and the tool's rotation by a fitted change
(:mod:`selfcal.calibration.drift.attribution`), and the bound on a kinematic change fitted
beside the camera's, which moves no tool point (:func:`kinematic_bound_mm`).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from selfcal.calibration.drift.attribution import Fits
from selfcal.calibration.drift.views import ViewJacobians

__all__ = ["BOUND_LEVEL", "kinematic_bound_mm", "tool_point_moves"]

BOUND_LEVEL = 0.95
"""The confidence of the tool-point bound a camera change's verdict gives."""


def _twist_map(key: str, views: list[ViewJacobians]) -> np.ndarray:
    """(m, 6, d) the tool point's move (m) and the tool's rotation (rad), world frame, at every
    view per unit of the kinematic candidate ``key``'s d parameters
    (:mod:`selfcal.calibration.drift.attribution`)."""
    if key == "hand-eye":
        return np.array([v.B for v in views])
    if key == "world":
        return np.array([v.B @ v.Ad for v in views])
    j = int(key.split(" ")[1]) - 1
    return np.array([v.B @ v.tw[:, j : j + 1] for v in views])


def tool_point_moves(key: str, x: np.ndarray, views: list[ViewJacobians]) -> np.ndarray:
    """(m, 6) the tool point's move (m) and the tool's rotation (rad), world frame, at every
    view by the candidate change ``key`` (:mod:`selfcal.calibration.drift.attribution`) of
    size ``x``: 0 for the camera."""
    if key == "camera":
        return np.zeros((len(views), 6))
    return _twist_map(key, views) @ x


def kinematic_bound_mm(fits: Fits, rw: np.ndarray, views: list[ViewJacobians],
                       level: float = BOUND_LEVEL) -> float:  # fmt: skip
    """The largest RMS tool-point move (over the views, mm) that a kinematic candidate (the
    mounts, a joint's offset) fitted beside the camera's change reaches at confidence ``level``:
    per candidate its fitted move plus the confidence ellipsoid's largest RMS move (the whitened
    fit's parameters have the covariance ``(D^T D)^-1``), the largest over the candidates.
    ``fits`` the candidates' whitened columns, ``rw`` the whitened residuals."""
    cols = fits.directed_columns
    cam = cols["camera"]
    worst = 0.0
    for key in fits.what:
        if key == "camera":
            continue
        G = (np.concatenate([cols[f"{key} translation"], cols[f"{key} rotation"]], axis=1)
             if key in ("hand-eye", "world") else cols[key])  # fmt: skip
        D = np.concatenate([cam, G], axis=1)
        x = np.linalg.lstsq(D, rw, rcond=None)[0][cam.shape[1] :]
        cov = np.linalg.pinv(D.T @ D)[cam.shape[1] :, cam.shape[1] :]
        M = _twist_map(key, views)[:, :3].reshape(-1, G.shape[1]) / np.sqrt(len(views))
        # |M x| = the moves' RMS
        spread = float(np.max(np.linalg.eigvalsh(M @ cov @ M.T)))
        reach = np.linalg.norm(M @ x) + np.sqrt(chi2.ppf(level, G.shape[1]) * max(spread, 0.0))
        worst = max(worst, float(reach))
    return worst * 1e3
