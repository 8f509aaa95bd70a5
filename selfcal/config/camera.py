"""The scenario's ``[camera]`` table and its per-camera ``[camera.right]`` table, and their checks.

``[camera]`` describes every camera of the rig; ``[camera.right]`` (any of
:data:`PER_CAMERA_KEYS`) gives the right camera its own true lens and its own estimated
intrinsics. Read by :func:`selfcal.config.scenario.load_scenario`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from selfcal.camera import MODELS, Pinhole, camera_model, centered_principal_point, lens_names
from selfcal.choices import SETUPS
from selfcal.errors import InputError

__all__ = ["CameraConfig", "ConfigError", "PER_CAMERA_KEYS", "SETUPS", "check_setup",
           "validate_camera"]  # fmt: skip


class ConfigError(InputError):
    """A scenario file that cannot be used; the message names the file, key and expected type."""


PER_CAMERA_KEYS = (
    "fx",
    "mu",
    "model",
    "principal_point_offset_px",
    "skew_px",
    "distortion",
    "free",
)
"""The ``[camera]`` keys a ``[camera.right]`` table may give the right camera its own value of
(its true lens and what is estimated of it; resolution, baseline and count are the rig's)."""


@dataclass(frozen=True)
class CameraConfig:
    resolution: list[int] = field(default_factory=lambda: [640, 480])
    fx: float = 800.0
    """Focal length in px: the true value in simulation, unknown to the calibration."""
    mu: float = 1.0
    """Aspect ratio: fy = mu * fx."""
    baseline_mm: float = 60.0
    count: int = 2
    """Cameras the calibration uses: 2 (the wrist stereo pair, ``left`` and ``right``) or 1 (the
    ``left`` camera alone, the paper's own one-camera setup: its "stereo images" are views from
    two configurations)."""
    model: str = "pinhole"
    """Camera model of both cameras: "pinhole", "opencv" (Brown-Conrady k1, k2, p1, p2, k3,
    k4-k6) or "fisheye" (Kannala-Brandt k1-k4); OpenCV's conventions and names."""
    principal_point_offset_px: list[float] = field(default_factory=lambda: [0.0, 0.0])
    """True principal point minus the image centre ((W - 1) / 2, (H - 1) / 2), px (simulation)."""
    skew_px: float = 0.0
    """True skew ``K[0, 1]`` in px (simulation: ``u = fx x + skew y + cx``; MuJoCo has none, the
    renderer draws it through the lens remap). The calibration starts from 0 and estimates it
    when ``free`` names ``skew``."""
    distortion: dict = field(default_factory=dict)
    """True lens coefficients by OpenCV name, e.g. {k1 = -0.25, p1 = 1e-3} (simulation; the
    others are zero). The calibration starts from no distortion."""
    free: list[str] = field(default_factory=lambda: ["fx", "mu"])
    """Parameters the calibration estimates, by name (fx, mu = fy / fx or its OpenCV name fy,
    cx, cy and the model's lens coefficients); the others stay at their start (the image centre,
    no distortion). ``fy`` is read as ``mu`` (the one parametrisation the estimation uses)."""
    setup: str = "eye-in-hand"
    """Where the camera is: ``"eye-in-hand"`` (on the flange, the target static in the cell) or
    ``"eye-to-hand"`` (static in the cell, looking at a board on the flange: needs ``[target]
    board`` and ``count = 1``; the simulator places it 0.6 m in front of the board at home, the
    wrist turned so that the board faces away from the arm)."""
    pose: list[float] = field(default_factory=list)
    """Eye-to-hand: where the static camera stands instead, ``[x, y, z, rx, ry, rz]`` mm and deg,
    its centre in the robot's base frame and the rotation of its OpenCV axes from the base's
    (fixed axes x, y, z: ``R = Rz Ry Rx``; :func:`selfcal.target.placement.camera_pose`), as
    ``selfcal plan --camera-pose`` resolves it. Empty: in front of the board at home."""
    right: dict = field(default_factory=dict)
    """``[camera.right]``: how the right camera differs from ``[camera]`` (any of
    :data:`PER_CAMERA_KEYS`; the others are ``[camera]``'s). Empty: both cameras are ``[camera]``'s
    and share one estimated camera (the paper's); a table: the right camera has its own true lens
    and its own estimated intrinsics."""

    def __post_init__(self) -> None:
        free = list(self.free)
        if "mu" not in free:  # both named: the validation says so with the file's name
            free = ["mu" if n == "fy" else n for n in free]
        object.__setattr__(self, "free", free)

    @property
    def names(self) -> tuple[str, ...]:
        """The dataset's camera names: ``("left", "right")`` or ``("left",)``."""
        return ("left", "right")[: self.count]

    def of(self, name: str) -> CameraConfig:
        """The camera ``name`` (``left``, ``right``): ``[camera]`` with the ``[camera.right]``
        keys for the right camera (no ``right`` table of its own)."""
        over = self.right if name == "right" else {}
        return dataclasses.replace(self, **over, right={})

    @property
    def own_intrinsics(self) -> bool:
        """True when the right camera differs (a ``[camera.right]`` table, two cameras)."""
        return bool(self.right) and self.count > 1

    def true_models(self) -> tuple[Pinhole, ...]:
        """The simulated camera of every name of :attr:`names`."""
        return tuple(self.of(n).true_model() for n in self.names)

    def true_model(self) -> Pinhole:
        """The simulated (left) camera (principal point offset, lens) with the ``free``
        selection."""
        W, H = self.resolution
        cx, cy = centered_principal_point(W, H)
        dx, dy = self.principal_point_offset_px
        return camera_model(
            self.model, fx=self.fx, mu=self.mu, cx=cx + dx, cy=cy + dy, width=W, height=H,
            coeffs=self.distortion, free=self.free, skew=self.skew_px,
        )  # fmt: skip


def validate_camera(f: str, c: CameraConfig, key: str) -> None:
    """Check the camera ``c`` of the table ``key`` (``camera``, ``camera.right``) of file ``f``."""
    if c.model not in MODELS:
        raise ConfigError(
            f"{f}: {key}.model must be one of {', '.join(sorted(MODELS))}, got {c.model!r}"
        )
    if len(c.principal_point_offset_px) != 2:
        raise ConfigError(f"{f}: {key}.principal_point_offset_px must be [dx, dy] in px")
    known = lens_names(c.model)
    for k, v in c.distortion.items():
        if k not in known:
            raise ConfigError(
                f"{f}: unknown key '{key}.distortion.{k}'; the {c.model!r} model has "
                f"{', '.join(known) or 'no lens coefficients'}",
                fix=f'set {key}.model = "opencv" or "fisheye" for a lens, or remove the key',
            )
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise ConfigError(f"{f}: {key}.distortion.{k}: expected number, got {v!r}")
    names = MODELS[c.model].names
    if "fy" in c.free:  # left by CameraConfig only when mu is named as well
        raise ConfigError(
            f"{f}: {key}.free names both 'fy' and 'mu'; fy is OpenCV's name for the same "
            "freedom (mu = fy / fx with fx free)",
            fix=f"keep one of them in {key}.free",
        )
    for n in c.free:
        if n not in names:
            raise ConfigError(
                f"{f}: {key}.free: {n!r} is not a parameter of the {c.model!r} model; "
                f"use names of {', '.join(names)}"
            )
    if "fx" not in c.free or len(set(c.free)) != len(c.free):
        raise ConfigError(f"{f}: {key}.free must list distinct names and include 'fx'")


def check_setup(s: Any) -> None:
    """ConfigError for a ``[camera] setup`` of the scenario ``s``
    (:class:`selfcal.config.scenario.Scenario`; not imported: it imports this module) the
    simulator cannot build: an unknown one,
    eye-to-hand without a board, with two cameras, on hardware, with a ``[target] board_pose``
    (the board rides on the flange) or a ``camera.pose`` of other than six numbers, or a
    ``camera.pose`` on the flange (eye-in-hand)."""
    f, setup = s.source, s.camera.setup
    if setup not in SETUPS:
        raise ConfigError(f"{f}: camera.setup must be one of {', '.join(SETUPS)}, got {setup!r}")
    if setup == "eye-in-hand" and s.camera.pose:
        raise ConfigError(f"{f}: camera.pose places a static camera; this camera rides on the "
                          "flange (camera.setup = \"eye-in-hand\")",
                          fix="set camera.setup = \"eye-to-hand\", or remove camera.pose")  # fmt: skip
    if setup == "eye-in-hand":
        return
    if len(s.camera.pose) not in (0, 6) or s.target.board_pose:
        raise ConfigError(f"{f}: eye-to-hand the board rides on the flange and camera.pose, if "
                          "given, is [x, y, z, rx, ry, rz] (mm, deg)",
                          fix="give camera.pose 6 numbers and leave target.board_pose out")  # fmt: skip
    if not s.target.board:
        raise ConfigError(f"{f}: camera.setup = \"eye-to-hand\" needs a board on the flange",
                          fix="set [target] board to a target TOML (e.g. "
                          "models/targets/charuco.toml)")  # fmt: skip
    if s.camera.count != 1 or s.robot.backend != "sim":
        raise ConfigError(f"{f}: camera.setup = \"eye-to-hand\" is simulated with one static "
                          "camera (camera.count = 1, robot.backend = \"sim\")",
                          fix="set camera.count = 1 and robot.backend = \"sim\"")  # fmt: skip
