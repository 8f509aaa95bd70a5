"""A recording plan for a laser tracker: which postures to measure so that the tracker route
(:func:`selfcal.calibration.tracker.identify.identify_tracker`, positions of a tool point)
predicts the smallest tool-point error (``selfcal plan --measure tracker``, issue #30).

Candidates: postures drawn uniformly in the robot file's planning window around home
(``[planning] span_deg``), within the joint ranges, free of self-collision, of the table and of
the keep-out boxes (the capsule chain with the tool point as its tool;
:func:`selfcal.calibration.board.plan.ground.workspace_sample`). No line of sight is asked:
a tracker's view of its reflector is not modelled (check it at the cell).

Information: the tracker route's position rows, ``(y_i - p(q_i)) / sigma_t`` per coordinate, at
the nominal chain (world = the tracker, here the base frame; tool = the tool point on the
flange): each posture's Fisher information about the minimal MCPC parameters is
``J_i^T J_i / sigma_t^2`` with ``J_i`` (3, k) the derivative of the tool point's position
(:func:`position_jacobian`; the same rows as
:class:`selfcal.estimation.tracker.TrackerPositionBlock`'s, a unit test compares them). The
joints are taken as read exactly, as the route does.

Criterion: the predicted RMS of the tool point's position error over a sample of the workspace
in the tracker frame (no alignment: the tracker route's accuracy is stated in the tracker's
frame, :mod:`selfcal.calibration.tracker.accuracy`), ``sqrt(trace(G C))`` with
``G = mean_w J_w^T J_w``. The greedy choice and the ordering are the board plan's
(:func:`selfcal.calibration.board.plan.greedy.select_greedy`,
:func:`~selfcal.calibration.board.plan.path.order_path`).
The greedy choice lowers the error with every parameter estimated (from a slight
regularisation, or from the deviation's prior), not the prediction below, which holds what the
route cannot estimate: with fewer position rows than parameters (e.g. 6 postures, 18 rows for
30 parameters) its choice can be several times worse by the prediction than random postures
(issue #30: 2.4 and 15.6 mm against 1.06 mm on the UR5e, 6 postures of 400 and of 60
candidates). So the plan is the best, by the prediction, of the two greedy choices and the
pool's disjoint sets of ``count`` in draw order (the first of them the random plan): never worse
than the random plan by its own criterion; :attr:`TrackerPlan.chosen_by` says which won.
``selfcal plan --add K DIR`` makes the same choice after the rows a calibration already has
(:func:`choose_postures`' ``measured``; :mod:`selfcal.calibration.tracker.add`).

Too few postures: the route refuses to identify from no more position equations than the
parameters positions identify on the robot (its structural rank, e.g. 27 on the UR5e: at
least 10 postures); a plan of fewer would predict a calibration the route never makes, so the planner
refuses it by the route's own rule (:func:`minimum_count`:
:func:`selfcal.calibration.tracker.rows.rows_needed`).
The prediction of the chosen postures keeps the parameters the route's rank and conditioning
tests keep at them (:func:`kept_by_rank`: offered in
:func:`selfcal.calibration.tracker.identify.priority_order`, the route's rank tolerance and
conditioning test), every other one held at the drawing and erring by the arm's deviation from
it (:func:`selfcal.calibration.board.plan.predict.predicted_with_held`, no camera parameters). Positions never see the tool frame's orientation (three angles of ``V_n``):
those are held and move no tool point. Units: SI inside.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.greedy import pool_sets, select_greedy
from selfcal.calibration.board.plan.ground import workspace_sample
from selfcal.calibration.board.plan.path import order_path, path_length
from selfcal.calibration.board.plan.predict import (
    Directions,
    predicted_with_held,
    prior_information,
)
from selfcal.calibration.tracker.identify import conditioned, priority_order
from selfcal.calibration.tracker.rows import rows_needed
from selfcal.errors import InputError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.identifiability import select_identifiable, triangular_factor
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, nominal_mcpc
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.robot.definition import RobotDef
from selfcal.transforms import trans

__all__ = [
    "RANK_RTOL",
    "TrackerPlanSetup",
    "TrackerPlan",
    "position_jacobian",
    "posture_information",
    "kept_by_rank",
    "minimum_count",
    "predict_tracker",
    "fair_nominal_indices",
    "predict_fair_nominal",
    "workspace_weight",
    "Choice",
    "choose_postures",
    "plan_tracker",
]

RANK_RTOL = 1e-9
"""The tracker route's rank tolerance (:func:`selfcal.calibration.tracker.identify.identify_tracker`'s
default)."""


@dataclass(frozen=True, eq=False)
class TrackerPlanSetup:
    """One arm and a tracker's reflector on its flange: ``robot``, ``tool_point_m`` (3,) the
    reflector's centre in the flange frame (m), keep-out ``boxes`` (b, 6) m in the base frame,
    ``sigma_m`` the tracker's noise per coordinate (m)."""

    robot: RobotDef
    tool_point_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    sigma_m: float = 1e-4

    @property
    def model(self) -> MCPCModel:
        """The nominal chain base (the tracker) -> the tool point."""
        return nominal_mcpc(self.robot).with_tool(trans(np.asarray(self.tool_point_m, float)))

    @property
    def chain(self) -> CapsuleChain:
        """The self-collision and table check of the nominal arm with its tool point."""
        return CapsuleChain(nominal_mcpc(self.robot), trans(np.asarray(self.tool_point_m, float)))


def position_jacobian(model: MCPCModel, q: np.ndarray) -> np.ndarray:
    """(m, 3, k) the derivative of the tool point's position (world frame, m) by the minimal
    MCPC parameters (SI, the order of :func:`selfcal.kinematics.mcpc.minimal_indices`) at the
    joints ``q`` (m, n) rad."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(model.joint_types)
    R = fk_tool(model, q)[:, :3, :3]
    return R @ identification_jacobian(model, q)[:, :3][:, :, idx]


def posture_information(setup: TrackerPlanSetup, q: np.ndarray) -> np.ndarray:
    """(m, k, k) each posture's Fisher information about the minimal parameters (module
    docstring)."""
    J = position_jacobian(setup.model, q) / setup.sigma_m
    return np.einsum("mri,mrj->mij", J, J)


def _scaled(setup: TrackerPlanSetup, q: np.ndarray) -> np.ndarray:
    """The position Jacobian at ``q`` (m, n) rad stacked (3m, k), columns scaled to unit norm
    (the route's scaling; zero columns left as zero), as the triangular factor."""
    J = position_jacobian(setup.model, q).reshape(-1, minimal_indices(setup.model.joint_types).size)
    col = np.linalg.norm(J, axis=0)
    col = np.where(col > 1e-10 * col.max(initial=0.0), col, np.inf)
    return triangular_factor(J / col)


def minimum_count(setup: TrackerPlanSetup) -> tuple[int, int]:
    """``(need, rank)``: the fewest postures the tracker route identifies from (``3 need >
    rank``) and ``rank`` the count of minimal parameters positions identify on the arm with the
    setup's tool point, by the route's own rule
    (:func:`selfcal.calibration.tracker.rows.rows_needed`, its rank tolerance and the setup's
    noise) at the nominal chain with the setup's tool point: 27 on the UR5e and the KR 6 (10
    postures), 23 on the ER-4u (8)."""
    model = setup.model
    q = np.asarray(setup.robot.home, float)[None]
    meas = TrackerMeasurements(q=q, xyz=fk_tool(model, q)[:, :3, 3])
    count = rows_needed(model, meas, sigmas=(setup.sigma_m,) * 3, rank_rtol=RANK_RTOL)
    return count.need, count.rank


def kept_by_rank(setup: TrackerPlanSetup, q: np.ndarray) -> np.ndarray:
    """(k,) bool: the minimal parameters the tracker route's rank and conditioning tests keep
    at the postures ``q`` (m, n) rad (module docstring)."""
    A = _scaled(setup, q)
    order = priority_order(setup.model.joint_types)
    keep, _, _ = select_identifiable(A, order, RANK_RTOL)
    held = [k for k, why in conditioned(A, order, keep).items() if why is not None]
    keep[held] = False
    return keep


def predict_tracker(
    setup: TrackerPlanSetup,
    q: np.ndarray,
    F: np.ndarray,
    G: np.ndarray,
    variance: np.ndarray,
    keep: np.ndarray | None = None,
) -> float:
    """The predicted tool-point RMS (m) of the tracker route on the postures ``q`` with the
    information ``F`` (k, k) (:func:`posture_information` summed over them), the workspace
    weight ``G`` (k, k) and the deviation's ``variance`` (k,): the parameters ``keep`` (k,)
    bool estimated (None: those :func:`kept_by_rank` keeps at ``q``), the others held."""
    keep = kept_by_rank(setup, q) if keep is None else np.asarray(keep, bool)
    M = np.eye(len(keep))[:, keep]
    return predicted_with_held(F, G, 0, M, variance)


def fair_nominal_indices(n: int) -> np.ndarray:
    """Flat MCPC indices of what the tracker route's fair nominal fits to positions
    (:mod:`selfcal.calibration.tracker.nominal`) on a chain of ``n`` joints: all six of ``V_0``
    (the tracker frame) and the translation of ``V_n`` (the tool point), the chain held."""
    return np.r_[np.arange(6), 6 * n + np.arange(3, 6)]


def predict_fair_nominal(
    setup: TrackerPlanSetup, F: np.ndarray, G: np.ndarray, variance: np.ndarray
) -> float:
    """The predicted tool-point RMS (m) of the fair nominal on postures of information ``F``
    (k, k), with the workspace weight ``G`` and the deviation's ``variance`` (k,): the chain
    held at its drawing, erring by the deviation less what the fitted tracker frame and tool
    point absorb (:func:`fair_nominal_indices`, their directions among the minimal parameters
    at the nominal chain: :class:`selfcal.calibration.board.plan.predict.Directions`), plus
    their noise; what a calibration of the same rows has to beat (the board's
    :func:`selfcal.calibration.board.plan.reference.nominal_reference` for its placement)."""
    model = setup.model
    fitted = fair_nominal_indices(model.n)
    M = Directions(model).of(fitted, np.zeros(0, np.int64))
    held = np.where(np.isin(minimal_indices(model.joint_types), fitted), 0.0, variance)
    return predicted_with_held(F, G, 0, M, held)


def workspace_weight(setup: TrackerPlanSetup, qw: np.ndarray) -> np.ndarray:
    """(k, k) ``G = mean_w J_w^T J_w`` over the workspace postures ``qw`` (w, n) rad (module
    docstring)."""
    Jw = position_jacobian(setup.model, qw)
    return np.einsum("wri,wrj->ij", Jw, Jw) / len(qw)


@dataclass(frozen=True, eq=False)
class Choice:
    """The best set of ``count`` candidates by the prediction (:func:`choose_postures`):
    ``index`` (count,) into the pool, unordered; ``predicted_m`` its prediction (m),
    ``greedy_m`` the better greedy choice's, ``random_m`` the pool's first ``count``'s (the
    random plan) and ``chosen_by`` which set won (module docstring)."""

    index: np.ndarray
    predicted_m: float
    greedy_m: float
    random_m: float
    chosen_by: str


def choose_postures(
    setup: TrackerPlanSetup,
    pool: np.ndarray,
    G: np.ndarray,
    variance: np.ndarray,
    count: int,
    measured: np.ndarray | None = None,
) -> Choice:
    """The ``count`` candidates of ``pool`` (c, n) rad the plan takes (module docstring: the
    better of the two greedy choices and the pool's disjoint sets, by the prediction with the
    parameters the route's tests keep), after the postures ``measured`` (m, n) rad already
    measured (``selfcal plan --add``, :mod:`selfcal.calibration.tracker.add`; None: none):
    their information starts every greedy choice and every set is predicted with them."""
    q0 = np.zeros((0, pool.shape[1])) if measured is None else np.asarray(measured, float)
    F = posture_information(setup, pool)
    F0 = posture_information(setup, q0).sum(axis=0) if len(q0) else np.zeros(F.shape[1:])

    def predict(i: np.ndarray) -> float:
        q = np.concatenate([q0, pool[i]])
        return predict_tracker(setup, q, F0 + F[i].sum(axis=0), G, variance)

    greedy = {
        "greedy": select_greedy(F, G, 0, count, start=F0),
        "greedy from the prior": select_greedy(
            F, G, 0, count, start=F0 + prior_information(variance, 0)
        ),
    }
    tried = {name: (predict(i), i) for name, i in greedy.items()}
    greedy_m = min(m for m, _ in tried.values())
    rivals = pool_sets(len(pool), count)
    for name, i in rivals:
        tried[name] = (predict(i), i)
    chosen_by = min(tried, key=lambda name: tried[name][0])  # the first of equals: greedy
    predicted_m, chosen = tried[chosen_by]
    return Choice(chosen, predicted_m, greedy_m, tried[rivals[0][0]][0], chosen_by)


@dataclass(frozen=True, eq=False)
class TrackerPlan:
    """``q`` (N, n) rad the planned postures in path order and ``predicted_m`` their predicted
    tool-point RMS (m) over the ``workspace`` (w, n) rad; ``q_random`` the pool's first N
    postures and ``random_m`` their prediction; ``kept`` how many minimal parameters the route
    estimates on the plan (of ``parameters``); the pool's size and the joint paths (rad) of the
    plan and of the random plan, each in its own short order; ``greedy_m`` the prediction of
    the greedy choice (the better of its two starts) and ``chosen_by`` which set the plan is
    (``"greedy"``, ``"greedy from the prior"`` or ``"random set i of s"``, module
    docstring)."""

    q: np.ndarray
    predicted_m: float
    q_random: np.ndarray
    random_m: float
    workspace: np.ndarray
    kept: int
    parameters: int
    candidates: int
    path_rad: float
    random_path_rad: float
    greedy_m: float
    chosen_by: str


def plan_tracker(
    setup: TrackerPlanSetup,
    count: int,
    *,
    seed: int = 1,
    candidates: int = 400,
    workspace: int = 50,
    deviation: Deviation | None = None,
) -> TrackerPlan:
    """``count`` postures for ``setup`` (module docstring), deterministic for a ``seed``.

    Raises:
        InputError: fewer free postures than ``count`` or ``workspace``; ``count`` fewer than
            the route identifies from (:func:`minimum_count`).
    """
    pool = workspace_sample(setup, max(candidates, count), seed=seed)
    need, rank = minimum_count(setup)
    if count < need:
        raise InputError(
            f"--count {count}: the tracker route identifies from more position equations than "
            f"the {rank} parameters positions can identify on {setup.robot.name} ({3 * count} "
            f"equations); it refuses fewer than {need} postures, so no plan of {count} predicts "
            "a calibration it makes",
            fix=f"plan at least {need} postures (--count {need}), better 3 times that",
        )
    qw = workspace_sample(setup, workspace, seed=seed + 1)
    var = (deviation or Deviation()).variance(setup.model.joint_types)
    got = choose_postures(setup, pool, workspace_weight(setup, qw), var, count)
    home = setup.robot.home
    q = pool[got.index]
    q = q[order_path(q, home)]
    rand = pool[:count]
    return TrackerPlan(
        q=q,
        predicted_m=got.predicted_m,
        q_random=rand,
        random_m=got.random_m,
        workspace=qw,
        kept=int(kept_by_rank(setup, q).sum()),
        parameters=int(minimal_indices(setup.model.joint_types).size),
        candidates=len(pool),
        path_rad=path_length(q, home),
        random_path_rad=path_length(rand[order_path(rand, home)], home),
        greedy_m=got.greedy_m,
        chosen_by=got.chosen_by,
    )
