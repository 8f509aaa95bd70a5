"""The simulated camera-equipped SCORBOT: ``calib.robot.Robot`` backed by MuJoCo.

Kinematic simulation: a move sets the joint positions directly (no dynamics) and runs
``mj_forward``; the robot's geometry is the "actual" MCPC chain (``sim.actual``), so the images
show the true robot while the joint read-back is what the encoders report (quantised to
``counts_per_deg`` of the robot's TOML). ``truth_frame()`` gives the ground truth of the current
posture for ``truth.json``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from calib.errors import InputError
from calib.mcpc import MCPCModel
from calib.robot import StereoPair
from sim.kinematic_robot import KinematicRobot
from sim.markers import MarkerField
from sim.mj_camera import T_world_cam_cv
from sim.render import StereoRenderer
from sim.robot_mjcf import CAMERA_NAMES, TOOL_SITE, RigConfig, scene_with_robot

__all__ = ["SimRobot"]


class SimRobot(KinematicRobot):
    """A simulated robot with a wrist stereo rig photographing a marker field.

    Args:
        model_name: nominal robot model (``models/robots/<name>.toml``).
        actual: the simulated robot's MCPC chain, tool = left camera (default: nominal, i.e.
            ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)``); see ``sim.actual.perturb``.
        rig: stereo rig (intrinsics, baseline); default ``RigConfig()``.
        field: marker field; default ``make_marker_field()``.
        image_sigma: std of additive Gaussian image noise (grey levels, 0-255).
        seed: seed of the image-noise generator.
        quantize: report joints at encoder resolution (False: the exact angles, for noise-free
            regression tests).

    Starts at the home posture. Raises ``RobotDefinitionError`` for an unknown model name and
    ``ValueError`` if ``actual`` does not fit the robot.
    """

    def __init__(
        self,
        model_name: str,
        actual: MCPCModel | None = None,
        rig: RigConfig | None = None,
        field: MarkerField | None = None,
        image_sigma: float = 0.0,
        seed: int = 0,
        quantize: bool = True,
    ) -> None:
        if not image_sigma >= 0:
            raise InputError(f"image_sigma must be >= 0 (grey levels), got {image_sigma}")
        super().__init__(model_name, actual, rig, field, quantize)
        self.image_sigma = float(image_sigma)
        self._rng = np.random.default_rng(seed)
        spec = scene_with_robot(self.robot, self.actual, self.rig, self.field)
        self.mj_model = spec.compile()
        self.mj_data = mujoco.MjData(self.mj_model)
        self._renderer = None
        self._n_captures = 0
        self.home()

    def capture(self) -> StereoPair:
        """Render the stereo pair at the current posture (uint8 RGB, H x W x 3 each), with the
        configured Gaussian intensity noise."""
        self._check_open()
        if self._renderer is None:
            self._renderer = StereoRenderer(
                self.mj_model,
                self.rig.intrinsics.width,
                self.rig.intrinsics.height,
                camera_names=CAMERA_NAMES,
                lenses=(self.rig.intrinsics, self.rig.right),
            )
        left, right = self._renderer.render(self.mj_data, self.image_sigma, self._rng)
        meta = {
            "model_name": self.model_name,
            "index": self._n_captures,
            "joints_deg": self.joints().tolist(),
            "image_sigma": self.image_sigma,
        }
        self._n_captures += 1
        return StereoPair(left=left, right=right, meta=meta)

    def close(self) -> None:
        """Free the renderer (idempotent); later moves and captures raise ``RobotError``."""
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
        self.mj_data.qpos[:n] = q
        self.mj_data.qvel[:] = 0.0
        self.mj_data.ctrl[:n] = q
        mujoco.mj_forward(self.mj_model, self.mj_data)

    def __repr__(self) -> str:
        return f"SimRobot({self.model_name!r}, image_sigma={self.image_sigma})"
