"""Scenario configuration: TOML files over typed defaults.

Every key has a default, so a scenario file states only what it changes. Units at this edge are
those of the key names (``_mm``, ``_deg``, ``px``); the code converts to SI where it uses them.
An unknown key or a value of the wrong type is an error naming the file, the key and the type.
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from selfcal.calibration.board.folds import MIN_FRAMES  # not .dataset: its imports
from selfcal.calibration.field.failures import MIN_POSTURES  # not .calibrate: 0.6 s of imports
from selfcal.config.camera import (
    PER_CAMERA_KEYS,
    CameraConfig,
    ConfigError,
    check_setup,
    validate_camera,
)
from selfcal.config.defaults import DEFAULT_ROBOT
from selfcal.config.shipped import scenario_file, shipped_model_file, shipped_scenarios
from selfcal.errors import InternalError
from selfcal.robot.definition import models_dir
from selfcal.tomlfile import read_toml

if TYPE_CHECKING:  # OpenCV: imported where a board is loaded (scenario_board)
    from selfcal.target.boards import Board

__all__ = [
    "Scenario",
    "ConfigError",
    "load_scenario",
    "default_scenario_path",
    "scenario_board",
    "board_path",
    "joints_path",
    "scenario_to_dict",
    "DEFAULT_ROBOT",
]


@dataclass(frozen=True)
class HardwareConfig:
    port: str = "/dev/ttyUSB0"
    """Any pyserial URL: a device path, socket://host:port, loop://, a pty."""
    baudrate: int = 9600
    xonxoff: bool = True
    cameras: list[str] = field(default_factory=lambda: ["0", "1"])
    """Left and right camera: device index, stream URL or image-sequence pattern."""
    options: dict = field(default_factory=dict)
    """Further adapter settings passed through to the hardware adapter (see docs/hardware.md)."""


@dataclass(frozen=True)
class RobotConfig:
    model: str = DEFAULT_ROBOT
    """Nominal kinematics by name (models/<folder>/<name>.toml)."""
    backend: str = "sim"
    """"sim" or "hardware"."""
    hardware: HardwareConfig = field(default_factory=HardwareConfig)


@dataclass(frozen=True)
class TargetConfig:
    markers: int = 20
    """ArUco markers at unknown positions, some raised on blocks."""
    scale_length_mm: float = 200.0
    """The one known distance (the paper's d) between the two scale markers' centres."""
    marker_size_mm: float = 30.0
    extent_mm: float = 300.0
    """Side of the square region (centred where the home posture looks) that holds the markers;
    the trajectory planner keeps this region in view."""
    seed: int = 1
    """Layout of the (simulated) marker field."""
    board: str = ""
    """A board of known geometry instead of the marker field: the path of its target TOML
    (``models/targets/*.toml``, docs/targets.md), relative to the scenario file. Empty: the ArUco
    field of the keys above (the self-calibration). With a board the simulator puts it on the
    table where the home posture looks, the planner keeps it in view, and the calibration is the
    board route (:mod:`selfcal.calibration.board.dataset`); ``[noise] render = false`` projects its features
    with the true cameras instead of rendering (the analytic path)."""
    board_pose: list[float] = field(default_factory=list)
    """Where the board is instead: ``[x, y, z]`` mm, or ``[x, y, z, rx, ry, rz]`` mm and deg, the
    centre of its printed image in the robot's base frame and its rotation from lying printed
    face up (fixed axes x, y, z: ``R = Rz Ry Rx``; :mod:`selfcal.target.placement`), as
    ``selfcal plan --board-pose`` takes it. Empty: on the table where the home posture looks."""


@dataclass(frozen=True)
class PerturbationConfig:
    seed: int = 1
    translation_mm: float = 1.0
    """Each translational MCPC parameter uniformly within +-this (simulation only)."""
    rotation_deg: float = 0.5
    """Each rotational MCPC parameter uniformly within +-this (simulation only)."""
    table: dict = field(default_factory=dict)
    """Explicit errors by parameter name (e.g. beta2 = 0.2): deg for angles, mm for lengths;
    added on top of the random ones."""


@dataclass(frozen=True)
class TrajectoryConfig:
    poses: int = 30
    seed: int = 1
    kind: str = "random"
    """"random" (postures drawn in a window around home), "optimal" (D-optimal selection) or
    "file" (the postures of ``joints``, e.g. a plan of ``selfcal plan``)."""
    joints: str = ""
    """With ``kind = "file"``: a joints CSV in ``selfcal import``'s format (header ``j1..jn``,
    deg; mm for a prismatic joint), relative to the scenario file; its rows are the calibration
    postures in order (``poses`` is not used)."""
    min_markers: int = 6
    """A pose is kept only if both cameras see at least this many of 36 points spread over the
    target region (nominal prediction), i.e. a good part of the marker field."""


@dataclass(frozen=True)
class NoiseConfig:
    render: bool = True
    """false: analytic corner projections instead of rendered images (fast path)."""
    image_sigma: float = 2.0
    """Rendered path: Gaussian sensor noise on pixel intensities (0-255 scale)."""
    msaa: int = 4
    """Rendered path: multisample anti-aliasing samples (0: off; Mesa llvmpipe grants at most
    4). Off renders 2x faster but draws robot silhouettes aliased: the default scenario then
    detects 3 marker views fewer (1600 corners instead of 1612) and its numbers move within
    their uncertainty, so the default keeps 4 (the golden files)."""
    pixel_sigma: float = 0.5
    """Analytic path: Gaussian noise on the projected corners, px."""
    quantize_joints: bool = True
    """Simulated joint read-back at encoder resolution (false: exact, for noise-free tests)."""
    seed: int = 1


@dataclass(frozen=True)
class ValidationConfig:
    poses: int = 20
    """Held-out configurations, never used to calibrate."""
    seed: int = 2


@dataclass(frozen=True)
class Scenario:
    robot: RobotConfig = field(default_factory=RobotConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    target: TargetConfig = field(default_factory=TargetConfig)
    perturbation: PerturbationConfig = field(default_factory=PerturbationConfig)
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    validation: ValidationConfig = field(default_factory=ValidationConfig)
    source: str = "<defaults>"
    """Where this scenario came from (not a key of the file)."""


@dataclass(frozen=True)
class Range:
    """The valid values of one numeric scenario key: ``lo <= value <= hi`` (finite)."""

    lo: float
    hi: float
    unit: str
    why: str


RANGES: dict[str, Range] = {
    # key (a list's elements and a table's values share the key of the list or table)
    "robot.hardware.baudrate": Range(50, 4_000_000, "baud", "serial rates pyserial opens"),
    "camera.resolution": Range(16, 16384, "px", "width and height of an image"),
    "camera.fx": Range(10.0, 1e5, "px", "focal length of a real camera (fov 0.4 .. 175 deg at 640 px)"),
    "camera.mu": Range(0.2, 5.0, "", "fy / fx of a real sensor"),
    "camera.baseline_mm": Range(1.0, 2000.0, "mm", "stereo baseline of a rig on a wrist"),
    "camera.count": Range(1, 2, "", "one wrist camera or the stereo pair"),
    "camera.principal_point_offset_px": Range(-5000.0, 5000.0, "px", "offset from the image centre"),
    "camera.skew_px": Range(-100.0, 100.0, "px", "K[0, 1] of a real sensor (pixels not square)"),
    "camera.distortion": Range(-100.0, 100.0, "", "lens coefficients (OpenCV scale)"),
    "camera.pose": Range(-100_000.0, 100_000.0, "mm or deg", "static camera's centre and rotation"),
    "target.markers": Range(4, 250, "", "markers of the ArUco dictionary (at least 4)"),
    "target.scale_length_mm": Range(10.0, 10_000.0, "mm", "a distance a person can measure well"),
    "target.marker_size_mm": Range(1.0, 1000.0, "mm", "printed marker side"),
    "target.extent_mm": Range(10.0, 10_000.0, "mm", "side of the marker region"),
    "target.seed": Range(0, 2**32 - 1, "", "random seed (numpy)"),
    "target.board_pose": Range(-100_000.0, 100_000.0, "mm or deg", "board centre and rotation"),
    "perturbation.seed": Range(0, 2**32 - 1, "", "random seed (numpy)"),
    "perturbation.translation_mm": Range(0.0, 100.0, "mm", "injected length errors"),
    "perturbation.rotation_deg": Range(0.0, 30.0, "deg", "injected angle errors"),
    "perturbation.table": Range(-100.0, 100.0, "deg or mm", "explicit injected errors"),
    "trajectory.poses": Range(min(MIN_FRAMES, MIN_POSTURES), 10_000, "",
                              f"calibration postures; a marker field's {MIN_POSTURES} or more"),
    "trajectory.seed": Range(0, 2**32 - 1, "", "random seed (numpy)"),
    "trajectory.min_markers": Range(1, 36, "", "points of the 36 the planner checks"),
    "noise.image_sigma": Range(0.0, 64.0, "grey levels", "sensor noise on 0-255 images"),
    "noise.msaa": Range(0, 16, "samples", "anti-aliasing of the rendered images (0: off)"),
    "noise.pixel_sigma": Range(0.0, 20.0, "px", "corner noise (beyond 20 px no marker is found)"),
    "noise.seed": Range(0, 2**32 - 1, "", "random seed (numpy)"),
    "validation.poses": Range(3, 10_000, "", "held-out postures"),
    "validation.seed": Range(0, 2**32 - 1, "", "random seed (numpy)"),
}  # fmt: skip
"""Every numeric scenario key's valid range; ``load_scenario`` refuses a value outside it (or
NaN, infinite) naming file, key, value and range. docs/scenarios.md shows this table
(:func:`ranges_markdown`; a test keeps them equal)."""


_UNRANGED = {"robot.hardware.options"}
"""Tables passed through to another reader that checks them (the hardware adapter's settings)."""


def _fmt(x: float) -> str:
    """A number for messages and the docs table: integers in full, others in ``%g``."""
    x = float(x)
    return str(int(x)) if x.is_integer() and abs(x) < 1e15 else f"{x:g}"


def ranges_markdown() -> str:
    """:data:`RANGES` as the Markdown table of docs/scenarios.md."""
    rows = ["| key | valid range | unit | why |", "|---|---|---|---|"]
    for key, r in RANGES.items():
        rows.append(f"| `{key}` | {_fmt(r.lo)} .. {_fmt(r.hi)} | {r.unit} | {r.why} |")
    return "\n".join(rows) + "\n"


def _numeric_leaves(d: dict, prefix: str = ""):
    """(key, value) of every number in the scenario as plain data (lists and tables of numbers
    under the key of the list or table)."""
    for k, v in d.items():
        key = f"{prefix}{k}"
        if key in _UNRANGED:
            continue
        if isinstance(v, dict) and _range_key(key) not in RANGES:
            yield from _numeric_leaves(v, key + ".")
        elif isinstance(v, dict):
            yield from ((f"{key}.{kk}", key, vv) for kk, vv in v.items())
        elif isinstance(v, list):
            yield from ((f"{key}[{i}]", key, vv) for i, vv in enumerate(v))
        else:
            yield key, key, v


def _range_key(key: str) -> str:
    """The :data:`RANGES` key of a scenario key (``camera.right.fx`` has ``camera.fx``'s)."""
    return "camera." + key[len("camera.right.") :] if key.startswith("camera.right.") else key


def _check_ranges(s: Scenario) -> None:
    for name, key, v in _numeric_leaves(scenario_to_dict(s)):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        r = RANGES[_range_key(key)]
        if not r.lo <= v <= r.hi:  # NaN fails too
            unit = f" {r.unit}" if r.unit else ""
            raise ConfigError(
                f"{s.source}: {name} = {_fmt(v)} is outside its valid range "
                f"{_fmt(r.lo)} .. {_fmt(r.hi)}{unit} ({r.why})",
                fix=f"set {name} within {_fmt(r.lo)} .. {_fmt(r.hi)} (docs/scenarios.md lists "
                "every range)",
            )


def scenarios_dir() -> Path:
    """The shipped scenarios, beside the robot models: ``scenarios/`` of the source checkout, or
    ``selfcal/scenarios`` inside an installed wheel (package data, pyproject ``force-include``)."""
    return models_dir().parent / "scenarios"


def default_scenario_path() -> Path:
    """``scenarios/paper.toml``, the default scenario."""
    return scenarios_dir() / "paper.toml"


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is list:
        (arg,) = typing.get_args(tp)
        return f"list of {_type_name(arg)}"
    return {bool: "boolean", int: "integer", float: "number", str: "string", dict: "table"}.get(
        tp, str(tp)
    )


def _coerce(value: Any, tp: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    ok: bool
    if tp is bool:
        ok = isinstance(value, bool)
    elif tp is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif tp is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif tp is str:
        ok = isinstance(value, str)
    elif tp is dict:
        ok = isinstance(value, dict)
    elif origin is list:
        (arg,) = typing.get_args(tp)
        ok = isinstance(value, list)
        if ok:
            return [_coerce(v, arg, f"{where}[{i}]") for i, v in enumerate(value)]
    else:  # pragma: no cover - schema error
        raise InternalError(f"unsupported schema type {tp}")
    if not ok:
        raise ConfigError(
            f"key '{where}': expected {_type_name(tp)}, got {type(value).__name__} {value!r}"
        )
    return value


def _build(cls: type, data: dict, where: str, file: str) -> Any:
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.name != "source"}
    kwargs = {}
    for key, value in data.items():
        if key not in names:
            raise _unknown_key(file, f"{where}{key}", where.rstrip(".") or "top level",
                               ", ".join(sorted(names)))  # fmt: skip
        tp = hints[key]
        if cls is CameraConfig and key == "right":
            kwargs[key] = _per_camera(value, f"{where}{key}", file)
        elif isinstance(tp, type) and dataclasses.is_dataclass(tp):
            if not isinstance(value, dict):
                raise ConfigError(f"{file}: '{where}{key}' must be a table [{where}{key}]")
            kwargs[key] = _build(tp, value, f"{where}{key}.", file)
        else:
            kwargs[key] = _coerce(value, tp, f"{where}{key}")
    return cls(**kwargs)


def _unknown_key(file: str, key: str, table: str, allowed: str) -> ConfigError:
    """The error of an unknown ``key`` of ``table`` in ``file``, listing the ``allowed`` keys."""
    return ConfigError(
        f"{file}: unknown key '{key}'; allowed in [{table}]: {allowed}",
        fix="check the spelling; `selfcal run --help` lists every key with its default",
    )


def _per_camera(value: Any, where: str, file: str) -> dict:
    """A ``[camera.right]`` table: keys of :data:`PER_CAMERA_KEYS`, typed as in ``[camera]``."""
    if not isinstance(value, dict):
        raise ConfigError(f"{file}: '{where}' must be a table [{where}]")
    hints = typing.get_type_hints(CameraConfig)
    out = {}
    for k, v in value.items():
        if k not in PER_CAMERA_KEYS:
            raise _unknown_key(file, f"{where}.{k}", where, ", ".join(PER_CAMERA_KEYS) +
                               " (the others are the rig's, in [camera])")  # fmt: skip
        out[k] = _coerce(v, hints[k], f"{where}.{k}")
    return out


def _validate(s: Scenario) -> None:
    f = s.source
    if s.robot.backend not in ("sim", "hardware"):
        raise ConfigError(
            f'{f}: robot.backend must be "sim" or "hardware", got {s.robot.backend!r}'
        )
    if s.trajectory.kind not in ("random", "optimal", "file"):
        raise ConfigError(
            f'{f}: trajectory.kind must be "random", "optimal" or "file", got {s.trajectory.kind!r}'
        )
    if (s.trajectory.kind == "file") != bool(s.trajectory.joints):
        raise ConfigError(
            f"{f}: trajectory.joints names the postures' file exactly when trajectory.kind = "
            '"file"',
            fix='give both kind = "file" and joints = "joints.csv", or neither',
        )
    if len(s.target.board_pose) not in (0, 3, 6) or (s.target.board_pose and not s.target.board):
        raise ConfigError(
            f"{f}: target.board_pose must be [x, y, z] (mm) or [x, y, z, rx, ry, rz] (mm, deg) "
            "of a board (target.board)",
            fix="give 3 or 6 numbers and target.board, or leave board_pose out (the board lies "
            "where the home posture looks)",
        )
    if len(s.camera.resolution) != 2 or min(s.camera.resolution) < 16:
        raise ConfigError(f"{f}: camera.resolution must be [width, height] in px, each >= 16")
    if len(s.robot.hardware.cameras) != 2:
        raise ConfigError(f"{f}: robot.hardware.cameras must list two cameras: [left, right]")
    validate_camera(s.source, s.camera, "camera")
    if s.camera.right:
        if s.camera.count < 2:
            raise ConfigError(
                f"{f}: [camera.right] describes the right camera, but camera.count = 1 (the left "
                "camera alone)",
                fix="set camera.count = 2, or remove [camera.right]",
            )
        validate_camera(s.source, s.camera.of("right"), "camera.right")
    scenario_board(s)  # a bad target file is an error naming it and the key
    check_setup(s)
    for k, v in s.perturbation.table.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise ConfigError(f"{f}: perturbation.table.{k}: expected number, got {v!r}")
    _check_ranges(s)
    if not s.target.board and s.trajectory.poses < MIN_POSTURES:
        raise ConfigError(
            f"{f}: trajectory.poses = {s.trajectory.poses}: the marker field's self-calibration "
            f"needs {MIN_POSTURES} postures or more (a board of known geometry, target.board, "
            f"{MIN_FRAMES})",
            fix=f"set trajectory.poses = {MIN_POSTURES} or more",
        )


def board_path(s: Scenario) -> Path | None:
    """The target TOML of ``[target] board`` (relative to the scenario file), or None."""
    if not s.target.board:
        return None
    if s.source == "<defaults>":
        return (Path.cwd() / s.target.board).resolve()
    path = (Path(s.source).parent / s.target.board).resolve()
    if not path.is_file():  # a shipped scenario's "../models/..." inside a wheel
        return shipped_model_file(Path(s.source), s.target.board) or path
    return path


def joints_path(s: Scenario) -> Path:
    """The joints file of ``[trajectory] joints`` (relative to the scenario file)."""
    base = Path.cwd() if s.source == "<defaults>" else Path(s.source).parent
    return (base / s.trajectory.joints).resolve()


def scenario_board(s: Scenario) -> Board | None:
    """The board of ``[target] board`` (:class:`selfcal.target.boards.Board`, SI) or None: the
    ArUco field.

    Raises:
        ConfigError: naming the scenario file and ``target.board``: the file is missing, is not
            a target TOML (its own error, naming its key, follows) or declares the field.
    """
    path = board_path(s)
    if path is None:
        return None
    from selfcal.io.target_toml import TargetFileError, load_target  # OpenCV: only when used
    from selfcal.target.boards import Board

    key = f"{s.source}: target.board = {s.target.board!r}"
    if not path.is_file():
        raise ConfigError(
            f"{key}: no such file {path}",
            fix="give the path of a target TOML relative to the scenario file, e.g. "
            '"../models/targets/charuco.toml" (docs/targets.md)',
        )
    try:
        board = load_target(path)
    except TargetFileError as exc:
        raise ConfigError(f"{key}: {exc.message}", fix=exc.fix) from None
    if not isinstance(board, Board):
        raise ConfigError(
            f"{key}: {path} declares the ArUco field, not a board",
            fix="leave target.board out for the marker field ([target] markers, ...), or give a "
            "board's target TOML (chessboard, charuco, circles, aprilgrid)",
        )
    return board


def load_scenario(path: str | Path | None = None, overrides: dict | None = None) -> Scenario:
    """Read a scenario TOML file (default ``scenarios/paper.toml``) over the defaults.

    ``overrides`` is a nested dict applied on top of the file (e.g. from the command line).

    Raises:
        ConfigError: missing file, invalid TOML, unknown key, wrong type or value out of range.
    """
    given = Path(path) if path is not None else default_scenario_path()
    p = scenario_file(given)
    if p is None:
        raise ConfigError(
            f"scenario file not found: {given}",
            fix="give a path to a .toml scenario or the name of a shipped one: "
            + ", ".join(shipped_scenarios())
            + " (`selfcal scenarios`)",
        )
    data = read_toml(p, ConfigError)
    if overrides:
        data = _merge(data, overrides)
    try:
        s = _build(Scenario, data, "", str(p))
    except ConfigError as exc:
        msg = exc.message
        raise ConfigError(msg if msg.startswith(str(p)) else f"{p}: {msg}", fix=exc.fix) from None
    s = dataclasses.replace(s, source=str(p))
    _validate(s)
    return s


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = (
            _merge(out.get(k, {}), v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
        )
    return out


def scenario_to_dict(s: Scenario) -> dict:
    """The scenario as plain data (for dataset.json)."""
    d = dataclasses.asdict(s)
    d.pop("source", None)
    return d
