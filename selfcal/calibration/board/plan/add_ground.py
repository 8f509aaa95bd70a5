"""What ``selfcal plan --add`` forecasts over and with (issue #30): the workspace the tool-point
error is averaged over and the held parameters' deviation from the drawing, both taken from the
dataset rather than from a new plan's defaults.

Workspace (:func:`dataset_workspace`): a new plan averages over the robot file's planning window
around home. A robot file without one (a URDF never has ``[planning] span_deg``) gets the
default window around its zero posture, which a real dataset may lie partly outside of (the
repository's Nachi recording: docs/plan.md). There the workspace is what the dataset covers:
its postures' joint region (each joint's lowest to highest reading) grown on each side by
:data:`selfcal.kinematics.tool_error.EDGE_FRACTION` of the joint's range (the band the
predicted accuracy's "edge" region adds to the calibrated region,
:func:`selfcal.kinematics.tool_error.workspace_sample`), within the joint limits. A robot file
with a planning window keeps it: the window is the user's statement of where the arm works.

Deviation (:func:`sized_deviation`): how far the held parameters err sets the prediction before
(the dataset's calibration holds most of them) and the forecast of the selection after. The
default (1 mm, 0.5 deg: the simulated robots' own) is an assumption the dataset can check:
its calibration's cross-validation measured how well the fair nominal (placement and camera
fitted, every kinematic parameter held) predicts each left-out fold of arm configurations, and
the forecast expects that misfit, per fold, at ``sqrt(a_f + b_f s^2)`` px (``a_f`` the corner
and read-back noise's share, ``b_f`` the default deviation's, ``s`` its scale:
:func:`selfcal.calibration.board.plan.selection.candidate_fold_rms`). The rule: the one scale
``s`` at which the forecast's mean square over the folds equals the measured one,
``s^2 = (mean(measured^2) - mean(a)) / mean(b)``, within :data:`SCALE_RANGE`; lengths and
angles scale together (the default's ratio kept). The mean square rather than the selection's
geometric mean because it is linear in ``s^2``: no search needed (matching geometric means by
bisection, tried first, gave much the same). Every fold enters, also one that leaves out more
than half of the frames and so does not count in the selection
(:func:`selfcal.calibration.board.folds.counted_folds`): here no fold stands for the
calibration, the forecast models each fold's own fit on its own training part, and such a
fold's misfit measures the deviation as well as any.

Its bias: the measured misfit holds everything the fair nominal misses, so the sized deviation
carries it all as geometry. Model error the chain cannot express (compliance, a lens misfit)
and corner noise larger than the forecast's ``pixel_sigma_px`` make it an upper figure (the
prediction before then too pessimistic, the gain too large); noise smaller than assumed a lower
one. It rests on one arm and a few folds, a spread not counted: in a first-order simulation
(tests/unit/test_plan_add_ground.py: the UR5e cell's plan of 8 postures in 5 folds, 0.5 px, arms
drawn within a set deviation, one calibration each) the sized deviation was 0.72 and 0.68
times the set one at the median of the test's 5 arms (the default deviation and 0.3 times it);
its helper run with 20 arms (not kept as a command) gave 0.88 (10 to 90 %: 0.52 to 1.16) at
0.3, 1 and 3 times the default and 0.76 at 0.1 times it, where the noise outweighs it: biased
low by about 12 %, and one arm's anywhere from about half to 1.2 times the truth. Where the
folds measured no more than the noise explains the scale is the range's floor; a calibration
without cross-validation (one arm configuration: a wrist-only dataset) cannot size it, and the
default is kept and said. Units: SI, px.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.add import DatasetPlan
from selfcal.calibration.board.plan.ground import PlanOptions, workspace_sample
from selfcal.calibration.board.plan.information import (
    board_model,
    frame_information,
    prediction_information,
)
from selfcal.calibration.board.plan.selection import candidate_fold_rms, selection_folds
from selfcal.kinematics.tool_error import EDGE_FRACTION

__all__ = [
    "SCALE_RANGE",
    "DatasetWorkspace",
    "SizedDeviation",
    "dataset_workspace",
    "sized_deviation",
]

SCALE_RANGE = (1e-3, 1e2)
"""The scales of the default deviation :func:`sized_deviation` gives (lowest, highest)."""


@dataclass(frozen=True, eq=False)
class DatasetWorkspace:
    """The postures ``q`` (w, n) rad the error is averaged over, the joint ``window`` (n, 2)
    rad they were drawn in, ``source`` (``"planning window"`` or ``"dataset region"``) and
    ``words``: which workspace it is, for the printed line."""

    q: np.ndarray
    window: np.ndarray
    source: str
    words: str

    def to_json(self) -> dict:
        """plan.json's ``workspace``: where it was drawn (the window in rad, m for a prismatic
        joint)."""
        return {"source": self.source, "postures": len(self.q), "words": self.words,
                "window_si": np.round(self.window, 9).tolist()}  # fmt: skip


def dataset_workspace(plan: DatasetPlan, n: int, *, seed: int) -> DatasetWorkspace:
    """The ``n`` workspace postures of ``plan``'s dataset (module docstring), drawn with
    ``seed`` free of collision and the keep-out boxes.

    Raises:
        InputError: too few collision-free postures in the window.
    """
    setup = plan.setup
    r = setup.robot
    if r.planning_window:
        lo = np.maximum(r.limits[:, 0], r.home - r.planning_span)
        hi = np.minimum(r.limits[:, 1], r.home + r.planning_span)
        q = workspace_sample(setup, n, seed=seed)
        return DatasetWorkspace(q, np.stack([lo, hi], axis=1), "planning window",
                                "the robot file's planning window around home")  # fmt: skip
    band = EDGE_FRACTION * (r.limits[:, 1] - r.limits[:, 0])
    lo = np.maximum(r.limits[:, 0], plan.q.min(axis=0) - band)
    hi = np.minimum(r.limits[:, 1], plan.q.max(axis=0) + band)
    q = workspace_sample(setup, n, seed=seed, window=(lo, hi))
    return DatasetWorkspace(
        q, np.stack([lo, hi], axis=1), "dataset region",
        f"the dataset's joint region grown by {EDGE_FRACTION * 100:g} % of each joint's range, "
        "the robot file having no planning window",
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class SizedDeviation:
    """The deviation ``--add`` forecasts with (module docstring): ``deviation``, its ``scale``
    of the default, ``source`` (``"sized"`` or ``"default"``), the calibration's measured
    nominal fold RMS ``measured_px`` (geometric mean, px; None when it has none), the
    forecast's at the sized and at the default deviation (px), the ``folds`` and ``words``:
    which deviation and why, for the printed line."""

    deviation: Deviation
    scale: float
    source: str
    measured_px: float | None
    forecast_px: float | None
    default_px: float | None
    folds: int
    words: str

    def to_json(self) -> dict:
        """plan.json's ``deviation``."""
        return {
            "source": self.source,
            "mm": round(self.deviation.translation_m * 1e3, 6),
            "deg": round(float(np.degrees(self.deviation.rotation_rad)), 6),
            "scale_of_default": round(self.scale, 6),
            "nominal_folds_measured_px": _round(self.measured_px),
            "nominal_folds_forecast_px": _round(self.forecast_px),
            "nominal_folds_forecast_at_default_px": _round(self.default_px),
            "folds": self.folds,
            "words": self.words,
        }


def _round(v: float | None) -> float | None:
    return None if v is None else round(v, 4)


def sized_deviation(
    plan: DatasetPlan, selection: dict | None, options: PlanOptions
) -> SizedDeviation:
    """The deviation of ``plan``'s dataset sized from its calibration's ``selection``
    (``calibration.json``'s, :meth:`selfcal.calibration.board.param_selection.Selection.to_json`;
    None: none recorded) by the rule of the module docstring, scaling ``options.deviation``;
    that deviation itself (``source`` ``"default"``, the reason in ``words``) when the
    calibration has no cross-validation to size it from."""
    base = options.deviation

    def kept(why: str, folds: int = 0, measured: float | None = None) -> SizedDeviation:
        return SizedDeviation(base, 1.0, "default", measured, None, None, folds,
                              f"{_dev_words(base)}, the default: {why}")  # fmt: skip

    cands = (selection or {}).get("candidates") or []
    if not cands:
        return kept("calibration.json records no cross-validation to size it from")
    measured = np.array([np.nan if v is None else v for v in cands[0]["fold_rms_px"]], float)
    if len(measured) < 2:
        return kept("the calibration has no cross-validation to size it from (one arm "
                    "configuration)", len(measured))  # fmt: skip
    setup = plan.setup
    model = board_model(setup)
    folds = selection_folds(model, plan.q)
    if len(folds.labels) != len(measured) or folds.candidates[0].label != cands[0]["label"]:
        return kept(f"the forecast's folds ({len(folds.labels)}, {folds.candidates[0].label}) are "
                    f"not the calibration's ({len(measured)}, {cands[0]['label']})")  # fmt: skip
    if not np.all(np.isfinite(measured) & (measured > 0)):
        return kept("a fold of the calibration's fair nominal failed", len(measured))
    js = options.joint_sigma
    sigma = options.pixel_sigma_px
    F = frame_information(setup, plan.q, sigma, js, plan.seen)
    A = prediction_information(setup, plan.q, sigma, js, plan.seen)
    var = base.variance(model.joint_types)
    n_cam = setup.camera.n_free
    a = candidate_fold_rms(folds, 0, F, A, plan.n_features, n_cam, 0.0 * var, sigma) ** 2
    b = candidate_fold_rms(folds, 0, F, A, plan.n_features, n_cam, var, sigma) ** 2 - a
    target = float(np.sqrt(np.mean(measured**2)))
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return kept("a fold of the forecast's fair nominal is not determined", len(measured),
                    target)  # fmt: skip

    def forecast(s: float) -> float:
        return float(np.sqrt(np.mean(a + b * s * s)))

    s2 = (target**2 - float(np.mean(a))) / float(np.mean(b))  # the mean square is linear in s^2
    s = float(np.clip(np.sqrt(max(s2, 0.0)), *SCALE_RANGE))
    dev = Deviation(base.translation_m * s, base.rotation_rad * s)
    got = forecast(s)
    words = (f"{_dev_words(dev)}, {s:.3g} times the default, sized from the dataset: the forecast "
             f"expects its calibration's fair nominal to predict the left-out folds at {got:.2f} "
             f"px, as its {len(measured)} folds measured {target:.2f} px (RMS over the folds; "
             f"{forecast(1.0):.2f} px at the default {_dev_words(base)}); --deviation-mm and "
             "--deviation-deg override it")  # fmt: skip
    if s <= SCALE_RANGE[0] * 1.0001:
        words += "; at the search's floor: the folds measured no more than the noise explains"
    elif s >= SCALE_RANGE[1] * 0.9999:
        words += "; at the search's ceiling"
    return SizedDeviation(dev, s, "sized", target, got, forecast(1.0), len(measured), words)


def _dev_words(d: Deviation) -> str:
    return (f"deviation +-{d.translation_m * 1e3:.3g} mm, "
            f"+-{float(np.degrees(d.rotation_rad)):.3g} deg")  # fmt: skip
