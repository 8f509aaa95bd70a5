"""When a board calibration's folds show a model error beyond the deviation of the parameters it
holds (issue #29). The arm is one draw of the deviation prior
(:mod:`selfcal.calibration.board.held_prior`): what its held directions add to each fold's
held-out pixels is ``delta^T M_f delta``, the same ``delta`` in every fold, scattering about the
prior's mean ``tr(M_f D)`` (a fold's ``px2_held``). Summed over the folds that scatter can pass
the noise many times over (a 7-joint arm's 12 postures: 1.22 times the mean, 2.9 standard
errors of the noise alone), so the excess's size cannot tell a model error from the draw; but
the draw moves the folds together, in the pattern its ``M_f`` give them, and a model error need
not (the real mecheye set's four folds, excess ``[406, 283, 260, 138]`` px^2 where the one held
direction gives ``[539, 169, 74, 142]``: 7-43 noise standard errors off any share of it). A
model error is counted when the folds' excess passes the noise (as before the draw's scatter was
known) and no share of the prior's draw explains its pattern across the folds
(:func:`pattern_misfit`, :func:`counted_excess`). SI: px^2 and px^4 for the pixels' sums and
their variances, m^2 / rad^2 for the prior's variances.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.held_prior import Share

__all__ = [
    "SHARES",
    "counted_excess",
    "fold_noise_variance",
    "held_excess_covariance",
    "pattern_misfit",
    "shared_covariances",
]

SHARES = np.linspace(0.0, 1.0, 101)
"""The shares ``c`` of the prior :func:`pattern_misfit` tries (0-1, steps of 0.01)."""


def shared_covariances(errors: list[np.ndarray],
                       held: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """What one fit's estimate error, shared by the frames it predicts, adds to their sums'
    covariances: ``errors`` per frame ``U_i`` (rows_i, p) px per unit of the estimate's whitened
    error (its pixel errors ``U_i z``, the same ``z`` for every frame), ``held`` per frame
    ``L_i`` (rows_i, k) px per unit deviation of each minimal parameter. Returns per frame the
    covariance (px^4) of its summed squared pixel errors with the other frames' (Gaussian:
    ``2 sum_{j != i} tr(U_i^T U_i U_j^T U_j)``) and per frame (k,) px^2 the part of the
    deviation's cross term with the noise the other frames share with it (``sum_{j != i}``
    the diagonal of ``L_i^T U_i U_j^T L_j``): summed over the frames, with each frame's own
    variance, the variance of their sum (a fold's: a stacked-rows covariance, not the frames
    apart)."""
    grams = np.array([u.T @ u for u in errors])  # (m, p, p)
    total = np.sum(grams, axis=0)
    cov = 2.0 * (np.einsum("ipq,pq->i", grams, total) - np.einsum("ipq,ipq->i", grams, grams))
    a = np.array([u.T @ L for u, L in zip(errors, held, strict=True)])  # (m, p, k)
    cross = np.einsum("ipk,pk->ik", a, np.sum(a, axis=0)) - np.sum(a**2, axis=1)
    return cov, cross


def fold_noise_variance(fold: dict[str, np.ndarray]) -> float:
    """The variance (px^4) of a fold's summed squared pixel errors without a model error: its
    held-out frames' own (``px2_var``) and their covariances through the fold fit's one
    estimate error (``px2_cov``; :func:`shared_covariances`), the keys of
    :func:`selfcal.calibration.board.accuracy.held_out_errors`."""
    return float(np.sum(fold["px2_var"]) + np.sum(fold["px2_cov"]))


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
    (``var`` (F,) px^4, their :func:`fold_noise_variance`: a fold's frames share its fit's
    estimate error), the deviation's cross term with them (``4 c cross_f
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
    (each fold's :func:`fold_noise_variance` summed; the folds' fits taken apart, though each
    trains on the others' frames) and, where the folds measured the prior's share (``share.basis``
    ``"folds"``; ``variance`` (k,) the prior's, None: none), their pattern lies beyond every
    share of the deviation's one draw (:func:`pattern_misfit` above the chi-square quantile on F degrees of freedom at the
    rate ``Z_MODEL_ERROR`` states for a normal sum, one-sided: 2.3 %); else 0. A fitting arm is
    counted a model error in 2-3.2 % of calibrations, not 2.3 % (the sums of squares' right
    tail is heavier than the normal's): tests/unit/test_board_model_error_null.py, 4000 draws
    each of five folds, with and without a shared estimate error. ``folds``: one dict per
    fitted fold of its held-out frames
    (:func:`selfcal.calibration.board.accuracy.held_out_errors`' keys, with ``px2_held``)."""
    h = {k: np.concatenate([f[k] for f in folds]) for k in folds[0]}
    extra = float(np.sum(h["px2"]) - np.sum(h["px2_expected"])
                  - share.point * np.sum(h["px2_held"]))  # fmt: skip
    var = [fold_noise_variance(f) for f in folds]  # the folds' fits apart: no covariance between
    if extra <= Z_MODEL_ERROR * np.sqrt(np.sum(var)):
        return 0.0
    if variance is None or share.basis != "folds":  # no share measured: the prior unscaled
        return extra
    x = [np.sum(f["px2"] - f["px2_expected"]) for f in folds]
    a = [np.sum(f["px2_held"]) for f in folds]
    grams, cross = (np.array([np.sum(f[k], axis=0) for f in folds]) for k in ("held_gram",
                                                                             "held_cross"))  # fmt: skip
    misfit = pattern_misfit(np.array(x), np.array(a), np.array(var), grams, cross, variance)
    from scipy.stats import chi2, norm  # here: `selfcal calibrate` of a field imports this module

    return extra if misfit > chi2.isf(norm.sf(Z_MODEL_ERROR), len(folds)) else 0.0
