"""Eye-to-hand in simulation: one camera static in the cell, a board of known geometry on the flange.

The true robot is the nominal chain with its minimal parameters perturbed
(:func:`selfcal.sim.actual.perturb`) and the board as its tool: ``actual`` (world = the robot's
base frame, tool = the board frame, m). The cell's home (:func:`cell_home`) is the robot's home
with the wrist turned so that the board faces the cell rather than the table; the camera looks
at the board's printed face there, on the nominal robot, from ``distance_m`` along its normal
(camera axes = board axes: the board shows upright; where a person would set it up, so a plan
from the nominal cell serves the true one), so ``T_cam_board(q) = inv(T_base_cam) @ fk_tool(actual, q)``. Postures are drawn
around the cell's home (:func:`plan_static_postures`: arm configurations, each with several wrist
orientations) and kept when the camera sees the whole board. The features are projected
analytically (:func:`project_views`, :func:`selfcal.sim.analytic.project_board`) or rendered with
MuJoCo (:class:`StaticCameraRenderer`: the robot of :mod:`selfcal.sim.robot_mjcf` with the board
tile on its last link and one fixed camera in the world).

Truth stays here (:class:`StaticCameraTruth`): what a calibration is compared with, never given
to it. SI units; OpenCV camera frame and pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from selfcal.camera import CameraModel, Pinhole
from selfcal.errors import InputError, UsageTypeError
from selfcal.io.target_toml import target_document
from selfcal.io.truth import Truth
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.definition import RobotDef
from selfcal.robot.interface import StereoPair
from selfcal.sim.actual import make_truth, perturb
from selfcal.sim.analytic import project_board
from selfcal.sim.board_scene import add_board
from selfcal.sim.kinematic_robot import KinematicRobot
from selfcal.sim.lens import source_pinhole
from selfcal.sim.mj_camera import add_camera
from selfcal.sim.render import StereoRenderer
from selfcal.sim.robot_mjcf import RigConfig, scene_with_robot
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.target.placement import board_on_flange
from selfcal.transforms import inv_pose, make_pose

__all__ = [
    "CONFIGURATION_DRAWS",
    "POSTURE_DRAWS",
    "STATIC_CAMERA",
    "StaticCameraTruth",
    "StaticCameraRenderer",
    "StaticCameraRobot",
    "board_on_flange",
    "cell_home",
    "static_camera_truth",
    "plan_static_postures",
    "project_views",
    "rendered_views",
]

STATIC_CAMERA = "cam_static"
"""The MuJoCo name of the static camera."""

_FLIP_X = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class StaticCameraTruth:
    """The simulated eye-to-hand cell: ``robot``; ``actual`` the true chain (world = base,
    tool = board); ``T_base_cam`` the camera's pose (OpenCV frame -> base, m); ``camera`` the
    true camera; ``board``; ``T_flange_board_nominal`` the mount as drawn (no error); ``home``
    (n,) rad the posture the camera was set up at (:func:`cell_home`)."""

    robot: RobotDef
    actual: MCPCModel
    T_base_cam: np.ndarray
    camera: CameraModel
    board: Board
    T_flange_board_nominal: np.ndarray
    home: np.ndarray

    def chain(self) -> MCPCModel:
        """The true chain as the calibration writes it: world = the camera, tool = the board."""
        return self.actual.with_base(inv_pose(self.T_base_cam))

    def T_cam_board(self, q: np.ndarray) -> np.ndarray:
        """(m, 4, 4) the board's true pose in the camera frame at the true joints ``q`` (m, n)."""
        return fk_tool(self.chain(), np.atleast_2d(q))


def _camera_pose(chain: MCPCModel, board: Board, q: np.ndarray, distance_m: float) -> np.ndarray:
    """``T_base_cam`` of a camera ``distance_m`` in front of the board's printed face at ``q``,
    its axes the board's (``chain``: world = base, tool = the board)."""
    T = fk_tool(chain, q[None])[0]
    _, pts = board.layout()
    centre = T[:3, :3] @ ((pts.min(axis=0) + pts.max(axis=0)) / 2) + T[:3, 3]
    return make_pose(T[:3, :3], centre - distance_m * T[:3, 2])


def cell_home(robot: RobotDef, chain: MCPCModel, board: Board, distance_m: float) -> np.ndarray:
    """(n,) rad: the robot's home with the wrist's first two joints (the 4th and 5th of a
    6-axis arm; none of an arm of four joints or fewer) turned by 0 or +-90 deg each: of the
    turns within the joint ranges whose camera (:func:`_camera_pose`) stands above the table
    (z > 0.05 m), the one whose board faces most directly away from the base's axis (the camera
    outside the arm's reach, the arm behind the board); without such a turn the one with the
    highest camera. ``chain``: world = base, tool = the board."""
    n = robot.n
    turns = [np.zeros(n)]
    if n - 3 >= 2:  # a wrist of three joints after an arm of two or more
        for a in (0.0, -90.0, 90.0):
            for b in (0.0, -90.0, 90.0):
                d = np.zeros(n)
                d[n - 3], d[n - 2] = np.radians(a), np.radians(b)
                turns.append(d)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    homes = [robot.home + d for d in turns
             if np.all((robot.home + d >= lo) & (robot.home + d <= hi))]  # fmt: skip
    height, outward = [], []
    for q in homes:
        T = fk_tool(chain, q[None])[0]
        radial = np.r_[T[:2, 3], 0.0] / max(float(np.linalg.norm(T[:2, 3])), 1e-9)
        outward.append(float(-T[:3, 2] @ radial))
        height.append(_camera_pose(chain, board, q, distance_m)[2, 3])
    above = np.array(height) > 0.05
    if not above.any():
        return homes[int(np.argmax(height))].astype(float)
    return homes[int(np.argmax(np.where(above, outward, -np.inf)))].astype(float)


def static_camera_truth(
    robot: RobotDef,
    board: Board,
    camera: CameraModel,
    *,
    distance_m: float = 0.6,
    seed: int = 0,
    translation_m: float = 0.001,
    rotation_rad: float = np.radians(0.1),
) -> StaticCameraTruth:
    """The cell of the module docstring: the nominal chain with ``board`` on the flange
    (:func:`board_on_flange`), every minimal parameter (board mount included) perturbed by up
    to ``translation_m`` / ``rotation_rad`` (seeded), and ``camera`` at ``distance_m`` in front
    of the board's printed face at the home posture."""
    T_fb = board_on_flange(board)
    actual = perturb(nominal_mcpc(robot).with_tool(T_fb), seed=seed,
                     translation_m=translation_m, rotation_rad=rotation_rad)  # fmt: skip
    nominal = nominal_mcpc(robot).with_tool(T_fb)
    home = cell_home(robot, nominal, board, distance_m)
    T_base_cam = _camera_pose(nominal, board, home, distance_m)
    return StaticCameraTruth(robot, actual, T_base_cam, camera, board, T_fb, home)


def _sees_board(truth: StaticCameraTruth, q: np.ndarray) -> bool:
    T_bc = truth.T_base_cam
    return len(project_board(T_bc, truth.camera, truth.board, fk_tool(truth.actual, q[None])[0])) \
        == truth.board.n_features  # fmt: skip


CONFIGURATION_DRAWS = 50
"""Arm configurations :func:`plan_static_postures` draws for one of the plan before it gives
up: a draw near the edge of the arm's window can carry the board out of the camera's view at
every wrist orientation (the UR5e's cell at trajectory seeds 6 and 29: its shoulder and elbow
both +7 deg, 50 of the board's 88 corners in view); it is drawn again."""

POSTURE_DRAWS = 200
"""Wrist orientations :func:`plan_static_postures` draws for one posture of a configuration
before it draws the configuration again."""


def plan_static_postures(
    truth: StaticCameraTruth,
    configurations: int,
    per_configuration: int,
    *,
    arm_deg: float = 8.0,
    wrist_deg: float = 20.0,
    seed: int = 0,
) -> np.ndarray:
    """(configurations * per_configuration, n) rad: joint vectors around the cell's home
    (``truth.home``), the arm joints
    (all but the last three) drawn within ``arm_deg`` once per configuration and the wrist's
    last three within ``wrist_deg`` per posture, each kept when the camera sees every feature
    of the board (within the joint ranges). A configuration where one of its postures finds no
    such wrist orientation in :data:`POSTURE_DRAWS` draws (the arm carried the board out of
    view) is dropped with its postures and drawn again, up to :data:`CONFIGURATION_DRAWS`
    draws per configuration kept. Deterministic for ``seed``.

    Raises:
        InputError: no configuration found in :data:`CONFIGURATION_DRAWS` draws (a camera
            that cannot see the board around the cell's home), naming what was tried.
    """
    robot = truth.robot
    rng = np.random.default_rng(seed)
    n = robot.n
    arm = np.arange(n) < max(n - 3, 0) if n > 3 else np.ones(n, bool)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]

    def configuration() -> list[np.ndarray] | None:
        """One configuration's postures, or None when one of them finds no view."""
        base = truth.home.astype(float).copy()
        base[arm] += np.radians(rng.uniform(-arm_deg, arm_deg, int(arm.sum())))
        got = []
        for _ in range(per_configuration):
            for _ in range(POSTURE_DRAWS):
                q = base.copy()
                q[~arm] += np.radians(rng.uniform(-wrist_deg, wrist_deg, int((~arm).sum())))
                if np.all((q >= lo) & (q <= hi)) and _sees_board(truth, q):
                    got.append(q)
                    break
            else:
                return None
        return got

    out: list[np.ndarray] = []
    for k in range(configurations):
        for _ in range(CONFIGURATION_DRAWS):
            got = configuration()
            if got is not None:
                out += got
                break
        else:
            raise InputError(
                f"no posture around home shows the whole board to the camera: configuration "
                f"{k + 1} of {configurations} found none in {CONFIGURATION_DRAWS} draws of the arm "
                f"joints within {arm_deg:g} deg of the cell's home, each with up to "
                f"{POSTURE_DRAWS} wrist orientations within {wrist_deg:g} deg",
                fix="a larger camera image or focal length, or a smaller board",
            )
    return np.array(out)


def project_views(
    truth: StaticCameraTruth,
    q: np.ndarray,
    pixel_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
) -> list[Features]:
    """The board's features (px) in the camera at the true joints ``q`` (m, n) rad, projected
    analytically with Gaussian noise ``pixel_sigma`` px per coordinate (``rng`` for it)."""
    out = []
    for T in fk_tool(truth.actual, np.atleast_2d(q)):
        seen = project_board(truth.T_base_cam, truth.camera, truth.board, T,
                             pixel_sigma=pixel_sigma, rng=rng)  # fmt: skip
        ids = np.array(sorted(seen), dtype=np.int64)
        out.append(Features(ids, np.array([seen[i][0] for i in ids.tolist()]).reshape(-1, 2)))
    return out


class StaticCameraRenderer:
    """MuJoCo images of the cell (module docstring): the true robot with the board tile on its
    last link and the camera fixed in the world; :meth:`render` gives the camera's RGB image at
    joints ``q`` (n,) rad. The robot model's wrist rig (its cameras unused) sits behind the
    board, turned away from the camera. Close it (or use ``with``)."""

    def __init__(self, truth: StaticCameraTruth, *, offsamples: int = 4):
        if not isinstance(truth.camera, Pinhole):
            raise UsageTypeError("the static camera must be a camera model of selfcal.camera")
        T_board_rig = make_pose(_FLIP_X, np.array([0.0, 0.0, 0.03]))  # behind the board
        W, H = truth.camera.width, truth.camera.height
        rig = RigConfig(intrinsics=Pinhole.centered(500.0, 1.0, W, H))
        spec = scene_with_robot(truth.robot, truth.actual.with_tool(T_board_rig), rig, None,
                                offsamples=offsamples)  # fmt: skip
        rig_body = next(b for b in spec.bodies if b.name == "rig")
        add_board(spec, truth.board, inv_pose(T_board_rig), body=rig_body)
        add_camera(spec.worldbody, STATIC_CAMERA, truth.camera, truth.T_base_cam)
        g, src = spec.visual.global_, source_pinhole(truth.camera)  # a lens renders larger
        g.offwidth, g.offheight = max(int(g.offwidth), src.width), max(int(g.offheight), src.height)
        self.truth = truth
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._renderer = StereoRenderer(self.model, W, H, camera_names=(STATIC_CAMERA,),
                                        lenses=(truth.camera,))  # fmt: skip

    def render(self, q: np.ndarray, image_sigma: float = 0.0,
               rng: np.random.Generator | None = None) -> np.ndarray:  # fmt: skip
        """The camera's image (H, W, 3) uint8 at the true joints ``q`` (n,) rad, with Gaussian
        intensity noise ``image_sigma`` (grey levels; ``rng`` for it)."""
        n = self.truth.robot.n
        self.data.qpos[:n] = np.asarray(q, dtype=float)
        mujoco.mj_forward(self.model, self.data)
        return self._renderer.render_all(self.data, image_sigma, rng)[0]

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> StaticCameraRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def rendered_views(truth: StaticCameraTruth, q: Sequence[np.ndarray],
                   image_sigma: float = 0.0, seed: int = 0) -> list[np.ndarray]:  # fmt: skip
    """The camera's images at the true joints ``q`` (:class:`StaticCameraRenderer`)."""
    rng = np.random.default_rng(seed)
    with StaticCameraRenderer(truth) as r:
        return [r.render(qi, image_sigma, rng) for qi in q]


class StaticCameraRobot(KinematicRobot):
    """The simulated eye-to-hand cell as a robot to acquire with
    (:func:`selfcal.acquisition.acquire.acquire`): the arm of ``truth`` with the board on its
    flange (joint read-back quantised as :class:`selfcal.sim.kinematic_robot.KinematicRobot`'s),
    :meth:`capture` the static camera's MuJoCo image (``render``; the pair's both images are
    it) with Gaussian intensity noise ``image_sigma`` (``seed``), :meth:`truth_frame` and
    :meth:`truth` the ground truth: the camera's pose as ``T_world_cam_left`` (world = the
    robot's base), the board's origin as ``tool_tip_m``, the chains with the board as tool and
    ``board`` = ``{"target", "setup": "eye-to-hand", "T_world_cam", "T_flange_board"}``."""

    def __init__(self, truth: StaticCameraTruth, *, quantize: bool = True, render: bool = True,
                 image_sigma: float = 0.0, seed: int = 0, offsamples: int = 4):  # fmt: skip
        if not isinstance(truth.camera, Pinhole):
            raise UsageTypeError("the static camera must be a camera model of selfcal.camera")
        super().__init__(truth.robot, truth.actual, RigConfig(intrinsics=truth.camera),
                         quantize=quantize)  # fmt: skip
        self.field = None  # the cell has a board (on the flange), no marker field
        self.static = truth
        self.image_sigma = float(image_sigma)
        self._rng = np.random.default_rng(seed)
        self._renderer = StaticCameraRenderer(truth, offsamples=offsamples) if render else None
        self._n = 0

    def capture(self) -> StereoPair:
        """The static camera's image at the current posture (uint8 RGB, H x W x 3)."""
        self._check_open()
        if self._renderer is None:
            return super().capture()  # raises: the analytic path renders nothing
        img = self._renderer.render(self.true_joints(), self.image_sigma, self._rng)
        meta = {"index": self._n, "joints_deg": self.joints().tolist()}
        self._n += 1
        return StereoPair(left=img, right=img, meta=meta)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()

    def truth_frame(self) -> dict:
        q = self.true_joints()
        T = self.static.T_base_cam
        return {"joints_rad": q, "joints_deg": q / self._unit, "T_world_cam_left": T.copy(),
                "T_world_cam_right": T.copy(),
                "tool_tip_m": fk_tool(self.actual, q[None])[0, :3, 3]}  # fmt: skip

    def truth(self, meta: dict | None = None) -> Truth:
        st = self.static
        nominal = nominal_mcpc(st.robot).with_tool(st.T_flange_board_nominal)
        truth = make_truth(st.robot, nominal, st.actual, self.rig, self.field,
                           {"image_sigma": self.image_sigma, **(meta or {})})  # fmt: skip
        doc = {"target": target_document(st.board), "setup": "eye-to-hand",
               "T_world_cam": st.T_base_cam, "T_flange_board": truth.T_flange_cam}  # fmt: skip
        return replace(truth, board=doc)
