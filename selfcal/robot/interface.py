"""The one robot interface that the simulator (``sim``) and the hardware adapter (``hw``) implement.

Declared here, in the lowest layer, so that ``sim`` and ``hw`` implement it without knowing each
other or the top layer; the acquisition loop (``selfcal.acquisition.acquire``) talks only to it. Joint
angles cross it in degrees (the unit of the controller, of ``joints.csv`` and of people at the
robot); everything behind it is SI.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from selfcal.errors import HardwareError

__all__ = ["StereoPair", "Robot", "RobotError"]


class RobotError(HardwareError):
    """A robot (simulated or real) refused or failed a command; the message names the cause."""


@dataclass(frozen=True)
class StereoPair:
    """One synchronised stereo capture: RGB uint8 images of shape (H, W, 3)."""

    left: np.ndarray
    right: np.ndarray
    meta: dict = field(default_factory=dict)


@runtime_checkable
class Robot(Protocol):
    """A camera-equipped arm. Implementations: ``selfcal.sim.sim_robot.SimRobot``, ``selfcal.hw.acl.robot.AclRobot``."""

    model_name: str
    """Name of the nominal kinematic model (``models/<folder>/<name>.toml``)."""

    def home(self) -> None:
        """Move to (or find) the home posture."""

    def move_to(self, joints_deg: np.ndarray) -> None:
        """Move to joint angles (deg); raises ``InputError`` (a ``ValueError``) naming the joint
        if out of range, before anything moves, and ``RobotError`` if the move fails."""

    def joints(self) -> np.ndarray:
        """Joint angles read back from the encoders (deg), quantised as the encoders are."""

    def capture(self) -> StereoPair:
        """Capture a stereo pair at the current posture."""

    def close(self) -> None:
        """Release the robot (stop motion safely, close ports and renderers)."""
