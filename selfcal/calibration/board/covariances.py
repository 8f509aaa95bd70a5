"""The covariances of a board calibration's estimate that its accuracy block carries to the
tool point and the drift check carries to new views (:mod:`selfcal.calibration.board.accuracy`):
the estimated minimal kinematic parameters (SI: m, rad) with the first camera's free parameters
(px and the lens's own units), their correlation included."""

from __future__ import annotations

import numpy as np

from selfcal.calibration.board.bounds import BoardCramerRao
from selfcal.kinematics.mcpc import minimal_indices

__all__ = ["bounds_covariance", "bounds_noise_covariance", "padded_bounds_covariance"]


def bounds_covariance(cr: BoardCramerRao,
                        misfit: bool = False) -> tuple[np.ndarray, np.ndarray, int]:  # fmt: skip
    """The estimated minimal parameters' flat indices, the joint covariance (p + c, p + c) of
    them and the first camera's free parameters (with their correlation), and ``c``;
    ``misfit``: instead of the covariance, what a unit model error gives them
    (:attr:`BoardCramerRao.misfit`, zero when the bounds carry none)."""
    idx = minimal_indices(cr.model.joint_types)
    est = np.ones(idx.size, bool) if cr.estimated is None else np.asarray(cr.estimated, bool)
    p = int(est.sum())
    n0 = 0 if cr.camera_covariance is None else len(cr.camera_covariance)
    keep = np.r_[np.flatnonzero(est), idx.size + np.arange(n0)]
    if misfit:
        G = np.zeros((p + n0, p + n0)) if cr.misfit is None else cr.misfit[np.ix_(keep, keep)]
        return idx[est], G, n0
    return idx[est], padded_bounds_covariance(cr)[np.ix_(keep, keep)], n0


def bounds_noise_covariance(cr: BoardCramerRao, cols: np.ndarray) -> np.ndarray:
    """(p + c, p + c) the covariance of ``cr``'s estimate from the noise alone (no deviation, no
    model error) in the order of the block's ``estimated`` (the flat minimal indices ``cols``
    (p,); a parameter ``cr`` held has zero rows) and the first camera's free parameters: what a
    calibration frame's noise shares with the estimate (:mod:`selfcal.calibration.drift.paired`)."""
    idx, C0, n0 = bounds_covariance(cr)
    at = {int(k): j for j, k in enumerate(cols)}
    keep = np.r_[[at[int(k)] for k in idx], len(cols) + np.arange(n0)].astype(int)
    C = np.zeros((len(cols) + n0, len(cols) + n0))
    C[np.ix_(keep, keep)] = C0
    return C


def padded_bounds_covariance(cr: BoardCramerRao) -> np.ndarray:
    """(k + c, k + c) the covariance of ``cr``'s estimate in every minimal parameter's order
    (zero rows where it holds one) then the first camera's ``c`` free parameters."""
    k = len(cr.covariance)
    n0 = 0 if cr.camera_covariance is None else len(cr.camera_covariance)
    C = np.zeros((k + n0, k + n0))
    C[:k, :k] = cr.covariance
    if n0:
        assert cr.camera_cross is not None
        C[k:, k:] = cr.camera_covariance
        C[:k, k:] = cr.camera_cross
        C[k:, :k] = cr.camera_cross.T
    return C
