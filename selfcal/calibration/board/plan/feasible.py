"""Which postures a recording plan may use (:func:`feasible`): within the joint ranges, seeing
the board as the cell's view rule asks (:func:`selfcal.calibration.board.plan.views.
board_views_ok`), and clear of the arm, the table, the keep-out boxes and the board.

A posture ``q`` (rad, within the robot file's joint ranges) of the cell
(:class:`selfcal.calibration.board.plan.views.PlanSetup`) is a candidate when

- the board is seen as the view rule asks (:mod:`selfcal.calibration.board.plan.views`);
- the capsule chain (:class:`selfcal.kinematics.self_collision.CapsuleChain`, its tool the camera
  or the board) neither folds onto itself nor touches the table (the base frame's z = 0 plane),
  nor enters a keep-out box (:mod:`selfcal.kinematics.keep_out`) or the board's own plate
  (eye-in-hand); eye-to-hand the board's plate stays above the table and out of the keep-out
  boxes, the arm (but the wrist that holds the board) out of the plate and the arm
  :data:`CAMERA_CLEARANCE_M` from the static camera;
- either mount: no link of the arm and no keep-out box crosses the lines of sight from the
  camera to the board's printed image (:mod:`selfcal.calibration.board.plan.sight`).

The rules are applied in that order, each to the postures that passed those before
(:func:`tally` says how many pass each). Units: m, rad.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from selfcal.calibration.board.plan.sight import sight_clear, sight_grid
from selfcal.calibration.board.plan.views import PlanSetup, board_views_ok
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.keep_out import SAMPLES, chain_samples, outside_boxes
from selfcal.transforms import inv_pose

__all__ = ["CAMERA_CLEARANCE_M", "feasible", "tally"]

CAMERA_CLEARANCE_M = 0.08
"""Eye-to-hand: no sample of the arm's capsule chain comes nearer the static camera's centre than
this plus the capsule radius (the camera's body, m)."""


def _off_board(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m,) bool: no point of the chain inside the board's plate grown by the capsule radius
    and clearance."""
    pts = chain_samples(setup.chain, q)  # base frame
    T_bb = inv_pose(setup.T_base_board)
    return ~_in_plate(setup, pts @ T_bb[:3, :3].T + T_bb[:3, 3])


def _in_plate(setup: PlanSetup, Pb: np.ndarray) -> np.ndarray:
    """(m,) bool: a point of ``Pb`` (m, s, 3; board frame, m) inside the board's plate grown by
    the capsule radius and clearance."""
    x0, y0, x1, y1 = setup.board.image(1.0).extent_m
    g = setup.chain.radius_m + setup.chain.clearance_m
    lo, hi = np.array([x0 - g, y0 - g, -g]), np.array([x1 + g, y1 + g, 0.01 + g])
    return np.all((Pb > lo) & (Pb < hi), axis=-1).any(axis=1)


def _plate_points(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m, 9, 3) the board plate's corners, edge midpoints and centre (base frame, m) at ``q``
    (eye-to-hand: the board on the flange)."""
    x0, y0, x1, y1 = setup.board.image(1.0).extent_m
    xs, ys = np.array([x0, (x0 + x1) / 2, x1]), np.array([y0, (y0 + y1) / 2, y1])
    P = np.array([[x, y, 0.0] for x in xs for y in ys])
    T = fk_tool(setup.model_tool, q)
    return np.einsum("mij,kj->mki", T[:, :3, :3], P) + T[:, None, :3, 3]


def _plate_clear(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m,) bool, eye-to-hand: the board's plate above the table and outside the keep-out boxes
    (by the chain's clearance), and no sample of the arm before the wrist's last two segments
    inside the plate grown by the capsule radius and clearance."""
    chain = setup.chain
    c = chain.clearance_m
    P = _plate_points(setup, q)
    ok = np.all(P[..., 2] >= chain.floor_z_m + c, axis=1)
    for box in setup.boxes:
        ok &= ~np.all((P > box[:3] - c) & (P < box[3:] + c), axis=-1).any(axis=1)
    pts = chain_samples(chain, q)[:, : -2 * SAMPLES]  # the wrist holding the board left out
    T_bb = inv_pose(fk_tool(setup.model_tool, q))  # base -> board
    Pb = np.einsum("mij,mkj->mki", T_bb[:, :3, :3], pts) + T_bb[:, None, :3, 3]
    return ok & ~_in_plate(setup, Pb)


def _sight_clear(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m,) bool: the lines of sight from the camera to the board's printed image clear of the
    arm and the keep-out boxes (:func:`selfcal.calibration.board.plan.sight.sight_clear`);
    eye-to-hand also the arm :data:`CAMERA_CLEARANCE_M` from the static camera."""
    chain = setup.chain
    grid = sight_grid(setup.board.image(1.0).extent_m, chain.radius_m + chain.clearance_m)
    if setup.T_base_cam is None:  # eye-in-hand: the camera on the flange, the board static
        C = fk_tool(setup.model_cam, q)[:, :3, 3]
        T = setup.T_base_board
        P = np.broadcast_to(grid @ T[:3, :3].T + T[:3, 3], (len(q), *grid.shape))
        return sight_clear(chain, q, C, P, setup.boxes)
    C = setup.T_base_cam[:3, 3]
    pts = chain_samples(chain, q)[:, :-SAMPLES]  # (m, s, 3) without flange -> board
    ok = np.all(np.linalg.norm(pts - C, axis=-1) > chain.radius_m + CAMERA_CLEARANCE_M, axis=1)
    T = fk_tool(setup.model_tool, q[ok])
    P = np.einsum("mij,kj->mki", T[:, :3, :3], grid) + T[:, None, :3, 3]
    ok[ok] = sight_clear(chain, q[ok], C, P, setup.boxes)
    return ok


def _checks(setup: PlanSetup) -> tuple[tuple[str, Callable[[np.ndarray], np.ndarray]], ...]:
    """The candidate rules after the joint ranges, in the order they are applied: (what a
    posture that passes does, the check: (m, n) rad -> (m,) bool)."""
    return (
        (_view_words(setup), lambda x: board_views_ok(setup, setup.T_cam_board(x))),
        ("are free of self-collision and the table", setup.chain.ok),
        ("stay out of the keep-out boxes", lambda x: outside_boxes(setup.chain, x, setup.boxes)),
        (("keep the board's plate above the table and clear", lambda x: _plate_clear(setup, x))
         if setup.eye_to_hand else
         ("keep the arm off the board's plate", lambda x: _off_board(setup, x))),
        ("keep the lines of sight to the board clear", lambda x: _sight_clear(setup, x)),
    )  # fmt: skip


def _view_words(setup: PlanSetup) -> str:
    """What a posture passing the view rule does, in words."""
    rule = setup.rule
    if rule.min_corners <= 0 or setup.board.whole_grid:
        return "see the whole board as the view rule asks"
    return (f"see at least {rule.min_corners} of the board's features spanning "
            f"{rule.min_spread:.0%} of the image as the view rule asks")  # fmt: skip


def feasible(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m,) bool: which postures ``q`` (m, n) rad are candidates (module docstring)."""
    return _passing(setup, q)[-1][1]


def _passing(setup: PlanSetup, q: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Per rule in turn (the joint ranges first, then :func:`_checks`): what passing it does
    and which postures of ``q`` (m, n) rad pass it and every rule before (m,) bool; the list
    stops after the first rule no posture passes."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    r = setup.robot
    ok = np.all((q >= r.limits[:, 0]) & (q <= r.limits[:, 1]), axis=1)
    out = [("lie within the joint ranges", ok.copy())]
    for what, check in _checks(setup):
        if not ok.any():
            break
        ok[ok] = check(q[ok])
        out.append((what, ok.copy()))
    return out


def tally(setup: PlanSetup, q: np.ndarray, where: str) -> str:
    """Which rule the postures ``q`` (m, n) rad, drawn ``where``, fail: how many pass each rule
    and those before it, up to the first no posture passes."""
    counts = ", ".join(f"{int(ok.sum())} {what}" for what, ok in _passing(setup, q))
    return f"of the last {len(q)} drawn ({where}): {counts}"
