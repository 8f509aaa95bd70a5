"""The common ground every plan is chosen on (``selfcal plan``, issue #30;
:mod:`selfcal.calibration.board.plan.planner`): the candidate postures
(:func:`selfcal.calibration.board.plan.candidates.candidate_pool`), the random workspace postures the
predicted tool-point error is averaged over, the aligned tool weight over them and the arm's
deviation from its drawing. Units: SI inside.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.candidates import candidate_pool
from selfcal.calibration.board.plan.information import board_model
from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.errors import InputError
from selfcal.estimation.joint_report import aligned_tool_weight
from selfcal.kinematics.keep_out import collision_free
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.robot.definition import RobotDef

__all__ = ["PlanGround", "PlanOptions", "PostureCell", "plan_ground", "workspace_sample"]


class PostureCell(Protocol):
    """What :func:`workspace_sample` draws for: an arm, its collision check and keep-out boxes
    (:class:`selfcal.calibration.board.plan.views.PlanSetup`, a tracker plan's setup)."""

    @property
    def robot(self) -> RobotDef: ...

    @property
    def chain(self) -> CapsuleChain: ...

    @property
    def boxes(self) -> np.ndarray: ...


def workspace_sample(
    setup: PostureCell,
    n: int,
    *,
    seed: int,
    window: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """(n, dof) rad: random postures of the planning window around home (or of ``window``,
    (lower, upper) (dof,) rad within the joint limits), free of self-collision and keep-out
    boxes (the board need not be in view): where the predicted error is averaged, and a
    tracker plan's candidates."""
    r = setup.robot
    rng = np.random.default_rng(seed)
    if window is None:
        lo = np.maximum(r.limits[:, 0], r.home - r.planning_span)
        hi = np.minimum(r.limits[:, 1], r.home + r.planning_span)
    else:
        lo, hi = (np.asarray(w, dtype=float) for w in window)
    out: list[np.ndarray] = []
    for _ in range(50):
        q = rng.uniform(lo, hi, size=(max(4 * n, 256), r.n))
        out.append(q[collision_free(setup.chain, q, setup.boxes)])
        if sum(map(len, out)) >= n:
            break
    w = np.concatenate(out)[:n]
    if len(w) < n:
        where = "the planning window around home" if window is None else "the window asked"
        raise InputError(
            f"only {len(w)} of {n} postures of {where} are free of collision and of the "
            "keep-out boxes",
            fix="check the keep-out boxes against the robot's home posture and [planning] span_deg",
        )
    return w


@dataclass(frozen=True)
class PlanOptions:
    """What every plan is drawn and predicted with: the ``seed`` of the candidates and the
    workspace, the pool's size ``candidates``, the ``workspace`` postures the error is averaged
    over, the corner noise ``pixel_sigma_px`` (px), the joint read-back noise ``joint_sigma``
    (n,) rad (None: exact; :func:`selfcal.calibration.board.plan.information.frame_information`)
    and the arm's ``deviation`` from its drawing
    (:class:`selfcal.calibration.board.deviation.Deviation`)."""

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
    (k, k) over it and the deviation's ``variance`` (k,), the inner parameters', and
    ``drawn_variance`` (k,), the placement's included
    (:class:`selfcal.calibration.board.deviation.Deviation`)."""

    pool: np.ndarray
    drawn_from: str
    workspace: np.ndarray
    G: np.ndarray
    variance: np.ndarray
    drawn_variance: np.ndarray


def plan_ground(
    setup: PlanSetup, count: int, options: PlanOptions, workspace: np.ndarray | None = None
) -> PlanGround:
    """The candidates, the workspace and the weights a plan of ``count`` postures chooses with;
    ``workspace`` (w, n) rad the postures the error is averaged over (None: the planning
    window's, :func:`workspace_sample`).

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
    qw = (workspace_sample(setup, options.workspace, seed=options.seed + 1)
          if workspace is None else np.atleast_2d(np.asarray(workspace, dtype=float)))  # fmt: skip
    model = board_model(setup)
    G = aligned_tool_weight(model, qw, setup.T_tool_tip)
    dev, types = options.deviation, model.joint_types
    return PlanGround(pool, where, qw, G, dev.variance(types), dev.drawn_variance(types))
