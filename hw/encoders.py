"""Encoder counts <-> joint angles (deg, the robot model's DH convention).

Per axis ``i``: ``counts_i = home_counts_i + counts_per_deg_i * (q_i - home_deg_i)``, where
``counts_per_deg`` carries the sign (ER-4u: base and shoulder count negative for positive DH
angles) and ``home_deg`` is the posture at which the axis reads ``home_counts`` (the encoders are
zeroed by HOME, so by default ``home_counts = 0`` at the home posture).

The ER-4u wrist is a differential: motors 4 and 5 both turn for pitch and for roll. In motor
counts ``pitch = (enc4 - enc5) / 2`` and ``roll = (enc4 + enc5) / 2``, so
``enc4 = pitch + roll`` and ``enc5 = roll - pitch``; ``counts_per_deg`` of the pitch and roll axes
is in those (half-sum / half-difference) counts per joint degree.

Defaults (``EncoderTable.er4u()``), from ``shared/hardware/acl-notes.md``: -12770, -10216, +10216
counts per +90 deg for base, shoulder, elbow and 2511 for each wrist motor; encoder zero = the
vendor home posture (0, 120.28, -95.02, -88.81, 0) deg of the ``er4u-vendor`` model. The wrist signs
are not settled by the sources: override them from the config if the arm disagrees.

``EncoderTable.for_robot(model)``: the table of any model from its TOML (zero at its ``home_deg``,
resolution from ``[encoder] counts_per_deg``), used by the simulated-robot emulator backend and by
the adapter when the config gives no table.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from calib.errors import InputError
from calib.robot_def import RobotDef, load_robot

__all__ = ["EncoderTable", "ER4U_COUNTS_PER_DEG", "ER4U_HOME_DEG", "ER4U_SIGNS"]

ER4U_COUNTS_PER_DEG = (-12770 / 90, -10216 / 90, 10216 / 90, 2511 / 90, 2511 / 90)
"""Signed counts per joint degree of the ER-4u (base, shoulder, elbow, pitch, roll)."""
ER4U_HOME_DEG = (0.0, 120.28, -95.02, -88.81, 0.0)
"""Joint angles (deg, ``er4u-vendor`` DH convention) at which the ER-4u encoders read zero."""
ER4U_SIGNS = (-1, -1, 1, 1, 1)
"""Sign of counts per positive DH angle on the ER-4u (base and shoulder count down)."""

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
    differential: tuple[int, int] | None = (3, 4)

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
    def er4u(cls) -> EncoderTable:
        """The ER-4u defaults of the notes (see the module docstring)."""
        return cls(np.array(ER4U_COUNTS_PER_DEG), np.array(ER4U_HOME_DEG), np.zeros(5), (3, 4))

    @classmethod
    def for_robot(
        cls,
        robot: RobotDef | str,
        *,
        signs: Any = None,
        differential: tuple[int, int] | None | str = "auto",
    ) -> EncoderTable:
        """Table of a robot model: encoder zero at the model's home posture (TOML ``home_deg``),
        resolution from its TOML ``[encoder] counts_per_deg``.

        The TOML's ``counts_per_deg`` is the read-back resolution: counts per degree of joint
        motion (``sim.sim_robot`` quantises to ``1 / counts_per_deg``). On a differential wrist one
        joint degree moves *each* motor by ``c`` counts, so ``(e4 -/+ e5)`` changes by ``2 c``
        per degree of pitch and of roll alike: the resolution is ``2 c`` for both axes and the
        table's value is ``c`` = TOML / 2. Pitch and roll must therefore have the same TOML value;
        if they differ the pitch value is used (ER-4u: 55.80 = 2 x 2511/90, the vendor's 2511
        counts per 90 deg per motor) and a ``UserWarning`` names the file.

        Args:
            robot: model name or ``RobotDef``.
            signs: (n,) +1/-1 per axis (default: ``ER4U_SIGNS`` for a 5-axis arm, else +1).
            differential: 0-based (pitch, roll) axes of a differential wrist, ``None``, or
                ``"auto"`` (= (3, 4) for a 5-axis arm).

        Raises:
            ValueError: the model has no finite ``[encoder] counts_per_deg`` or a non-revolute
                joint.
        """
        robot = load_robot(robot) if isinstance(robot, str) else robot
        n = robot.n
        if any(t != "revolute" for t in robot.joint_types):
            raise InputError(f"{robot.name}: encoder tables support revolute joints only")
        res = np.abs(np.asarray(robot.counts_per_unit, dtype=float)) * np.pi / 180.0
        if not np.all(np.isfinite(res) & (res > 0)):
            raise InputError(
                f"{robot.name}: the model has no [encoder] counts_per_deg; give an encoder table "
                "([robot.hardware.options.encoders] counts_per_deg, home_deg)"
            )
        if signs is None:
            signs = ER4U_SIGNS if n == 5 else (1,) * n
        sg = np.sign(np.asarray(signs, dtype=float).reshape(-1))
        if sg.size != n or np.any(sg == 0):
            raise InputError(f"signs must be {n} values of +1 or -1, got {signs}")
        if isinstance(differential, str):
            if differential != "auto":
                raise InputError(
                    f"differential must be (pitch, roll), None or 'auto', got {differential!r}"
                )
            differential = (3, 4) if n == 5 else None
        cpd = sg * res
        if differential is not None:
            p, r = differential
            if not np.isclose(res[p], res[r], rtol=1e-6):
                warnings.warn(
                    f"models/robots/{robot.name}.toml: [encoder] counts_per_deg gives "
                    f"{res[p]:g} for {robot.joint_names[p]} and {res[r]:g} for "
                    f"{robot.joint_names[r]}, but the differential wrist has one resolution for "
                    f"both (2 x the counts per degree of each motor); using {res[p]:g} for both "
                    f"-- set both to {res[p]:g} in the TOML",
                    UserWarning,
                    stacklevel=2,
                )
            cpd[p] = sg[p] * res[p] / 2.0
            cpd[r] = sg[r] * res[p] / 2.0
        # the TOML states degrees with a few decimals: drop the rad <-> deg round-off
        return cls(np.round(cpd, 9), np.round(np.degrees(robot.home), 9), np.zeros(n), differential)

    @classmethod
    def from_config(
        cls, cfg: Mapping[str, Any] | None, base: EncoderTable | None = None
    ) -> EncoderTable:
        """Table from a config dict (keys ``counts_per_deg``, ``home_deg``, ``home_counts``,
        ``differential`` = [pitch axis, roll axis] 1-based or ``false``), missing keys taken from
        ``base`` (default: the ER-4u table).

        Raises:
            ValueError: unknown keys or malformed values (the message names them).
        """
        base = base or cls.er4u()
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
        res = 1.0 / np.abs(self.counts_per_deg)
        if self.differential:
            res[list(self.differential)] /= 2.0
        return res

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
        if self.differential:
            p, r = self.differential
            hp, hr = self._home_pitch_roll()
            pc, rc = c[..., p] + hp, c[..., r] + hr
            out = np.rint(c + self.home_counts).astype(np.int64)
            out[..., p] = np.rint(pc + rc).astype(np.int64)
            out[..., r] = np.rint(rc - pc).astype(np.int64)
            return out
        return np.rint(c + self.home_counts).astype(np.int64)

    def to_degrees(self, counts: np.ndarray) -> np.ndarray:
        """Encoder counts (shape (..., n)) -> joint angles (deg)."""
        e = self._check(counts, "counts")
        rel = e - self.home_counts
        if self.differential:
            p, r = self.differential
            hp, hr = self._home_pitch_roll()
            pc = (e[..., p] - e[..., r]) / 2.0
            rc = (e[..., p] + e[..., r]) / 2.0
            rel = rel.copy()
            rel[..., p] = pc - hp
            rel[..., r] = rc - hr
        return self.home_deg + rel / self.counts_per_deg

    def _home_pitch_roll(self) -> tuple[float, float]:
        p, r = self.differential  # type: ignore[misc]
        h4, h5 = float(self.home_counts[p]), float(self.home_counts[r])
        return (h4 - h5) / 2.0, (h4 + h5) / 2.0
