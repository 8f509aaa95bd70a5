"""The prediction of a board calibration with the deviation from the drawing of the parameters
it holds (issue #29): :mod:`selfcal.calibration.board.held`'s response ``R`` (per unit
deviation, :attr:`selfcal.calibration.board.bounds.BoardCramerRao.held`) weighed by the prior
``S`` (:class:`selfcal.calibration.board.deviation.Deviation`, the one ``selfcal plan``
predicts with) into the bounds' covariances, ``c R S R^T``, ``c`` (0-1) the share of the prior the
calibration's leave-one-configuration-out frames show, counted at its upper 95 % confidence
bound (:func:`held_share`; the prior an upper limit: the selection holds a direction more often
when the arm deviates little along it, and the folds lower it only as far as they show). When
the folds' excess is a model error beyond it: :mod:`selfcal.calibration.board.held_null`. SI.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.special import ndtri, stdtrit

from selfcal.calibration.board.bounds import BoardCramerRao
from selfcal.calibration.board.deviation import Deviation

__all__ = [
    "NO_FOLDS",
    "SHARE_LEVEL",
    "UNMEASURABLE",
    "Share",
    "held_block",
    "held_sentence",
    "held_share",
    "with_deviation",
]


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


SHARE_LEVEL = 0.95
"""The one-sided confidence level of the share's upper bound (:func:`held_share`): the
prediction's bounds are 95 % statements."""


@dataclasses.dataclass(frozen=True)
class Share:
    """The share ``c`` of the deviation prior's variance a calibration counts (module docstring).

    Attributes:
        used: the share (0-1) the prediction counts: the upper bound ``upper`` clipped to 0-1
            when the folds measured it, else 1 (the prior unscaled).
        basis: ``"folds"`` (measured), ``"no_folds"`` (none, or one fitted: the prior
            unscaled), ``"unmeasurable"`` (too small in the folds' pixels to measure: the prior
            unscaled) or ``"nothing_held"`` (the held directions add nothing to the folds'
            frames: nothing to measure, and nothing added).
        folds: the folds it was measured on.
        estimate: the folds' point estimate (not clipped; None unless measured).
        upper: its one-sided :data:`SHARE_LEVEL` upper confidence bound from the folds'
            spread, Student's t with ``folds - 1`` degrees of freedom (None unless measured).
    """

    used: float
    basis: str
    folds: int = 0
    estimate: float | None = None
    upper: float | None = None

    @property
    def point(self) -> float:
        """The point estimate clipped to 0-1 (1 unless measured): the part of the folds' excess
        the deviation takes, the model error what is left beyond it."""
        return 1.0 if self.estimate is None else float(np.clip(self.estimate, 0.0, 1.0))


UNMEASURABLE = 0.01
"""What the prior's full deviation must add to the folds' frames, as a share of the standard
deviation of their summed excess without it, for the folds to measure its share
(:func:`held_share`): below it the share's standard error passes 1/0.01 = 100 and its point
estimate is rounding (a 7-joint arm's structurally redundant held directions added 2.5e-6 px^2
against a 0.23 px^2 deviation, and the report printed a share of -2.05e+07)."""


def held_share(excess: np.ndarray, added: np.ndarray, expected: np.ndarray,
               var: np.ndarray | None = None) -> Share:  # fmt: skip
    """The share of the prior's variance the leave-one-configuration-out folds show, one entry
    per fitted fold (each (F,) px^2, summed over its held-out frames): ``excess`` their squared
    pixel errors beyond what the estimate and the noise give them (``expected``), ``added``
    what the prior's full deviation would add to them.

    The point estimate is the ratio of the sums; its standard error the folds' spread about it
    (``sqrt(F / (F - 1) sum r_f^2) / sum added``, ``r_f = excess_f - c added_f``), so its
    uncertainty is that of ``F - 1`` degrees of freedom and of the arm's one deviation seen
    from ``F`` configurations, not of the frames' count; the share counted is the one-sided
    :data:`SHARE_LEVEL` upper bound (Student's t), and with ``var`` at least the bound the
    folds' known noise gives the ratio (normal, standard error ``sqrt(sum var) / sum added``:
    one fold carrying most of ``added`` leaves the spread on ``F - 1`` degrees of freedom far
    below it, a 3-joint arm's 23 against 72 px^2, and the bound at -0.02 covered the true share
    in 73 % of such draws), the prior an upper limit: few or
    disagreeing folds keep it near 1, and it falls below only as far as the folds show. With
    fewer than two folds there is no spread: the prior is counted unscaled (``"no_folds"``);
    when the prior adds nothing to the folds' frames (to rounding against what they expect)
    there is nothing to measure (``"nothing_held"``); when it adds less than
    :data:`UNMEASURABLE` of the standard deviation of the folds' summed excess (``var`` (F,)
    px^4 each fold's variance of it without a model error, given) the folds cannot measure the
    share and the prior is counted unscaled (``"unmeasurable"``)."""
    x, h = np.asarray(excess, float), np.asarray(added, float)
    total = float(np.sum(h))
    if total <= 1e-9 * max(float(np.sum(expected)), np.finfo(float).tiny):
        return Share(1.0, "nothing_held", x.size)
    if x.size < 2:
        return Share(1.0, "no_folds", x.size)
    if var is not None and total < UNMEASURABLE * float(np.sqrt(np.sum(var))):
        return Share(1.0, "unmeasurable", x.size)
    c = float(np.sum(x)) / total
    r = x - c * h
    se = float(np.sqrt(x.size / (x.size - 1) * np.sum(r**2))) / total
    margin = float(stdtrit(x.size - 1, SHARE_LEVEL)) * se
    if var is not None:  # the folds' noise alone gives the ratio this standard error
        margin = max(margin, float(ndtri(SHARE_LEVEL)) * float(np.sqrt(np.sum(var))) / total)
    upper = c + margin
    return Share(float(np.clip(upper, 0.0, 1.0)), "folds", x.size, c, upper)


NO_FOLDS = Share(1.0, "no_folds")
"""The share without folds: the prior unscaled."""

_BASIS = {
    "folds": "the one-sided 95 % upper confidence bound (clipped to 0-1) of the share the "
    "leave-one-configuration-out folds show: their held-out frames' pixel excess over the "
    "estimate's errors and the noise against what the prior would add to them, its standard "
    "error from the folds' spread (Student's t, folds - 1 degrees of freedom) or, when larger, "
    "from their known noise (normal); the model error "
    "is what the folds' excess leaves beyond the point estimate's share",
    "no_folds": "no folds measured it (fewer than two configurations, or fewer than two folds "
    "fitted): the prior is counted unscaled (share 1)",
    "unmeasurable": "the held directions add too little to the leave-one-configuration-out "
    "folds' held-out pixels (less than 1 % of the standard deviation of their summed excess) "
    "for the folds to measure the share: the prior is counted unscaled (share 1)",
    "nothing_held": "the held directions add nothing to the folds' frames' pixels: nothing to "
    "measure, and the prior adds nothing to the prediction",
}


def held_block(deviation: Deviation, share: Share = NO_FOLDS) -> dict:
    """The ``accuracy`` block's ``held_deviation``: the prior it was predicted with and the
    share of its variance counted (:func:`held_share`), with how it was found."""
    return {
        "what": "the arm's deviation from the drawing the prediction carries: each inner "
        "minimal parameter uniform within +-translation_mm (lengths) or +-rotation_deg "
        "(angles) of the robot file's value, less what the fit absorbs of it at the "
        "calibration frames (the held parameters' part; `covariance_si` and its `estimated` "
        "list cover every minimal parameter then; docs/tool-accuracy.md)",
        "translation_mm": 1e3 * deviation.translation_m,
        "rotation_deg": float(np.degrees(deviation.rotation_rad)),
        "share": share.used,
        "share_basis": share.basis,
        "share_folds": share.folds,
        "share_estimate": share.estimate,
        "share_upper": share.upper,
        "share_what": f"the share of the prior's variance counted: {_BASIS[share.basis]}",
    }


def held_sentence(block: dict | None) -> str | None:
    """The words ``selfcal report`` gives of a ``held_deviation`` block (:func:`held_block`):
    how much of the prior the prediction counts and why; None without the block or when the
    selection holds nothing the folds see."""
    if not block or block.get("share_basis") == "nothing_held":
        return None
    prior = (f"the prior of +-{block.get('translation_mm', 0.0):g} mm / "
             f"+-{block.get('rotation_deg', 0.0):g} deg")  # fmt: skip
    share = float(block.get("share", 1.0))
    if block.get("share_basis") == "no_folds":
        return (f"the held parameters' deviation from the drawing: {prior} counted unscaled, "
                "no folds measured its share")  # fmt: skip
    if block.get("share_basis") == "unmeasurable":
        return (f"the held parameters' deviation from the drawing: {prior} counted unscaled, "
                "as it adds too little to the folds' held-out pixels for them to measure its "
                "share")  # fmt: skip
    if block.get("share_estimate") is None:  # a block written before the share's bound
        return f"the held parameters' deviation from the drawing: {share:.3g} of {prior}"
    return (f"the held parameters' deviation from the drawing: {share:.3g} of {prior}, the "
            f"upper 95 % bound of the {block.get('share_folds')} folds' "
            f"{block['share_estimate']:.3g}")  # fmt: skip
