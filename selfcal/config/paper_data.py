"""The seed paper's printed numbers, in one place (mm and degrees, as printed).

Typos are kept as printed here on purpose (this module is the paper, not the truth);
``selfcal.studies.paper.checks.paper_inconsistencies`` finds and names them.
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.forward import fk_nominal
from selfcal.kinematics.ik import ik_nearest
from selfcal.kinematics.tool_pose import tool_pose

__all__ = [
    "TABLE_I_THETA_DEG",
    "TABLE_II_MM",
    "TABLE_II_THETA4_DEG",
    "PAPER_TABLE_III_MM",
    "PAPER_TABLE_IV",
    "table_ii_postures",
    "AXES",
]

AXES = ("x", "y", "z")
"""The position columns of Tables II-IV: p_x, p_y, p_z."""

TABLE_I_THETA_DEG = np.array([38.15, -30.0, 45.0, -63.54, 0.0])
"""Table I's theta column: the posture of the paper's Fig. 2 (deg)."""

TABLE_II_MM = np.array(
    [
        [315.60, 247.90, 190.30],
        [320.80, 252.00, 182.80],
        [310.40, 243.80, 197.70],
        [309.70, 243.30, 183.60],
        [321.80, 240.10, 190.30],
    ]
)
"""Table II: expected tool-tip positions of the er4u-paper model (mm)."""

TABLE_II_THETA4_DEG = -63.54
"""Table II's "Pitch (theta4)" column (the same in every row)."""

PAPER_TABLE_III_MM = np.array(
    [
        [315.00, 248.00, 183.00],
        [321.00, 252.50, 182.80],
        [311.00, 244.00, 198.00],
        [310.00, 244.00, 184.00],
        [322.00, 240.20, 190.60],
    ]
)
"""The paper's Table III "measured values" (mm), as printed."""

PAPER_TABLE_IV = {
    "desired_mm": TABLE_II_MM.copy(),
    "measured_mm": np.array(
        [
            [315.00, 248.00, 190.00],
            [321.00, 252.50, 183.00],
            [311.00, 244.00, 198.00],
            [310.00, 244.00, 184.00],
            [322.00, 240.20, 190.60],
        ]
    ),
    "error_mm": np.array(
        [
            [-0.60, 0.10, -0.30],
            [0.20, 0.50, 0.20],
            [0.60, 0.20, 0.70],
            [0.30, 0.70, 0.40],
            [0.20, 0.10, 0.30],
        ]
    ),
}
"""The paper's Table IV (desired = "0T5 desired values", measured, error), as printed."""


def table_ii_postures(robot) -> tuple[np.ndarray, float, float]:
    """Joint postures (rad, (5, n)) reaching Table II's rows with the Cartesian tool pitch and
    roll of row 1 held, and that pitch and roll (rad). Raises ``UnreachableError`` if not."""
    _, pitch_, roll_ = tool_pose(fk_nominal(robot, robot.home)[0, -1])
    pitch, roll = float(pitch_), float(roll_)
    q = np.array([ik_nearest(robot, p / 1000, pitch, roll) for p in TABLE_II_MM])
    return q, pitch, roll
