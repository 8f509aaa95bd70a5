"""The postures a recording plan may use: reachable, collision-free, and seeing the whole board
well (the candidate pool of :mod:`selfcal.calibration.board.plan`).

A posture ``q`` (rad, within the robot file's joint ranges) is a candidate when

- the capsule chain (:class:`selfcal.kinematics.self_collision.CapsuleChain`) neither folds onto
  itself nor touches the table (the base frame's z = 0 plane), nor enters a keep-out box
  (:mod:`selfcal.kinematics.keep_out`) or the board's own plate;
- the nominal camera sees every feature of the board and every corner of its printed image
  inside the image with :attr:`ViewRule.margin_px` to spare, at least
  :attr:`ViewRule.min_depth_m` in front of it;
- the board faces the camera: the angle between the optical axis and the board's normal (into
  the board) is at most :attr:`ViewRule.max_tilt_deg` (beyond it the far squares foreshorten
  past what the corner detectors handle);
- the board is large enough in the image: one feature pitch (the closest two features) spans at
  least :attr:`ViewRule.min_pitch_px` along each edge of the feature grid.

Candidates are drawn uniformly in the robot file's planning window around home
(``[planning] span_deg``); when too few lie there (a board far from where home looks), in the
whole joint ranges (wrapped to +-180 deg), then in the planning window around the candidates
found so far. Units: m, rad, px.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from selfcal.camera import CameraModel
from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.keep_out import chain_samples, outside_boxes
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.robot.definition import RobotDef
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = ["ViewRule", "PlanSetup", "board_views_ok", "feasible", "candidate_pool"]


@dataclass(frozen=True)
class ViewRule:
    """What a planned view asks of the board (module docstring)."""

    margin_px: float = 12.0
    min_depth_m: float = 0.05
    max_tilt_deg: float = 60.0
    min_pitch_px: float = 12.0


@dataclass(frozen=True, eq=False)
class PlanSetup:
    """One arm, one wrist camera, one board: ``robot`` (its ``T_flange_cam`` places the camera
    on the flange), ``camera`` (the nominal camera), ``board`` at ``T_base_board`` (board ->
    base, m), keep-out ``boxes`` (b, 6) m in the base frame, the view ``rule``."""

    robot: RobotDef
    camera: CameraModel
    board: Board
    T_base_board: np.ndarray
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    rule: ViewRule = field(default_factory=ViewRule)

    @property
    def model_cam(self) -> MCPCModel:
        """The nominal chain base -> camera (OpenCV frame)."""
        return nominal_mcpc(self.robot).with_tool(self.robot.T_flange_cam)

    @property
    def chain(self) -> CapsuleChain:
        """The self-collision and table check of the nominal arm with its camera."""
        return CapsuleChain(nominal_mcpc(self.robot), self.robot.T_flange_cam)

    def board_points(self) -> np.ndarray:
        """(k + 4, 3) the board's features and its printed image's corners (base frame, m)."""
        _, pts = self.board.layout()
        x0, y0, x1, y1 = self.board.image(1.0).extent_m
        corners = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], dtype=float)
        X = np.concatenate([pts, corners])
        T = self.T_base_board
        return X @ T[:3, :3].T + T[:3, 3]


def _pitch_edges(board: Board) -> tuple[np.ndarray, float]:
    """The feature grid's four extreme corners (4, 3) (board frame, m; in order around the grid)
    and the pitch (m): the smallest distance between two features."""
    _, pts = board.layout()
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    d[np.diag_indices(len(pts))] = np.inf
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    grid = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]])
    return grid, float(d.min())


def _in_view(setup: PlanSetup, T_cam_base: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(m,) bool: every point ``X`` (k, 3) base frame m projected by the camera model beyond the
    rule's least depth and inside the image."""
    rule, cam = setup.rule, setup.camera
    Xc = np.einsum("mij,kj->mki", T_cam_base[:, :3, :3], X) + T_cam_base[:, None, :3, 3]
    ok = np.all(cam.valid(Xc) & (cam.depth(Xc) > rule.min_depth_m), axis=1)
    return ok & np.all(cam.in_image(cam.project_valid(Xc)[0], rule.margin_px), axis=1)


def board_views_ok(setup: PlanSetup, T_base_cam: np.ndarray) -> np.ndarray:
    """(m,) bool: which camera poses ``T_base_cam`` (m, 4, 4) see the board as the module
    docstring asks."""
    T = np.asarray(T_base_cam, dtype=float).reshape(-1, 4, 4)
    rule = setup.rule
    T_cw = inv_pose(T)
    T_cb = T_cw @ setup.T_base_board  # board -> camera
    # the optical axis against the board's normal (board z, into the board) in the camera frame
    ok = T_cb[:, 2, 2] >= np.cos(np.radians(rule.max_tilt_deg))
    X = setup.board_points()
    ok[ok] = _in_view(setup, T_cw[ok], X[-4:])  # the printed corners first: cheap
    ok[ok] = _in_view(setup, T_cw[ok], X)  # then every feature (a lens bends the edges)
    grid, pitch = _pitch_edges(setup.board)
    Gc = np.einsum("mij,kj->mki", T_cb[ok, :3, :3], grid) + T_cb[ok, None, :3, 3]
    uv = setup.camera.project(Gc)
    side_px = np.linalg.norm(uv - np.roll(uv, -1, axis=1), axis=-1)  # (m, 4)
    side_m = np.linalg.norm(grid - np.roll(grid, -1, axis=0), axis=-1)  # (4,)
    has = side_m > 1e-9  # a one-row grid has two sides of zero length
    ok[ok] = (side_px[:, has] / side_m[has] * pitch).min(axis=1) >= rule.min_pitch_px
    return ok


def _off_board(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m,) bool: no point of the chain inside the board's plate grown by the capsule radius
    and clearance."""
    pts = chain_samples(setup.chain, q)  # base frame
    T_bb = inv_pose(setup.T_base_board)
    Pb = pts @ T_bb[:3, :3].T + T_bb[:3, 3]
    x0, y0, x1, y1 = setup.board.image(1.0).extent_m
    g = setup.chain.radius_m + setup.chain.clearance_m
    lo, hi = np.array([x0 - g, y0 - g, -g]), np.array([x1 + g, y1 + g, 0.01 + g])
    return ~np.all((Pb > lo) & (Pb < hi), axis=-1).any(axis=1)


def feasible(setup: PlanSetup, q: np.ndarray) -> np.ndarray:
    """(m,) bool: which postures ``q`` (m, n) rad are candidates (module docstring)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    r = setup.robot
    ok = np.all((q >= r.limits[:, 0]) & (q <= r.limits[:, 1]), axis=1)
    checks = (
        lambda x: board_views_ok(setup, fk_tool(setup.model_cam, x)),
        setup.chain.ok,
        lambda x: outside_boxes(setup.chain, x, setup.boxes),
        lambda x: _off_board(setup, x),
    )
    for check in checks:
        if not ok.any():
            break
        ok[ok] = check(q[ok])
    return ok


def _window(robot: RobotDef, centre: np.ndarray, span: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.maximum(robot.limits[:, 0], centre - span)
    hi = np.minimum(robot.limits[:, 1], centre + span)
    return lo, hi


def _check_within_reach(setup: PlanSetup) -> None:
    """Refuse at once a board no camera on the arm can see large enough: farther from the base
    than the chain's length plus the distance at which one feature pitch spans
    :attr:`ViewRule.min_pitch_px` (a pinhole's ``fx pitch / px``)."""
    P = setup.chain.points(setup.robot.home[None])[0]
    reach = float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
    reach += float(np.linalg.norm(setup.robot.T_flange_cam[:3, 3]))
    _, pitch = _pitch_edges(setup.board)
    fx = float(dict(zip(setup.camera.names, setup.camera.values()))["fx"])
    far = fx * pitch / setup.rule.min_pitch_px
    centre = setup.board_points()[-4:].mean(axis=0)
    if np.linalg.norm(centre) > reach + far:
        raise InputError(
            f"the board's centre is {np.linalg.norm(centre) * 1000:.0f} mm from {setup.robot.name}'s "
            f"base, beyond its reach ({reach * 1000:.0f} mm) plus the farthest the camera sees a "
            f"feature pitch of {setup.rule.min_pitch_px:g} px ({far * 1000:.0f} mm): no posture "
            "sees the whole board",
            fix="check --board-pose (the centre of the printed board in the base frame, mm)",
        )


def candidate_pool(
    setup: PlanSetup, n: int, *, seed: int, batch: int = 4096, max_draws: int = 400_000
) -> tuple[np.ndarray, str]:
    """Up to ``n`` candidate postures (m, dof) rad in random order (deterministic for a seed)
    and where they were drawn (``"home window"``, ``"joint ranges"``); at least one.

    Raises:
        InputError: no posture of ``max_draws`` sees the board as asked.
    """
    rng = np.random.default_rng(seed)
    r = setup.robot
    _check_within_reach(setup)
    lo, hi = _window(r, r.home, r.planning_span)
    found: list[np.ndarray] = []
    drawn, where = 0, "home window"
    wide = (np.maximum(r.limits[:, 0], -np.pi), np.minimum(r.limits[:, 1], np.pi))
    while sum(map(len, found)) < n and drawn < max_draws:
        if where == "home window" and drawn >= max_draws // 4 and sum(map(len, found)) < n // 4:
            where = "joint ranges"  # the board lies away from where home looks
        if where == "home window" or not sum(map(len, found)):
            a, b = (lo, hi) if where == "home window" else wide
            q = rng.uniform(a, b, size=(batch, r.n))
        else:  # around the candidates found so far, within the planning window's spans
            seeds = np.concatenate(found)
            c = seeds[rng.integers(len(seeds), size=batch)]
            q = np.clip(c + rng.uniform(-1, 1, size=c.shape) * r.planning_span,
                        r.limits[:, 0], r.limits[:, 1])  # fmt: skip
        drawn += batch
        found.append(q[feasible(setup, q)])
    pool = np.concatenate(found)[:n]
    if not len(pool):
        raise InputError(
            f"none of {drawn} postures of {r.name} sees the whole board within the image "
            f"(margin {setup.rule.margin_px:g} px, board normal within "
            f"{setup.rule.max_tilt_deg:g} deg of the optical axis, a feature pitch of at least "
            f"{setup.rule.min_pitch_px:g} px) without collision",
            fix="check --board-pose (the centre of the printed board in the base frame, mm) and "
            "the camera (--camera or --fov-deg/--resolution); a board too large for the view at a "
            "working distance needs a wider lens, one too small a closer approach",
        )
    return pool, where
