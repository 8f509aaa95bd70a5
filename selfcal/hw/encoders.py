"""Encoder counts <-> joint angles (deg, the robot model's DH convention).

Per axis ``i``: ``counts_i = home_counts_i + counts_per_deg_i * (q_i - home_deg_i)``, where
``counts_per_deg`` carries the sign (ER-4u: base and shoulder count negative for positive DH
angles) and ``home_deg`` is the posture at which the axis reads ``home_counts`` (the encoders are
zeroed by HOME, so by default ``home_counts = 0`` at the home posture).

The ER-4u wrist is a differential: motors 4 and 5 both turn for pitch and for roll. In motor
counts ``pitch = (enc4 - enc5) / 2`` and ``roll = (enc4 + enc5) / 2``, so
``enc4 = pitch + roll`` and ``enc5 = roll - pitch``; ``counts_per_deg`` of the pitch and roll axes
is in those (half-sum / half-difference) counts per joint degree. That arithmetic has one home,
:func:`selfcal.robot.encoder.motor_counts` / :func:`~selfcal.robot.encoder.joint_counts`, which
the simulator's read-back (:meth:`selfcal.robot.encoder.EncoderSpec.read_back`) uses too.

The numbers live in the robot file's ``[encoder]`` table (keys: :mod:`selfcal.robot.encoder`;
ER-4u: ``models/scorbot_er4u/er4u-vendor.toml``). ``EncoderTable.for_robot(model)`` builds the table of a
model from it; the simulated-robot emulator backend and the adapter (when the config gives no
table) use it, and a config's ``encoders`` table overrides it key by key (``from_config``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from selfcal.errors import InputError
from selfcal.robot.definition import RobotDef, load_robot, robot_files
from selfcal.robot.encoder import joint_counts, motor_counts

__all__ = ["EncoderTable"]

_CONFIG_KEYS = {"counts_per_deg", "home_deg", "home_counts", "differential"}


@dataclass(frozen=True, eq=False)
class EncoderTable:
    """Per-axis conversion between encoder counts and joint angles.

    Attributes:
        counts_per_deg: (n,) signed counts per joint degree (for the differential axes: counts of
            ``(enc4 -/+ enc5) / 2`` per degree of pitch/roll).
        home_deg: (n,) joint angles (deg) at which the counts equal ``home_counts``.
        home_counts: (n,) encoder (motor) counts at ``home_deg``.
        differential: 0-based (pitch axis, roll axis) of a differential wrist, or ``None``.
    """

    counts_per_deg: np.ndarray
    home_deg: np.ndarray
    home_counts: np.ndarray
    differential: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        cpd = np.asarray(self.counts_per_deg, dtype=float).reshape(-1)
        n = cpd.size
        home = np.asarray(self.home_deg, dtype=float).reshape(-1)
        hc = np.asarray(self.home_counts, dtype=float).reshape(-1)
        if n == 0:
            raise InputError("encoder table: counts_per_deg is empty")
        if home.size != n or hc.size != n:
            raise InputError(
                f"encoder table: counts_per_deg ({n}), home_deg ({home.size}) and home_counts "
                f"({hc.size}) must have one value per axis"
            )
        if not (np.all(np.isfinite(cpd)) and np.all(cpd != 0)):
            raise InputError(
                f"encoder table: counts_per_deg must be finite and non-zero, got {cpd}"
            )
        if not np.all(np.isfinite(home)):
            raise InputError(f"encoder table: home_deg must be finite, got {home}")
        if not np.all(hc == np.round(hc)):
            raise InputError(f"encoder table: home_counts must be integers, got {hc}")
        diff = self.differential
        if diff is not None:
            diff = (int(diff[0]), int(diff[1]))
            if diff[0] == diff[1] or not all(0 <= d < n for d in diff):
                raise InputError(
                    f"encoder table: differential must name two different axes in 1..{n}, "
                    f"got {tuple(d + 1 for d in diff)} (1-based)"
                )
        object.__setattr__(self, "counts_per_deg", cpd)
        object.__setattr__(self, "home_deg", home)
        object.__setattr__(self, "home_counts", hc.astype(np.int64))
        object.__setattr__(self, "differential", diff)

    @property
    def n(self) -> int:
        return int(self.counts_per_deg.size)

    @classmethod
    def for_robot(cls, robot: RobotDef | str) -> EncoderTable:
        """The table of a robot model, from its file's ``[encoder]`` (:mod:`selfcal.robot.encoder`):
        signed counts per degree, encoder zero (``zero_deg``, else the home posture), the
        differential wrist; all counts read zero at that posture.

        Raises:
            InputError: the model has no finite ``[encoder] counts_per_deg``, or a non-revolute
                joint.
        """
        robot = load_robot(robot) if isinstance(robot, str) else robot
        if any(t != "revolute" for t in robot.joint_types):
            raise InputError(f"{robot.name}: encoder tables support revolute joints only")
        enc = robot.encoder
        if enc is None:
            raise InputError(
                f"{robot.name}: the model has no [encoder] counts_per_deg",
                fix="give an encoder table ([robot.hardware.options.encoders] counts_per_deg, "
                f"home_deg) or add [encoder] to {robot_files().get(robot.name, 'its robot file')}",
            )
        cpd = enc.counts_per_unit * np.pi / 180.0
        # the TOML states degrees with a few decimals: drop the rad <-> deg round-off
        return cls(
            np.round(cpd, 9),
            np.round(np.degrees(enc.zero), 9),
            np.zeros(robot.n),
            enc.differential,
        )

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None, base: EncoderTable) -> EncoderTable:
        """Table from a config dict (keys ``counts_per_deg``, ``home_deg``, ``home_counts``,
        ``differential`` = [pitch axis, roll axis] 1-based or ``false``), missing keys taken from
        ``base`` (e.g. ``for_robot(model)``).

        Raises:
            ValueError: unknown keys or malformed values (the message names them).
        """
        cfg = dict(cfg or {})
        unknown = set(cfg) - _CONFIG_KEYS
        if unknown:
            raise InputError(
                f"unknown encoder config key(s) {sorted(unknown)}; known: {sorted(_CONFIG_KEYS)}"
            )
        cpd = np.asarray(cfg.get("counts_per_deg", base.counts_per_deg), dtype=float)
        n = cpd.size
        home = cfg.get("home_deg", base.home_deg if base.n == n else None)
        hc = cfg.get("home_counts", base.home_counts if base.n == n else np.zeros(n))
        if home is None:
            raise InputError(f"encoder config: home_deg is needed for a {n}-axis table")
        diff = cfg.get("differential", "base")
        if isinstance(diff, str) and diff == "base":
            d = base.differential if base.n == n else None
        elif diff is False or diff is None:
            d = None
        else:
            vals = list(diff)
            if len(vals) != 2:
                raise InputError(
                    "encoder config: differential must be [pitch_axis, roll_axis] (1-based) or false"
                )
            d = (int(vals[0]) - 1, int(vals[1]) - 1)
        return cls(cpd, np.asarray(home, dtype=float), np.asarray(hc, dtype=float), d)

    def to_config(self) -> dict[str, Any]:
        """The dict ``from_config`` reads back."""
        return {
            "counts_per_deg": [float(x) for x in self.counts_per_deg],
            "home_deg": [float(x) for x in self.home_deg],
            "home_counts": [int(x) for x in self.home_counts],
            "differential": [d + 1 for d in self.differential] if self.differential else False,
        }

    @property
    def resolution_deg(self) -> np.ndarray:
        """(n,) joint angle of one motor count (deg); half that on the differential axes."""
        # one motor's count moves each joint it drives by this many joint-space counts
        per_motor = np.abs(joint_counts(np.eye(self.n), self.differential)).max(axis=0)
        return per_motor / np.abs(self.counts_per_deg)

    def _check(self, x: np.ndarray, what: str) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.ndim == 0 or x.shape[-1] != self.n:
            raise InputError(f"{what} must have shape (..., {self.n}), got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise InputError(f"{what} must be finite, got {x}")
        return x

    def to_counts(self, joints_deg: np.ndarray) -> np.ndarray:
        """Joint angles (deg, shape (..., n)) -> nearest integer encoder counts (int64)."""
        q = self._check(joints_deg, "joints_deg")
        c = self.counts_per_deg * (q - self.home_deg)  # joint-space counts relative to home
        return np.rint(motor_counts(c, self.differential) + self.home_counts).astype(np.int64)

    def to_degrees(self, counts: np.ndarray) -> np.ndarray:
        """Encoder counts (shape (..., n)) -> joint angles (deg)."""
        e = self._check(counts, "counts")
        rel = joint_counts(e - self.home_counts, self.differential)
        return self.home_deg + rel / self.counts_per_deg
