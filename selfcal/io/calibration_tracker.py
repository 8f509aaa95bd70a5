"""``calibration.json`` ``tracker``: the tracker measurements estimated with the images.

When ``selfcal calibrate DIR --tracker FILE`` combines the dataset's images with tracker readings
of the same robot (positions, poses or distances of a tool point; :mod:`selfcal.io.tracker`), the
calibration's ``sources`` are ``["images", "tracker"]`` and this block records the tracker's part:
the files and their joint units, what they hold, the noise assumed, the fit (RMS per kind) and the
extra unknowns estimated with the kinematics: the tracker frame in the calibration's world frame
(the field's reference left camera; a board calibration's board frame, eye-to-hand its first
camera), the tool point (and, for poses, the measured tool frame) in the calibrated tool frame
(the left or first camera, OpenCV; eye-to-hand the board).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from selfcal.io.jsonblock import JsonBlock

__all__ = ["TrackerSource", "TRACKER_NOTE"]

POSE = {"shape": (4, 4)}
TRACKER_NOTE = (
    "tracker measurements and the dataset's images estimated together: T_tracker_world_m is "
    "the tracker frame's placement in the calibration's world (as the mcpc chain: the field's "
    "reference left camera, a board's world_frame); tool_point_mm is the measured tool point "
    "and T_cam_tool_m the measured tool frame, both in the calibrated tool frame (mcpc's tool: "
    "the left or first camera, OpenCV, or eye-to-hand the board); rms_mm is the fit per kind "
    "(translation part); the parameter standard deviations and the Cramer-Rao bounds are those "
    "of the images alone"
)


@dataclass(frozen=True, eq=False)
class TrackerSource(JsonBlock):
    """``tracker``: see the module docstring. Units: mm and deg for people, m in ``_m`` keys."""

    kind: ClassVar[str] = "tracker"

    file: str | None
    distances_file: str | None
    joint_units: str = field(metadata={"choices": ("deg", "rad")})
    kinds: tuple[str, ...]
    rows: int
    distances: int
    sigma_mm: float
    sigma_deg: float
    rms_mm: dict[str, float]
    T_tracker_world_m: np.ndarray | None = field(metadata=POSE)
    tool_point_mm: tuple[float, ...] | None
    T_cam_tool_m: np.ndarray | None = field(metadata=POSE)
    note: str = TRACKER_NOTE

    def summary(self) -> str:
        """One line on the tracker part of a calibration."""
        what = " + ".join(
            f"{self.rows} {k}" if k != "distances" else f"{self.distances} distances"
            for k in self.kinds
        )
        fit = ", ".join(f"{k} {v:.4f} mm" for k, v in self.rms_mm.items())
        point = ""
        if self.tool_point_mm is not None:
            point = (
                "; tool point in the calibrated tool frame ("
                + ", ".join(f"{v:.3f}" for v in self.tool_point_mm)
                + ") mm"
            )
        return f"tracker: {what} estimated with the images, fit RMS {fit}{point}"
