"""The folds' held-out rows' excess with each row in its own metric (issue #29): the drift
check's second null (:mod:`selfcal.calibration.drift.fold_error`), the board route's
``whitened_excess_mm`` / ``_deg`` (:mod:`selfcal.calibration.board.accuracy`).

Each held-out row ``e_i`` (a frame's flange error, a ``d``-vector) has the covariance ``V_i =
S_i + N_i`` its fold's estimate and the noise give it; the excess is the isotropic ``m`` at which
the rows, each whitened by its own ``V_i + m^2 I``, have their expected chi-square
(:func:`whitened_excess`), counted only when the whitened sum ``Q = sum_i e_i^T V_i^-1 e_i``
exceeds what it reaches under no excess with the one-sided normal tail of
:data:`selfcal.calibration.accuracy.Z_MODEL_ERROR` (2.3 %). Cross-validated rows are not
independent: a fold's rows share its estimate's error, and the folds' fits share their training
rows (:func:`fold_row_covariance`), which spreads ``Q`` wider than a chi-square of ``d rows``
degrees of freedom (``tests/unit/test_drift_null.py``: 1.26x at the estimation's share of 13 %,
the level 3.8 % taken as independent); its threshold is read from ``Q``'s first three cumulants
with that covariance (:func:`whitened_null`, :func:`whitened_threshold`). Units: those of the
rows (m, rad).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy.optimize import brentq
from scipy.special import gammainccinv, ndtr

from selfcal.calibration.accuracy import Z_MODEL_ERROR, ModelError

__all__ = [
    "fold_row_covariance",
    "whitened_excess",
    "whitened_null",
    "whitened_rows",
    "whitened_threshold",
    "with_whitened",
]


def whitened_null(V: np.ndarray, between: np.ndarray | None = None) -> tuple[float, float, float]:
    """The first three cumulants of the whitened sum ``Q = sum_i e_i^T V_i^-1 e_i`` of held-out
    ``d``-vectors with the covariances ``V`` (rows, d, d) under no excess: ``e`` Gaussian with
    the joint covariance ``Sigma`` whose diagonal blocks are ``V`` and whose others are
    ``between`` (rows, d, rows, d; its diagonal blocks ignored; None: the rows independent).
    ``Q`` is a quadratic form, a sum of ``lambda_k chi2_1`` with ``lambda`` the eigenvalues of
    ``K = W^1/2 Sigma W^1/2`` (``W`` the blocks ``V_i^-1``): its mean ``tr K = d rows``, its
    variance ``2 tr K^2`` (``2 d rows`` for independent rows; rows that share their fold's
    estimate error, or whose folds' fits share training rows, spread it wider) and its third
    cumulant ``8 tr K^3``."""
    V = np.asarray(V, float)
    rows, d = V.shape[:2]
    if between is None:
        return float(d * rows), float(2 * d * rows), float(8 * d * rows)
    Li = np.linalg.inv(np.linalg.cholesky(V))  # V_i^-1 = Li^T Li
    B = np.array(between, float)
    B[np.arange(rows), :, np.arange(rows), :] = V
    K = np.einsum("iab,ibjc,jdc->iajd", Li, B, Li, optimize=True).reshape(rows * d, rows * d)
    K2 = K @ K
    return float(np.trace(K)), float(2.0 * np.trace(K2)), float(8.0 * np.sum(K2 * K))


def whitened_threshold(V: np.ndarray, between: np.ndarray | None = None) -> float:
    """The value the whitened sum of :func:`whitened_null` exceeds under no excess with the
    one-sided normal tail probability of :data:`Z_MODEL_ERROR` (``Phi(-2)``, 2.3 %): the sum
    taken as a shifted and scaled chi-square with its first three cumulants (Pearson's:
    ``h = 8 k2^3 / k3^2`` degrees of freedom; for independent rows ``h = d rows``, exact)."""
    k1, k2, k3 = whitened_null(V, between)
    h = 8.0 * k2**3 / k3**2
    q = 2.0 * gammainccinv(h / 2.0, ndtr(-Z_MODEL_ERROR))
    return float(k1 + np.sqrt(k2 / (2.0 * h)) * (q - h))


def whitened_excess(e: np.ndarray, V: np.ndarray, between: np.ndarray | None = None) -> float:
    """Per-coordinate standard deviation ``m`` of an isotropic error of the held-out ``d``-vectors
    ``e`` (rows, d) beyond what each row's own covariance ``V`` (rows, d, d) explains (the
    estimation error and the noise: ``S_i + N_i``), every row weighed in its own metric: the
    ``m`` at which ``sum_i e_i^T (V_i + m^2 I)^-1 e_i = d rows`` (the moment of the whitened
    rows, whose mean under no excess is ``d rows`` however the rows correlate; unit of ``e``).
    0 unless ``sum_i e_i^T V_i^-1 e_i`` exceeds :func:`whitened_threshold` (its level under no
    excess that of :data:`Z_MODEL_ERROR`) with the rows' covariance between them ``between``
    (rows, d, rows, d; cross-validated rows share their fold's estimate error and their folds'
    training rows: :func:`fold_row_covariance`; None: independent). Unlike :func:`excess` of the
    squared norms, a row's poorly known direction (a single view's depth along its line of
    sight) neither hides an excess in the well known ones nor, by its own spread, passes for
    one."""
    e, V = np.asarray(e, float), np.asarray(V, float)
    rows, d = e.shape
    if rows == 0:
        return 0.0
    eye = np.eye(d)

    def whitened(m2: float) -> float:
        return float(np.sum(e * np.linalg.solve(V + m2 * eye, e[..., None])[..., 0]))

    dof = d * rows
    if whitened(0.0) <= whitened_threshold(V, between):
        return 0.0
    lo, hi = 0.0, max(float(np.mean(np.sum(e**2, axis=1))) / d, np.finfo(float).tiny)
    while whitened(hi) > dof:  # the whitened sum falls as m^2 grows
        lo, hi = hi, 2.0 * hi
    m2 = brentq(lambda m2: whitened(m2) - dof, lo, hi, xtol=np.finfo(float).tiny, maxiter=200)
    return float(np.sqrt(m2))


def fold_row_covariance(G: np.ndarray, fold: np.ndarray, C: Sequence[np.ndarray],
                        A: Sequence[np.ndarray], N: np.ndarray) -> np.ndarray:  # fmt: skip
    """(rows, d, rows, d) the covariance between cross-validated rows that the folds' estimate
    errors give them, in a linear model: row ``i`` of fold ``f`` is ``e_i = n_i - G_i delta_f``
    with its noise ``n_i`` (covariance ``N_i``) and the error ``delta_f = C_f sum_(k not in f)
    s_k`` (covariance ``C_f``) of the estimate fitted without fold ``f`` from the other folds'
    rows' scores ``s_k`` (covariance ``A_k``, the row's information; ``cov(n_k, s_k) = G_k``).
    Within a fold ``G_i C_f G_j^T`` (one error shared; the diagonal blocks are the rows' own
    ``S_i``); between folds ``f != g`` ``G_i (C_f T_fg C_g - C_f - C_g) G_j^T`` with ``T_fg``
    the information of the rows in neither fold (both estimates' common part; row ``i``'s noise
    is in fold ``g``'s fit, ``j``'s in ``f``'s): ``-G_i C_f C^-1 C_g G_j^T`` when ``C_f^-1`` is
    the other folds' information. Where it is not (a fold that extrapolates: its own rows, not
    its training, hold the information in a direction, and the rows' information ``A`` is
    linearised at other fits), the between-fold part is shrunk to the largest share at which
    the rows' joint covariance (``S_i + N_i`` on the diagonal) is still one. ``G`` (rows, d, p):
    each row's map of the parameters' error; ``fold`` (rows,) each row's fold, ``0 .. K - 1``;
    ``C``, ``A``: per fold its estimate's covariance and its own rows' information (p, p), in
    one order of the parameters (a parameter a fold holds: zero rows); ``N`` (rows, d, d)."""
    G, fold = np.asarray(G, float), np.asarray(fold, int)
    Cs, As = (np.array([np.asarray(x, float) for x in X]) for X in (C, A))
    X = np.einsum("idp,ipq->idq", G, Cs[fold])  # G_i C_f
    same = (fold[:, None] == fold[None, :])[:, None, :, None]
    within = np.einsum("idp,jep->idje", X, G)
    if same.all():
        return within
    between = -(within + within.transpose(2, 3, 0, 1))  # -G_i (C_f + C_g) G_j^T
    total, every = As.sum(axis=0), np.ones(G.shape[1], bool)
    for f in range(len(Cs)):
        for g in range(len(Cs)):
            i, j = fold == f, fold == g
            if f != g and i.any() and j.any():
                T = total - As[f] - As[g]
                between[np.ix_(i, every, j, every)] += np.einsum("idp,pq,jeq->idje", X[i], T, X[j])
    rows, d = G.shape[:2]
    within = np.where(same, within, 0.0)
    between = np.where(same, 0.0, between)
    k = np.arange(rows)
    Li = np.linalg.inv(np.linalg.cholesky(within[k, :, k, :] + np.asarray(N, float)))
    Kw, Kb = (np.einsum("iab,ibjc,jdc->iajd", Li, M, Li, optimize=True).reshape(rows * d, -1)
              for M in (within, between))  # fmt: skip
    Kw += np.eye(rows * d) - np.kron(np.eye(rows), np.ones((d, d))) * Kw  # unit diagonal blocks
    return within + _covariance_share(Kw, Kb) * between


def _covariance_share(Kw: np.ndarray, Kb: np.ndarray, tol: float = 1e-9) -> float:
    """The largest ``t`` in [0, 1] at which ``Kw + t Kb`` is positive semi-definite (``Kw`` is):
    1 when it is at 1, else by bisection (the set of such ``t`` is an interval from 0)."""

    def ok(t: float) -> bool:
        return bool(np.linalg.eigvalsh(Kw + t * Kb)[0] >= -tol * len(Kw))

    if ok(1.0):
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def whitened_rows(folds: Sequence[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The held-out frames of the folds ``folds`` (each
    :func:`selfcal.calibration.board.accuracy.held_out_errors` of one fold's fit at its own
    frames), as :func:`with_whitened` weighs them: their flange errors ``e`` (rows, 6; m, rad),
    covariances ``S + N`` (rows, 6, 6) and the covariance between them that the folds' estimate
    errors give (rows, 6, rows, 6; :func:`fold_row_covariance`: a fold's frames share its error,
    and the folds' fits share their training frames; each fold's information its frames' first
    camera's, a rig's other cameras' left out)."""
    got = [h for h in folds if len(h["frame"])]
    if not got:
        return np.zeros((0, 6)), np.zeros((0, 6, 6)), np.zeros((0, 6, 0, 6))
    fold = np.concatenate([np.full(len(h["frame"]), k) for k, h in enumerate(got)])
    G = np.concatenate([h["G"] for h in got])
    e, S, N = (np.concatenate([h[k] for h in got]) for k in ("e", "S", "N"))
    C, A = [h["C"][0] for h in got], [np.sum(h["A"], axis=0) for h in got]
    return e, S + N, fold_row_covariance(G, fold, C, A, N)


def with_whitened(me: ModelError, e: np.ndarray, V: np.ndarray, position: slice,
                  orientation: slice, between: np.ndarray | None = None) -> ModelError:  # fmt: skip
    """``me`` with its held-out rows' excess in each row's own metric (:func:`whitened_excess`
    of the tool-pose errors ``e`` (rows, 6) against their covariances ``V`` (rows, 6, 6), the
    estimation's and the noise's, and their covariance between rows ``between`` (rows, 6, rows,
    6; :func:`fold_row_covariance`; None: independent); m and rad), the ``position`` and the
    ``orientation`` coordinates apart (the drift check's second null)."""
    P, R = position, orientation
    B = (None, None) if between is None else (between[:, P, :, P], between[:, R, :, R])
    return replace(me, whitened_m=whitened_excess(e[:, P], V[:, P, P], B[0]),
                   whitened_rad=whitened_excess(e[:, R], V[:, R, R], B[1]))  # fmt: skip
