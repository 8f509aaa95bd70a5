"""The simulated robot of the analytic path: ``selfcal.robot.interface.Robot`` without MuJoCo.

When no images are rendered (``[noise] render = false``: corners are projected analytically,
``selfcal.sim.analytic``), the simulator needs only the actual chain's camera poses, which are its forward
kinematics (``selfcal.kinematics.forward.fk_tool`` of the actual MCPC chain, tool = left camera). This robot
gives exactly that for any serial arm (no MJCF needed), with the same joint read-back (encoder
quantisation, :func:`read_back`) and ground truth (``truth_frame``, ``truth``) as
:class:`selfcal.sim.sim_robot.SimRobot`; it has no camera images (``capture`` raises).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from selfcal.errors import InputError, UsageError
from selfcal.io.target_toml import target_document
from selfcal.io.truth import Truth
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.robot.encoder import EncoderSpec
from selfcal.robot.interface import RobotError, StereoPair
from selfcal.sim.actual import make_truth
from selfcal.sim.compliance import JointMisfit
from selfcal.sim.link_frames import nominal_camera_model
from selfcal.sim.markers import MarkerField, make_marker_field
from selfcal.sim.robot_mjcf import RigConfig
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = ["KinematicRobot", "read_back", "joint_units"]


def joint_units(robot: RobotDef) -> np.ndarray:
    """Per joint: SI units per edge unit (rad per deg, or m per mm for a prismatic joint)."""
    return robot.edge_unit


def read_back(q: np.ndarray, encoder: EncoderSpec | None, quantize: bool) -> np.ndarray:
    """Joint read-back (rad / m) of true positions ``q`` (..., n): the motors' counts rounded
    as the controller's ``encoder`` table reads them (:meth:`EncoderSpec.read_back`, the
    differential wrist included) when ``quantize``; exact without a table (a robot file
    without an encoder resolution, which the calibration also takes as exact)."""
    q = np.asarray(q, dtype=float)
    return encoder.read_back(q) if quantize and encoder is not None else q.copy()


class KinematicRobot:
    """A simulated robot whose camera poses are the actual chain's forward kinematics.

    Arguments as :class:`selfcal.sim.sim_robot.SimRobot` (without image noise): ``model_name`` (a model
    name or robot file for :func:`selfcal.robot.definition.load_robot`, or the loaded robot), ``actual``
    (tool = left camera; default nominal), ``rig``, ``field`` (default ``make_marker_field()``,
    none with a board), ``quantize``, ``board`` (``(board, T_world_board)``: recorded in
    ``truth()``; its features are projected by :func:`selfcal.sim.analytic.project_board`).
    Starts at home.
    ``compliance`` (a :class:`selfcal.sim.compliance.JointMisfit`: a joint compliance, or an
    eccentric gear, :class:`selfcal.sim.gear.EccentricGear`): the links stand at its bent
    joints while the encoders read the commanded ones (a misfit for the benchmarks; ``truth()``'s
    true chain does not include it). ``SimRobot`` is this robot plus MuJoCo (it overrides
    ``_set_q``, ``truth_frame``, ``capture``).
    """

    image_sigma: float = 0.0

    def __init__(
        self,
        model_name: str | RobotDef,
        actual: MCPCModel | None = None,
        rig: RigConfig | None = None,
        field: MarkerField | None = None,
        quantize: bool = True,
        board: tuple[Board, np.ndarray] | None = None,
        compliance: JointMisfit | None = None,
    ) -> None:
        self.robot = model_name if isinstance(model_name, RobotDef) else load_robot(model_name)
        self.model_name = self.robot.name
        self.nominal = nominal_camera_model(self.robot)
        self.actual = self.nominal if actual is None else actual
        if self.actual.joint_types != self.robot.joint_types:
            raise UsageError(
                f"actual model joints {self.actual.joint_types} do not match {self.model_name}"
            )
        self.rig = RigConfig() if rig is None else rig
        self.field: MarkerField | None = field  # the scene's markers: none with a board
        if field is None and board is None:
            self.field = make_marker_field()
        self.quantize = bool(quantize)
        self.board = board
        self.compliance = compliance
        self._unit = joint_units(self.robot)
        self._q = self.robot.home.astype(float).copy()
        self._closed = False

    def home(self) -> None:
        """Move to the home posture of the robot's TOML."""
        self._set_q(self.robot.home)

    def _set_q(self, q: np.ndarray) -> None:
        self._check_open()
        self._q = np.asarray(q, dtype=float).copy()

    def move_to(self, joints_deg: np.ndarray) -> None:
        """Move to joint angles (deg; mm for a prismatic joint), range-checked like ``SimRobot``."""
        self._check_open()
        q_deg = np.asarray(joints_deg, dtype=float)
        if q_deg.shape != (self.robot.n,):
            raise InputError(
                f"{self.model_name}: move_to needs {self.robot.n} joint values (deg), "
                f"got shape {q_deg.shape}"
            )
        q = q_deg * self._unit
        self.robot.check_joints(q)
        self._set_q(q)

    def joints(self) -> np.ndarray:
        """Joint angles (deg; mm for prismatic) as the encoders report them: the true position's
        motor counts rounded to the nearest count (:func:`read_back`)."""
        return read_back(self.true_joints(), self.robot.encoder, self.quantize) / self._unit

    def capture(self) -> StereoPair:
        """Not available: this robot renders nothing (use ``SimRobot`` for images)."""
        raise RobotError(
            f"{self.model_name}: the kinematic simulator renders no images",
            fix="set [noise] render = false (analytic corners) or use the MuJoCo simulator",
        )

    def close(self) -> None:
        """Idempotent; later moves raise ``RobotError``."""
        self._closed = True

    def true_joints(self) -> np.ndarray:
        """The true joint positions (rad; m for prismatic), unquantised."""
        return self._q.copy()

    def link_joints(self) -> np.ndarray:
        """The joints (rad; m) the links stand at: the true joints, bent by ``compliance``."""
        return self._q.copy() if self.compliance is None else self.compliance.bent(self._q)

    def truth_frame(self) -> dict:
        """Ground truth of the current posture, as ``SimRobot.truth_frame`` (the cameras where
        the links stand, :meth:`link_joints`)."""
        T_left = fk_tool(self.actual, self.link_joints()[None])[0]
        return {
            "joints_rad": self._q.copy(),
            "joints_deg": self._q / self._unit,
            "T_world_cam_left": T_left,
            "T_world_cam_right": T_left @ self.rig.T_left_right,
            "tool_tip_m": (T_left @ inv_pose(self.robot.T_flange_cam))[:3, 3],
        }

    def truth(self, meta: dict | None = None) -> Truth:
        """The ground-truth header (no frames; append ``truth_frame()`` records), with the
        board's target keys and true pose when there is one (:class:`selfcal.io.truth.Truth`
        ``board``)."""
        meta = {"image_sigma": self.image_sigma, **(meta or {})}
        truth = make_truth(self.robot, self.nominal, self.actual, self.rig, self.field, meta)
        if self.board is None:
            return truth
        doc = {"target": target_document(self.board[0]), "T_world_board": self.board[1]}
        return dataclasses.replace(truth, board=doc)

    def _check_open(self) -> None:
        if self._closed:
            raise RobotError(f"{type(self).__name__}({self.model_name}) is closed")

    def __enter__(self) -> KinematicRobot:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
