"""A joint compliance: a misfit no rigid kinematic chain expresses (issue #29's misfitting model).

The true robot's joint ``joint`` turns past its reading by ``amplitude_rad * cos(sum of the
coupled joints)``: a shoulder bending under the arm's own weight, most where the upper arm and
forearm reach out horizontally. The encoder reads the motor's angle, so the joints a calibration
is given are the readings ``q`` while the links stand at :meth:`JointCompliance.bent` ``(q)``.
A constant chain can absorb only the bend's mean over the calibration postures; what varies with
``q2 + q3`` stays a model error that grows with reach.

Used by the accuracy benchmarks (:mod:`selfcal.benchmarks.tracker.accuracy` on tracker rows,
:mod:`selfcal.benchmarks.board.accuracy` through the simulator's actual robot,
:class:`selfcal.sim.kinematic_robot.KinematicRobot`'s ``compliance``). Simulation only: a
dataset never carries it, and ``truth.json``'s true chain is the chain without the bend.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from selfcal.errors import UsageError

__all__ = ["JointCompliance", "JointMisfit", "SHOULDER"]


class JointMisfit(Protocol):
    """A simulated misfit of the joints: where the links stand for the encoders' readings
    (:class:`JointCompliance`, :class:`selfcal.sim.gear.EccentricGear`)."""

    def bent(self, q: np.ndarray) -> np.ndarray:
        """The joints (..., n) the links stand at for the readings ``q`` (..., n) rad / m."""
        ...


@dataclass(frozen=True)
class JointCompliance:
    """Joint ``joint`` (0-based) bends by ``amplitude_rad * cos(q[coupled].sum())`` (rad; the
    coupled joints revolute, rad)."""

    amplitude_rad: float
    joint: int = 1
    coupled: tuple[int, ...] = (1, 2)

    def __post_init__(self) -> None:
        if not np.isfinite(self.amplitude_rad):
            raise UsageError(f"JointCompliance: amplitude_rad must be finite, got "
                             f"{self.amplitude_rad}")  # fmt: skip

    def bent(self, q: np.ndarray) -> np.ndarray:
        """The joints (..., n) the links stand at for the readings ``q`` (..., n) rad / m."""
        q = np.asarray(q, dtype=float)
        n = q.shape[-1]
        if not all(0 <= j < n for j in (self.joint, *self.coupled)):
            raise UsageError(f"JointCompliance: joints {self.joint} and {self.coupled} do not "
                             f"exist in a chain of {n} joints")  # fmt: skip
        out = q.copy()
        out[..., self.joint] += self.amplitude_rad * np.cos(q[..., list(self.coupled)].sum(-1))
        return out


SHOULDER = JointCompliance(np.radians(0.05))
"""The benchmarks' misfit: joint 2 bends by 0.05 deg x cos(q2 + q3)."""
