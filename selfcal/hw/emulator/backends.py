"""The arm behind the emulated ACL controller: the ``EmulatorBackend`` interface and
``KinematicBackend``, a pure-kinematic arm that renders nothing.

The controller tells its backend where the arm came to rest and asks it for the stereo pair seen
there (``selfcal.acquisition.emulator_backend.SimEmulatorBackend`` renders the simulated robot).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from selfcal.hw.settings import DEFAULT_MODEL
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.robot.interface import StereoPair

__all__ = ["EmulatorBackend", "KinematicBackend"]


@runtime_checkable
class EmulatorBackend(Protocol):
    """The arm behind the emulated controller.

    Attributes:
        model_name: robot model name (``models/<folder>/<name>.toml``), used for LISTPV's Cartesian
            line when the backend has no ``robot`` attribute.
        limits_deg: (n, 2) joint ranges (deg) the controller enforces (``*** OUT OF RANGE``).
    """

    model_name: str
    limits_deg: np.ndarray
    # optional: ``robot`` (a ``RobotDef``, for LISTPV's Cartesian line) and ``encoders`` (an
    # ``EncoderTable``: the emulator's default table when it is given none)

    def set_joints_deg(self, joints_deg: np.ndarray) -> np.ndarray | None:
        """The arm has come to rest at ``joints_deg`` (n,) (deg, as commanded in encoder counts).
        Return the joint angles the encoders actually read there (e.g. with servo error), or
        ``None`` for "as commanded"."""

    def capture(self) -> StereoPair:
        """The stereo pair (RGB uint8) seen at the current posture."""


class KinematicBackend:
    """Pure-kinematic arm: remembers the posture, renders nothing (blank images).

    Args:
        robot: model name or ``RobotDef`` (limits and the Cartesian line of LISTPV).
        image_size: (width, height) of the blank images.
        limits_deg: override of the (n, 2) joint ranges (deg), e.g. tighter than the model's.
    """

    def __init__(
        self,
        robot: str | RobotDef = DEFAULT_MODEL,
        image_size: tuple[int, int] = (640, 480),
        limits_deg: np.ndarray | None = None,
    ):
        self.robot = load_robot(robot) if isinstance(robot, str) else robot
        self.model_name = self.robot.name
        lim = np.degrees(self.robot.limits) if limits_deg is None else limits_deg
        self.limits_deg = np.asarray(lim, dtype=float).reshape(self.robot.n, 2)
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.joints_deg = np.degrees(self.robot.home)
        self.rests = 0

    def set_joints_deg(self, joints_deg: np.ndarray) -> np.ndarray | None:
        self.joints_deg = np.asarray(joints_deg, dtype=float).copy()
        self.rests += 1
        return None

    def capture(self) -> StereoPair:
        w, h = self.image_size
        blank = np.zeros((h, w, 3), dtype=np.uint8)
        return StereoPair(blank, blank.copy(), {"joints_deg": self.joints_deg.tolist()})
