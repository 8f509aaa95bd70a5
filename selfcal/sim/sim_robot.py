"""The simulated camera-equipped SCORBOT: ``selfcal.robot.interface.Robot`` backed by MuJoCo.

Kinematic simulation: a move sets the joint positions directly (no dynamics) and runs
``mj_forward``; the robot's geometry is the "actual" MCPC chain (``selfcal.sim.actual``), so the images
show the true robot while the joint read-back is what the encoders report (quantised to
``counts_per_deg`` of the robot's TOML). ``truth_frame()`` gives the ground truth of the current
posture for ``truth.json``.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import mujoco
import numpy as np

from selfcal.camera import Intrinsics
from selfcal.errors import InputError, InternalError
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.robot.definition import RobotDef
from selfcal.robot.interface import StereoPair
from selfcal.sim.board_scene import add_board
from selfcal.sim.compliance import JointMisfit
from selfcal.sim.kinematic_robot import KinematicRobot
from selfcal.sim.markers import MarkerField
from selfcal.sim.mj_camera import T_world_cam_cv
from selfcal.sim.render import StereoRenderer, apply_noise, noise_field
from selfcal.sim.robot_mjcf import CAMERA_NAMES, TOOL_SITE, RigConfig, scene_with_robot
from selfcal.target.boards import Board

__all__ = ["SimRobot"]


class SimRobot(KinematicRobot):
    """A simulated robot with a wrist stereo rig photographing a marker field.

    Args:
        model_name: nominal robot model (``models/<folder>/<name>.toml``), robot file or the
            loaded :class:`~selfcal.robot.definition.RobotDef`.
        actual: the simulated robot's MCPC chain, tool = left camera (default: nominal, i.e.
            ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)``); see ``selfcal.sim.actual.perturb``.
        rig: stereo rig (intrinsics, baseline); default ``RigConfig()``.
        field: marker field; default ``make_marker_field()`` (none with a ``board``).
        image_sigma: std of additive Gaussian image noise (grey levels, 0-255).
        seed: seed of the image-noise generator.
        quantize: report joints at encoder resolution (False: the exact angles, for noise-free
            regression tests).
        board: ``(board, T_world_board)``: a board of known geometry on the table instead of
            the marker field (``selfcal.sim.board_scene``; a ``field`` given too is left out of
            the scene), recorded in ``truth()`` under ``board``.
        msaa: multisample anti-aliasing samples of the renderer (0: off; None: the scene's, 4).
        compliance: the links stand at its bent joints (``KinematicRobot``'s ``compliance``).

    The noise of the next capture is drawn by a worker thread while the robot moves and renders
    (the draws are most of the noise's cost): the same draws from the same generator in the same
    order as drawing them inside :meth:`capture`, so the images are those of one seed whatever
    the timing.

    Starts at the home posture. Raises ``RobotDefinitionError`` for an unknown model name and
    ``ValueError`` if ``actual`` does not fit the robot.
    """

    def __init__(
        self,
        model_name: str | RobotDef,
        actual: MCPCModel | None = None,
        rig: RigConfig | None = None,
        field: MarkerField | None = None,
        image_sigma: float = 0.0,
        seed: int = 0,
        quantize: bool = True,
        msaa: int | None = None,
        board: tuple[Board, np.ndarray] | None = None,
        compliance: JointMisfit | None = None,
    ) -> None:
        if not image_sigma >= 0:
            raise InputError(f"image_sigma must be >= 0 (grey levels), got {image_sigma}")
        super().__init__(model_name, actual, rig, field, quantize, board, compliance)
        self.image_sigma = float(image_sigma)
        self._rng = np.random.default_rng(seed)
        scene_kw = {} if msaa is None else {"offsamples": int(msaa)}
        spec = scene_with_robot(
            self.robot, self.actual, self.rig, self.field, markers=board is None, **scene_kw
        )
        if board is not None:
            add_board(spec, board[0], board[1])
        self.mj_model = spec.compile()
        self.mj_data = mujoco.MjData(self.mj_model)
        self._renderer: StereoRenderer | None = None
        self._n_captures = 0
        self._noise_pool: ThreadPoolExecutor | None = None
        self._next_noise: Future | None = None  # the next capture's draws, (left, right)
        self.home()

    def _draw_noise(self, shapes: list[tuple[int, ...]]) -> list[np.ndarray]:
        return [noise_field(shape, self.image_sigma, self._rng) for shape in shapes]

    def _noise_ahead(self, shapes: list[tuple[int, ...]]) -> None:
        """Start drawing the next capture's noise fields on the worker thread."""
        if self._noise_pool is None:
            self._noise_pool = ThreadPoolExecutor(1, thread_name_prefix="image-noise")
        self._next_noise = self._noise_pool.submit(self._draw_noise, shapes)

    def _noise(self, shapes: list[tuple[int, ...]]) -> list[np.ndarray]:
        """This capture's noise fields (drawn ahead when possible) and the next one's started."""
        ahead, self._next_noise = self._next_noise, None
        z = ahead.result() if ahead is not None else self._draw_noise(shapes)
        if [f.shape for f in z] != shapes:  # pragma: no cover - one renderer, fixed sizes
            raise InternalError(f"noise drawn for images {[f.shape for f in z]}, got {shapes}")
        self._noise_ahead(shapes)
        return z

    def capture(self) -> StereoPair:
        """Render the stereo pair at the current posture (uint8 RGB, H x W x 3 each), with the
        configured Gaussian intensity noise."""
        self._check_open()
        if self._renderer is None:
            if self.image_sigma > 0:  # the first capture's noise is drawn while the renderer starts
                self._noise_ahead([(c.height, c.width, 3) for c in self._lenses()])
            self._renderer = StereoRenderer(
                self.mj_model,
                self.rig.intrinsics.width,
                self.rig.intrinsics.height,
                camera_names=CAMERA_NAMES,
                lenses=self._lenses(),
            )
        left, right = self._renderer.render(self.mj_data)
        if self.image_sigma > 0:
            z = self._noise([left.shape, right.shape])
            left, right = apply_noise(left, z[0]), apply_noise(right, z[1])
        meta = {
            "model_name": self.model_name,
            "index": self._n_captures,
            "joints_deg": self.joints().tolist(),
            "image_sigma": self.image_sigma,
        }
        self._n_captures += 1
        return StereoPair(left=left, right=right, meta=meta)

    def _lenses(self) -> tuple[Intrinsics, Intrinsics]:
        """The true camera model of each rendered camera (left, right): their sizes are the
        images'."""
        return (self.rig.intrinsics, self.rig.right)

    def close(self) -> None:
        """Free the renderer (idempotent); later moves and captures raise ``RobotError``."""
        if self._noise_pool is not None:
            self._noise_pool.shutdown(wait=True, cancel_futures=True)
            self._noise_pool, self._next_noise = None, None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._closed = True

    # ------------------------------------------------------------------ ground truth
    def truth_frame(self) -> dict:
        """Ground truth of the current posture: ``joints_rad`` / ``joints_deg`` (true, unquantised),
        ``T_world_cam_left`` / ``T_world_cam_right`` (4, 4, OpenCV camera -> world, m) and
        ``tool_tip_m`` (3,) in the world frame."""
        q = self.true_joints()
        m, d = self.mj_model, self.mj_data
        return {
            "joints_rad": q,
            "joints_deg": q / self._unit,
            "T_world_cam_left": T_world_cam_cv(m, d, CAMERA_NAMES[0]),
            "T_world_cam_right": T_world_cam_cv(m, d, CAMERA_NAMES[1]),
            "tool_tip_m": d.site(TOOL_SITE).xpos.copy(),
        }

    def _set_q(self, q: np.ndarray) -> None:
        super()._set_q(q)
        n = self.robot.n
        self.mj_data.qpos[:n] = self.link_joints()
        self.mj_data.qvel[:] = 0.0
        self.mj_data.ctrl[:n] = q
        mujoco.mj_forward(self.mj_model, self.mj_data)

    def __repr__(self) -> str:
        return f"SimRobot({self.model_name!r}, image_sigma={self.image_sigma})"
