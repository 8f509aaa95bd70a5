"""A recording plan for a user's arm, camera and board: which postures to record so that the
board calibration predicts the smallest tool-point error (``selfcal plan``, issue #30). Both
mounts: the camera on the flange and the board static (eye-in-hand), or the camera static and
the board on the flange (eye-to-hand: the board route's inverted chain, world = the camera, tool
= the board, :class:`selfcal.estimation.kinematic_poses.KinematicPoses`); the tool point is the
flange's origin either way.

Candidates: :func:`selfcal.calibration.board.plan.candidates.candidate_pool` (reachable, free of
collision and keep-out boxes, the whole board well in view), with the workspace sample the error
is averaged over (:mod:`selfcal.calibration.board.plan.ground`). Criterion: the Cramer-Rao bound
of the board route (:func:`selfcal.calibration.board.bounds.board_cramer_rao`: the camera's free
parameters and every minimal kinematic parameter of the chain in the board frame, the board
known, Gaussian corner noise of ``pixel_sigma_px`` and, optionally, joint read-back noise
whose per-frame corrections are estimated under their prior) carried to the predicted RMS error
of the tool point (the flange centre) over a sample of the workspace after the best rigid
alignment, as the calibration reports it
(:func:`selfcal.estimation.joint_report.aligned_tool_weight`). Every other parameter is shared
by the frames and a frame's own joint corrections are eliminated frame by frame, so the Fisher
information is the sum of each frame's
(:func:`selfcal.calibration.board.plan.information.frame_information`): the greedy choice
(:func:`selfcal.calibration.board.plan.greedy.select_greedy`) adds, step by step, the candidate
that lowers the predicted error most (from a slightly regularised start, so the first few frames
count while the information is not yet of full rank; a dataset's additions start from its
frames and the prior of the arm's deviation from its drawing,
:mod:`selfcal.calibration.board.plan.add`), and the exchange
(:func:`selfcal.calibration.board.plan.greedy.exchange`) then swaps a chosen posture for another
candidate while a swap lowers the same criterion (both mounts: on eye-to-hand the docs
example's plan of 12 predicts 0.191 mm with it, 0.224 mm without, docs/plan.md). The prediction
of the chosen postures is that of
the calibration with the parameters its selection keeps, every other one held at the drawing
(:func:`predict_kept`, :mod:`selfcal.calibration.board.plan.predict`). The greedy criterion
estimates every parameter the postures identify; when the selection is forecast to keep fewer
(few postures: the UR5e example's 6 of 60 candidates keep none of its 18 beyond the placement,
and the greedy choice's postures, those the deviation moves most, then leave the fair nominal
8.19 mm off where the pool's first 6 leave it 4.36 mm off; docs/plan.md "A plan of a few postures"), the plan is
the best by that prediction of the greedy choice and the pool's disjoint sets of ``count`` in
draw order, as the tracker plan's (:func:`_best_with_the_selection`); a plan whose forecast
keeps every parameter (the tables' plans of 12) is the greedy choice. The chosen postures are
then ordered for a short joint-space path from home
(:func:`selfcal.calibration.board.plan.path.order_path`). The random plan of the same size (the
pool's first postures: the same filters) is predicted the same way, for contrast. Units: SI
inside.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.nominal_fit import beyond_placement
from selfcal.calibration.board.plan.greedy import exchange, pool_sets, select_greedy
from selfcal.calibration.board.plan.ground import PlanOptions, plan_ground
from selfcal.calibration.board.plan.information import (
    board_model,
    frame_information,
    prediction_information,
)
from selfcal.calibration.board.plan.path import order_path, path_length
from selfcal.calibration.board.plan.predict import (
    Directions,
    estimated_directions,
    kept_by_rank,
    predicted_with_held,
)
from selfcal.calibration.board.plan.reference import NominalReference, nominal_reference
from selfcal.calibration.board.plan.selection import SelectionForecast, forecast_selection
from selfcal.calibration.board.plan.views import PlanSetup

__all__ = ["RecordingPlan", "Selected", "count_to_beat", "plan_recording", "predict_kept"]

SEARCH_FACTOR = 4
"""A plan not predicted to beat the reference looks for the count that would among the greedy
choice's first this many times the count (within the pool)."""
SEARCH_STEP = 4
"""... in steps of this many postures."""

RIVAL_LOG = 0.2
"""The next smaller candidate is the forecast choice's rival when its expected CV error is within
``exp(RIVAL_LOG)`` (1.22) times the choice's: the selection's one-standard-error rule keeps the
smaller of two candidates whose folds' mean log ratio to the best's is within its standard
error, and the forecast's expected fold errors have no noise. The rival is a caveat beside the
verdict, not its decider (:meth:`Selected.beats`). Measured under the paired rule
(``selfcal run`` of the plan's scenario with ``[perturbation]`` and ``[noise] seed`` 1 .. 2,
4 or 8, docs/plan.md "What a plan has to beat"): the UR5e example's plan of 12 (the rival's
expected CV error 1.07 times the choice's) kept the rival in 4 of 8 draws; its plans of 24 and
48 (1.08, 1.06) and arm7's of 16 and 24 (1.16, 1.14; tests/data/arm7.toml) in none of 14, so
the margin names a rival the selection rarely keeps at more postures: not re-sized (the
expected errors alone do not tell the two cases apart)."""


@dataclass(frozen=True, eq=False)
class RecordingPlan:
    """``q`` (N, n) rad the planned postures in path order; ``predicted_m`` their predicted
    tool-point RMS error (m) over the ``workspace`` postures (w, n) rad; ``q_random`` a random
    plan of the same size from the same candidates and ``random_m`` its prediction;
    ``candidates`` the pool's size and ``drawn_from`` where it was drawn; the noise level and
    the joint path lengths (rad, the sum of the largest joint move of every step from home) of
    the plan in its order and of the random plan in its own. ``predicted_m`` keeps every
    parameter the rank test identifies (``kept_all`` of them beyond the placement);
    ``selected`` the prediction with the parameters the forecast of the selection's
    cross-validation keeps (what the calibration is expected to estimate, :class:`Selected`);
    ``reference`` the error without
    calibrating the kinematics (:mod:`selfcal.calibration.board.plan.reference`);
    ``to_beat`` (count, predicted m) the smallest plan of the same greedy choice that beats it
    clearly (:meth:`Selected.beats`), when this one does not (None: it does, or no plan of up
    to ``searched`` postures does); ``chosen_by`` which set the plan is: ``"greedy"`` (the
    greedy choice improved by swaps) or, when the selection is forecast to keep fewer
    parameters than the greedy criterion counted on, ``"random set i of s"`` of the pool's
    disjoint sets in draw order if one predicts better with the parameters its own selection is
    forecast to keep (module docstring); ``greedy_m`` the greedy choice's prediction so (m),
    ``random_selected_m`` the random plan's when the sets were judged (None when not)."""

    q: np.ndarray
    predicted_m: float
    q_random: np.ndarray
    random_m: float
    workspace: np.ndarray
    candidates: int
    drawn_from: str
    pixel_sigma_px: float
    joint_sigma: np.ndarray | None
    path_rad: float
    random_path_rad: float
    kept_all: int
    selected: Selected
    reference: NominalReference
    to_beat: tuple[int, float] | None
    searched: int
    chosen_by: str = "greedy"
    greedy_m: float = float("nan")
    random_selected_m: float | None = None

    @property
    def is_the_random_plan(self) -> bool:
        """Whether the plan's postures are the random plan's (in another order): ``chosen_by``
        the pool's first set, which is the random plan. A comparison of the two (the forecast's
        draws) then compares the plan with itself."""
        q, r = self.q, self.q_random
        return q.shape == r.shape and np.array_equal(
            q[np.lexsort(q.T[::-1])], r[np.lexsort(r.T[::-1])]
        )


@dataclass(frozen=True, eq=False)
class Selected:
    """A plan's prediction with the parameters the selection's cross-validation is forecast to
    keep: ``selected_m`` (m) with the ``forecast``'s choice; ``rival_m`` with the next smaller
    candidate when its expected CV error is within ``exp(RIVAL_LOG)`` of the choice's (the
    selection's one-standard-error rule may keep it: the forecast sees the folds' expected
    errors, not their noise), else None."""

    selected_m: float
    forecast: SelectionForecast
    rival_m: float | None = None

    def beats(self, reference: NominalReference) -> bool:
        """Whether the calibration is predicted to beat ``reference`` clearly: with the
        forecast's choice (``selected_m``), the parameters the selection is expected to keep.
        Not with the rival's: the expected CV errors cannot say which of the two the noise of
        one recording will pick, and the worse of the two decided wrongly on the plans
        rehearsed (docs/plan.md "What a plan has to beat"): arm7's plan of 24 kept the choice
        in 4 of 4 draws and reached 0.37 - 0.54 mm against the drawn chain's 0.77 - 1.05 mm
        while the rival's prediction said no gain; the UR5e example's plan of 12 kept the rival
        in 4 of 8 draws and beat the drawn chain in all 8, by 0.29 - 0.81 times."""
        return reference.beaten_by(self.selected_m)

    def rival_beats(self, reference: NominalReference) -> bool | None:
        """... and whether the rival would (None without one): the verdict's caveat."""
        return None if self.rival_m is None else reference.beaten_by(self.rival_m)

    def kept(self, n: int) -> int:
        """The kinematic parameters beyond the placement the forecast keeps (chain of ``n``
        joints)."""
        return beyond_placement(*self.forecast.kept, n)

    def rival_kept(self, n: int) -> int | None:
        """... and its rival keeps (None without one)."""
        if self.rival_m is None:
            return None
        return beyond_placement(*self.forecast.kept_sets[self.forecast.chosen - 1], n)


def plan_recording(
    setup: PlanSetup,
    count: int,
    *,
    seed: int = 1,
    candidates: int = 400,
    workspace: int = 50,
    pixel_sigma_px: float = 0.5,
    joint_sigma: np.ndarray | None = None,
    deviation: Deviation | None = None,
) -> RecordingPlan:
    """``count`` postures for ``setup`` (module docstring), deterministic for a ``seed``;
    the other arguments as :class:`PlanOptions`'s (``deviation`` None: the default).

    Raises:
        InputError: fewer candidates than ``count``, or no posture sees the board.
    """
    opts = PlanOptions(seed, candidates, workspace, pixel_sigma_px, joint_sigma,
                       deviation or Deviation())  # fmt: skip
    g = plan_ground(setup, count, opts)
    pool, G, var = g.pool, g.G, g.variance
    F = frame_information(setup, pool, pixel_sigma_px, joint_sigma)
    A = prediction_information(setup, pool, pixel_sigma_px, joint_sigma)
    n_cam = setup.camera.n_free
    searched = min(len(pool), SEARCH_FACTOR * count)
    home = setup.robot.home
    chosen = exchange(F, G, n_cam, select_greedy(F, G, n_cam, count))
    chosen = chosen[order_path(pool[chosen], home)]
    rand = pool[:count]
    rand_order = order_path(rand, home)
    model = board_model(setup)
    dirs = Directions(model)
    n_feat = np.full(len(pool), len(setup.board.layout()[0]))

    def selected(idx: np.ndarray) -> tuple[Selected, NominalReference]:
        """The pool's postures ``idx`` in recording order: the prediction with the parameters
        the selection is forecast to keep (and its rival's) and the reference."""
        Fs = F[idx].sum(axis=0)
        fc = forecast_selection(model, pool[idx], F[idx], n_feat[idx], n_cam, var,
                                pixel_sigma_px, dirs, held_out=A[idx])  # fmt: skip
        got = predict_kept(setup, pool[idx], Fs, G, var, fc.kept, dirs)
        cv, c = fc.cv_px, fc.chosen
        rival = None
        if c > 0 and cv[c - 1] <= np.exp(RIVAL_LOG) * cv[c]:
            rival = predict_kept(setup, pool[idx], Fs, G, var, fc.kept_sets[c - 1], dirs)
        ref = nominal_reference(model, Fs, G, n_cam, g.drawn_variance, dirs,
                                eye_to_hand=setup.eye_to_hand)  # fmt: skip
        return Selected(got, fc, rival), ref

    def first(n: int) -> tuple[Selected, NominalReference]:
        """The greedy choice's first ``n`` postures improved by swaps (the plan of ``n``)."""
        idx = exchange(F, G, n_cam, picks[:n])
        idx = idx[order_path(pool[idx], home)]
        return selected(idx)

    sel, ref = selected(chosen)
    kept_all = beyond_placement(*kept_by_rank(model, pool[chosen]), model.n)
    chosen_by, greedy_m, random_sel_m = "greedy", sel.selected_m, None
    if sel.kept(model.n) < kept_all:  # the criterion counted on parameters the CV will drop
        chosen, sel, ref, chosen_by, random_sel_m = _best_with_the_selection(
            len(pool), count, (chosen, sel, ref), selected, lambda i: i[order_path(pool[i], home)]
        )
        kept_all = beyond_placement(*kept_by_rank(model, pool[chosen]), model.n)
    q = pool[chosen]
    to_beat = None
    if not sel.beats(ref):
        picks = select_greedy(F, G, n_cam, searched)  # one by one: the first n start a plan of n
        to_beat = count_to_beat(count, searched, first)
    return RecordingPlan(
        q=q,
        predicted_m=predict_kept(setup, q, F[chosen].sum(axis=0), G, var, directions=dirs),
        q_random=rand,
        random_m=predict_kept(setup, rand, F[:count].sum(axis=0), G, var, directions=dirs),
        workspace=g.workspace,
        candidates=len(pool),
        drawn_from=g.drawn_from,
        pixel_sigma_px=float(pixel_sigma_px),
        joint_sigma=None if joint_sigma is None else np.asarray(joint_sigma, dtype=float),
        path_rad=path_length(q, home),
        random_path_rad=path_length(rand[rand_order], home),
        kept_all=kept_all,
        selected=sel,
        reference=ref,
        to_beat=to_beat,
        searched=searched,
        chosen_by=chosen_by,
        greedy_m=greedy_m,
        random_selected_m=random_sel_m,
    )


def _best_with_the_selection(
    size: int,
    count: int,
    plan: tuple[np.ndarray, Selected, NominalReference],
    selected: Callable[[np.ndarray], tuple[Selected, NominalReference]],
    ordered: Callable[[np.ndarray], np.ndarray],
) -> tuple[np.ndarray, Selected, NominalReference, str, float]:
    """``(indices, prediction, reference, chosen_by, random_m)``: of the greedy choice ``plan`` (its
    indices into the pool of ``size``, prediction and reference) and the pool's disjoint sets
    of ``count`` in draw order (``ordered`` puts indices in recording order; the first set is
    the random plan), the one ``selected`` predicts best with the parameters the selection is
    forecast to keep (:attr:`Selected.selected_m`); the first of equals: the greedy choice.
    ``chosen_by`` names it (``"greedy"`` or ``"random set i of s"``); ``random_m`` the first
    set's (the random plan's) prediction so (m)."""
    best, random_m = (*plan, "greedy"), float("nan")
    for k, (name, drawn) in enumerate(pool_sets(size, count)):
        idx = ordered(drawn)
        got, ref = selected(idx)
        random_m = got.selected_m if k == 0 else random_m
        if got.selected_m < best[1].selected_m:
            best = (idx, got, ref, name)
    return (*best, random_m)


def count_to_beat(
    count: int, searched: int, plan_of: Callable[[int], tuple[Selected, NominalReference]]
) -> tuple[int, float] | None:
    """(count, predicted m) of the smallest plan, ``count`` + :data:`SEARCH_STEP`, ... up to
    ``searched`` postures, that beats its reference clearly (:meth:`Selected.beats`: with the
    parameters the selection is forecast to keep), ``plan_of(n)`` a plan of ``n`` postures'
    prediction and reference; None when none does."""
    for n in range(count + SEARCH_STEP, searched + 1, SEARCH_STEP):
        got, ref = plan_of(n)
        if got.beats(ref):
            return n, got.selected_m
    return None


def predict_kept(
    setup: PlanSetup,
    q: np.ndarray,
    F: np.ndarray,
    G: np.ndarray,
    variance: np.ndarray,
    kept: tuple[np.ndarray, np.ndarray] | None = None,
    directions: Directions | None = None,
) -> float:
    """The predicted tool-point RMS (m) of a calibration on the postures ``q`` (m, n) rad with
    the information ``F`` (p, p) (:func:`frame_information` summed over them), the tool weight
    ``G`` and the deviation's ``variance`` (k,): its ``kept`` parameters (flat MCPC indices,
    offset joints) estimated, by default those the selection's rank and conditioning test
    accepts at ``q``, the others held at the drawing
    (:func:`selfcal.calibration.board.plan.predict.predicted_with_held`); ``directions`` the
    model's when already computed."""
    model = board_model(setup)
    free_idx, offsets = kept_by_rank(model, q) if kept is None else kept
    if directions is None:
        M = estimated_directions(model, free_idx, offsets)
    else:
        M = directions.of(free_idx, offsets)
    return predicted_with_held(F, G, setup.camera.n_free, M, variance)
