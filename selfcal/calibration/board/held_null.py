"""When a board calibration's folds show a model error beyond the deviation of the parameters it
holds (issue #29). The arm is one draw of the deviation prior
(:mod:`selfcal.calibration.board.held_prior`): what its held directions add to each fold's
held-out pixels is ``delta^T M_f delta``, the same ``delta`` in every fold, scattering about the
prior's mean ``tr(M_f D)`` (a fold's ``px2_held``). Summed over the folds that scatter can pass
the noise many times over (a 7-joint arm's 12 postures: 1.22 times the mean, 2.9 standard
errors of the noise alone), so the excess's size cannot tell a model error from the draw; but
the draw moves the folds together, in the pattern its ``M_f`` give them, and a model error need
not (the real mecheye set's four folds, excess ``[406, 283, 260, 138]`` px^2 where the one held
direction gives ``[539, 169, 74, 142]``: 8-46 noise standard errors off any share of it). A
model error is counted when the folds' excess passes the noise (as before the draw's scatter was
known) and no share of the prior's draw explains its pattern across the folds
(:func:`pattern_misfit`, :func:`counted_excess`). SI: px^2 and px^4 for the pixels' sums and
their variances, m^2 / rad^2 for the prior's variances.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.held_prior import Share

__all__ = ["SHARES", "counted_excess", "held_excess_covariance", "pattern_misfit"]

SHARES = np.linspace(0.0, 1.0, 101)
"""The shares ``c`` of the prior :func:`pattern_misfit` tries (0-1, steps of 0.01)."""


def held_excess_covariance(grams: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """The covariance (F, F) px^4 of what the arm's one deviation ``delta`` from the drawing adds
    to each of F folds' summed squared pixel errors, ``delta^T M_f delta``: ``grams`` (F, k, k)
    the folds' ``M_f`` (their held-out frames' ``held_gram`` summed,
    :func:`selfcal.calibration.board.accuracy.held_out_errors`), ``delta`` drawn with the
    prior's ``variance`` (k,) m^2 / rad^2 per minimal parameter (:meth:`Deviation.variance`):
    ``2 tr(M_f D M_g D)``, ``D = diag(variance)``, a Gaussian ``delta``'s (the prior's uniform
    one scatters less: the count is then on the safe side). Its mean is the folds' ``px2_held``
    (``tr(M_f D)``)."""
    d = np.sqrt(np.asarray(variance, float))
    W = d[None, :, None] * np.asarray(grams, float) * d[None, None, :]  # D^1/2 M_f D^1/2
    return 2.0 * np.einsum("fij,gji->fg", W, W)


def pattern_misfit(excess: np.ndarray, added: np.ndarray, var: np.ndarray, grams: np.ndarray,
                   cross: np.ndarray, variance: np.ndarray) -> float:  # fmt: skip
    """How far F folds' excess lies from every share ``c`` (0-1, :data:`SHARES`) of the arm's
    one deviation, without a model error: ``min_c (x - c a)^T S_c^-1 (x - c a)``, ``x`` the
    folds' ``excess`` (F,) px^2 (their held-out frames' ``px2`` beyond ``px2_expected``),
    ``a`` what the prior's deviation adds to them on average (``added``, their ``px2_held``),
    ``S_c`` their covariance without a model error: the noise and the estimate's errors
    (``var`` (F,) px^4, their ``px2_var``), the deviation's cross term with them (``4 c cross_f
    . variance``, ``cross`` (F, k) their ``held_cross``) and ``c^2`` the scatter of the
    deviation's one draw (:func:`held_excess_covariance` of ``grams`` (F, k, k) and the prior's
    ``variance`` (k,)). Chi-square with at most F degrees of freedom when the folds' excess is
    the deviation's and the noise's (normal; fewer as ``c`` is fitted)."""
    x, a = np.asarray(excess, float), np.asarray(added, float)
    noise = np.asarray(var, float)
    linear = 4.0 * np.asarray(cross, float) @ np.asarray(variance, float)
    scatter = held_excess_covariance(grams, variance)
    c = SHARES[:, None]
    r = x - c * a  # (shares, F)
    S = (noise + c * linear)[:, :, None] * np.eye(x.size) + c[:, :, None] ** 2 * scatter
    return float(np.min(np.einsum("sf,sf->s", r, np.linalg.solve(S, r[:, :, None])[:, :, 0])))


def counted_excess(folds: list[dict[str, np.ndarray]], share: Share,
                   variance: np.ndarray | None) -> float:  # fmt: skip
    """The folds' summed squared-pixel excess (px^2) a model error is read from: the held-out
    frames' ``px2`` beyond what the estimate, the noise (``px2_expected``) and the deviation's
    counted part (``share.point`` of ``px2_held``) give them, when it exceeds
    :data:`selfcal.calibration.accuracy.Z_MODEL_ERROR` standard deviations of the noise's
    (``px2_var`` summed) and, where the folds measured the prior's share (``share.basis``
    ``"folds"``; ``variance`` (k,) the prior's, None: none), their pattern lies beyond every
    share of the deviation's one draw (:func:`pattern_misfit` above the chi-square quantile on F degrees of freedom at the
    rate ``Z_MODEL_ERROR`` states, one-sided normal: 2.3 %); else 0. ``folds``: one dict per
    fitted fold of its held-out frames
    (:func:`selfcal.calibration.board.accuracy.held_out_errors`' keys, with ``px2_held``)."""
    h = {k: np.concatenate([f[k] for f in folds]) for k in folds[0]}
    extra = float(np.sum(h["px2"]) - np.sum(h["px2_expected"])
                  - share.point * np.sum(h["px2_held"]))  # fmt: skip
    if extra <= Z_MODEL_ERROR * np.sqrt(np.sum(h["px2_var"])):
        return 0.0
    if variance is None or share.basis != "folds":  # no share measured: the prior unscaled
        return extra
    x = [np.sum(f["px2"] - f["px2_expected"]) for f in folds]
    a, var = ([np.sum(f[k]) for f in folds] for k in ("px2_held", "px2_var"))
    grams, cross = (np.array([np.sum(f[k], axis=0) for f in folds]) for k in ("held_gram",
                                                                             "held_cross"))  # fmt: skip
    misfit = pattern_misfit(np.array(x), np.array(a), np.array(var), grams, cross, variance)
    from scipy.stats import chi2, norm  # here: `selfcal calibrate` of a field imports this module

    return extra if misfit > chi2.isf(norm.sf(Z_MODEL_ERROR), len(folds)) else 0.0
