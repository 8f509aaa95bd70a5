"""The prediction of a board calibration with the deviation from the drawing of the parameters
it holds (issue #29): :mod:`selfcal.calibration.board.held`'s response ``R`` (per unit
deviation, :attr:`selfcal.calibration.board.bounds.BoardCramerRao.held`) weighed by the prior
``S`` (:class:`selfcal.calibration.board.plan_predict.Deviation`, the one ``selfcal plan``
predicts with) into the bounds' covariances, ``c R S R^T``, ``c`` (0-1) the share of the prior the
calibration's leave-one-configuration-out frames show (:func:`held_share`; the prior an upper
limit: the selection holds a direction more often when the arm deviates little along it). SI.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from selfcal.calibration.board.bounds import BoardCramerRao
from selfcal.calibration.board.plan_predict import Deviation

__all__ = ["held_block", "held_share", "with_deviation"]


def with_deviation(cr: BoardCramerRao, variance: np.ndarray) -> BoardCramerRao:
    """``cr`` with the deviation from the drawing (module docstring, ``variance`` (k,) every
    minimal parameter's, m^2 / rad^2: :meth:`Deviation.variance`) in its covariance, its first
    camera's and their cross block, every minimal parameter among the ``estimated`` ones (the
    covariance now covers the held ones); ``cr`` unchanged when it carries no
    :attr:`BoardCramerRao.held` response."""
    if cr.held is None:
        return cr
    var = np.asarray(variance, float)
    k = var.size
    V = (cr.held * var) @ cr.held.T
    cam, cross = cr.camera_covariance, cr.camera_cross
    return dataclasses.replace(
        cr,
        covariance=cr.covariance + V[:k, :k],
        estimated=np.ones(k, bool),
        camera_covariance=None if cam is None else cam + V[k:, k:],
        camera_cross=None if cross is None else cross + V[:k, k:],
        held=None,
    )


def held_share(px2: np.ndarray, expected: np.ndarray, held: np.ndarray) -> float:
    """The share (0-1) of the prior's variance the cross-validated frames show: their squared
    pixel errors ``px2`` beyond what the estimate and the noise give them (``expected``), over
    what the prior's deviation would add (``held``; each (m,) px^2, one per held-out frame) --
    the prior taken as an upper limit, the folds' excess as the measure of how far this arm
    lies from its drawing along what the calibration holds (1 when the prior adds nothing)."""
    add = float(np.sum(held))
    if add <= 0.0:
        return 1.0
    return float(np.clip((np.sum(px2) - np.sum(expected)) / add, 0.0, 1.0))


def held_block(deviation: Deviation, share: float = 1.0) -> dict:
    """The ``accuracy`` block's ``held_deviation``: the prior it was predicted with and the
    share of its variance the folds showed (:func:`held_share`)."""
    return {
        "what": "the arm's deviation from the drawing the prediction carries: each inner "
        "minimal parameter uniform within +-translation_mm (lengths) or +-rotation_deg "
        "(angles) of the robot file's value, less what the fit absorbs of it at the "
        "calibration frames (the held parameters' part; `covariance_si` and its `estimated` "
        "list cover every minimal parameter then; docs/tool-accuracy.md)",
        "translation_mm": 1e3 * deviation.translation_m,
        "rotation_deg": float(np.degrees(deviation.rotation_rad)),
        "share": share,
        "share_what": "the share of the prior's variance counted: the leave-one-configuration-"
        "out frames' pixel excess over the estimate's errors and the noise, against what the "
        "prior would add to them (at most 1); the model error is what is left beyond it",
    }
