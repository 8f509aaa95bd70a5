"""The controller's encoder table of a robot file (``[encoder]`` in ``models/<folder>/<name>.toml``).

Keys (units in the names; all per joint, in the file's joint order; only ``counts_per_deg`` is
needed for the simulator's read-back, the others describe the real controller):

- ``counts_per_deg``: read-back resolution, encoder counts per degree (mm: prismatic) of joint
  motion, unsigned. On a differential wrist (``differential_joints``) one degree of pitch or roll
  turns *each* motor by ``c`` counts, so the half-difference/half-sum of the two motor counts
  changes by ``2 c``: the file gives ``2 c`` for both joints.
- ``signs``: +1/-1, the sign of the controller's counts for a positive joint angle (default +1).
- ``zero_deg``: joint angles (deg; mm for a prismatic joint) at which the encoders read zero, in
  the file's DH convention (default: ``home_deg``, an assumption hardware adapters warn about).
- ``motor_counts_per_90deg``: the controller's motor counts per 90 deg (mm: per 90 mm) of joint
  motion, unsigned, as the vendor states them (default: from ``counts_per_deg``, halved on the
  differential joints). Gives the exact table where ``counts_per_deg`` is rounded.
- ``differential_joints``: 1-based ``[pitch, roll]`` joints of a differential wrist, whose motors
  read ``pitch + roll`` and ``roll - pitch`` (default: none).

The read-back (:meth:`EncoderSpec.read_back`) and its noise (:attr:`EncoderSpec.read_back_sigma`)
live here, for the simulator and the calibration alike: every motor's count is rounded to the
nearest integer from the encoder zero. A joint read by its own motor errs by a uniform
fraction of one count, standard deviation ``1 / (c sqrt 12)`` (``c`` counts per rad); pitch and
roll of a differential wrist are the half-difference and half-sum of two motors' rounded counts,
``(e1 -/+ e2) / (2 c)`` with ``c`` each motor's counts per rad of joint motion, so their errors
have standard deviation ``sqrt(2 / 12) / (2 c) = 1 / (c sqrt 24)``: ``sqrt 2`` times what one
joint read at the file's ``counts_per_deg`` (``2 c``) would have, and uncorrelated with each
other (the two motors' errors enter the difference and the sum with equal weight).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from selfcal.errors import InputError

__all__ = ["EncoderSpec", "encoder_spec", "joint_counts", "motor_counts"]


@dataclass(frozen=True, eq=False)
class EncoderSpec:
    """The controller's counts <-> joint angle table, SI units.

    Attributes:
        counts_per_unit: (n,) signed controller counts per rad (per m: prismatic) of joint motion;
            on the ``differential`` joints counts of the half-difference (pitch) and half-sum
            (roll) of the two motor counts.
        zero: (n,) joint posture (rad or m) at which the encoders read zero.
        zero_stated: whether the file states ``zero_deg`` (else ``zero`` is the home posture).
        differential: 0-based ``(pitch, roll)`` joints of a differential wrist, or ``None``.
    """

    counts_per_unit: np.ndarray
    zero: np.ndarray
    zero_stated: bool
    differential: tuple[int, int] | None

    @property
    def read_back_sigma(self) -> np.ndarray:
        """(n,) standard deviation (rad / m) of each joint's read-back error, the motors'
        counts rounded (module docstring): ``1 / (|c| sqrt 12)``, on the differential wrist
        ``1 / (|c| sqrt 24)``. The errors of different joints are uncorrelated."""
        sigma = 1.0 / (np.abs(self.counts_per_unit) * np.sqrt(12.0))
        if self.differential is not None:
            sigma[list(self.differential)] /= np.sqrt(2.0)
        return sigma

    @property
    def count_step(self) -> np.ndarray:
        """(n,) joint motion (rad / m) that turns a joint's motor(s) by one count: ``1 / |c|``.
        A posture moved by a uniform fraction of it in every joint puts each motor at a
        uniformly distributed fraction of its count (on the differential wrist too)."""
        return 1.0 / np.abs(self.counts_per_unit)

    def read_back(self, q: np.ndarray) -> np.ndarray:
        """The joints (rad / m, shape of ``q``) the controller reports with the arm at the true
        posture ``q`` (..., n): every motor's count from the encoder zero rounded to the
        nearest integer, converted back (the differential wrist's pitch and roll from its two
        motors' rounded counts: :func:`motor_counts`, :func:`joint_counts`)."""
        q = np.asarray(q, dtype=float)
        counts = (q - self.zero) * self.counts_per_unit
        read = joint_counts(np.rint(motor_counts(counts, self.differential)), self.differential)
        return self.zero + read / self.counts_per_unit


def motor_counts(joint: np.ndarray, differential: tuple[int, int] | None) -> np.ndarray:
    """The motors' counts (..., n) of joint-space counts ``joint`` (..., n), both from the
    encoder zero, not rounded: each joint's own motor, except on a differential wrist
    (0-based ``(pitch, roll)``), whose motors read ``pitch + roll`` and ``roll - pitch``.
    Unit-free (counts in, counts out); :func:`joint_counts` is its inverse."""
    joint = np.asarray(joint, dtype=float)
    if differential is None:
        return joint.copy()
    p, r = differential
    out = joint.copy()
    out[..., p] = joint[..., p] + joint[..., r]
    out[..., r] = joint[..., r] - joint[..., p]
    return out


def joint_counts(motor: np.ndarray, differential: tuple[int, int] | None) -> np.ndarray:
    """The joint-space counts (..., n) of motor counts ``motor`` (..., n), the inverse of
    :func:`motor_counts`: on a differential wrist pitch is the half-difference and roll the
    half-sum of its two motors' counts."""
    motor = np.asarray(motor, dtype=float)
    if differential is None:
        return motor.copy()
    p, r = differential
    out = motor.copy()
    out[..., p] = (motor[..., p] - motor[..., r]) / 2.0
    out[..., r] = (motor[..., p] + motor[..., r]) / 2.0
    return out


def _per_joint(table: dict[str, Any], key: str, n: int) -> np.ndarray | None:
    if key not in table:
        return None
    try:
        v = np.asarray(table[key], dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{key}: not numbers ({exc})") from None
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise InputError(f"{key} must be {n} finite numbers, got {table[key]}")
    return v


def encoder_spec(
    table: dict[str, Any], resolution: np.ndarray, home: np.ndarray, unit: np.ndarray
) -> EncoderSpec | None:
    """The :class:`EncoderSpec` of an ``[encoder]`` ``table`` (module docstring), or ``None``
    when the robot has no finite read-back ``resolution`` (n,) (counts per rad or m). ``home``
    (n,) is the home posture (rad or m), ``unit`` (n,) the size of a file unit (deg or mm) in SI.

    Raises:
        InputError: a malformed or unknown key, or a differential wrist whose two joints have
            different resolutions (the message names the key; the loader adds the file).
    """
    n = len(home)
    if not np.all(np.isfinite(resolution)):
        return None
    known = {"counts_per_deg", "signs", "zero_deg", "motor_counts_per_90deg", "differential_joints"}
    unknown = sorted(set(table) - known)
    if unknown:
        raise InputError(f"unknown key(s) {unknown}; known: {sorted(known)}")
    signs = _per_joint(table, "signs", n)
    if signs is None:
        signs = np.ones(n)
    if not np.all(np.abs(signs) == 1):
        raise InputError(f"signs must be +1 or -1, got {table['signs']}")
    zero = _per_joint(table, "zero_deg", n)
    diff = table.get("differential_joints")
    differential = None
    if diff is not None:
        if (
            not isinstance(diff, list)
            or len(diff) != 2
            or not all(isinstance(d, int) and 1 <= d <= n for d in diff)
            or diff[0] == diff[1]
        ):
            raise InputError(
                f"differential_joints must be two different joints [pitch, roll] in "
                f"1..{n}, got {diff}"
            )
        differential = (diff[0] - 1, diff[1] - 1)
    motor = _per_joint(table, "motor_counts_per_90deg", n)
    if motor is not None:
        if not np.all(motor > 0):
            raise InputError("motor_counts_per_90deg must be positive")
        counts = motor / (90.0 * unit)
    else:
        counts = np.array(resolution, dtype=float)
        if differential is not None:
            p, r = differential
            if not np.isclose(resolution[p], resolution[r], rtol=1e-6):
                raise InputError(
                    f"counts_per_deg gives {resolution[p] * unit[p]:g} and "
                    f"{resolution[r] * unit[r]:g} for the differential joints {p + 1} and {r + 1}; "
                    "the wrist has one resolution for both (2 x each motor's counts per degree)",
                    fix=f"set both to {resolution[p] * unit[p]:g}",
                )
            counts[[p, r]] = resolution[p] / 2.0
    return EncoderSpec(
        counts_per_unit=signs * counts,
        zero=home.copy() if zero is None else zero * unit,
        zero_stated=zero is not None,
        differential=differential,
    )
