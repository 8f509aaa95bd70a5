"""What a planned view sees of the board: the cell (:class:`PlanSetup`: arm, camera, board and
either mount) and its view rule (:class:`ViewRule`), which views show the whole board well
(:func:`board_views_ok`: the recording plan's) and which features a view of part of it sees
(:attr:`ViewRule.min_corners`, :func:`seen_features`: a drift check's). Which postures are
candidates (these views, clear of collision and the lines of sight):
:mod:`selfcal.calibration.board.plan.feasible`; drawing them:
:mod:`selfcal.calibration.board.plan.candidates`.

Two mounts (:class:`PlanSetup`): eye-in-hand (the camera on the flange, the board static in the
base frame) and eye-to-hand (the camera static in the base frame, the board on the flange). A
view (the board's pose in the camera frame) passes when

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
(:data:`EYE_TO_HAND_RULE`, measured on rendered replays). Units: m, rad, px.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from selfcal.camera import CameraModel
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.robot.definition import RobotDef
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = [
    "EYE_TO_HAND_RULE",
    "ViewRule",
    "PlanSetup",
    "board_views_ok",
    "module_m",
    "module_words",
    "pitch_edges",
    "seen_features",
]


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


def pitch_edges(board: Board) -> tuple[np.ndarray, float]:
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
    grid, pitch = pitch_edges(setup.board)
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
    _, pitch = pitch_edges(board)
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


def module_words(setup: PlanSetup) -> str:
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
