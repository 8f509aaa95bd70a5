"""The simulator's set-up of a scenario: the actual (perturbed) robot, the true cameras, the
marker field or board and, eye-to-hand, the static cell (:class:`SimSetup`, :func:`sim_setup`),
deterministic per the scenario's seeds; and the field centre and board pose the planning shares
with it. The backends (:mod:`selfcal.acquisition.backends`) build the simulated robots from it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from selfcal.camera import Intrinsics
from selfcal.config.scenario import ConfigError, Scenario, scenario_board
from selfcal.errors import InputError, InternalError, UsageError
from selfcal.kinematics.mcpc import (
    MCPCModel,
    minimal_indices,
    nominal_mcpc,
    param_is_angle,
    param_names,
)
from selfcal.kinematics.trajectory import home_target_center
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.sim.actual import apply_errors, perturb
from selfcal.sim.board_scene import BOARD_THICKNESS_M, board_on_table
from selfcal.sim.compliance import JointMisfit
from selfcal.sim.markers import MarkerField, make_marker_field
from selfcal.sim.robot_mjcf import RigConfig
from selfcal.transforms import trans

if TYPE_CHECKING:  # their modules load where they are used (OpenCV, the still camera's scene)
    from selfcal.sim.static_camera import StaticCameraTruth
    from selfcal.target.boards import Board

__all__ = [
    "DICTIONARY",
    "SCALE_IDS",
    "TABLE_CLEARANCE_M",
    "SimSetup",
    "check_board_above_table",
    "field_center",
    "scenario_board_pose",
    "sim_setup",
]

DICTIONARY = "DICT_4X4_50"
SCALE_IDS = (48, 49)
"""The scale bar's two markers: the dictionary's last two ids (as ``selfcal.sim.markers`` places them)."""

TABLE_CLEARANCE_M = 1e-4
"""How far above the table (the world's z = 0 plane, m) every corner of a rendered board's printed
image must lie: a face in the table's plane is drawn at the table's depth, and the table hides
parts of it (a face 0.2 mm above it renders whole)."""


@dataclass
class SimSetup:
    """Everything the simulator needs, derived from a scenario (deterministic per seeds)."""

    robot: RobotDef
    nominal: MCPCModel
    actual: MCPCModel
    intrinsics: Intrinsics
    T_left_right: np.ndarray
    field: MarkerField | None
    """The marker field in the scene, or None: a board scenario has none."""
    meta: dict = dataclasses.field(default_factory=dict)
    board: Board | None = None
    """``[target] board`` (selfcal.target.boards.Board) or None: the marker field."""
    T_world_board: np.ndarray | None = None
    """The board's true pose on the table (board -> world, m; ``selfcal.sim.board_scene.board_on_table``),
    or None: no board, or eye-to-hand (the board rides on the flange, ``static``)."""
    intrinsics_right: Intrinsics | None = None
    """The right camera's own true model (``[camera.right]``), or None: ``intrinsics``."""
    static: StaticCameraTruth | None = None
    """Eye-to-hand (``[camera] setup``): the cell (selfcal.sim.static_camera.StaticCameraTruth:
    the static camera, the board on the flange), or None: the cameras on the flange."""
    compliance: JointMisfit | None = None
    """The actual robot's joint misfit (a compliance, selfcal.sim.compliance, or an eccentric
    gear, selfcal.sim.gear; a benchmark's misfit, not
    in scenarios), or None: a rigid arm."""

    def marker_field(self) -> MarkerField:
        """The marker field, for what only a field scenario has (a :class:`UsageError` in a
        board scenario, which has none)."""
        if self.field is None:
            raise UsageError("a board scenario has no marker field; this needs a field scenario")
        return self.field

    def board_pose(self) -> tuple[Board, np.ndarray] | None:
        """The board and its true pose on the table (board -> world, m) for a scene with the
        cameras on the flange, or None: the marker field. An eye-to-hand cell's board rides on
        the flange (an :class:`InternalError`: its scene is :attr:`static`'s)."""
        if self.board is None:
            return None
        if self.T_world_board is None:
            raise InternalError(
                "the board of an eye-to-hand scenario rides on the flange: it has no pose on "
                "the table (simulate it with its still camera, SimSetup.static)"
            )
        return self.board, self.T_world_board

    def rig(self) -> RigConfig:
        """The simulated rig: the true cameras and the baseline."""
        return RigConfig(intrinsics=self.intrinsics, T_left_right=self.T_left_right,
                         intrinsics_right=self.intrinsics_right)  # fmt: skip


def field_center(robot: RobotDef, nominal: MCPCModel) -> tuple[float, float]:
    """The field's centre: where the home posture's optical axis meets the table
    (:func:`selfcal.kinematics.trajectory.home_target_center`; ``nominal``: base -> camera)."""
    try:
        return home_target_center(robot, nominal)
    except InputError as exc:
        raise ConfigError(exc.message, fix=exc.fix) from exc


def _perturbation_table(s: Scenario, joint_types: tuple[str, ...]) -> dict[str, float]:
    idx = minimal_indices(joint_types)
    names = param_names(idx)
    out = {}
    for k, v in s.perturbation.table.items():
        if k not in names:
            raise ConfigError(
                f"{s.source}: perturbation.table.{k}: unknown parameter; known: {', '.join(names)}"
            )
        is_angle = param_is_angle(idx)[names.index(k)]
        out[k] = float(v) * (np.pi / 180 if is_angle else 1e-3)
    return out


def sim_setup(s: Scenario) -> SimSetup:
    """The simulated actual robot, rig and marker field or board of a scenario (a board
    scenario has no marker field; eye-to-hand its board rides on the flange, not on the table:
    no ``T_world_board``, so an arm whose flange camera never sees the table simulates it).

    Raises:
        ConfigError: a rendered scenario whose board touches the table
            (:func:`check_board_above_table`).
    """
    robot = load_robot(s.robot.model)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    actual = perturb(
        nominal,
        seed=s.perturbation.seed,
        translation_m=s.perturbation.translation_mm / 1000,
        rotation_rad=np.radians(s.perturbation.rotation_deg),
    )
    table = _perturbation_table(s, robot.joint_types)
    if table:
        actual = apply_errors(actual, table)
    intr = s.camera.true_model()
    board = scenario_board(s)
    field_ = (
        None
        if board is not None
        else make_marker_field(
            n_markers=s.target.markers,
            seed=s.target.seed,
            center_xy_m=field_center(robot, nominal),
            extent_m=(s.target.extent_mm / 1000, s.target.extent_mm / 1000),
            size_m=s.target.marker_size_mm / 1000,
            scale_length_m=s.target.scale_length_mm / 1000,
            dictionary=DICTIONARY,
        )
    )
    T_lr = trans(np.array([s.camera.baseline_mm / 1000, 0.0, 0.0]))
    static = None
    if s.camera.setup == "eye-to-hand":  # its simulator's modules load for such a scenario only
        from selfcal.acquisition.eye_to_hand import static_cell

        static = static_cell(s, robot)
        if table:  # its own perturbed chain (the board's mount its tool): the table's errors too
            static = dataclasses.replace(static, actual=apply_errors(static.actual, table))
    T_world_board = (None if board is None or static is not None
                     else scenario_board_pose(s, board, robot, nominal))  # fmt: skip
    right = s.camera.of("right").true_model() if s.camera.own_intrinsics else None
    setup = SimSetup(robot, nominal, actual, intr, T_lr, field_, board=board,
                     T_world_board=T_world_board, intrinsics_right=right,
                     static=static)  # fmt: skip
    if s.noise.render and s.robot.backend == "sim":  # before anything is written (run, acquire)
        check_board_above_table(s, setup)
    return setup


def scenario_board_pose(s: Scenario, board, robot: RobotDef, nominal: MCPCModel) -> np.ndarray:
    """The board's pose on the table (board -> world, m): ``[target] board_pose`` or where the
    home posture looks (a :class:`ConfigError` when the home camera does not see the table)."""
    bp = s.target.board_pose
    if not bp:
        return board_on_table(board, field_center(robot, nominal))
    from selfcal.target.placement import board_pose  # lazy: a marker field needs no placement

    rpy = np.radians(bp[3:]) if len(bp) == 6 else None
    return board_pose(board, np.asarray(bp[:3]) / 1000.0, rpy)


def check_board_above_table(s: Scenario, setup: SimSetup) -> None:
    """Refuse to render a board (cameras on the flange) whose printed image touches or dips
    below the table: ``[target] board_pose`` with z = 0 (a board lying on the table is as high as
    it is thick) puts the print in the table's plane, and the rendered table hides parts of it
    (frames without the board, corners off by pixels), where the analytic path sees it whole.

    Raises:
        ConfigError: naming the scenario file, ``target.board_pose``, the printed image's lowest
            corner (mm above the table) and the fix.
    """
    if setup.board is None or setup.T_world_board is None:
        return
    x0, y0, x1, y1 = setup.board.image(1.0).extent_m
    corners = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x0, y1, 0.0], [x1, y1, 0.0]])
    T = setup.T_world_board
    low = float((corners @ T[:3, :3].T + T[:3, 3])[:, 2].min())
    if low >= TABLE_CLEARANCE_M:
        return
    bp = [float(v) for v in s.target.board_pose]
    lift = bp[:2] + [round(bp[2] + (BOARD_THICKNESS_M - low) * 1000, 1)] + bp[3:]
    raise ConfigError(
        f"{s.source}: target.board_pose = {bp}: the board's printed image reaches "
        f"{low * 1000:.1f} mm above the table (z = 0) at its lowest corner: the rendered table "
        "hides the print where it touches (frames without the board, corners off), so the "
        "rendered images would not be the ones the plan or scenario meant",
        fix=f"lift the board by its thickness: board_pose = {lift} (mm, deg; a board lying on "
        "the table has z = its thickness, `selfcal plan --board-pose X,Y,3`)"
        + (", or set [noise] render = false (the analytic corners see it whole)"
           if s.noise.render else ""),
    )  # fmt: skip
