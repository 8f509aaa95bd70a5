"""Scenario configuration: TOML files over typed defaults.

Every key has a default, so a scenario file states only what it changes. Units at this edge are
those of the key names (``_mm``, ``_deg``, ``px``); the code converts to SI where it uses them.
An unknown key or a value of the wrong type is an error naming the file, the key and the type.
"""

from __future__ import annotations

import dataclasses
import sys
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from calib.calibrate import MIN_POSTURES
from calib.camera import MODELS, CameraModel, camera_model, centered_principal_point, lens_names
from calib.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Scenario", "ConfigError", "load_scenario", "default_scenario_path", "scenario_to_dict"]


class ConfigError(InputError):
    """A scenario file that cannot be used; the message names the file, key and expected type."""


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
    model: str = "er4u-paper"
    """Nominal kinematics by name (models/robots/<name>.toml)."""
    backend: str = "sim"
    """"sim" or "hardware"."""
    hardware: HardwareConfig = field(default_factory=HardwareConfig)


@dataclass(frozen=True)
class CameraConfig:
    resolution: list[int] = field(default_factory=lambda: [640, 480])
    fx: float = 800.0
    """Focal length in px: the true value in simulation, unknown to the calibration."""
    mu: float = 1.0
    """Aspect ratio: fy = mu * fx."""
    baseline_mm: float = 60.0
    model: str = "pinhole"
    """Camera model of both cameras: "pinhole", "opencv" (Brown-Conrady k1, k2, p1, p2, k3,
    k4-k6) or "fisheye" (Kannala-Brandt k1-k4); OpenCV's conventions and names."""
    principal_point_offset_px: list[float] = field(default_factory=lambda: [0.0, 0.0])
    """True principal point minus the image centre ((W - 1) / 2, (H - 1) / 2), px (simulation)."""
    distortion: dict = field(default_factory=dict)
    """True lens coefficients by OpenCV name, e.g. {k1 = -0.25, p1 = 1e-3} (simulation; the
    others are zero). The calibration starts from no distortion."""
    free: list[str] = field(default_factory=lambda: ["fx", "mu"])
    """Parameters the calibration estimates, by name (fx, mu = fy / fx, cx, cy and the model's
    lens coefficients); the others stay at their start (the image centre, no distortion)."""

    def true_model(self) -> CameraModel:
        """The simulated camera (principal point offset, lens) with the ``free`` selection."""
        W, H = self.resolution
        cx, cy = centered_principal_point(W, H)
        dx, dy = self.principal_point_offset_px
        return camera_model(
            self.model, fx=self.fx, mu=self.mu, cx=cx + dx, cy=cy + dy, width=W, height=H,
            coeffs=self.distortion, free=self.free,
        )  # fmt: skip


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
    """"random" (postures drawn in a window around home) or "optimal" (D-optimal selection)."""
    min_markers: int = 6
    """A pose is kept only if both cameras see at least this many of 36 points spread over the
    target region (nominal prediction), i.e. a good part of the marker field."""


@dataclass(frozen=True)
class NoiseConfig:
    render: bool = True
    """false: analytic corner projections instead of rendered images (fast path)."""
    image_sigma: float = 2.0
    """Rendered path: Gaussian sensor noise on pixel intensities (0-255 scale)."""
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


def default_scenario_path() -> Path:
    """``scenarios/paper.toml``, the default scenario."""
    return Path(__file__).resolve().parent / "paper.toml"


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
        raise TypeError(f"unsupported schema type {tp}")
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
            raise ConfigError(
                f"{file}: unknown key '{where}{key}'; allowed in "
                f"[{where.rstrip('.') or 'top level'}]: {', '.join(sorted(names))}",
                fix="check the spelling; `selfcal run --help` lists every key with its default",
            )
        tp = hints[key]
        if isinstance(tp, type) and dataclasses.is_dataclass(tp):
            if not isinstance(value, dict):
                raise ConfigError(f"{file}: '{where}{key}' must be a table [{where}{key}]")
            kwargs[key] = _build(tp, value, f"{where}{key}.", file)
        else:
            kwargs[key] = _coerce(value, tp, f"{where}{key}")
    return cls(**kwargs)


def _validate(s: Scenario) -> None:
    f = s.source
    if s.robot.backend not in ("sim", "hardware"):
        raise ConfigError(
            f'{f}: robot.backend must be "sim" or "hardware", got {s.robot.backend!r}'
        )
    if s.trajectory.kind not in ("random", "optimal"):
        raise ConfigError(
            f'{f}: trajectory.kind must be "random" or "optimal", got {s.trajectory.kind!r}'
        )
    if len(s.camera.resolution) != 2 or min(s.camera.resolution) < 16:
        raise ConfigError(f"{f}: camera.resolution must be [width, height] in px, each >= 16")
    if len(s.robot.hardware.cameras) != 2:
        raise ConfigError(f"{f}: robot.hardware.cameras must list two cameras: [left, right]")
    _validate_camera(s)
    checks = [
        (s.camera.fx > 0, "camera.fx must be > 0 (px)"),
        (s.camera.mu > 0, "camera.mu must be > 0"),
        (s.camera.baseline_mm > 0, "camera.baseline_mm must be > 0"),
        (s.target.markers >= 4, "target.markers must be >= 4"),
        (s.target.scale_length_mm > 0, "target.scale_length_mm must be > 0"),
        (s.target.marker_size_mm > 0, "target.marker_size_mm must be > 0"),
        (s.target.extent_mm > 0, "target.extent_mm must be > 0"),
        (s.perturbation.translation_mm >= 0, "perturbation.translation_mm must be >= 0"),
        (s.perturbation.rotation_deg >= 0, "perturbation.rotation_deg must be >= 0"),
        (
            s.trajectory.poses >= MIN_POSTURES,
            f"trajectory.poses must be >= {MIN_POSTURES} (what a calibration needs)",
        ),
        (
            1 <= s.trajectory.min_markers <= 36,
            "trajectory.min_markers must be 1..36 (the planner checks 36 points of the target region)",
        ),
        (s.noise.image_sigma >= 0, "noise.image_sigma must be >= 0"),
        (s.noise.pixel_sigma >= 0, "noise.pixel_sigma must be >= 0"),
        (s.validation.poses >= 3, "validation.poses must be >= 3"),
    ]
    for ok, msg in checks:
        if not ok:
            raise ConfigError(f"{f}: {msg}")
    for k, v in s.perturbation.table.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise ConfigError(f"{f}: perturbation.table.{k}: expected number, got {v!r}")


def _validate_camera(s: Scenario) -> None:
    f, c = s.source, s.camera
    if c.model not in MODELS:
        raise ConfigError(
            f"{f}: camera.model must be one of {', '.join(sorted(MODELS))}, got {c.model!r}"
        )
    if len(c.principal_point_offset_px) != 2:
        raise ConfigError(f"{f}: camera.principal_point_offset_px must be [dx, dy] in px")
    known = lens_names(c.model)
    for k, v in c.distortion.items():
        if k not in known:
            raise ConfigError(
                f"{f}: unknown key 'camera.distortion.{k}'; the {c.model!r} model has "
                f"{', '.join(known) or 'no lens coefficients'}",
                fix='set camera.model = "opencv" or "fisheye" for a lens, or remove the key',
            )
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise ConfigError(f"{f}: camera.distortion.{k}: expected number, got {v!r}")
    names = MODELS[c.model].names
    for n in c.free:
        if n not in names:
            raise ConfigError(
                f"{f}: camera.free: {n!r} is not a parameter of the {c.model!r} model; "
                f"use names of {', '.join(names)}"
            )
    if "fx" not in c.free or len(set(c.free)) != len(c.free):
        raise ConfigError(f"{f}: camera.free must list distinct names and include 'fx'")


def load_scenario(path: str | Path | None = None, overrides: dict | None = None) -> Scenario:
    """Read a scenario TOML file (default ``scenarios/paper.toml``) over the defaults.

    ``overrides`` is a nested dict applied on top of the file (e.g. from the command line).

    Raises:
        ConfigError: missing file, invalid TOML, unknown key, wrong type or value out of range.
    """
    p = Path(path) if path is not None else default_scenario_path()
    if not p.is_file():
        raise ConfigError(f"scenario file not found: {p} (give a path to a .toml scenario)")
    try:
        data = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from exc
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
