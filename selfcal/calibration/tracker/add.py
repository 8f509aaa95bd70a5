"""The postures to add to a tracker calibration: the ``count`` that most lower the predicted
tool-point error of ``selfcal identify``'s calibration, given the rows it already has
(``selfcal plan --add K DIR`` with DIR the folder ``identify`` wrote, issue #30).

The dataset is the calibration's (:func:`tracker_dataset`): the robot file it was identified
with, the tool point it identified (in the nominal flange frame), the tracker noise it was
weighted with (``sigmas.position_mm``, or the one given) and the joints of its position rows
(``accuracy.calibration_postures_si``: the file itself, not the measurements file, which may
have moved since). The planning is the tracker plan's
(:func:`selfcal.calibration.tracker.plan.choose_postures`, one code path): the same candidate
pool (reachable, free of self-collision, the table and the keep-out boxes; no line of sight is
modelled, as for a new tracker plan), the same information (positions, exact joints), the same
criterion (the tool point's position RMS over the workspace postures of the robot file's
planning window, in the tracker frame) and the same choice (the better greedy choice, started
from the rows' information, or from it with the deviation's prior, against the pool's disjoint
sets), every set predicted with the rows' postures and the parameters the route's rank and
conditioning tests keep at them all (:func:`selfcal.calibration.tracker.plan.kept_by_rank`).

Predicted before: the rows' information with the parameters the calibration estimated (its
``parameters``' ``estimated``), every other one held at the drawing and erring by the
deviation. Each is judged against the fair nominal of the same rows (the chain held at its
drawing, the tracker frame and the tool point fitted, as ``identify`` fits it beside the
calibration: :func:`selfcal.calibration.tracker.plan.predict_fair_nominal`). Not counted: distance rows (a ball bar's; ``distances`` says how many the
calibration had: the predictions of before and after then both leave their information out,
so both are pessimistic). A calibration fitted to poses is refused (the planner predicts
position rows; poses also see the tool frame's orientation). Units: SI inside.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.ground import workspace_sample
from selfcal.calibration.board.plan.path import order_path, path_length
from selfcal.calibration.tracker.accuracy import postures_from_json
from selfcal.calibration.tracker.calibration_file import (
    FORMAT,
    TrackerCalibration,
    read_tracker_calibration,
)
from selfcal.calibration.tracker.plan import (
    TrackerPlanSetup,
    choose_postures,
    kept_by_rank,
    posture_information,
    predict_fair_nominal,
    predict_tracker,
    workspace_weight,
)
from selfcal.errors import InputError
from selfcal.kinematics.mcpc import minimal_indices, param_names
from selfcal.robot.definition import load_robot

__all__ = ["TrackerDataset", "TrackerAddition", "tracker_dataset", "plan_tracker_additions"]

_FIX = "re-run `selfcal identify MEASUREMENTS.csv --robot ROBOT --joint-units UNITS --out DIR`"


@dataclass(frozen=True, eq=False)
class TrackerDataset:
    """What a tracker calibration gives the planner: the ``setup`` (robot, tool point m in the
    nominal flange frame, keep-out boxes, noise m per coordinate), the joints ``q`` (m, n) rad
    of its position rows, ``estimated`` (k,) bool the minimal parameters it estimated, how many
    ``distances`` rows it also had (not counted, module docstring) and ``sigma_source``
    (``"calibration"`` or ``"given"``)."""

    path: Path
    calibration: TrackerCalibration
    setup: TrackerPlanSetup
    q: np.ndarray
    estimated: np.ndarray
    distances: int
    sigma_source: str


def tracker_dataset(
    root: str | Path, boxes: np.ndarray | None = None, sigma_m: float | None = None
) -> TrackerDataset:
    """The :class:`TrackerDataset` of ``root`` (the folder ``selfcal identify --out`` wrote, or
    its ``calibration.json``), with keep-out ``boxes`` (b, 6) m in the base frame and the
    tracker noise ``sigma_m`` (m per coordinate; None: the calibration's).

    Raises:
        InputError: no such file, not a tracker calibration, a calibration of poses, one
            without its ``accuracy`` block (written before it or without position rows) or
            whose parameters are not the robot file's (each named, with the fix).
    """
    path = Path(root)
    path = path / "calibration.json" if path.is_dir() else path
    if not path.is_file():
        raise InputError(f"{path}: no tracker calibration ({FORMAT})",
                         fix="give the folder `selfcal identify ... --out DIR` wrote")  # fmt: skip
    cal = read_tracker_calibration(path)
    if cal.poses:
        raise InputError(
            f"{path}: a calibration fitted to poses (fit.kinds {cal.fit.get('kinds')}): --add "
            "plans position rows of a tool point (a laser tracker's reflector)",
            fix="plan the added postures of a pose sensor by hand, or identify from the "
            "positions alone (leave out the qw,qx,qy,qz columns) and give that folder to --add",
        )
    if cal.accuracy is None:
        raise InputError(f"{path}: no accuracy block, so the joints of its rows are not in it "
                         "(a file written before it, or without position rows)", fix=_FIX)  # fmt: skip
    robot = load_robot(cal.robot_source)
    where = f"{path}: key 'accuracy'"
    q = postures_from_json(cal.accuracy, robot.n, where)
    names = tuple(param_names(minimal_indices(robot.joint_types)))
    if robot.joint_types != cal.joint_types or cal.names != names:
        raise InputError(f"{path}: its parameters are not those of the robot file "
                         f"{cal.robot_source} (robot.given_as) as it reads now", fix=_FIX)  # fmt: skip
    given = sigma_m is not None
    sigma = float(cal.sigmas["position_mm"]) / 1e3 if sigma_m is None else float(sigma_m)
    setup = TrackerPlanSetup(robot, cal.tool_point_mm / 1e3,
                             np.zeros((0, 6)) if boxes is None else np.asarray(boxes, float),
                             sigma)  # fmt: skip
    estimated = np.array([nm not in cal.held for nm in names], bool)
    return TrackerDataset(path, cal, setup, q, estimated, int(cal.fit.get("distances") or 0),
                          "given" if given else "calibration")  # fmt: skip


@dataclass(frozen=True, eq=False)
class TrackerAddition:
    """``q`` (K, n) rad the postures to add in path order from home; ``before_m`` the
    calibration's predicted tool-point RMS (m) with the parameters it estimated, ``after_m``
    with the added rows and the parameters the route's tests keep at all of them; ``random_m``
    the pool's first K added instead, ``greedy_m`` the better greedy choice's, ``chosen_by``
    which set won (:class:`selfcal.calibration.tracker.plan.Choice`); ``kept_before``,
    ``kept_after`` the estimated parameters of ``parameters`` minimal ones; ``fair_before_m``,
    ``fair_after_m`` the fair nominal's prediction (m) on the rows and on them with the added
    ones (:func:`selfcal.calibration.tracker.plan.predict_fair_nominal`: what the calibration
    has to beat); the ``workspace``
    (w, n) rad, the pool's size and the joint path (rad) from home through the added ones."""

    q: np.ndarray
    before_m: float
    after_m: float
    random_m: float
    greedy_m: float
    chosen_by: str
    kept_before: int
    kept_after: int
    fair_before_m: float
    fair_after_m: float
    parameters: int
    workspace: np.ndarray
    candidates: int
    path_rad: float


def plan_tracker_additions(
    data: TrackerDataset,
    count: int,
    *,
    seed: int = 1,
    candidates: int = 400,
    workspace: int = 50,
    deviation: Deviation | None = None,
) -> TrackerAddition:
    """The ``count`` postures to add to ``data`` (module docstring), deterministic for a
    ``seed``; the held parameters err by ``deviation`` (default 1 mm, 0.5 deg).

    Raises:
        InputError: ``count`` < 1, or fewer free postures than ``count`` or ``workspace``.
    """
    if count < 1:
        raise InputError(f"--add {count}: add at least 1 posture")
    setup = data.setup
    pool = workspace_sample(setup, max(candidates, count), seed=seed)
    qw = workspace_sample(setup, workspace, seed=seed + 1)
    G = workspace_weight(setup, qw)
    var = (deviation or Deviation()).variance(setup.model.joint_types)
    got = choose_postures(setup, pool, G, var, count, measured=data.q)
    F_old = posture_information(setup, data.q).sum(axis=0)
    before = predict_tracker(setup, data.q, F_old, G, var, keep=data.estimated)
    home = setup.robot.home
    q = pool[got.index]
    q = q[order_path(q, home)]
    F_all = F_old + posture_information(setup, q).sum(axis=0)
    return TrackerAddition(
        q=q,
        before_m=before,
        after_m=got.predicted_m,
        random_m=got.random_m,
        greedy_m=got.greedy_m,
        chosen_by=got.chosen_by,
        kept_before=int(data.estimated.sum()),
        kept_after=int(kept_by_rank(setup, np.concatenate([data.q, q])).sum()),
        fair_before_m=predict_fair_nominal(setup, F_old, G, var),
        fair_after_m=predict_fair_nominal(setup, F_all, G, var),
        parameters=len(data.estimated),
        workspace=qw,
        candidates=len(pool),
        path_rad=path_length(q, home),
    )
