"""The postures a recording plan may use: reachable, collision-free, and seeing the whole board
well (the candidate pool of :mod:`selfcal.calibration.board.plan.planner`); a drift check's
may see part of it (:attr:`ViewRule.min_corners`, :func:`seen_features`).

Two mounts (:class:`PlanSetup`): eye-in-hand (the camera on the flange, the board static in the
base frame) and eye-to-hand (the camera static in the base frame, the board on the flange). A
posture ``q`` (rad, within the robot file's joint ranges) is a candidate when

- the capsule chain (:class:`selfcal.kinematics.self_collision.CapsuleChain`, its tool the camera
  or the board) neither folds onto itself nor touches the table (the base frame's z = 0 plane),
  nor enters a keep-out box (:mod:`selfcal.kinematics.keep_out`) or the board's own plate
  (eye-in-hand); eye-to-hand the board's plate stays above the table and out of the keep-out
  boxes, the arm (but the wrist that holds the board) out of the plate and the arm
  :data:`CAMERA_CLEARANCE_M` from the static camera;
- either mount: no link of the arm and no keep-out box crosses the lines of sight from the
  camera to the board's printed image (:mod:`selfcal.calibration.board.plan.sight`);
- the nominal camera sees every feature of the board and every corner of its printed image
  inside the image with :attr:`ViewRule.margin_px` to spare, at least
  :attr:`ViewRule.min_depth_m` in front of it;
- the board faces the camera: the angle between the optical axis and the board's normal (into
  the board) is at most :attr:`ViewRule.max_tilt_deg` (beyond it the far squares foreshorten
  past what the corner detectors handle);
- the board is large enough in the image: one feature pitch (the closest two features) spans at
  least :attr:`ViewRule.min_pitch_px` along each edge of the feature grid, and (a board with
  markers) one cell of its markers spans at least :attr:`ViewRule.min_module_px` at every
  feature in the direction the view foreshortens most (:func:`module_m`): measured on rendered
  plans of the three simulated robots (docs/plan.md), the ChArUco detector lost 0.1 - 2 % of
  the corners whose cell spanned 1.6 - 2.4 px and none at 2.5 px and more.

Eye-to-hand asks a longer pitch and a smaller tilt and no marker cell size
(:data:`EYE_TO_HAND_RULE`, measured on rendered replays).

Candidates are drawn uniformly in the robot file's planning window around home
(``[planning] span_deg``); when too few lie there (a board far from where home looks), in the
whole joint ranges (wrapped to +-180 deg), then in the planning window around the candidates
found so far. Units: m, rad, px.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.board.plan.sight import sight_clear, sight_grid
from selfcal.camera import CameraModel
from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.keep_out import SAMPLES, chain_samples, outside_boxes
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.robot.definition import RobotDef
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = [
    "CAMERA_CLEARANCE_M",
    "EYE_TO_HAND_RULE",
    "ViewRule",
    "PlanSetup",
    "board_views_ok",
    "module_m",
    "seen_features",
    "feasible",
    "candidate_pool",
]

CAMERA_CLEARANCE_M = 0.08
"""Eye-to-hand: no sample of the arm's capsule chain comes nearer the static camera's centre than
this plus the capsule radius (the camera's body, m)."""


@dataclass(frozen=True)
class ViewRule:
    """What a planned view asks of the board (module docstring)."""

    margin_px: float = 12.0
    min_depth_m: float = 0.05
    max_tilt_deg: float = 60.0
    min_pitch_px: float = 12.0
    min_module_px: float = 2.5
    min_corners: int = 0
    """0: the whole board in view (a plan's rule). Otherwise a view of part of the board counts
    when at least this many features are seen (:func:`seen_features`) and they span
    :attr:`min_spread` of the image (a drift check's views, :mod:`selfcal.calibration.drift.
    choose`); a board whose detector finds the whole grid or nothing still needs every feature."""
    min_spread: float = 0.0
    """With :attr:`min_corners`: the share of the image's width and of its height the seen
    features' pixels span at least."""


EYE_TO_HAND_RULE = ViewRule(min_pitch_px=24.0, max_tilt_deg=45.0, min_module_px=0.0)
"""What an eye-to-hand view asks: a longer pitch and a smaller tilt than eye-in-hand's default.
Measured: rendered with MuJoCo and detected (the slow test of tests/integration/test_plan_cli.py),
a ChArUco on an arm's flange 0.5 - 0.9 m from a still camera lost corners in frames of a
13 - 21 px pitch at 34 - 59 deg (the markers' bits then span 1.4 - 2.2 px); the eye-in-hand
plans' candidates stay within 36 deg."""


@dataclass(frozen=True, eq=False)
class PlanSetup:
    """One arm, one camera, one board. Eye-in-hand: ``robot``'s ``T_flange_cam`` places the
    camera on the flange and the ``board`` is static at ``T_base_board`` (board -> base, m).
    Eye-to-hand (``T_base_cam`` given: the camera static, OpenCV frame -> base, m): the board
    rides on the flange at ``T_flange_board`` (board -> flange, m) and ``T_base_board`` is not
    used (:meth:`eye_to_hand_setup`). ``camera`` the nominal camera, keep-out ``boxes`` (b, 6) m
    in the base frame, the view ``rule``."""

    robot: RobotDef
    camera: CameraModel
    board: Board
    T_base_board: np.ndarray
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    rule: ViewRule = field(default_factory=ViewRule)
    T_base_cam: np.ndarray | None = None
    T_flange_board: np.ndarray | None = None

    @classmethod
    def eye_to_hand_setup(cls, robot: RobotDef, camera: CameraModel, board: Board,
                          T_base_cam: np.ndarray, T_flange_board: np.ndarray,
                          boxes: np.ndarray | None = None) -> PlanSetup:  # fmt: skip
        """The eye-to-hand cell: the camera static at ``T_base_cam`` (4, 4, m), the board on
        the flange at ``T_flange_board`` (4, 4, m)."""
        return cls(robot, camera, board, np.full((4, 4), np.nan),
                   np.zeros((0, 6)) if boxes is None else np.asarray(boxes, dtype=float),
                   rule=EYE_TO_HAND_RULE, T_base_cam=np.asarray(T_base_cam, dtype=float),
                   T_flange_board=np.asarray(T_flange_board, dtype=float))  # fmt: skip

    @property
    def eye_to_hand(self) -> bool:
        """True when the camera is static and the board rides on the flange."""
        return self.T_base_cam is not None

    @property
    def T_flange_tool(self) -> np.ndarray:
        """What rides on the flange (4, 4, m): the camera (eye-in-hand) or the board."""
        if self.T_flange_board is not None:
            return self.T_flange_board
        return self.robot.T_flange_cam

    @property
    def model_cam(self) -> MCPCModel:
        """The nominal chain base -> camera (OpenCV frame; eye-in-hand)."""
        return nominal_mcpc(self.robot).with_tool(self.robot.T_flange_cam)

    @property
    def model_tool(self) -> MCPCModel:
        """The nominal chain base -> what rides on the flange (the camera or the board)."""
        return nominal_mcpc(self.robot).with_tool(self.T_flange_tool)

    @property
    def chain(self) -> CapsuleChain:
        """The self-collision and table check of the nominal arm with its camera or board."""
        return CapsuleChain(nominal_mcpc(self.robot), self.T_flange_tool)

    def calibration_model(self) -> MCPCModel:
        """The nominal chain the board calibration fits: eye-in-hand world = the board, tool =
        the camera; eye-to-hand world = the camera, tool = the board
        (:class:`selfcal.estimation.kinematic_poses.KinematicPoses`)."""
        if self.T_base_cam is not None:
            return self.model_tool.with_base(inv_pose(self.T_base_cam))
        return self.model_cam.with_base(inv_pose(self.T_base_board))

    def T_cam_board(self, q: np.ndarray) -> np.ndarray:
        """(m, 4, 4) board -> camera at the nominal joints ``q`` (m, n) rad."""
        T = fk_tool(self.calibration_model(), np.atleast_2d(np.asarray(q, dtype=float)))
        return T if self.eye_to_hand else inv_pose(T)

    @property
    def T_tool_tip(self) -> np.ndarray:
        """The tool point the plan predicts, the flange's origin, in the chain's tool frame
        (the camera's or the board's, 4 x 4)."""
        return inv_pose(self.T_flange_tool)

    def board_points(self) -> np.ndarray:
        """(k + 4, 3) the board's features and its printed image's corners (board frame, m)."""
        _, pts = self.board.layout()
        x0, y0, x1, y1 = self.board.image(1.0).extent_m
        corners = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], dtype=float)
        return np.concatenate([pts, corners])


def _pitch_edges(board: Board) -> tuple[np.ndarray, float]:
    """The feature grid's four extreme corners (4, 3) (board frame, m; in order around the grid)
    and the pitch (m): the smallest distance between two features."""
    _, pts = board.layout()
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    d[np.diag_indices(len(pts))] = np.inf
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    grid = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]])
    return grid, float(d.min())


def _in_view(setup: PlanSetup, T_cam_board: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(m,) bool: every point ``X`` (k, 3) board frame m projected by the camera model beyond
    the rule's least depth and inside the image."""
    return np.asarray(_points_in_view(setup, T_cam_board, X).all(axis=1))


def _points_in_view(setup: PlanSetup, T_cam_board: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(m, k) bool: which points ``X`` (k, 3) board frame m the camera model projects beyond the
    rule's least depth and inside the image with its margin."""
    rule, cam = setup.rule, setup.camera
    Xc = np.einsum("mij,kj->mki", T_cam_board[:, :3, :3], X) + T_cam_board[:, None, :3, 3]
    ok = cam.valid(Xc) & (cam.depth(Xc) > rule.min_depth_m)
    return ok & cam.in_image(cam.project_valid(Xc)[0], rule.margin_px)


def board_views_ok(setup: PlanSetup, T_cam_board: np.ndarray) -> np.ndarray:
    """(m,) bool: which board poses in the camera frame ``T_cam_board`` (m, 4, 4; board ->
    camera, m) show the board as the module docstring asks."""
    T_cb = np.asarray(T_cam_board, dtype=float).reshape(-1, 4, 4)
    rule = setup.rule
    if rule.min_corners > 0 and not setup.board.whole_grid:
        return _part_ok(setup, T_cb)
    # the optical axis against the board's normal (board z, into the board) in the camera frame
    ok = T_cb[:, 2, 2] >= np.cos(np.radians(rule.max_tilt_deg))
    X = setup.board_points()
    ok[ok] = _in_view(setup, T_cb[ok], X[-4:])  # the printed corners first: cheap
    grid, pitch = _pitch_edges(setup.board)
    module = module_m(setup.board) if rule.min_module_px > 0 else None
    if module is not None:  # the feature grid's corners first (most views fail there): cheap
        ok[ok] = _module_px(setup, T_cb[ok], grid, module) >= rule.min_module_px
    ok[ok] = _in_view(setup, T_cb[ok], X)  # then every feature (a lens bends the edges)
    Gc = np.einsum("mij,kj->mki", T_cb[ok, :3, :3], grid) + T_cb[ok, None, :3, 3]
    uv = setup.camera.project(Gc)
    side_px = np.linalg.norm(uv - np.roll(uv, -1, axis=1), axis=-1)  # (m, 4)
    side_m = np.linalg.norm(grid - np.roll(grid, -1, axis=0), axis=-1)  # (4,)
    has = side_m > 1e-9  # a one-row grid has two sides of zero length
    ok[ok] = (side_px[:, has] / side_m[has] * pitch).min(axis=1) >= rule.min_pitch_px
    if module is not None and ok.any():  # at every feature
        ok[ok] = _module_px(setup, T_cb[ok], X[:-4], module) >= rule.min_module_px
    return ok


def seen_features(setup: PlanSetup, T_cam_board: np.ndarray) -> np.ndarray:
    """(m, k) bool: which of the board's features (its layout's order) the views ``T_cam_board``
    (m, 4, 4; board -> camera, m) count as seen. The whole-board rule (:attr:`ViewRule.
    min_corners` 0, or a board whose detector finds every feature or none): every feature of a
    view :func:`board_views_ok` passes. A view of part of the board: the board within the
    rule's tilt, and per feature the square cells about it (one feature pitch each way: OpenCV
    returns a ChArUco corner only with ``CharucoParameters.minMarkers``, default 2, of the
    markers beside it found, the two in those cells)
    inside the image with the rule's margin beyond its least depth, one pitch at least
    :attr:`ViewRule.min_pitch_px` and one marker cell :attr:`ViewRule.min_module_px` at the
    feature in the direction the view foreshortens most."""
    T_cb = np.asarray(T_cam_board, dtype=float).reshape(-1, 4, 4)
    rule, board = setup.rule, setup.board
    n = len(board.layout()[1])
    if rule.min_corners <= 0 or board.whole_grid:
        return np.repeat(board_views_ok(setup, T_cb)[:, None], n, axis=1)
    out = np.zeros((len(T_cb), n), bool)
    tilt = T_cb[:, 2, 2] >= np.cos(np.radians(rule.max_tilt_deg))
    out[tilt] = _seen(setup, T_cb[tilt])
    return out


def _seen(setup: PlanSetup, T_cb: np.ndarray) -> np.ndarray:
    """(m, k) bool: :func:`seen_features` of a view of part of the board, its tilt passed."""
    rule, board = setup.rule, setup.board
    _, X = board.layout()
    _, pitch = _pitch_edges(board)
    ok = _points_in_view(setup, T_cb, X)
    for dx, dy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):  # the cells about each feature
        ok &= _points_in_view(setup, T_cb, X + pitch * np.array([dx, dy, 0.0]))
    ok &= _cell_px(setup, T_cb, X, pitch) >= rule.min_pitch_px
    module = module_m(board) if rule.min_module_px > 0 else None
    if module is not None:
        ok &= _cell_px(setup, T_cb, X, module) >= rule.min_module_px
    return ok


def _part_ok(setup: PlanSetup, T_cb: np.ndarray) -> np.ndarray:
    """(m,) bool: views of part of the board with :attr:`ViewRule.min_corners` features seen,
    their pixels spanning :attr:`ViewRule.min_spread` of the image each way."""
    seen = seen_features(setup, T_cb)
    ok = seen.sum(axis=1) >= setup.rule.min_corners
    if ok.any() and setup.rule.min_spread > 0:
        _, X = setup.board.layout()
        Xc = np.einsum("mij,kj->mki", T_cb[ok, :3, :3], X) + T_cb[ok, None, :3, 3]
        uv = setup.camera.project(Xc)  # (m, k, 2)
        m = seen[ok][..., None]
        span = np.where(m, uv, -np.inf).max(axis=1) - np.where(m, uv, np.inf).min(axis=1)
        size = np.array([setup.camera.width, setup.camera.height], float)
        ok[ok] = np.all(span >= setup.rule.min_spread * size, axis=1)
    return ok


def _module_words(setup: PlanSetup) -> str:
    """The marker cell rule for a message ("" for a board without markers)."""
    module = module_m(setup.board)
    if module is None or setup.rule.min_module_px <= 0:
        return ""
    return (
        f", every cell of its {module * 1000:.2f} mm marker cells at least "
        f"{setup.rule.min_module_px:g} px across"
    )


def module_m(board: Board) -> float | None:
    """The side of one cell of the board's markers (m): a ChArUco's marker or an AprilGrid's
    tag over its bits plus their black border (``markerSize + 2``); None for a board without
    markers (a chessboard, a circles grid)."""
    cv_board = getattr(board, "cv_board", None)
    if cv_board is None:
        return None
    b = cv_board()
    length = b.getMarkerLength() if hasattr(b, "getMarkerLength") else None
    if length is None:
        return None
    return float(length) / (b.getDictionary().markerSize + 2)


def _module_px(setup: PlanSetup, T_cb: np.ndarray, X: np.ndarray, module: float) -> np.ndarray:
    """(m,) the shortest image length (px) of one marker cell ``module`` (m) over the board
    points ``X`` (k, 3) (:func:`_cell_px`)."""
    return _cell_px(setup, T_cb, X, module).min(axis=1)


def _cell_px(setup: PlanSetup, T_cb: np.ndarray, X: np.ndarray, length: float) -> np.ndarray:
    """(m, k) the image length (px) of ``length`` (m) on the board at each point ``X`` (k, 3):
    the smaller singular value of the projection's derivative along the board's plane (px per
    m) times ``length``, so a board turned about any axis counts its foreshortened direction."""
    R = T_cb[:, :3, :3]
    Xc = np.einsum("mij,kj->mki", R, X) + T_cb[:, None, :3, 3]
    _, J_uv_X, _ = setup.camera.project_jacobians(Xc)  # (m, k, 2, 3) px per m
    J = J_uv_X @ R[:, None, :, :2]  # along the board's x and y axes: (m, k, 2, 2)
    return np.linalg.svd(J, compute_uv=False)[..., -1] * length


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


def _tally(setup: PlanSetup, q: np.ndarray, where: str) -> str:
    """Which rule the postures ``q`` (m, n) rad, drawn ``where``, fail: how many pass each rule
    and those before it, up to the first no posture passes."""
    counts = ", ".join(f"{int(ok.sum())} {what}" for what, ok in _passing(setup, q))
    return f"of the last {len(q)} drawn ({where}): {counts}"


def _window(robot: RobotDef, centre: np.ndarray, span: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    _, pitch = _pitch_edges(setup.board)
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
            f"{setup.rule.min_pitch_px:g} px{_module_words(setup)}) without collision and with "
            f"the arm out of the camera's lines of sight ({_tally(setup, q, where)})",
            fix="check --board-pose (the centre of the printed board in the base frame, mm) or "
            "--camera-pose and the camera (--camera or --fov-deg/--resolution); a board too large for the view at a "
            "working distance needs a wider lens, one too small (or its markers) a closer "
            "approach, a longer lens, more pixels or larger markers",
        )
    return pool, where
