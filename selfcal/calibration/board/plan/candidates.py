"""Drawing a recording plan's candidate postures (:func:`candidate_pool`), and a drift check's
near postures it has seen (:func:`candidates_near`): postures drawn at random and kept where
:func:`selfcal.calibration.board.plan.feasible.feasible` passes them.

The plan's candidates are drawn uniformly in the robot file's planning window around home
(``[planning] span_deg``); when too few lie there (a board far from where home looks), in the
whole joint ranges (wrapped to +-180 deg), then in the planning window around the candidates
found so far. Every draw around postures (those found so far, or a calibration's own) is
:func:`draws_near`'s. Units: rad.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from selfcal.calibration.board.plan.feasible import feasible, tally
from selfcal.calibration.board.plan.views import PlanSetup, module_words, pitch_edges
from selfcal.errors import InputError
from selfcal.robot.definition import RobotDef

__all__ = ["candidate_pool", "candidates_near", "draws_near"]


def draws_near(rng: np.random.Generator, centres: np.ndarray, span: np.ndarray | float,
               limits: np.ndarray, size: int) -> np.ndarray:  # fmt: skip
    """(size, n) postures (rad), each drawn uniformly within ``span`` (n,) or scalar rad of one
    of the ``centres`` (c, n) rad, chosen at random, on every joint, clipped to the joint
    ``limits`` (n, 2) rad."""
    c = centres[rng.integers(len(centres), size=size)]
    return np.clip(c + rng.uniform(-1, 1, size=c.shape) * span, limits[:, 0], limits[:, 1])


def _feasible_draws(setup: PlanSetup, n: int, max_draws: int, batch: int,
                    draw: Callable[[list[np.ndarray], int], np.ndarray],
                    ) -> tuple[np.ndarray, int, np.ndarray]:  # fmt: skip
    """Batches of ``batch`` postures ``draw(found so far, how many drawn)`` until ``n`` candidates are found or
    ``max_draws`` drawn: (up to ``n`` candidates (m, dof) rad in the order drawn, how many were
    drawn, the last batch)."""
    found: list[np.ndarray] = []
    drawn, q = 0, np.zeros((0, setup.robot.n))
    while sum(map(len, found)) < n and drawn < max_draws:
        q = draw(found, drawn)
        drawn += batch
        found.append(q[feasible(setup, q)])
    pool = np.concatenate(found)[:n] if found else np.zeros((0, setup.robot.n))
    return pool, drawn, q


def candidates_near(setup: PlanSetup, centres: np.ndarray, n: int, *, seed: int,
                    span: np.ndarray | float, batch: int = 1024,
                    max_draws: int = 100_000) -> np.ndarray:  # fmt: skip
    """Up to ``n`` candidate postures (m, dof) rad of the cell ``setup`` (:func:`feasible`)
    drawn uniformly within ``span`` (dof,) or scalar rad of one of the ``centres`` (c, dof) rad
    on every joint (:func:`draws_near`), in random order (deterministic for ``seed``); none
    after ``max_draws`` or without centres."""
    if not len(centres):
        return np.zeros((0, setup.robot.n))
    rng, lim = np.random.default_rng(seed), setup.robot.limits
    pool, _, _ = _feasible_draws(setup, n, max_draws, batch,
                                 lambda _, __: draws_near(rng, centres, span, lim, batch))  # fmt: skip
    return pool


def _window(robot: RobotDef, centre: np.ndarray, span: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The planning window: ``centre`` +- ``span`` (n,) rad within the joint ranges (lo, hi)."""
    lo = np.maximum(robot.limits[:, 0], centre - span)
    hi = np.minimum(robot.limits[:, 1], centre + span)
    return lo, hi


def _check_within_reach(setup: PlanSetup) -> None:
    """Refuse at once a board no camera on the arm can see large enough (eye-in-hand: farther
    from the base than the chain's length plus the distance at which one feature pitch spans
    :attr:`ViewRule.min_pitch_px`, a pinhole's ``fx pitch / px``), or a static camera that far
    from the base (eye-to-hand)."""
    P = setup.chain.points(setup.robot.home[None])[0]
    reach = float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
    reach += float(np.linalg.norm(setup.T_flange_tool[:3, 3]))
    _, pitch = pitch_edges(setup.board)
    fx = float(dict(zip(setup.camera.names, setup.camera.values()))["fx"])
    far = fx * pitch / setup.rule.min_pitch_px
    if setup.T_base_cam is not None:
        what, option = "static camera", "--camera-pose (the camera's centre in the base frame, mm)"
        centre = setup.T_base_cam[:3, 3]
    else:
        what, option = "board's centre", "--board-pose (the centre of the printed board in the " \
            "base frame, mm)"  # fmt: skip
        T = setup.T_base_board
        centre = T[:3, :3] @ setup.board_points()[-4:].mean(axis=0) + T[:3, 3]
    if np.linalg.norm(centre) > reach + far:
        raise InputError(
            f"the {what} is {np.linalg.norm(centre) * 1000:.0f} mm from {setup.robot.name}'s "
            f"base, beyond its reach ({reach * 1000:.0f} mm) plus the farthest the camera sees a "
            f"feature pitch of {setup.rule.min_pitch_px:g} px ({far * 1000:.0f} mm): no posture "
            "sees the whole board",
            fix=f"check {option}",
        )


def candidate_pool(
    setup: PlanSetup, n: int, *, seed: int, batch: int = 4096, max_draws: int = 400_000
) -> tuple[np.ndarray, str]:
    """Up to ``n`` candidate postures (m, dof) rad in random order (deterministic for a seed)
    and where they were drawn (``"home window"``, ``"joint ranges"``); at least one (module
    docstring).

    Raises:
        InputError: no posture of ``max_draws`` sees the board as asked.
    """
    rng = np.random.default_rng(seed)
    r = setup.robot
    _check_within_reach(setup)
    lo, hi = _window(r, r.home, r.planning_span)
    wide = (np.maximum(r.limits[:, 0], -np.pi), np.minimum(r.limits[:, 1], np.pi))
    where = "home window"

    def draw(found: list[np.ndarray], drawn: int) -> np.ndarray:
        nonlocal where
        count = sum(map(len, found))
        if where == "home window" and drawn >= max_draws // 4 and count < n // 4:
            where = "joint ranges"  # the board lies away from where home looks
        if where == "home window" or not count:
            a, b = (lo, hi) if where == "home window" else wide
            return rng.uniform(a, b, size=(batch, r.n))
        # around the candidates found so far, within the planning window's spans
        return draws_near(rng, np.concatenate(found), r.planning_span, r.limits, batch)

    pool, drawn, q = _feasible_draws(setup, n, max_draws, batch, draw)
    if not len(pool):
        raise InputError(
            f"none of {drawn} postures of {r.name} sees the whole board within the image "
            f"(margin {setup.rule.margin_px:g} px, board normal within "
            f"{setup.rule.max_tilt_deg:g} deg of the optical axis, a feature pitch of at least "
            f"{setup.rule.min_pitch_px:g} px{module_words(setup)}) without collision and with "
            f"the arm out of the camera's lines of sight ({tally(setup, q, where)})",
            fix="check --board-pose (the centre of the printed board in the base frame, mm) or "
            "--camera-pose and the camera (--camera or --fov-deg/--resolution); a board too large for the view at a "
            "working distance needs a wider lens, one too small (or its markers) a closer "
            "approach, a longer lens, more pixels or larger markers",
        )
    return pool, where
