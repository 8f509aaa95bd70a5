"""Reading a calibration for ``selfcal export``, ``fk`` and ``ik --calibration``: the file behind
a folder, its deployed model (:func:`load_calibration`), its robot (:func:`calibration_robot`),
its hand-eye and board mount (:func:`load_handeye`), and the refusals of an export: a
calibration no better than its fair nominal (:func:`_refuse_no_gain`) and a robot format of a
pose dataset's calibration (:func:`_refuse_pose_calibration`). Each raises :class:`CliError`
naming the file and what to give instead."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from selfcal.console.common import CliError
from selfcal.errors import SelfCalError, SelfCalWarning

if TYPE_CHECKING:
    from selfcal.io.calibration import CalibrationResult

# Heavy modules are imported by the functions that use them (`selfcal --help` stays fast).
__all__ = [
    "NoCameraMountWarning",
    "calibration_robot",
    "load_calibration",
    "load_handeye",
    "robot_of_calibration",
]


def _calibration_file(path: str) -> Path:
    p = Path(path)
    if p.is_dir():
        p = p / "calibration.json"
    if not p.is_file():
        raise CliError(
            f"{p} not found: give a dataset folder holding calibration.json (run `selfcal "
            "calibrate DIR` first), the calibration.json itself or an exported .toml"
        )
    return p


def load_calibration(path: str):
    """The :class:`selfcal.export.deploy.DeployedModel` of a calibration.json, its folder or an exported
    TOML parameter table.

    Raises:
        CliError: missing file or unusable TOML (the message says what to give instead).
        CalibrationFileError: a damaged or foreign calibration.json (named, with the fix).
    """
    from selfcal.export.deploy import DeployError, calibration_robot_model, deploy, deploy_chain
    from selfcal.export.robot_toml import from_toml
    from selfcal.io.board_calibration import calibration_kind, read_board_calibration
    from selfcal.io.calibration import read_calibration

    p = _calibration_file(path)
    try:
        if p.suffix == ".toml":
            return from_toml(p.read_text())
        if calibration_kind(p) == "board":  # world = the board frame, tool = the camera
            cal = read_board_calibration(p)
            robot = _robot_file(p) or calibration_robot_model(cal.robot_model)
            return deploy_chain(cal.model, robot, intrinsics=cal.cameras[0], source=str(p))
        return deploy(_usable(read_calibration(p), p), robot=_robot_file(p), source=str(p))
    except DeployError as exc:
        raise CliError(f"{p}: {exc.message}", fix=exc.fix) from None


def calibration_robot(path: str, robot_name: str):
    """The robot of the calibration ``path`` (as :func:`load_calibration` takes it): the robot
    file its dataset carries (:func:`_robot_file`), else the model ``robot_name``. An exported
    TOML finds it through the calibration.json it names as ``source`` when that is still there,
    else by ``robot_name`` among the shipped robots."""
    from selfcal.export.robot_toml import from_toml
    from selfcal.robot.definition import list_robots, load_robot

    p = _calibration_file(path)
    if p.suffix == ".json":
        _scale_said(p)
        return _mount_said(_robot_file(p) or load_robot(robot_name), p)
    # the robot file beside the calibration the TOML was exported from first: a user's robot
    # may carry a shipped robot's name (a URDF's <robot name="ur5e">) and other dimensions
    src = Path(from_toml(p.read_text()).source)
    if src.suffix == ".json" and src.is_file() and (robot := _robot_file(src)) is not None:
        return _mount_said(robot, p)
    if robot_name in list_robots():
        return _mount_said(load_robot(robot_name), p)
    raise CliError(
        f"{p}: robot {robot_name!r} is neither a shipped model nor found through the file's "
        f"source {str(src)!r}",
        fix="give the calibration.json the TOML was exported from (its folder keeps the robot "
        "file), or export again from it",
    )


def _scale_said(calibration: Path) -> None:
    """The scale warning ``calibration`` (a calibration.json) keeps, warned again: the robot
    read from it carries that scale in its link lengths (it was said once, by calibrate)."""
    from selfcal.calibration.scale_check import DISAGREES, ScaleWarning

    for text in json.loads(calibration.read_text()).get("warnings") or ():
        if isinstance(text, str) and text.startswith(DISAGREES):
            warnings.warn(f"{calibration} warns that {text}", ScaleWarning, stacklevel=3)


class NoCameraMountWarning(SelfCalWarning):
    """The calibration's robot file gives no camera mount: its tool tip is the camera."""


def _mount_said(robot, calibration: Path):
    """``robot``, warning when its file gives no ``[camera_mount]`` (a URDF never does): the
    calibrated tool tip is then ``inv(T_flange_cam)`` = the identity past the camera, the
    camera's optical frame (z along the view), not the flange, whatever the flange -> camera
    the calibration found (named in mm and deg when ``calibration`` gives it)."""
    if robot.camera_mount_given:
        return robot
    where = ""
    if calibration.suffix == ".json":
        try:
            T = next(t.T for t in load_handeye(str(calibration)).transforms
                     if t.what == "flange -> camera")  # fmt: skip
        except (CliError, SelfCalError, StopIteration):
            pass
        else:
            angle = np.degrees(np.arccos(np.clip((np.trace(T[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)))
            where = (f", {np.linalg.norm(T[:3, 3]) * 1000.0:.1f} mm and {angle:.1f} deg from the "
                     "flange as calibrated")  # fmt: skip
    warnings.warn(
        f"{calibration}: the robot file of {robot.name} gives no [camera_mount] (a URDF never "
        f"does), so the tool tip here is the calibrated camera's optical frame (z along its view"
        f"{where}), not the flange or your tool: the calibrated chain to the camera is right, the "
        "tool point is not; for a tool point give the camera's mount on the flange "
        "([camera_mount] xyz_mm, x_axis, z_axis) in a robot TOML that wraps the URDF ([urdf] "
        "file = ...) and import with that --robot (docs/own-data.md)",
        NoCameraMountWarning,
        stacklevel=3,
    )
    return robot


def robot_of_calibration(calibration: Path, name: str):
    """The robot of the ``calibration.json`` ``calibration`` whose ``robot_model`` is ``name``:
    the robot file behind it (:func:`_robot_file`), else the shipped model ``name``, or a
    :class:`CliError` naming the file."""
    return _robot_file(calibration) or _named(calibration, name)


def _named(calibration: Path, name: str):
    """The robot ``calibration``'s ``robot_model`` ``name`` names, or a :class:`CliError`
    naming the file."""
    from selfcal.export.deploy import DeployError, calibration_robot_model

    try:
        return calibration_robot_model(name)
    except DeployError as exc:
        raise CliError(f"{calibration}: {exc.message}", fix=exc.fix) from None


def _robot_file(calibration: Path):
    """The robot file behind the ``calibration.json`` ``calibration``, or None (a shipped model):
    its ``robot_model`` when that is a robot TOML or URDF (a board calibration's, relative to its
    folder, where ``selfcal import --robot FILE`` copies it), else the file of the dataset in
    its folder (a field calibration names the robot by its own name)."""
    from selfcal.io.dataset import Dataset
    from selfcal.robot.definition import load_robot

    ref = Path(str(json.loads(calibration.read_text()).get("robot_model", "")))
    if ref.suffix in (".toml", ".urdf"):
        return load_robot(ref if ref.is_absolute() else calibration.parent / ref)
    if not (calibration.parent / "dataset.json").is_file():
        return None
    src = Dataset.open(calibration.parent).robot_source
    return load_robot(src) if isinstance(src, Path) else None


def _usable(cal: CalibrationResult, path: Path) -> CalibrationResult:
    """``cal`` read from ``path``, unless it is marked failed (#15): then its failures, exit 3."""
    from selfcal.calibration.field.calibrate import CalibrationFailedError

    if cal.failed:
        raise CalibrationFailedError.of(cal.failures, path)
    return cal


def _refuse_no_gain(path: str, force: bool) -> None:
    """A :class:`CliError` when the calibration ``path`` (board or field) is no gain over its
    fair nominal -- by its cross-validation (a board's calibration.json ``selection``) or by the
    held-out check in its folder (``evaluation.json`` written by ``selfcal evaluate CAL DATASET2
    --out CAL/evaluation.json`` for THIS calibration; one of another is not used, with a
    warning) -- unless ``force`` (then a warning). No gain as ``selfcal evaluate`` says it
    (:func:`selfcal.calibration.board.evaluate.no_gain`)."""
    import warnings

    from selfcal.calibration.board.evaluate import evaluation_of, no_gain
    from selfcal.errors import SelfCalWarning
    from selfcal.io.board_calibration import calibration_kind, read_board_calibration

    p = _calibration_file(path)
    if p.suffix != ".json":
        return
    board = calibration_kind(p) == "board"
    why = read_board_calibration(p).cv_verdict() if board else None
    if why is None:
        ev_path, ev = evaluation_of(p, stacklevel=2)
        rms = ev.rms if ev is not None else None
        if rms is not None and no_gain(rms["calibrated"], rms["nominal"]):
            why = (f"its held-out reprojection in {ev_path} ({rms['calibrated']:.3f} px) is not "
                   f"below the fair nominal's ({rms['nominal']:.3f} px)")  # fmt: skip
    if why is None:
        return
    if force:
        warnings.warn(f"{p}: exported with --force although {why}", SelfCalWarning, stacklevel=2)
        return
    raise CliError(
        f"{p}: not exported: {why}; the calibrated kinematics are no better than the nominal "
        "robot's",
        fix="add arm configurations (move the first joints, not only the wrist) and calibrate "
        "again, or give --force to export it anyway",
    )


def _refuse_pose_calibration(path: str, fmt: str) -> None:
    """A CliError for a robot format of a pose dataset's calibration (it has no kinematics)."""
    from selfcal.calibration.handeye.calibration_file import is_handeye

    if is_handeye(_calibration_file(path)):
        raise CliError(f"{path} is the calibration of a pose dataset (flange poses, no joints): "
                       f"it identified no kinematics, so there is no robot to write as {fmt}",
                       fix="export the hand-eye with --format tf | easy_handeye | matrix, or the "
                       "camera with --format opencv | camera_info")  # fmt: skip


def load_handeye(path: str):
    """The :class:`selfcal.export.handeye.HandEyeExport` of the calibration ``path``: a pose
    dataset's (hand-eye and board mount), a board calibration's (flange -> camera, base ->
    board; eye-to-hand base -> camera, flange -> board) or a self-calibration's (flange ->
    camera)."""
    import math

    from selfcal.calibration.handeye.calibration_file import is_handeye, read_handeye
    from selfcal.export.handeye import from_chain, from_handeye_document, from_mounts
    from selfcal.io.board_calibration import calibration_kind, read_board_calibration
    from selfcal.io.calibration import read_calibration

    p = _calibration_file(path)
    if p.suffix == ".toml":
        raise CliError(f"{p}: the hand-eye formats need a calibration.json (an exported .toml "
                       "holds the tool tip, not the calibration's camera)")  # fmt: skip
    if is_handeye(p):
        return from_handeye_document(read_handeye(p)[3], str(p))
    if calibration_kind(p) == "board":
        cal = read_board_calibration(p)
        if cal.eye_to_hand:  # the camera static: base -> camera, flange -> board
            if not cal.mounts:
                raise CliError(f"{p}: an eye-to-hand calibration without mounts (no base frame "
                               "can be rebuilt on joints 1 and 2, or no Cramer-Rao bound: "
                               "calibration.json bounds_error says why)")  # fmt: skip
            return from_mounts(cal.mounts, str(p))
        # a board calibration keeps the Cramer-Rao bound of each parameter, not its std
        to_si = {"deg": math.pi / 180.0, "mm": 1e-3}
        std = {b.name: b.bound * to_si[b.unit] for b in (cal.bounds.parameters if cal.bounds else ())
               if b.bound is not None}  # fmt: skip
        robot = _robot_file(p) or _named(p, cal.robot_model)
        return from_chain(cal.model, robot, std, str(p), board=True,
                          sigma_source="Cramer-Rao bounds at the estimate")  # fmt: skip
    field = _usable(read_calibration(p), p)
    robot = _robot_file(p) or _named(p, field.robot_model)
    return from_chain(field.model, robot, field.std_si(), str(p), board=False)
