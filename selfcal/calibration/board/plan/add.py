"""The postures to add to a calibrated board dataset: the ``count`` that most lower the predicted
tool-point error of its calibration, given the frames it holds (``selfcal plan --add``, issue
#30).

The cell is the calibration's (:func:`dataset_setup`): the robot file, the calibrated camera and
the cell's two mounts where the calibration placed them, either mount (eye-in-hand the board in
the base and the camera on the flange, eye-to-hand the camera in the base and the board on the
flange: :func:`selfcal.calibration.board.plan.add_cell.calibrated_cell`, what differs between
the mounts; everything below is the same code for both). Candidates are drawn as for a new plan
(:func:`selfcal.calibration.board.plan.candidates.candidate_pool`). The information the dataset
already holds is its frames'
(:func:`selfcal.calibration.board.plan.information.frame_information` at its read-back joints,
with the board features detected in each) plus the prior of the arm's deviation from its drawing
(:mod:`selfcal.calibration.board.plan.predict`); the greedy choice adds, one at a time, the
candidate that lowers the predicted tool-point error most
(:func:`selfcal.calibration.board.plan.greedy.select_greedy`) and ranks :data:`SPARE` more; the
added postures are ordered for a short joint path from home.

The prediction after the additions is that of the calibration with the parameters its
selection's cross-validation is forecast to keep
(:func:`selfcal.calibration.board.plan.selection.forecast_selection`; the folds are dealt by the
joints, whatever the recording order). The swaps judge a choice by more than that one forecast:
by the RMS of the tool-point error over :data:`SWAP_DRAWS` draws of the arm and the noise, the
selection deciding in each (:func:`selfcal.calibration.board.plan.spread.selection_spread`),
and where it falls by :data:`GAIN` or more, one of the greedy's next :data:`SPARE` picks
replaces a chosen posture. The forecast's choice flips from one candidate to the next as the
postures change, and its prediction jumps with it: a choice on the edge, where the forecast
just keeps the larger set, is predicted far lower than one just short of it, though the
selection on one recording keeps the larger set in only a part of the draws (a dataset of one
configuration with 5 added, docs/plan.md: the fold that leaves the dataset out fits the added
postures alone). The draws' RMS counts every candidate the selection may keep by how often it
keeps it.

Predicted before: the dataset's calibration with the parameters its selection identified
(``calibration.json``), every other minimal parameter held at the drawing. Units: SI inside.

The hand-eye of every prediction is the calibration's (the dataset fitted it), not the robot
file's. The chain as drawn (:mod:`selfcal.calibration.board.plan.reference`) assumes the robot
file's camera mount within the arm's deviation; when that mount lies farther than
:data:`MOUNT_FACTOR` times the deviation from the calibrated one (a robot file without
``[camera_mount]`` puts the camera at the flange), the chain as drawn is no reference and the
verdicts are against the fair nominal, whose hand-eye is fitted from the dataset.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.calibration.board.bounds import estimated_parameters
from selfcal.calibration.board.dataset import dataset_board, detect_board
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.folds import configurations, fold_labels
from selfcal.calibration.board.nominal_fit import beyond_placement
from selfcal.calibration.board.plan import spread as forecast_spread
from selfcal.calibration.board.plan.add_cell import ADD_RULE, calibrated_cell
from selfcal.calibration.board.plan.greedy import select_greedy
from selfcal.calibration.board.plan.ground import PlanOptions, plan_ground
from selfcal.calibration.board.plan.information import (
    board_model,
    frame_information,
    prediction_information,
)
from selfcal.calibration.board.plan.path import order_path, path_length
from selfcal.calibration.board.plan.planner import predict_kept
from selfcal.calibration.board.plan.predict import Directions, prior_information
from selfcal.calibration.board.plan.reference import NominalReference, nominal_reference
from selfcal.calibration.board.plan.selection import SelectionForecast, forecast_selection
from selfcal.calibration.board.plan.spread import selection_spread
from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.errors import InputError
from selfcal.io.board_calibration import BoardCalibrationResult, read_board_calibration
from selfcal.io.dataset import Dataset
from selfcal.robot.definition import load_robot
from selfcal.target.base import Features

__all__ = [
    "ADD_RULE",
    "MOUNT_FACTOR",
    "drawn_mount_words",
    "AddedPostures",
    "DatasetPlan",
    "HALVE_MORE",
    "Halving",
    "first_halving",
    "calibration_plan",
    "dataset_setup",
    "plan_additions",
    "swap_spares",
    "training_sets",
]


@dataclass(frozen=True, eq=False)
class DatasetPlan:
    """What a calibrated dataset gives the planner: the cell ``setup``, the read-back joints
    ``q`` (m, n) rad of the frames its calibration used, the board features ``seen`` in each
    (m arrays of feature ids), the kinematic parameters it identified (``free_idx`` flat
    MCPC indices, ``offset_joints`` 0 based) and ``mount_off`` (rad, m): how far the robot
    file's camera mount lies from the calibrated one (``setup.robot``'s; eye-to-hand zero: no
    camera rides on the flange)."""

    setup: PlanSetup
    q: np.ndarray
    seen: tuple[np.ndarray, ...]
    free_idx: np.ndarray
    offset_joints: np.ndarray
    mount_off: tuple[float, float] = (0.0, 0.0)

    @property
    def n_features(self) -> np.ndarray:
        """(m,) how many board features each frame shows."""
        return np.array([len(s) for s in self.seen], dtype=np.int64)


def dataset_setup(root: str | Path, boxes: np.ndarray | None = None) -> DatasetPlan:
    """The :class:`DatasetPlan` of the dataset folder ``root`` and its ``calibration.json``
    (``selfcal calibrate``), with keep-out ``boxes`` (b, 6) m in the base frame. The frames
    count with the board features detected in them (the stored detections, or the images
    detected again), those showing fewer than the board's minimum left out as the calibration
    leaves them.

    Either mount (:func:`selfcal.calibration.board.plan.add_cell.calibrated_cell`).

    Raises:
        InputError: no calibration.json, a calibration of more than one camera (not planned
            yet), no frame showing the board, or a chain whose base frame cannot be rebuilt
            (joints 1 and 2 not revolute).
    """
    root = Path(root)
    if not (root / "calibration.json").is_file():
        raise InputError(f"{root}: no calibration.json",
                         fix=f"calibrate the dataset first: selfcal calibrate {root}")  # fmt: skip
    cal = read_board_calibration(root)
    if len(cal.cameras) > 1:
        raise InputError(
            f"{root}/calibration.json: --add plans for one camera (either mount) only; this "
            f"calibration is {cal.setup} with {len(cal.cameras)} cameras "
            f"({', '.join(cal.camera_names)})",
            fix="plan the additions of one camera's dataset: import the images of one camera "
            "(selfcal import --images 'cam0=...') into a dataset of its own, calibrate it "
            "(selfcal calibrate) and give that dataset to --add",
        )
    ds = Dataset.open(root)
    board = dataset_board(ds)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a frame without the board: left out below, as calibrate
        features, _ = detect_board(ds, board, ds.info.cameras[0])
    return calibration_plan(root, cal, features, np.radians(ds.joints_deg), boxes)


def calibration_plan(
    root: str | Path,
    cal: BoardCalibrationResult,
    features: Sequence[Features],
    q: np.ndarray,
    boxes: np.ndarray | None = None,
) -> DatasetPlan:
    """:func:`dataset_setup` of the one-camera calibration ``cal`` of the dataset ``root``
    with its first camera's ``features`` of every frame and the frames' read-back joints ``q``
    (m, n) rad already at hand (``selfcal calibrate`` detected them).

    Raises:
        InputError: as :func:`dataset_setup`'s.
    """
    ds = Dataset.open(root)
    robot = load_robot(ds.robot_source)
    board = dataset_board(ds)
    used = np.array([len(f) >= board.min_features for f in features], bool)
    if not used.any():
        raise InputError(f"{root}: no frame shows the board",
                         fix="calibrate a dataset whose images show the board")  # fmt: skip
    q = np.asarray(q, dtype=float)[used]
    try:
        setup, mount_off = calibrated_cell(
            cal, robot, cal.cameras[0], board,
            np.zeros((0, 6)) if boxes is None else np.asarray(boxes, dtype=float))  # fmt: skip
    except InputError as exc:  # no base frame to place the cell in (prismatic joints 1, 2)
        raise InputError(f"{root}/calibration.json: --add cannot place its cell in the robot's "
                         f"base frame: {exc.message}", fix=exc.fix) from exc  # fmt: skip
    free_idx, offsets = estimated_parameters(cal)
    seen = tuple(np.asarray(f.ids, np.int64) for f, u in zip(features, used) if u)
    return DatasetPlan(setup, q, seen, free_idx, offsets, mount_off)


MOUNT_FACTOR = 5.0
"""The robot file's camera mount stands for the drawn one when it lies within this many times
the deviation's half-widths (rotation and translation) of the calibrated mount; the deviation
itself never moves it farther than once."""


def drawn_mount_words(plan: DatasetPlan, deviation: Deviation) -> str:
    """Why the chain as drawn is no reference for ``plan``'s dataset (module docstring): the
    robot file's camera mount lies more than :data:`MOUNT_FACTOR` times ``deviation`` from the
    calibrated one; empty when it does not."""
    rot, tr = plan.mount_off
    if (
        rot <= MOUNT_FACTOR * deviation.rotation_rad
        and tr <= MOUNT_FACTOR * deviation.translation_m
    ):
        return ""
    which = ("its [camera_mount]" if plan.setup.robot.camera_mount_given
             else "no [camera_mount]: the camera at the flange")  # fmt: skip
    return (f"the robot file's camera mount lies {np.degrees(rot):.1f} deg and {tr * 1000:.1f} mm "
            f"from the calibrated one ({which}), beyond {MOUNT_FACTOR:g} times the deviation, so "
            "the chain as drawn has no hand-eye to go by")  # fmt: skip


def training_sets(plan: DatasetPlan, F_frames: np.ndarray) -> np.ndarray:
    """(1 + f, p, p) the information of the dataset's frames ``F_frames`` (m, p, p) summed:
    all of them, then every training set of the selection's cross-validation (all but one
    fold of its arm configurations,
    :func:`selfcal.calibration.board.folds.fold_labels`). A dataset of one
    configuration gives the whole and nothing: the fold that leaves it out fits the added
    postures alone, and they must then predict it.

    Every fold, also one that leaves out more than half of the frames and so does not count in
    the selection (:func:`selfcal.calibration.board.folds.counted_folds`): its term stands in
    for the folds that do count, which the greedy cannot name before it has chosen. On a
    wrist-only dataset those folds each leave out one added posture and train on the dataset,
    which adds little of the arm's kinematics, and the other added ones: nearly the added
    postures alone, what this fold's term asks of them. Serving only the folds that count (the
    whole alone there) was measured and reverted (session 29, commit 9c38632: the eye-in-hand
    ``--add 5`` benchmark's 12 truths achieved less, docs/plan.md)."""
    folds = fold_labels(configurations(plan.q, plan.setup.robot.joint_types))
    total = F_frames.sum(axis=0)
    return np.stack([total, *(total - F_frames[folds == f].sum(axis=0)
                              for f in np.unique(folds))])  # fmt: skip


@dataclass(frozen=True, eq=False)
class AddedPostures:
    """``q`` (K, n) rad the postures to add in recording order; ``before_m`` the dataset's
    predicted tool-point RMS (m) with its identified parameters, ``after_m`` with the added
    postures and the parameters the ``forecast`` of the selection keeps; ``kept_before``,
    ``kept_after`` how many kinematic parameters (flat MCPC and joint offsets) each estimates
    beyond the placement (:func:`selfcal.calibration.board.nominal_fit.beyond_placement`, as
    ``selfcal calibrate`` counts them);
    the ``workspace`` (w, n) rad the error is averaged over, the pool's size and where it was
    drawn, the joint path (rad) from home through the added ones, and the ``reference``: the
    error without calibrating the kinematics for the dataset's frames and the added ones
    (:mod:`selfcal.calibration.board.plan.reference`); ``reference_before`` the same for the
    dataset's frames alone (what ``before_m`` is judged against); ``halving`` how many postures
    are predicted to halve ``before_m`` (None: not asked)."""

    q: np.ndarray
    before_m: float
    after_m: float
    kept_before: int
    kept_after: int
    workspace: np.ndarray
    candidates: int
    drawn_from: str
    path_rad: float
    forecast: SelectionForecast
    reference: NominalReference
    reference_before: NominalReference
    halving: Halving | None = None


@dataclass(frozen=True)
class Halving:
    """How many postures the plan predicts to halve the dataset's error (:func:`first_halving`):
    ``count`` the fewest (None: none of those tried), ``after_m`` its predicted tool-point error
    (m; NaN without a count), ``tried`` the largest count tried, ``before_m`` the error before
    it is judged against (m). :func:`plan_additions` judges by the medians of the forecast's
    draws (:data:`selfcal.calibration.board.plan.spread.DRAWS` of them, seeded with the plan's
    seed: ``selfcal plan --add``'s sixth line, plan.json's ``forecast_draws``), not by the first
    line's prediction, which jumps with the one candidate the selection's forecast keeps."""

    count: int | None
    after_m: float
    tried: int
    before_m: float = float("nan")


HALVE_MORE = 3
"""When ``count`` added postures are not predicted to halve the error, :func:`plan_additions`
plans this many larger counts in turn (each as ``count`` is planned) and reports the first that
is (:class:`Halving`); each costs about as much as the plan itself."""


def first_halving(before_m: float, count: int, after: Callable[[int], float], most: int) -> Halving:
    """The fewest postures from ``count`` up to ``most`` whose predicted tool-point RMS
    ``after(n)`` (m) is at most half ``before_m`` (m), tried in increasing order and stopped at
    the first; ``after`` is called for no count above it."""
    for n in range(count, most + 1):
        got = after(n)
        if got <= 0.5 * before_m:
            return Halving(n, got, n, before_m)
    return Halving(None, float("nan"), most, before_m)


SPARE = 16
"""The greedy's next picks beyond the count that may replace a chosen posture."""
GAIN = 0.01
"""A swap is taken when the draws' RMS tool-point error falls by this share."""
SWAP_DRAWS = 100
"""Draws of the arm and the noise that judge a swap
(:func:`selfcal.calibration.board.plan.spread.selection_spread`, the same seed for every
choice); seeded apart from the forecast's draws ``selfcal plan`` reports, which then judge the
chosen postures on draws they were not chosen on."""
SWAP_SEED = 7919
"""Added to the plan's seed for the swaps' draws."""


def swap_spares(
    chosen: np.ndarray,
    spares: np.ndarray,
    cost: Callable[[np.ndarray], float],
    order: Callable[[np.ndarray], np.ndarray],
) -> np.ndarray:
    """``chosen`` (count,) indices with the ``spares`` swapped in where they lower ``cost`` by
    :data:`GAIN` or more: each place of ``chosen`` in turn tries every spare not chosen, a
    trial put in ``order`` before its ``cost`` is taken (so the cost is the set's, in one
    order). One pass; never above the ``cost`` it started from."""
    chosen = np.asarray(chosen)
    best = cost(chosen)
    for i in range(len(chosen)):
        for spare in spares:
            if spare in chosen:
                continue
            trial = chosen.copy()
            trial[i] = spare
            trial = order(trial)
            got = cost(trial)
            if got < (1.0 - GAIN) * best:
                chosen, best = trial, got
    return chosen


def plan_additions(
    plan: DatasetPlan,
    count: int,
    options: PlanOptions | None = None,
    workspace: np.ndarray | None = None,
    more: int = 0,
    spare: int = SPARE,
) -> AddedPostures:
    """The ``count`` postures to add to ``plan``'s dataset (module docstring), drawn and
    predicted with ``options`` (default :class:`selfcal.calibration.board.plan.ground.PlanOptions`)
    over the ``workspace`` postures (w, n) rad (None: the robot file's planning window around
    home, as a new plan's; ``selfcal plan --add`` gives
    :func:`selfcal.calibration.board.plan.add_ground.dataset_workspace`'s). With ``more`` > 0
    the result's ``halving`` says how many postures, up to ``count + more``, are predicted to
    halve the error before (:func:`first_halving` on the medians of the forecast's draws before
    and after, :class:`Halving`; each larger count planned from the same candidates as
    ``count`` is: the greedy choice is nested, the swaps its own); 0: not asked.
    ``spare``: how many of the greedy's next picks may replace a chosen posture (more than the
    pool holds: every candidate, one pass of swaps over the whole pool; a benchmark's question,
    ``python -m selfcal.benchmarks.plan.add_pool``).

    Raises:
        InputError: fewer candidates than ``count``.
    """
    opts = options or PlanOptions()
    setup = plan.setup
    g = plan_ground(setup, count, opts, workspace)
    G, var, n_cam = g.G, g.variance, setup.camera.n_free
    F_frames = frame_information(setup, plan.q, opts.pixel_sigma_px, opts.joint_sigma, plan.seen)
    F_old = F_frames.sum(axis=0)
    F = frame_information(setup, g.pool, opts.pixel_sigma_px, opts.joint_sigma)
    A_old = prediction_information(setup, plan.q, opts.pixel_sigma_px, opts.joint_sigma, plan.seen)
    A = prediction_information(setup, g.pool, opts.pixel_sigma_px, opts.joint_sigma)
    most = min(count + max(more, 0), len(F))
    picks = select_greedy(F, G, n_cam, min(most + spare, len(F)),
                          start=training_sets(plan, F_frames) + prior_information(var, n_cam))  # fmt: skip
    home = setup.robot.home
    n_feat = np.concatenate([plan.n_features, np.full(len(F), len(setup.board.layout()[0]))])
    model = board_model(setup)
    dirs = Directions(model)

    def frames(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The joints, informations, feature counts and held-out informations of the dataset's
        frames and the pool's postures ``idx``."""
        return (np.concatenate([plan.q, g.pool[idx]]), np.concatenate([F_frames, F[idx]]),
                np.concatenate([n_feat[: len(plan.q)], n_feat[len(plan.q) + idx]]),
                np.concatenate([A_old, A[idx]]))  # fmt: skip

    def predicted(idx: np.ndarray) -> tuple[float, SelectionForecast]:
        """The prediction after recording the pool's postures ``idx``."""
        q_all, F_all, nf, A_all = frames(idx)
        fc = forecast_selection(model, q_all, F_all, nf, n_cam, var, opts.pixel_sigma_px, dirs,
                                held_out=A_all)  # fmt: skip
        return predict_kept(setup, q_all, F_all.sum(axis=0), G, var, fc.kept, dirs), fc

    def drawn(idx: np.ndarray) -> float:
        """The RMS tool-point error (m) over the swaps' draws after recording ``idx``."""
        q_all, F_all, nf, A_all = frames(idx)
        tool = selection_spread(model, q_all, G, F_all, nf, n_cam, var, opts.pixel_sigma_px,
                                draws=SWAP_DRAWS, seed=opts.seed + SWAP_SEED, directions=dirs,
                                held_out=A_all).tool_m  # fmt: skip
        return float(np.sqrt(np.mean(tool**2)))

    def median(q_all: np.ndarray, F_all: np.ndarray, nf: np.ndarray, A_all: np.ndarray) -> float:
        """The median tool-point error (m) over the forecast's draws of these frames: the draws
        ``selfcal plan --add`` reports (the same count and seed, on draws the swaps were not
        judged on)."""
        return selection_spread(model, q_all, G, F_all, nf, n_cam, var, opts.pixel_sigma_px,
                                draws=forecast_spread.DRAWS, seed=opts.seed, directions=dirs,
                                held_out=A_all).percentile(50)  # fmt: skip

    def in_path_order(idx: np.ndarray) -> np.ndarray:
        return idx[order_path(g.pool[idx], home)]

    def choose(n: int) -> np.ndarray:
        """The ``n`` postures: the greedy's first ``n`` with its next ``spare`` swapped in."""
        return swap_spares(in_path_order(picks[:n]), picks[n : n + spare], drawn, in_path_order)

    chosen = choose(count)
    after, forecast = predicted(chosen)
    q = g.pool[chosen]

    def reference(F_sum: np.ndarray) -> NominalReference:
        return nominal_reference(model, F_sum, G, n_cam, g.drawn_variance, dirs,
                                 eye_to_hand=setup.eye_to_hand,
                                 drawn_why=drawn_mount_words(plan, opts.deviation))  # fmt: skip

    before = predict_kept(setup, plan.q, F_old, G, var, (plan.free_idx, plan.offset_joints))
    halving = None
    if more > 0:
        halving = first_halving(median(plan.q, F_frames, plan.n_features, A_old), count,
                                lambda n: median(*frames(chosen if n == count else choose(n))),
                                most)  # fmt: skip
    return AddedPostures(
        q=q,
        before_m=before,
        after_m=after,
        kept_before=beyond_placement(plan.free_idx, plan.offset_joints, model.n),
        kept_after=beyond_placement(*forecast.kept, model.n),
        forecast=forecast,
        workspace=g.workspace,
        candidates=len(g.pool),
        drawn_from=g.drawn_from,
        path_rad=path_length(q, home),
        reference=reference(F_old + F[chosen].sum(axis=0)),
        reference_before=reference(F_old),
        halving=halving,
    )
