"""``selfcal plan`` on a marker field (issue #30): the postures to record for the field route (the
paper's self-calibration: the camera's focal length and lens unknown, the markers' positions
unknown, one known distance for the scale, the MCPC parameters identified) and their forecast.

The postures are chosen from random candidates of the planning window around home (the robot
file's ``[planning] span_deg``) that

- lie within the joint ranges;
- are free of self-collision and of the table (the capsule chain of
  :class:`selfcal.kinematics.self_collision.CapsuleChain`, its tool the camera) and of the
  keep-out boxes (:func:`selfcal.kinematics.keep_out.outside_boxes`): the board plan's checks
  where they apply (a field has no plate to keep clear of; the lines of sight to the markers are
  not checked);
- show every camera of the rig at least ``min_visible`` of the 36 points of a 6 x 6 grid over the
  field's region (:data:`selfcal.kinematics.trajectory.PLANNING_VISIBILITY`: the planner's rule,
  in front at a working distance, inside the image, facing);
- and, for the plan (not the random plan, which is drawn under the filters above), let every
  camera find enough markers for the field route to register its view, as the renderer and the
  detector find them (:meth:`FieldPlanSetup.registers`, :mod:`selfcal.calibration.field.
  plan_sight`: within the detector's foreshortening limit, 12 px inside the image, not hidden by
  a raised support), and, with ``clear_views``, show no marker partly hidden by a raised
  support (whose corners the detector may return off).

The field's region is a square on the table (z = 0, base frame) centred where the home posture's
optical axis meets it (:func:`selfcal.kinematics.trajectory.home_target_center`), as the simulated
field lies. Of the candidates, four choices of ``count`` (:data:`CHOICES`) are forecast and
the plan is the one with the smallest forecast tool-point error (:func:`field_forecast`, what
the plan is judged by): the field route's D-optimal choice (:func:`selfcal.calibration.field.
optimal_poses.plan_optimal_postures`: the log-determinant of the kinematic parameters' proxy
information), and the board plan's criterion and code on the field's information (the
predicted tool-point error over the workspace, ``sqrt(trace(G C))``,
:mod:`selfcal.calibration.field.plan_information`): its greedy choice improved by its exchange
(:func:`selfcal.calibration.board.plan.greedy.select_greedy`, :func:`~selfcal.calibration.
board.plan.greedy.exchange`), and its exchange started from the D-optimal choice. That
criterion takes the markers' corners as known (the forecast estimates them), so no one choice
is best on every cell; the fourth, the best of those three exchanged on the forecast itself
(:mod:`selfcal.calibration.field.plan_corners`: the corners unknown and each posture's
read-back errors eliminated over its rows, as the field route estimates them, updated per
candidate by its rank), is the one that seeks views that fix the corners (docs/plan.md's
example: the table of ``python -m selfcal.benchmarks.plan.field_count``). The random plan of the same size is the first ``count`` candidates of the same
filters (:func:`selfcal.kinematics.trajectory.plan_postures` with the same seed).

The forecast (:func:`field_forecast`) is the field route's Cramer-Rao bound
(:mod:`selfcal.calibration.field.bounds`) of the one-step calibration at the postures, for a given
marker layout: it estimates the camera's free parameters (focal length, aspect ratio, lens), the
markers' corners (unknown points), the rig, the read-back errors of the joints and every minimal
MCPC parameter beyond the world gauge, with the scale fixed by the two scale markers' known
distance; its figure is the RMS error of the flange centre over random postures of the workspace
after the best rigid alignment (the report's tool-point metric). It is a bound: the estimator's
error, the detector's misses and the two-stage route's larger error are not in it. SI units.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from selfcal.calibration.board.plan.greedy import exchange, select_greedy
from selfcal.calibration.board.plan.ground import workspace_sample
from selfcal.calibration.board.plan.path import order_path, path_length
from selfcal.calibration.field.bounds import BoundsError, cramer_rao
from selfcal.calibration.field.bounds_setup import predicted_setup
from selfcal.calibration.field.optimal_poses import plan_optimal_postures
from selfcal.calibration.field.plan_corners import corner_blocks, corner_exchange, corner_grow
from selfcal.calibration.field.plan_information import (
    FieldLayout,
    posture_rows,
    rows_information,
    tool_weight,
)
from selfcal.calibration.field.plan_sight import found_markers, partly_hidden, registers
from selfcal.camera import Rig
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.keep_out import check_boxes, collision_free
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.kinematics.trajectory import (
    DegenerateTrajectoryError,
    home_target_center,
    plan_postures,
)
from selfcal.robot.definition import RobotDef
from selfcal.target import CORNERS_PER_MARKER
from selfcal.transforms import inv_pose

__all__ = [
    "FieldPlanSetup",
    "FieldPlan",
    "FieldLayout",
    "FieldForecast",
    "CHOICES",
    "plan_field",
    "field_forecast",
    "forecast_workspace",
    "GRID_SIDE",
    "MATCH_RANDOM",
    "count_to_match",
    "random_plan",
]

GRID_SIDE = 6
"""The planning grid over the field's region: GRID_SIDE x GRID_SIDE points (the scenarios')."""
CHOICES = (
    "D-optimal",
    "tool-point exchange",
    "D-optimal, tool-point exchange",
    "corners-unknown exchange",
)
"""The choices a field plan is the best of by its forecast (module docstring); the last starts
from the best of the others."""
MATCH_RANDOM = 30
"""The random plan a field plan's count advice is set against (issue #30: a plan of 12 against
a random plan of 30): a plan of fewer postures whose forecast is behind that random plan's
gives the count whose plan is not (:func:`count_to_match`)."""


@dataclass(frozen=True)
class FieldPlanSetup:
    """The cell of a field plan: the ``robot`` (its ``[camera_mount]`` puts the rig's first
    camera on the flange), the camera ``rig``, the square region of side ``extent_m`` (m) holding
    the markers, centred where the home posture looks, the keep-out ``boxes`` (b, 6) m (base
    frame) and ``min_visible``: the grid points every camera must see; with ``clear_views`` a
    planned posture's camera shows no marker partly hidden by a raised support of the field
    (:meth:`registers`)."""

    robot: RobotDef
    rig: Rig
    extent_m: float
    boxes: np.ndarray
    min_visible: int = 6
    clear_views: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "boxes", check_boxes(np.asarray(self.boxes, dtype=float)))

    @property
    def model_cam(self) -> MCPCModel:
        """The nominal chain whose tool is the first camera (OpenCV frame)."""
        return nominal_mcpc(self.robot).with_tool(self.robot.T_flange_cam)

    @cached_property
    def chain(self) -> CapsuleChain:
        """The capsule chain of the nominal arm with the camera as its tool."""
        return CapsuleChain(nominal_mcpc(self.robot), self.robot.T_flange_cam)

    def centre_m(self) -> tuple[float, float]:
        """The region's centre (x, y) m on the table: where the home optical axis meets it
        (:class:`selfcal.errors.InputError` naming the robot file when it does not)."""
        return home_target_center(self.robot, self.model_cam)

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """The planning grid: (36, 3) points m over the region and their normals (up)."""
        cx, cy = self.centre_m()
        h = self.extent_m / 2
        a = np.linspace(-h, h, GRID_SIDE)
        pts = np.array([[cx + x, cy + y, 0.0] for x in a for y in a])
        return pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1))

    def registers(self, q: np.ndarray, layout: FieldLayout) -> np.ndarray:
        """(m,) bool: postures ``q`` (m, n) rad at which every camera of the rig (at the
        nominal chain) finds enough of ``layout``'s markers for the field route to register
        its view (:func:`selfcal.calibration.field.plan_sight.found_markers`,
        :func:`~selfcal.calibration.field.plan_sight.registers`) and, with
        :attr:`clear_views`, shows no marker partly hidden behind another's support
        (:func:`~selfcal.calibration.field.plan_sight.partly_hidden`: the detector may return
        its corners off)."""
        T = fk_tool(self.model_cam, np.atleast_2d(q))
        ok = np.ones(len(T), dtype=bool)
        for cam, T_first_cam in zip(self.rig.cameras, self.rig.T_first_cam, strict=True):
            found = found_markers(cam, T @ T_first_cam, layout.corners_world,
                                  layout.normals_world, layout.supports)  # fmt: skip
            ok &= registers(found)
            if self.clear_views and layout.supports is not None:
                ok &= ~partly_hidden(cam, T @ T_first_cam, layout.corners_world,
                                     layout.normals_world, layout.supports).any(axis=1)  # fmt: skip
        return ok

    def collision_ok(self, q: np.ndarray) -> np.ndarray:
        """(m,) bool: postures ``q`` (m, n) rad free of self-collision, the table and the
        keep-out boxes."""
        return collision_free(self.chain, q, self.boxes)


@dataclass
class FieldPlan:
    """A field plan: ``q`` (count, n) rad in the order to record them (a short joint path from
    home, :func:`selfcal.calibration.board.plan.path.order_path`), ``q_random`` the random plan of
    the same size; ``path_rad``/``random_path_rad`` their joint paths (the sum of every step's
    largest joint move); ``candidates`` in the pool after the collision check
    (``rejected_collision`` removed) and the detector's (``rejected_unseen`` removed: free, but
    their camera would not find enough markers to register, :meth:`FieldPlanSetup.registers`); ``logdet``/``logdet_random`` the D-optimal selector's proxy
    information of its choice and of the random plan; ``exchanges`` its swaps; ``chosen_by``
    which of :data:`CHOICES` the plan is and ``choices`` every choice's forecast (m; None: no
    bound), the plan's the smallest (module docstring); ``random_match_m`` the forecast of the
    random plan of :data:`MATCH_RANDOM` (m; None: not computed, the plan has that many postures
    or more, the pool fewer, or no bound) and ``to_match`` (count, forecast m) the smallest
    plan that reaches it when this one does not (:func:`count_to_match`; None: it does, or none
    of up to :data:`MATCH_RANDOM` postures does); ``pool`` (c, n) rad the candidates and
    ``chosen`` the indices of ``q`` in it; ``start`` the indices the corners-unknown exchange
    started from, the choice ``start_by`` (None, "": it did not run); ``match`` the indices in
    ``pool`` of the plan of ``to_match``'s count (None with it): ``chosen`` first, then the
    postures the corners-unknown criterion adds one at a time
    (:func:`selfcal.calibration.field.plan_corners.corner_grow`)."""

    q: np.ndarray
    q_random: np.ndarray
    path_rad: float
    random_path_rad: float
    candidates: int
    rejected_collision: int
    logdet: float
    logdet_random: float
    exchanges: int
    chosen_by: str
    choices: dict[str, float | None]
    random_match_m: float | None = None
    to_match: tuple[int, float] | None = None
    pool: np.ndarray | None = None
    chosen: np.ndarray | None = None
    start: np.ndarray | None = None
    start_by: str = ""
    match: np.ndarray | None = None
    rejected_unseen: int = 0


def plan_field(
    setup: FieldPlanSetup,
    count: int,
    layout: FieldLayout,
    workspace: np.ndarray,
    *,
    seed: int,
    candidates: int,
    markers: int,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None,
) -> FieldPlan:
    """The ``count`` postures for ``setup`` (module docstring) from ``candidates`` random ones
    (seeded by ``seed``) with the least forecast tool-point error over the ``workspace``
    postures (w, n) rad for the markers of ``layout``: of the D-optimal selector's choice (each
    grid point worth the corners of ``markers`` markers spread over the grid) and the
    tool-point choices of :data:`CHOICES`; ``pixel_sigma_px`` px of corner noise and the
    read-back noise ``joint_sigma`` (n,) rad (None: exact). A plan of fewer than
    :data:`MATCH_RANDOM` postures is set against the random plan of that many (the pool's
    first) and, when its forecast is behind, gives the count that is not (``to_match``): of
    the plan grown one posture at a time on the corners-unknown criterion (the plan's own,
    :func:`selfcal.calibration.field.plan_corners.corner_grow`), the smallest that reaches it.

    Raises:
        DegenerateTrajectoryError: too few feasible candidates.
    """
    pts, nrm = setup.grid()
    unseen, colliding, looking = [0], [0], [0]

    def feasible(q: np.ndarray) -> np.ndarray:  # free, and the detector registers its view
        free = setup.collision_ok(q)
        seen = setup.registers(q, layout)
        unseen[0], colliding[0], looking[0] = int(np.sum(free & ~seen)), int(np.sum(~free)), len(q)
        return free & seen

    try:
        opt = plan_optimal_postures(
            setup.robot, setup.model_cam, setup.rig, pts, count, seed=seed,
            min_visible=setup.min_visible, normals_world=nrm, n_candidates=candidates,
            collision_ok=feasible, pixel_sigma_px=pixel_sigma_px,
            corners_per_point=CORNERS_PER_MARKER * markers / len(pts), joint_sigma=joint_sigma,
        )  # fmt: skip
    except DegenerateTrajectoryError as e:
        if unseen[0] == 0:
            raise
        hidden = " or shows a marker partly hidden (clear views)" if setup.clear_views else ""
        ok = looking[0] - colliding[0] - unseen[0]
        raise DegenerateTrajectoryError(
            f"only {ok} usable candidate postures for {count}: of the {looking[0]} candidates "
            f"that face the field, {colliding[0]} collide or leave the room and {unseen[0]} are "
            f"free but the detector would not register the field from them (too few of its "
            f"markers found whole{hidden}: selfcal.calibration.field.plan_sight)"
        ) from e
    q_random = random_plan(setup, count, seed=seed)
    sets = {CHOICES[0]: opt.chosen}
    G = tool_weight(setup.model_cam, workspace, setup.robot.T_flange_cam)
    try:
        fs = predicted_setup(setup.model_cam, opt.pool, setup.rig, layout.ids,
                             layout.corners_world, layout.normals_world, layout.scale_ids,
                             layout.scale_length_m, pixel_sigma_px=pixel_sigma_px,
                             joint_sigma=joint_sigma)  # fmt: skip
        rows = posture_rows(fs, setup.rig.n_cameras)
    except BoundsError:  # the pool does not see a scale marker twice: the D-optimal choice
        rows = None
    F = None if rows is None else rows_information(rows)
    if F is not None:
        n_cam = F.shape[1] - len(G)
        sets[CHOICES[1]] = exchange(F, G, n_cam, select_greedy(F, G, n_cam, count))
        sets[CHOICES[2]] = exchange(F, G, n_cam, opt.chosen)

    def forecast(q: np.ndarray) -> float | None:
        return field_forecast(setup, layout, q, workspace, pixel_sigma_px=pixel_sigma_px,
                              joint_sigma=joint_sigma).tool_rms_m  # fmt: skip

    choices = {k: forecast(opt.pool[i]) for k, i in sets.items()}
    rms = {k: np.inf if v is None else v for k, v in choices.items()}
    best = min(rms, key=rms.__getitem__)
    start, start_by = None, ""
    cb = None if rows is None else corner_blocks(rows)
    if cb is not None and np.isfinite(rms[best]):  # the corners unknown, from the best so far
        start, start_by = np.asarray(sets[best]), best
        sets[CHOICES[3]] = corner_exchange(cb, G, start)
        got = forecast(opt.pool[sets[CHOICES[3]]])
        choices[CHOICES[3]], rms[CHOICES[3]] = got, np.inf if got is None else got
        best = min(rms, key=rms.__getitem__)
    random_match = to_match = match = None
    if np.isfinite(rms[best]) and count < MATCH_RANDOM <= len(opt.pool):
        random_match = forecast(random_plan(setup, MATCH_RANDOM, seed=seed))
    if random_match is not None and cb is not None and rms[best] > random_match:
        grown = corner_grow(cb, G, sets[best], MATCH_RANDOM)  # the plan, then the criterion's
        to_match = count_to_match(count, lambda n: forecast(opt.pool[grown[:n]]), random_match)
        match = grown[: to_match[0]] if to_match is not None else None
    home = setup.robot.home
    chosen = np.asarray(sets[best])
    chosen = chosen[order_path(opt.pool[chosen], home)]
    q = opt.pool[chosen]
    return FieldPlan(
        q=q,
        q_random=q_random,
        path_rad=path_length(q, home),
        random_path_rad=path_length(q_random, home),
        candidates=opt.candidates,
        rejected_collision=opt.rejected_collision - unseen[0],
        rejected_unseen=unseen[0],
        logdet=opt.logdet,
        logdet_random=opt.logdet_random,
        exchanges=opt.exchanges,
        chosen_by=best,
        choices=choices,
        random_match_m=random_match,
        to_match=to_match,
        pool=opt.pool,
        chosen=chosen,
        start=start,
        start_by=start_by,
        match=match,
    )


def random_plan(setup: FieldPlanSetup, count: int, *, seed: int) -> np.ndarray:
    """(count, n) rad: the random plan of ``count`` postures, the first of the candidate
    sequence :func:`plan_field` seeded by ``seed`` chooses from (the same filters)."""
    pts, nrm = setup.grid()
    return plan_postures(setup.robot, setup.model_cam, setup.rig, pts, count, seed=seed,
                         min_visible=setup.min_visible, normals_world=nrm,
                         collision_ok=setup.collision_ok)  # fmt: skip


def count_to_match(
    count: int, forecast_of: Callable[[int], float | None], target_m: float
) -> tuple[int, float] | None:
    """(n, forecast m) of the smallest plan of ``count`` + 1 ... :data:`MATCH_RANDOM` postures
    whose forecast ``forecast_of(n)`` (m; None: no bound) is at most ``target_m`` (m); None when
    none is. The plans are nested (:func:`plan_field`'s: the plan, then the postures the
    corners-unknown criterion, by which the plan is chosen, adds one at a time), so their
    forecast falls with ``n`` (a posture more adds information) and the count is found by
    bisection."""
    lo, hi = count, MATCH_RANDOM  # the forecast of lo is above the target; hi's is unknown
    at_hi = forecast_of(hi)
    if at_hi is None or at_hi > target_m:
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        got = forecast_of(mid)
        if got is not None and got <= target_m:
            hi, at_hi = mid, got
        else:
            lo = mid
    return hi, at_hi


@dataclass
class FieldForecast:
    """The forecast of one plan: ``tool_rms_m`` the bound of the flange centre's RMS error over
    the workspace postures after the best rigid alignment (m; None when the bound does not exist,
    ``why`` says why), ``fx_std_px`` the bound of the focal length (px), ``observations`` the
    corners predicted seen."""

    tool_rms_m: float | None
    fx_std_px: float | None
    observations: int
    why: str = ""


def field_forecast(
    setup: FieldPlanSetup,
    layout: FieldLayout,
    q: np.ndarray,
    workspace: np.ndarray,
    *,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None,
) -> FieldForecast:
    """The field route's Cramer-Rao forecast (module docstring) of postures ``q`` (m, n) rad with
    the markers of ``layout`` seen by the rig as the analytic simulator decides it, at the
    nominal chain, ``pixel_sigma_px`` px of corner noise and the read-back noise ``joint_sigma``
    (n,) rad; the tool-point figure over ``workspace`` (w, n) rad. A plan whose data do not
    determine every unknown (a scale marker seen fewer than twice, a singular information) has
    no bound: ``tool_rms_m`` None and ``why`` the reason."""
    try:
        fs = predicted_setup(
            setup.model_cam, q, setup.rig, layout.ids, layout.corners_world,
            layout.normals_world, layout.scale_ids, layout.scale_length_m,
            pixel_sigma_px=pixel_sigma_px, joint_sigma=joint_sigma,
        )  # fmt: skip
        cr = cramer_rao(fs)
    except BoundsError as exc:
        return FieldForecast(None, None, 0, why=exc.message)
    rms = cr.aligned_tool_rms(workspace, inv_pose(setup.robot.T_flange_cam))
    return FieldForecast(float(rms), float(cr.fx_std), cr.n_observations)


def forecast_workspace(setup: FieldPlanSetup, n: int = 50, *, seed: int) -> np.ndarray:
    """(n, dof) rad: the workspace postures the forecast averages over (the board plan's: random
    postures of the planning window, free of collision and the keep-out boxes; the board plan
    seeds them with its ``--seed`` + 1)."""
    return workspace_sample(setup, n, seed=seed)
