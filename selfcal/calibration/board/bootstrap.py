"""Run-to-run spread of a board calibration by refitting resamples of its arm configurations:
the bootstrap of ``selfcal calibrate --spread N`` (issue #29).

Would the same kind of images, taken again at other postures of the same kind, give the same
tool point? The frames are grouped into arm configurations by the folds' rule
(:func:`selfcal.calibration.board.folds.configurations`); each of ``N`` resamples draws as many
configurations as there are, with replacement, and takes every frame of each drawn one (a frame
drawn twice weighs twice). Each resample is calibrated again by the same route
(:func:`selfcal.calibration.board.robot.calibrate_robot_with_board`: camera, hand-eye, board
pose and the final fit; no bounds, no predicted accuracy, as a Monte Carlo draw) with the model
selection held: the refit fits the calibration's chosen kinematic parameters, as the
jackknife's fold fits do (:func:`selfcal.calibration.board.param_selection.held_selection`; one
the resample cannot determine is held at its fair nominal). The spread is therefore the
estimation spread of the chosen model over resampled configurations. Letting each refit select
again measured something else: a resample holds about 9.7 distinct configurations of the 15 of
a small dataset (a configuration drawn twice falls in one fold), and one with 7-8 could not
cross-validate the larger candidates, so its selection fell back to the fair nominal or a
smaller candidate 4-8 mm away, and those few refits made the spread 2-5x the covariance's
prediction (docs/tool-accuracy.md). Its tool point is predicted at the joint vectors of the
accuracy block's workspace sample and at the calibration postures (:class:`SpreadPoints`). The
spread at a joint vector is the bootstrap's standard error of the tool point,

    spread^2 = 1 / (B - 1) * sum_b |t_b - t_mean|^2

over the ``B`` refits that succeeded (summed over the three coordinates, as the jackknife's,
:mod:`selfcal.calibration.board.spread`). It is taken about the refits' own mean, not the
calibration's tool point, so that it depends on the resamples alone.

The order of the dataset's frames does not change it: the configurations are numbered as the
folds number them (by their arm joints, the first joint first:
:func:`selfcal.calibration.board.folds.configurations`) and the frames within one by their
joints, then by their detections (:func:`canonical_frames`), and the resamples are drawn on that numbering, so a
shuffled dataset gives the same resamples, frame for frame, and the refits (deterministic in
their inputs) the same tool points. A refit that fails (an estimation error: too few distinct
configurations drawn to fit the chain, ...) is counted and its reason kept, never dropped
silently.

The refits are independent: :func:`refit_row` is one of them (a picklable task for a process
pool; the command runs them on ``--jobs`` worker processes) and :func:`bootstrap_spread`
gathers them. What it cannot see: a model error every resample shares.
"""

from __future__ import annotations

import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.folds import configurations
from selfcal.calibration.board.robot import BoardRobotCalibration, calibrate_robot_with_board
from selfcal.calibration.spread import BOOTSTRAP, Spread, region_spread
from selfcal.camera import Pinhole
from selfcal.errors import EXIT_INTERNAL, SelfCalError
from selfcal.kinematics.accuracy import tool_tips
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.terms.base import Term

__all__ = [
    "KEY",
    "WHAT",
    "WHAT_FREE",
    "BoardFitInputs",
    "bootstrap_spread",
    "canonical_frames",
    "refit_row",
    "resamples",
]

KEY = "bootstrap_spread"
"""The block's key in ``calibration.json``'s ``accuracy`` (beside the jackknife's ``spread``)."""
WHAT = (
    "bootstrap over the arm configurations (drawn with replacement, every frame of a drawn "
    "configuration, each resample calibrated again with the calibration's chosen kinematic "
    "parameters: the estimation spread of the chosen model, model selection held): "
    "sqrt(1 / (B - 1) * sum |t_b - t_mean|^2) of the B refits' tool points t_b, per joint "
    "vector (mm)"
)
WHAT_FREE = (
    "bootstrap over the arm configurations (drawn with replacement, every frame of a drawn "
    "configuration, each resample calibrated again with its own parameter selection: the "
    "spread of model selection and estimation together): sqrt(1 / (B - 1) * sum "
    "|t_b - t_mean|^2) of the B refits' tool points t_b, per joint vector (mm)"
)


@dataclass(frozen=True, eq=False)
class BoardFitInputs:
    """What a board calibration's fit was given (one camera): the ``board``, its ``features``
    in every frame and the frames' joints ``q`` (m, n) rad / m, the ``nominal`` chain, the
    image size ``width`` x ``height`` px, the camera ``model`` name and its ``free``
    parameters, the frames' ``names``, the joints' read-back ``joint_sigma`` (n,) rad / m (None:
    exact), the camera to start from ``initial``, ``eye_to_hand`` and the further measurement
    ``terms`` (kept whole in every refit, as the tracker's distance rows)."""

    board: Board
    features: tuple[Features, ...]
    q: np.ndarray
    nominal: MCPCModel
    size: tuple[int, int]
    model: str
    free: tuple[str, ...]
    names: tuple[str, ...]
    joint_sigma: np.ndarray | None
    initial: Pinhole | None
    eye_to_hand: bool
    terms: tuple[Term, ...] = ()

    def fit(self, pick: np.ndarray, keep: Sequence[str] | None = None) -> BoardRobotCalibration:
        """The calibration of the frames ``pick`` (indices, repeats allowed, in their order):
        of the kinematic parameters ``keep`` (the selection held), or None: of those its own
        selection chooses."""
        pick = np.asarray(pick, dtype=int)
        return calibrate_robot_with_board(
            self.board, [self.features[i] for i in pick], self.q[pick], self.nominal,
            *self.size, free=self.free, model=self.model,
            names=[self.names[i] for i in pick], joint_sigma=self.joint_sigma,
            initial=self.initial, eye_to_hand=self.eye_to_hand, terms=self.terms, keep=keep,
        )  # fmt: skip


def canonical_frames(q: np.ndarray, features: Sequence[Features],
                     joint_types: tuple[str, ...]) -> list[np.ndarray]:  # fmt: skip
    """The frames of every arm configuration of the joints ``q`` (m, n) rad / m, as lists of
    frame indices: the configurations in the folds' numbering (:func:`configurations`, which
    owns the arm-joint rule and numbers them by their joints, the first joint first), the
    frames within one by their joints, then by their detections' count and sums (the tie of two
    images at one posture); so the same frames in another order give the same lists of the same
    frames."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    label = configurations(q, joint_types)
    tie = np.array([[len(f), float(np.sum(f.uv)), float(np.sum(f.ids))] for f in features])
    out = []
    for k in range(int(label.max(initial=-1)) + 1):
        g = np.flatnonzero(label == k)
        keys = np.column_stack([q[g], tie[g]])
        out.append(g[np.lexsort(keys.T[::-1])])
    return out


def resamples(groups: Sequence[np.ndarray], count: int, seed: int) -> list[np.ndarray]:
    """``count`` bootstrap resamples of the configurations ``groups`` (:func:`canonical_frames`):
    each draws ``len(groups)`` configurations with replacement (``numpy.random.default_rng(seed)``)
    and lists the frames of the drawn ones, configurations in their numbering."""
    rng = np.random.default_rng(seed)
    k = len(groups)
    return [np.concatenate([groups[c] for c in np.sort(rng.integers(0, k, k))])
            for _ in range(count)]  # fmt: skip


def refit_row(item: dict) -> dict:
    """One refit (a process pool's task): ``item`` holds ``inputs`` (:class:`BoardFitInputs`),
    ``pick`` (its frames), ``points`` (:class:`SpreadPoints`) and ``keep`` (the calibration's
    chosen kinematic parameters, fitted as they are; absent or None: the refit's own selection
    chooses). Returns ``{"tips": {region: (k, 3) m}, "parameters": [name, ..]}`` of the refit's
    tool points and the kinematic parameters it fitted, or ``{"failed": reason}`` when the
    refit could not be made (an estimation error; a bug is raised)."""
    inputs, points = item["inputs"], item["points"]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the calibration's own warnings were said
            fit = inputs.fit(item["pick"], item.get("keep"))
    except SelfCalError as exc:
        if exc.exit_code == EXIT_INTERNAL:
            raise
        return {"failed": f"{type(exc).__name__}: {exc.message}"}
    except np.linalg.LinAlgError as exc:
        return {"failed": f"a singular system ({exc})"}
    if not np.isfinite(fit.model.params).all():
        return {"failed": "the refit gave non-finite parameters"}
    tips = {k: tool_tips(fit.model, q, points.T_tool_point) for k, q in points.qs.items()}
    return {
        "tips": tips,
        "parameters": [] if fit.selection is None else list(fit.selection.identified),
    }


def bootstrap_spread(outcomes: Sequence[dict], *, seed: int, configurations: int,
                     chosen: Sequence[str] | None = None, held: bool = True) -> Spread:  # fmt: skip
    """The bootstrap spread (module docstring) of the refits' ``outcomes`` (:func:`refit_row`'s
    rows, or ``{"failed": reason}`` of a task that raised), drawn with ``seed`` from
    ``configurations`` arm configurations. ``resamplings`` counts the refits used, ``failed``
    the others, whose reasons (with their counts) the block's ``failures`` lists; with fewer
    than two refits no spread is computed (``regions`` empty). ``held``: the refits fitted the
    calibration's chosen parameters (the default; False: each ran its own selection);
    ``chosen``: those parameters, and ``refits_other_parameters`` counts the refits that fitted
    another set (held: some the resample could not determine were held at the fair nominal;
    not held: the selection chose another candidate)."""
    tips = [o["tips"] for o in outcomes if "tips" in o]
    reasons = Counter(str(o.get("failed", "no result")) for o in outcomes if "tips" not in o)
    squared = {}
    if len(tips) >= 2:
        for k in tips[0]:
            t = np.stack([tp[k] for tp in tips])  # (B, m, 3)
            squared[k] = np.sum((t - t.mean(axis=0)) ** 2, axis=(0, 2)) / (len(tips) - 1)
    extra = {
        "requested": len(outcomes),
        "seed": int(seed),
        "resampled": "configurations",
        "selection": "held" if held else "free",
        "configurations": int(configurations),
        "failures": [{"reason": r, "count": c} for r, c in reasons.most_common()],
    }
    if chosen is not None:
        extra["refits_other_parameters"] = sum(
            set(o.get("parameters", ())) != set(chosen) for o in outcomes if "tips" in o
        )
    what = WHAT if held else WHAT_FREE
    return Spread(len(tips), sum(reasons.values()), region_spread(squared), what, BOOTSTRAP, extra)
