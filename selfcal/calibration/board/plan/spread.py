"""The spread of what a board calibration reaches at planned postures over the arms and noise
draws a plan may meet, with its selection deciding in each (``selfcal plan``, issue #30).

The plan's prediction (:mod:`selfcal.calibration.board.plan.predict`) is an RMS over every arm
within the deviation and every noise draw, with the parameters the selection's forecast keeps
(:mod:`selfcal.calibration.board.plan.selection`). The forecast sees the folds' expected errors,
but the selection decides on one recording's: where the arm's deviation along the parameters
the larger candidate adds happens to be small, or the noise of the folds hides it, the
one-standard-error rule keeps a smaller candidate, and the deviation it holds is an error the
expectation averages away (the ER-4u's cell at 0.5 px, docs/plan.md: 6 of the plan's 30 draws
held five parameters, and three of them were its three worst).

This module draws that decision, to first order, as the calibration would meet it: per draw one
arm's deviation ``d`` (every inner minimal parameter uniform within the deviation's half-width,
as the simulator draws it) and per fold the information-weighted noise of its frames
``h_f ~ N(0, F_f)`` (``F_f`` the fold's information, drawn through its symmetric square root
:func:`selfcal.solver.covariance.psd_sqrt`, so a draw changes with ``F_f`` continuously and not
with the signs round-off gives its eigenvectors; the folds partition the frames, so the
noise of a fit on several folds is the sum of theirs). A fit of the directions ``M`` on frames
of information ``F`` and noise ``g`` errs by ``-R d + C g``
(:func:`selfcal.calibration.board.plan.predict.linear_estimator`); a fold's RMS per feature is
``sqrt(sigma^2 (chi2_2n - 2 h^T e + sum_i x_i^T A_i x_i) / n)``, ``x_i = [e, z_i]``, with ``e``
the training fit's error, ``A_i`` a left-out frame's information with its joints and ``z_i``
its read-back errors drawn
(:func:`selfcal.calibration.board.plan.information.prediction_information`: the fold is
predicted from its joints alone),
``n`` the fold's features and ``chi2_2n`` its corners' squared noise over ``sigma^2``; the
candidates' fold errors go through the selection's own paired one-standard-error rule
(:func:`selfcal.calibration.board.param_selection.one_se_rule`) over the folds that count
(:func:`selfcal.calibration.board.folds.counted_folds`; a fold that does not count still adds
its frames' noise to every fit that has them), and the chosen candidate's fit on every frame errs by ``-R d + C sum_f h_f``, carried to the tool point by the aligned weight
``G``. Linear (the first order of the problem at the drawing), the camera's free parameters
fitted in every fit, the correlation of a fold's ``chi2`` with its ``h`` neglected (and its
``h`` that of the training fits, its joints' corrections eliminated, in the cross term of its
prediction too). Units: SI, px.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from selfcal.calibration.board.param_selection import cv_error, one_se_rule
from selfcal.calibration.board.plan.information import (
    board_model,
    frame_information,
    prediction_information,
)
from selfcal.calibration.board.plan.predict import Directions, linear_estimator
from selfcal.calibration.board.plan.selection import selection_folds
from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.errors import UsageError
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.solver.covariance import psd_sqrt

__all__ = ["DRAWS", "SelectionSpread", "plan_spread", "selection_spread"]

DRAWS = 400
"""Draws of :func:`selection_spread` by default (and ``selfcal plan``'s): the 90th percentile of
400 draws has a standard error near 2 % of it (a 90th percentile's, ``sqrt(0.09 / 400) /
density``); :meth:`SelectionSpread.standard_error` estimates it from one run's draws (2 - 4 %
of the percentiles of the UR5e example's plan of 12 and its random plan, docs/plan.md)."""


@dataclass(frozen=True, eq=False)
class SelectionSpread:
    """:func:`selection_spread`'s draws: ``tool_m`` (draws,) the tool point's RMS error (m)
    over the workspace after the best rigid alignment, ``chosen`` (draws,) the candidate the
    selection kept (an index into ``labels``, the nested candidates' labels)."""

    tool_m: np.ndarray
    chosen: np.ndarray
    labels: tuple[str, ...]

    def percentile(self, p: float) -> float:
        """The ``p``-th percentile (0-100) of the tool-point error (m)."""
        return float(np.percentile(self.tool_m, p))

    def kept_share(self, candidate: int) -> float:
        """The share of the draws whose selection kept ``candidate``."""
        return float(np.mean(self.chosen == candidate))

    @property
    def smaller_share(self) -> float:
        """The share of the draws whose selection kept a smaller set than its largest
        candidate."""
        return 1.0 - self.kept_share(len(self.labels) - 1)

    def standard_error(self, p: float) -> float:
        """The Monte Carlo standard error (m) of :meth:`percentile` ``p`` from the draws alone:
        half the distance between the order statistics one binomial standard deviation
        (``sqrt(n q (1 - q))`` ranks, ``q = p / 100``) below and above it."""
        x = np.sort(self.tool_m)
        n = len(x)
        q = p / 100.0
        half = np.sqrt(n * q * (1.0 - q))
        lo = int(np.clip(np.floor(n * q - half), 0, n - 1))
        hi = int(np.clip(np.ceil(n * q + half), 0, n - 1))
        return float((x[hi] - x[lo]) / 2.0)


def selection_spread(
    model: MCPCModel,
    q: np.ndarray,
    G: np.ndarray,
    F_frames: np.ndarray,
    n_features: np.ndarray,
    n_cam: int,
    variance: np.ndarray,
    sigma_px: float,
    *,
    draws: int = DRAWS,
    seed: int = 0,
    directions: Directions | None = None,
    on_draw: Callable[[], None] | None = None,
    held_out: np.ndarray | None = None,
) -> SelectionSpread:
    """The calibration's tool-point error in ``draws`` linearised draws (module docstring) at
    the joints ``q`` (m, n) rad in recording order of ``model`` (world = board, tool = camera),
    ``G`` (k, k) the aligned tool weight over the workspace: ``F_frames`` (m, p, p) the frames'
    information on ``[camera (n_cam), minimal (k)]``
    (:func:`selfcal.calibration.board.plan.information.frame_information`), ``n_features`` (m,)
    the features each shows, ``variance`` (k,) the deviation from the drawing (the placement's
    zero: every fit estimates it), ``sigma_px`` the corner noise (px); deterministic for a
    ``seed``. With fewer than two folds (or than two that count) the selection keeps the
    nominal in every draw.
    ``on_draw``: called after each draw (a progress bar). ``held_out`` (m, p + j, p + j) what
    each frame's prediction from its joints alone errs by
    (:func:`selfcal.calibration.board.plan.information.prediction_information`: the left-out
    fold's frames are predicted without their joints' corrections, and their read-back errors,
    ``j`` standard normal coordinates drawn per frame, move their features; None:
    ``F_frames``, the joints exact)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    F_frames = np.asarray(F_frames, dtype=float)
    n_features = np.asarray(n_features, dtype=float)
    variance = np.asarray(variance, dtype=float)
    k = len(variance)
    p = n_cam + k
    A = F_frames if held_out is None else np.asarray(held_out, dtype=float)
    if F_frames.shape != (len(q), p, p) or len(n_features) != len(q) or G.shape != (k, k) \
            or A.shape[:2] != (len(q), A.shape[2]) or A.shape[1] < p:  # fmt: skip
        raise UsageError(f"shapes do not match: {len(q)} frames, F {F_frames.shape}, held-out "
                         f"{A.shape}, features {n_features.shape}, G {G.shape}, k {k}")  # fmt: skip
    dirs = directions or Directions(model)
    folds = selection_folds(model, q, dirs)
    cands = folds.candidates
    nf = len(folds.labels) if folds.cross_validated else 1
    F_all = F_frames.sum(axis=0)
    full = [linear_estimator(F_all, n_cam, dirs.of(c.free_idx, c.offset_joints)) for c in cands]
    rng = np.random.default_rng(seed)
    half = np.sqrt(3.0 * variance)
    if nf < 2:
        F_fold = [F_all]
        fits: list[list] = []
    else:
        F_fold = [F_frames[folds.out(f)].sum(axis=0) for f in range(nf)]
        fits = [[linear_estimator(F_all - F_fold[f], n_cam, Mc) for Mc in folds.directions[f]]
                for f in range(nf)]  # fmt: skip
        n_out = np.array([n_features[folds.out(f)].sum() for f in range(nf)])
        A_fold = [A[folds.out(f)].sum(axis=0)[:p, :p] for f in range(nf)]
        z_at = [np.flatnonzero(folds.out(f)) for f in range(nf)]
    roots = [psd_sqrt(Ff) for Ff in F_fold]
    Gp = np.zeros((p, p))
    Gp[n_cam:, n_cam:] = G
    tool = np.empty(draws)
    chosen = np.zeros(draws, np.int64)
    for t in range(draws):
        d = np.concatenate([np.zeros(n_cam), rng.uniform(-half, half)])
        h = [L @ rng.standard_normal(L.shape[1]) for L in roots]
        if nf >= 2:
            chi2 = rng.chisquare(2.0 * n_out)
            z = rng.standard_normal((len(q), A.shape[1] - p))  # the read-back errors
            # per fold what its left-out frames' read-back errors add: 2 e^T b + zz (the same
            # for every candidate's fit)
            b = [np.einsum("ipj,ij->p", A[i, :p, p:], z[i]) for i in z_at]
            zz = [float(np.einsum("ij,ijk,ik->", z[i], A[i, p:, p:], z[i])) for i in z_at]
            H = sum(h)
            trial = []
            for c, ci in enumerate(cands):
                rms = []
                for f in range(nf):
                    fit = fits[f][c]
                    if fit is None:
                        rms.append(float("inf"))
                        continue
                    C, R = fit
                    e = -R @ d + C @ (H - h[f])
                    ss = chi2[f] - 2.0 * h[f] @ e + e @ A_fold[f] @ e + 2.0 * e @ b[f] + zz[f]
                    rms.append(float(sigma_px * np.sqrt(max(ss, 0.0) / n_out[f])))
                r = np.array(rms)
                trial.append(replace(ci, fold_rms_px=tuple(r.tolist()),
                                     cv_px=cv_error(r, folds.counted)))  # fmt: skip
            chosen[t] = one_se_rule(trial, folds.counted)[0]
        fit = full[chosen[t]]
        if fit is None:
            tool[t] = float("inf")
        else:
            C, R = fit
            e = -R @ d + C @ sum(h)
            tool[t] = float(np.sqrt(max(e @ Gp @ e, 0.0)))
        if on_draw is not None:
            on_draw()
    return SelectionSpread(tool, chosen, tuple(c.label for c in cands))


def plan_spread(
    setup: PlanSetup,
    q: np.ndarray,
    G: np.ndarray,
    variance: np.ndarray,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None = None,
    seen: Sequence[np.ndarray] = (),
    *,
    draws: int = DRAWS,
    seed: int = 0,
    on_draw: Callable[[], None] | None = None,
) -> SelectionSpread:
    """:func:`selection_spread` of a calibration on the postures ``q`` (m, n) rad of ``setup``
    in recording order: the frames' information at corner noise ``pixel_sigma_px`` (px) and
    joint read-back noise ``joint_sigma`` (n,) rad (None: exact;
    :func:`selfcal.calibration.board.plan.information.frame_information`), the first
    ``len(seen)`` frames showing the board features ``seen`` (a dataset's detections, arrays of
    feature ids), the others every feature; ``G`` (k, k) the aligned tool weight over the
    workspace, ``variance`` (k,) the deviation's (the placement's zero)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if len(seen) > len(q):
        raise UsageError(f"{len(seen)} frames' features for {len(q)} postures")
    ids = np.asarray(setup.board.layout()[0])
    shown = [*seen, *([ids] * (len(q) - len(seen)))]
    F = frame_information(setup, q, pixel_sigma_px, joint_sigma, shown)
    A = prediction_information(setup, q, pixel_sigma_px, joint_sigma, shown)
    n = np.array([len(s) for s in shown], dtype=float)
    return selection_spread(board_model(setup), q, G, F, n, setup.camera.n_free, variance,
                            pixel_sigma_px, draws=draws, seed=seed, on_draw=on_draw,
                            held_out=A)  # fmt: skip
