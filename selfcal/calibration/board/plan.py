"""A recording plan for a user's arm, camera and board: which postures to record so that the
board calibration predicts the smallest tool-point error (``selfcal plan``, issue #30). Both
mounts: the camera on the flange and the board static (eye-in-hand), or the camera static and
the board on the flange (eye-to-hand: the board route's inverted chain, world = the camera, tool
= the board, :class:`selfcal.estimation.kinematic_poses.KinematicPoses`); the tool point is the
flange's origin either way.

Candidates: :func:`selfcal.calibration.board.plan_views.candidate_pool` (reachable, free of
collision and keep-out boxes, the whole board well in view). Criterion: the Cramer-Rao bound of
the board route (:func:`selfcal.calibration.board.bounds.board_cramer_rao`: the camera's free
parameters and every minimal kinematic parameter of the chain in the board frame, the board
known, Gaussian corner noise of ``pixel_sigma_px`` and, optionally, joint read-back noise
whose per-frame corrections are estimated under their prior) carried to the predicted RMS error
of the tool point (the flange centre) over a sample of the workspace after the best rigid
alignment, as the calibration reports it
(:func:`selfcal.estimation.joint_report.aligned_tool_weight`). Every other parameter is shared
by the frames and a frame's own joint corrections are eliminated frame by frame, so the Fisher
information is the sum of each frame's (one Jacobian of
:func:`selfcal.calibration.board.problem.board_problem` over the whole pool):
the greedy choice adds, step by step, the candidate that lowers the predicted error most (from a
slightly regularised start, so the first few frames count while the information is not yet of
full rank; a dataset's additions start from its frames and the prior of the arm's deviation
from its drawing, :mod:`selfcal.calibration.board.plan_add`). The prediction of the chosen
postures is that of the calibration with the parameters its selection keeps, every other one
held at the drawing (:func:`predict_kept`, :mod:`selfcal.calibration.board.plan_predict`). The
chosen postures are then ordered for a short joint-space path from home
(nearest neighbour, then 2-opt; distance: the largest joint move, which sets the travel time
when the joints move together). The random plan of the same size (the pool's first postures: the
same filters) is predicted the same way, for contrast. Units: SI inside.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.plan_predict import (
    Deviation,
    Directions,
    estimated_directions,
    kept_by_rank,
    predicted_with_held,
)
from selfcal.calibration.board.plan_reference import NominalReference, nominal_reference
from selfcal.calibration.board.plan_selection import SelectionForecast, forecast_selection
from selfcal.calibration.board.plan_views import PlanSetup, candidate_pool
from selfcal.calibration.board.problem import board_problem
from selfcal.errors import InputError, UsageError
from selfcal.estimation.joint_report import aligned_tool_weight
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.keep_out import outside_boxes
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.robot.definition import RobotDef

__all__ = [
    "RecordingPlan",
    "PostureCell",
    "board_model",
    "frame_information",
    "workspace_sample",
    "predicted_error",
    "select_greedy",
    "order_path",
    "path_length",
    "plan_recording",
    "predict_kept",
    "PlanOptions",
    "PlanGround",
    "plan_ground",
    "Selected",
]

SEARCH_FACTOR = 4
"""A plan not predicted to beat the reference looks for the count that would among the greedy
choice's first this many times the count (within the pool)."""
SEARCH_STEP = 4
"""... in steps of this many postures."""

RIVAL_LOG = 0.2
"""The next smaller candidate is the forecast choice's rival when its expected CV error is within
``exp(RIVAL_LOG)`` (1.22) times the choice's: the selection's one-standard-error rule keeps the
smaller of two candidates whose folds' mean log ratio is within its standard error, where the
forecast's expected fold errors have no noise. Set when that standard error was the spread of
the ratio to the nominal (0.06 to 0.18 on arm7's plans of 12 and 16, tests/data/arm7.toml);
paired with the best candidate's folds it is 0.003 to 0.03 on arm7's plan of 24, so the range
is wide now: not measured again."""

REG = 1e-6
"""The greedy start's information: this times the identity in parameters scaled to unit mean
information per candidate (it only matters while fewer frames than parameters are chosen)."""


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
    calibrating the kinematics (:mod:`selfcal.calibration.board.plan_reference`);
    ``to_beat`` (count, predicted m) the smallest plan of the same greedy choice whose
    ``selected.worst_m`` beats it clearly, when this one does not (None: it does, or no plan of up to
    ``searched`` postures does)."""

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

    @property
    def worst_m(self) -> float:
        """The larger of the two predictions: what the plan stands by."""
        return max(self.selected_m, self.rival_m or 0.0)

    def kept(self, n: int) -> int:
        """The kinematic parameters beyond the placement the forecast keeps (chain of ``n``
        joints)."""
        return _beyond_placement(self.forecast.kept, n)

    def rival_kept(self, n: int) -> int | None:
        """... and its rival keeps (None without one)."""
        if self.rival_m is None:
            return None
        return _beyond_placement(self.forecast.kept_sets[self.forecast.chosen - 1], n)


def _beyond_placement(kept: tuple[np.ndarray, np.ndarray], n: int) -> int:
    """How many of ``kept`` (flat MCPC indices, offset joints) are not the placement's."""
    return int(np.setdiff1d(kept[0], placement_indices(n)).size + len(kept[1]))


def board_model(setup: PlanSetup) -> MCPCModel:
    """The nominal chain the board calibration fits: eye-in-hand board frame -> camera (world =
    the board, tool = the camera), eye-to-hand camera -> board (world = the camera, tool = the
    board; :meth:`selfcal.calibration.board.plan_views.PlanSetup.calibration_model`)."""
    return setup.calibration_model()


def frame_information(
    setup: PlanSetup,
    q: np.ndarray,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None = None,
    seen: Sequence[np.ndarray] | None = None,
) -> np.ndarray:
    """(m, p, p) the Fisher information of each posture ``q`` (m, n) rad about ``[camera's free
    parameters, minimal kinematic parameters]`` (px, rad, m; the order of
    :func:`selfcal.calibration.board.bounds.board_cramer_rao`): the board features ``seen``
    in each frame (m arrays of feature ids; None: every feature) at the nominal camera's
    projection, noise ``pixel_sigma_px`` px per coordinate; with ``joint_sigma`` (n,) rad
    (m for a prismatic joint) each frame's joint read-back errors are estimated under their
    Gaussian prior and eliminated (the Schur complement of the frame's own corrections), as the
    board route does."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m = len(q)
    model = board_model(setup)
    ids, pts = setup.board.layout()
    if seen is None:
        feature = [np.arange(len(ids))] * m
    else:
        at = {int(i): k for k, i in enumerate(ids.tolist())}
        feature = [np.array([at[i] for i in np.asarray(s).tolist() if i in at], np.int64)
                   for s in seen]  # fmt: skip
        if len(feature) != m:
            raise UsageError(f"{len(feature)} frames of seen features for {m} postures")
    T_cb = setup.T_cam_board(q)  # board -> camera
    Xc = np.einsum("mij,kj->mki", T_cb[:, :3, :3], pts) + T_cb[:, None, :3, 3]
    uv = setup.camera.project(Xc)  # (m, k, 2)
    idx = minimal_indices(model.joint_types)
    poses = KinematicPoses(model, q, idx, np.zeros((0, 4, 4)), np.ones(m, bool),
                           joint_corrections=joint_sigma is not None,
                           eye_to_hand=setup.eye_to_hand)  # fmt: skip
    frame = np.repeat(np.arange(m), [len(f) for f in feature])
    k = np.concatenate([np.zeros(0, np.int64), *feature])
    rows = [(poses.layout.view(frame, 0), ids[k], uv[frame, k])]
    prob = board_problem([setup.camera], poses, rows, setup.board, pixel_sigma_px=pixel_sigma_px,
                         joint_sigma=joint_sigma, n_frames=m)  # fmt: skip
    P = prob.problem
    pose_cols = P.columns("poses")
    cols = np.concatenate([P.columns("intrinsics"), pose_cols[: poses.n_kin]])
    J = P.jacobian(P.x0)[: 2 * len(frame)]  # the reprojection rows (the prior's follow)
    views = poses.layout.view(np.arange(m), 0)
    of_view = np.empty(int(views.max()) + 1, np.int64)
    of_view[views] = np.arange(m)
    row_frame = np.repeat(of_view[prob.block.view], 2)
    if len(row_frame) != J.shape[0]:
        raise InputError("the board problem's residuals do not match the frames' features")
    order = np.argsort(row_frame, kind="stable")
    ends = np.cumsum(np.bincount(row_frame, minlength=m))
    parts = np.split(order, ends[:-1])
    Jg = J[:, cols].toarray()
    F = np.stack([Jg[r].T @ Jg[r] for r in parts])
    if joint_sigma is not None:  # eliminate each frame's joint corrections
        dq = pose_cols[np.asarray(poses.dq_cols)].reshape(m, -1)
        js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (dq.shape[1],))
        prior = np.diag((pixel_sigma_px / js) ** 2)
        for f, r in enumerate(parts):
            Jl = J[r][:, dq[f]].toarray()
            B = Jg[r].T @ Jl
            F[f] -= B @ np.linalg.solve(Jl.T @ Jl + prior, B.T)
    return F / pixel_sigma_px**2


class PostureCell(Protocol):
    """What :func:`workspace_sample` draws for: an arm, its collision check and keep-out boxes
    (:class:`selfcal.calibration.board.plan_views.PlanSetup`, a tracker plan's setup)."""

    @property
    def robot(self) -> RobotDef: ...

    @property
    def chain(self) -> CapsuleChain: ...

    @property
    def boxes(self) -> np.ndarray: ...


def workspace_sample(setup: PostureCell, n: int, *, seed: int) -> np.ndarray:
    """(n, dof) rad: random postures of the planning window around home, free of self-collision
    and keep-out boxes (the board need not be in view): where the predicted error is averaged,
    and a tracker plan's candidates."""
    r = setup.robot
    rng = np.random.default_rng(seed)
    lo = np.maximum(r.limits[:, 0], r.home - r.planning_span)
    hi = np.minimum(r.limits[:, 1], r.home + r.planning_span)
    out: list[np.ndarray] = []
    for _ in range(50):
        q = rng.uniform(lo, hi, size=(max(4 * n, 256), r.n))
        ok = setup.chain.ok(q)
        ok[ok] = outside_boxes(setup.chain, q[ok], setup.boxes)
        out.append(q[ok])
        if sum(map(len, out)) >= n:
            break
    w = np.concatenate(out)[:n]
    if len(w) < n:
        raise InputError(
            f"only {len(w)} of {n} postures of the planning window around home are free of "
            "collision and of the keep-out boxes",
            fix="check the keep-out boxes against the robot's home posture and [planning] span_deg",
        )
    return w


def predicted_error(F: np.ndarray, G: np.ndarray, n_cam: int) -> float:
    """The predicted RMS tool-point error (m): ``sqrt(trace(G C))``, ``C`` the kinematic block
    of ``F^-1`` (``F`` (p, p) the information, the first ``n_cam`` parameters the camera's);
    infinite when ``F`` is singular."""
    try:
        C = np.linalg.inv(F)
    except np.linalg.LinAlgError:
        return float("inf")
    if not np.all(np.isfinite(C)) or np.linalg.cond(F) > 1e14:
        return float("inf")
    return float(np.sqrt(max(np.trace(G @ C[n_cam:, n_cam:]), 0.0)))


def select_greedy(
    F: np.ndarray, G: np.ndarray, n_cam: int, count: int, start: np.ndarray | None = None
) -> np.ndarray:
    """Indices (count,) into the candidates' informations ``F`` (m, p, p), chosen one by one to
    lower ``trace(W (F_0 + sum F_i)^-1)`` most, ``W`` = ``G`` (k, k) on the kinematic block
    (module docstring); ``F_0`` the information ``start`` (p, p) already held (the prior of
    the deviation from the drawing, a dataset's frames) plus a slight regularisation. A stack
    ``start`` (s, p, p) of several: the sum of their ``s`` costs is lowered (the added postures
    serve each)."""
    m, p, _ = F.shape
    if count > m:
        raise InputError(f"cannot choose {count} postures from {m} candidates",
                         fix="lower --count or widen the candidate pool (--candidates)")  # fmt: skip
    d = np.sqrt(np.maximum(np.einsum("mii->i", F) / m, 1e-300))
    Fs = F / np.outer(d, d)
    W = np.zeros((p, p))
    W[n_cam:, n_cam:] = G
    Ws = W / np.outer(d, d)
    starts = np.zeros((1, p, p)) if start is None else np.asarray(start, dtype=float)
    total = REG * np.eye(p) + starts.reshape(-1, p, p) / np.outer(d, d)
    free = np.ones(m, bool)
    chosen: list[int] = []
    for _ in range(count):
        cost = np.zeros(m)
        for t in total:
            cost += np.einsum("ij,mji->m", Ws, np.linalg.inv(t + Fs))
        cost[~free] = np.inf
        b = int(np.argmin(cost))
        chosen.append(b)
        free[b] = False
        total = total + Fs[b]
    return np.asarray(chosen)


def _step(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.max(np.abs(a - b), axis=-1)


def path_length(q: np.ndarray, start: np.ndarray) -> float:
    """The joint path from ``start`` through ``q`` (m, n) in order: the sum of every step's
    largest joint move (rad)."""
    pts = np.concatenate([np.asarray(start, dtype=float)[None], np.asarray(q, dtype=float)])
    return float(_step(pts[1:], pts[:-1]).sum())


def order_path(q: np.ndarray, start: np.ndarray) -> np.ndarray:
    """An order (m,) of postures ``q`` (m, n) for a short path from ``start`` (n,): nearest
    neighbour, then 2-opt (reversing a stretch while that shortens the open path)."""
    q = np.asarray(q, dtype=float)
    m = len(q)
    pts = np.concatenate([np.asarray(start, dtype=float)[None], q])
    D = _step(pts[:, None], pts[None])
    tour, left = [0], set(range(1, m + 1))
    while left:
        nxt = min(left, key=lambda j: D[tour[-1], j])
        tour.append(nxt)
        left.remove(nxt)
    improved = True
    while improved:
        improved = False
        for i in range(1, m):
            for j in range(i + 1, m + 1):
                a, b = tour[i - 1], tour[i]
                c = tour[j]
                e = tour[j + 1] if j < m else None
                old = D[a, b] + (D[c, e] if e is not None else 0.0)
                new = D[a, c] + (D[b, e] if e is not None else 0.0)
                if new < old - 1e-12:
                    tour[i : j + 1] = tour[i : j + 1][::-1]
                    improved = True
    return np.asarray(tour[1:]) - 1


@dataclass(frozen=True)
class PlanOptions:
    """What every plan is drawn and predicted with: the ``seed`` of the candidates and the
    workspace, the pool's size ``candidates``, the ``workspace`` postures the error is averaged
    over, the corner noise ``pixel_sigma_px`` (px), the joint read-back noise ``joint_sigma``
    (n,) rad (None: exact; :func:`frame_information`) and the arm's ``deviation`` from its
    drawing (:class:`selfcal.calibration.board.plan_predict.Deviation`)."""

    seed: int = 1
    candidates: int = 400
    workspace: int = 50
    pixel_sigma_px: float = 0.5
    joint_sigma: np.ndarray | None = None
    deviation: Deviation = field(default_factory=Deviation)


@dataclass(frozen=True, eq=False)
class PlanGround:
    """The common ground of a plan (:func:`plan_ground`): the candidate ``pool`` (m, n) rad and
    where it was ``drawn_from``, the ``workspace`` (w, n) rad, the aligned tool weight ``G``
    (k, k) over it and the deviation's ``variance`` (k,)."""

    pool: np.ndarray
    drawn_from: str
    workspace: np.ndarray
    G: np.ndarray
    variance: np.ndarray


def plan_ground(setup: PlanSetup, count: int, options: PlanOptions) -> PlanGround:
    """The candidates, the workspace and the weights a plan of ``count`` postures chooses with.

    Raises:
        InputError: fewer candidates than ``count``, or no posture sees the board.
    """
    pool, where = candidate_pool(setup, max(options.candidates, count), seed=options.seed)
    if len(pool) < count:
        raise InputError(
            f"only {len(pool)} postures of {setup.robot.name} see the whole board without "
            f"collision; {count} asked",
            fix="plan fewer postures, move the board (--board-pose) nearer to where the arm "
            "works, or remove keep-out boxes",
        )
    qw = workspace_sample(setup, options.workspace, seed=options.seed + 1)
    model = board_model(setup)
    G = aligned_tool_weight(model, qw, setup.T_tool_tip)
    return PlanGround(pool, where, qw, G, options.deviation.variance(model.joint_types))


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
    n_cam = setup.camera.n_free
    searched = min(len(pool), SEARCH_FACTOR * count)
    home = setup.robot.home
    chosen = select_greedy(F, G, n_cam, count)
    chosen = chosen[order_path(pool[chosen], home)]
    q = pool[chosen]
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
                                pixel_sigma_px, dirs)  # fmt: skip
        got = predict_kept(setup, pool[idx], Fs, G, var, fc.kept, dirs)
        cv, c = fc.cv_px, fc.chosen
        rival = None
        if c > 0 and cv[c - 1] <= np.exp(RIVAL_LOG) * cv[c]:
            rival = predict_kept(setup, pool[idx], Fs, G, var, fc.kept_sets[c - 1], dirs)
        return Selected(got, fc, rival), nominal_reference(model, Fs, G, n_cam, var, dirs)

    sel, ref = selected(chosen)
    to_beat = None
    if not ref.beaten_by(sel.worst_m):
        picks = select_greedy(F, G, n_cam, searched)  # one by one: its first count are the plan
        for n in range(count + SEARCH_STEP, searched + 1, SEARCH_STEP):
            idx = picks[:n][order_path(pool[picks[:n]], home)]
            got, r = selected(idx)
            if r.beaten_by(got.worst_m):
                to_beat = (n, got.worst_m)
                break
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
        kept_all=_beyond_placement(kept_by_rank(model, q), model.n),
        selected=sel,
        reference=ref,
        to_beat=to_beat,
        searched=searched,
    )


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
    (:func:`selfcal.calibration.board.plan_predict.predicted_with_held`); ``directions`` the
    model's when already computed."""
    model = board_model(setup)
    free_idx, offsets = kept_by_rank(model, q) if kept is None else kept
    if directions is None:
        M = estimated_directions(model, free_idx, offsets)
    else:
        M = directions.of(free_idx, offsets)
    return predicted_with_held(F, G, setup.camera.n_free, M, variance)
