"""Which parameters a board calibration's selection will keep at planned postures: its
cross-validation forecast from the information alone (``selfcal plan --add``, issue #30).

The selection (:mod:`selfcal.calibration.board.param_selection`) keeps the smallest nested
candidate that predicts the frames of every left-out configuration fold clearly better than the
nominal does. Its rank test alone (:func:`selfcal.calibration.board.plan.predict.kept_by_rank`)
says what every frame together determines, not what each fold's training frames can predict:
a dataset recorded in one arm configuration is left out whole by one fold, whose fit has only
the added postures of the other folds. With few of them a large candidate is barely determined
there and predicts the dataset's frames badly, so the selection keeps a smaller one.

The forecast runs the selection's own steps on expectations: the same pool and nested
candidates at the joints, the same folds (:func:`selfcal.calibration.board.folds.configurations`,
:func:`selfcal.calibration.board.folds.fold_labels`: numbered by their joints, whatever the
order of the postures),
in every fold the parameters its training frames cannot determine held
(:func:`selfcal.calibration.board.parameter_pool.determined`), and the same paired
one-standard-error rule (:func:`selfcal.calibration.board.param_selection.one_se_rule`) on the
folds' expected RMS over the folds that count
(:func:`selfcal.calibration.board.folds.counted_folds`: a fold leaving out more than half of
the frames does not; with fewer than two counting the nominal is kept). A fold's expected mean square per feature (both image coordinates): the
corners' noise ``2 sigma^2`` plus ``sigma^2 sum_i (trace(A_i C) + trace(Z_i)) / n``, ``A_i``
the information of the fold's frames with their joints (``n`` features; the selection predicts
a left-out fold from its joints alone, their read-back corrections not fitted:
:func:`selfcal.calibration.board.plan.information.prediction_information`, whose ``Z_i`` is
what the frame's read-back errors add; with the corrections eliminated, as the training fits
have them, the ER-4u A3 cell's plan of 12 expected its nominal's folds at 0.47 px where its
calibrations measured 2.2 - 3.1 px, docs/plan.md), ``C`` the error covariance of the fit on the other
folds' frames (:func:`selfcal.calibration.board.plan.predict.error_covariance`: the noise and
the held parameters' deviation from the drawing), the camera's free parameters fitted with
the kinematics as each fold's fit does (it starts from the camera of the fit on every frame and
fits it again on the fold's training frames: taken as known, a fold of few training frames
predicted the large candidates too well, and the forecast kept 22 parameters of arm7's plan of
12 where the selection kept 13 in each of 7 simulated truths and noise draws). Units: SI, px.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.folds import (
    MIN_COUNTED,
    configurations,
    counted_folds,
    fold_labels,
)
from selfcal.calibration.board.param_selection import (
    Candidate,
    cv_error,
    nested_candidates,
    one_se_rule,
)
from selfcal.calibration.board.parameter_pool import determined_each, parameter_pool
from selfcal.calibration.board.plan.predict import Directions, error_covariance
from selfcal.errors import UsageError
from selfcal.kinematics.mcpc import MCPCModel, param_names

__all__ = [
    "SelectionFolds",
    "SelectionForecast",
    "candidate_fold_rms",
    "forecast_selection",
    "selection_folds",
]


@dataclass(frozen=True, eq=False)
class SelectionForecast:
    """The forecast of :func:`forecast_selection`: the chosen candidate's ``label`` and its
    kinematic parameters (``free_idx`` flat MCPC indices, ``offset_joints`` 0 based); every
    candidate's label and expected fold RMS (px) in ``fold_rms_px``; ``folds`` how many;
    ``kept_sets`` every candidate's (flat MCPC indices, offset joints) and ``chosen`` the
    chosen one's index among them; ``counted`` per fold whether it counts
    (:func:`selfcal.calibration.board.folds.counted_folds`; empty: all)."""

    label: str
    free_idx: np.ndarray
    offset_joints: np.ndarray
    labels: tuple[str, ...]
    fold_rms_px: tuple[tuple[float, ...], ...]
    folds: int
    kept_sets: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    chosen: int = 0
    counted: tuple[bool, ...] = ()

    @property
    def cv_px(self) -> tuple[float, ...]:
        """Every candidate's expected CV error (px): its counted folds' geometric mean
        (:func:`selfcal.calibration.board.param_selection.cv_error`)."""
        return tuple(cv_error(r, self.counted or None) for r in self.fold_rms_px)

    @property
    def kept(self) -> tuple[np.ndarray, np.ndarray]:
        """(flat MCPC indices, offset joints) the forecast keeps."""
        return self.free_idx, self.offset_joints


def forecast_selection(
    model: MCPCModel,
    q: np.ndarray,
    F_frames: np.ndarray,
    n_features: np.ndarray,
    n_cam: int,
    variance: np.ndarray,
    sigma_px: float,
    directions: Directions | None = None,
    held_out: np.ndarray | None = None,
) -> SelectionForecast:
    """The candidate the selection is expected to keep (module docstring) for the frames at the
    joints ``q`` (m, n) rad (in any order: the folds are dealt by the joints), of ``model``
    (world = board, tool = camera):
    ``F_frames`` (m, p, p) their information on ``[camera (n_cam), minimal (k)]``
    (:func:`selfcal.calibration.board.plan.information.frame_information`), ``n_features`` (m,) the
    features each shows, ``variance`` (k,) the deviation from the drawing, ``sigma_px`` the
    corner noise (px); ``directions`` the model's estimated directions when already computed
    (:class:`selfcal.calibration.board.plan.predict.Directions`); ``held_out`` (m, p + j, p + j)
    what each frame's prediction from its joints alone errs by
    (:func:`selfcal.calibration.board.plan.information.prediction_information`; None:
    ``F_frames``, the joints exact)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n_features = np.asarray(n_features, dtype=float)
    A = F_frames if held_out is None else np.asarray(held_out, dtype=float)
    if len(F_frames) != len(q) or len(n_features) != len(q) or len(A) != len(q):
        raise UsageError(f"{len(q)} frames, {len(F_frames)} informations, {len(A)} held-out "
                         f"informations, {len(n_features)} feature counts")  # fmt: skip
    folds = selection_folds(model, q, directions)
    cands = folds.candidates
    first = cands[0]
    if not folds.cross_validated:  # no cross-validation: the selection keeps the nominal
        return SelectionForecast(first.label, first.free_idx, first.offset_joints,
                                 (first.label,), ((),), max(len(folds.labels), 1),
                                 ((first.free_idx, first.offset_joints),), 0)  # fmt: skip
    rms = np.stack([candidate_fold_rms(folds, k, F_frames, A, n_features, n_cam, variance,
                                       sigma_px) for k in range(len(cands))], axis=1)  # fmt: skip
    for c, r in zip(cands, rms.T):
        c.fold_rms_px = tuple(r.tolist())
        c.cv_px = cv_error(r, folds.counted)
    chosen, _ = one_se_rule(cands, folds.counted)
    c = cands[chosen]
    return SelectionForecast(
        c.label, c.free_idx, c.offset_joints, tuple(x.label for x in cands),
        tuple(x.fold_rms_px for x in cands), len(folds.labels),
        tuple((x.free_idx, x.offset_joints) for x in cands), chosen,
        tuple(folds.counted.tolist()),
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class SelectionFolds:
    """What the selection cross-validates at the joints of :func:`selection_folds`: its nested
    ``candidates``, each frame's fold ``of_frame`` (m,) and the folds' ``labels``, and per fold
    and candidate the kinematic directions (k, e) its fit on the other folds' frames estimates
    (``directions[fold][candidate]``: those the training frames determine); ``counted`` (f,)
    bool whether each fold counts (:func:`selfcal.calibration.board.folds.counted_folds`)."""

    candidates: list[Candidate]
    of_frame: np.ndarray
    labels: np.ndarray
    directions: tuple[tuple[np.ndarray, ...], ...]
    counted: np.ndarray

    @property
    def cross_validated(self) -> bool:
        """Whether the selection cross-validates: two folds or more, enough of them counted
        (:data:`selfcal.calibration.board.folds.MIN_COUNTED`); else it keeps the nominal."""
        return len(self.labels) >= 2 and int(self.counted.sum()) >= MIN_COUNTED

    def out(self, fold: int) -> np.ndarray:
        """(m,) bool: the frames fold number ``fold`` leaves out."""
        return self.of_frame == self.labels[fold]


def selection_folds(
    model: MCPCModel, q: np.ndarray, directions: Directions | None = None
) -> SelectionFolds:
    """The selection's candidates and folds at the joints ``q`` (m, n) rad
    of ``model`` (module docstring); ``directions`` the model's when already computed (no
    directions with fewer than two folds)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    cands = nested_candidates(parameter_pool(model, q))
    folds = fold_labels(configurations(q, model.joint_types))
    labels = np.unique(folds)
    counted = counted_folds(folds)
    if len(labels) < 2:
        return SelectionFolds(cands, folds, labels, (), counted)
    last = cands[-1]  # the candidates are nested: every direction is one of the last's
    M = (directions or Directions(model)).of(last.free_idx, last.offset_joints)
    column = {nm: k for k, nm in enumerate(_names(last))}
    dirs = tuple(tuple(M[:, [column[nm] for nm in _names(c) if nm not in held]]
                       for c, held in zip(cands, determined_each(
                           model, q[folds != f], [c.names for c in cands])))
                 for f in labels)  # fmt: skip
    return SelectionFolds(cands, folds, labels, dirs, counted)


def candidate_fold_rms(
    folds: SelectionFolds,
    candidate: int,
    F_frames: np.ndarray,
    held_out: np.ndarray,
    n_features: np.ndarray,
    n_cam: int,
    variance: np.ndarray,
    sigma_px: float,
) -> np.ndarray:
    """(f,) the expected RMS (px) of every fold of ``folds`` for its candidate number
    ``candidate`` (as :func:`forecast_selection` computes them; inf where a fold's fit is
    singular): the arguments as :func:`forecast_selection`'s, ``held_out`` given."""
    return np.array([_fold_rms(F_frames, held_out, np.asarray(n_features, dtype=float),
                               folds.out(f), n_cam, folds.directions[f][candidate], variance,
                               sigma_px)
                     for f in range(len(folds.labels))])  # fmt: skip


def _names(cand: Candidate) -> list[str]:
    """A candidate's kinematic parameters in the order of its estimated directions' columns:
    the flat MCPC ones, then the joint offsets."""
    return [*param_names(cand.free_idx), *(f"offset_j{j + 1}" for j in cand.offset_joints)]


def _fold_rms(F, A, n_features, out, n_cam, M, variance, sigma_px) -> float:
    """The expected RMS (px) of the fit on the frames outside ``out`` predicting those in it
    (module docstring): ``F`` (m, p, p) the frames' information on ``[camera (n_cam), minimal]``
    (the training fit's, the joints' corrections eliminated), ``A`` (m, p + j, p + j) the
    left-out frames' prediction from their joints alone
    (:func:`selfcal.calibration.board.plan.information.prediction_information`: its read-back
    errors' ``j`` last), ``M`` the kinematic directions the fit estimates (those its training
    frames determine) with the camera's free parameters."""
    C = error_covariance(F[~out].sum(axis=0), n_cam, M, variance)
    if C is None:
        return float("inf")
    p = len(C)
    A_out = A[out].sum(axis=0)
    spread = float(np.einsum("ij,ji->", A_out[:p, :p], C)) + float(np.trace(A_out[p:, p:]))
    return float(np.sqrt(2.0 * sigma_px**2 + sigma_px**2 * spread / n_features[out].sum()))
