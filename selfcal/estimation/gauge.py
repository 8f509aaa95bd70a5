"""The world-frame gauge of the kinematic chain: its directions and the chosen held parameters.

With an unknown scene the world frame (6 dof) is free; :func:`selfcal.calibration.field.joint_refine.choose_gauge`
holds six MCPC parameters to fix it. Units: SI (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices
from selfcal.transforms import pose_from_vec

__all__ = ["gauge_directions", "GaugeChoice"]


def gauge_directions(model: MCPCModel, eps: float = 1e-6) -> np.ndarray:
    """(P, 6): derivative of the minimal parameters (eq. 10 order, SI) w.r.t. a change of world
    frame ``T_new_old = exp([v; w])`` (central differences through :func:`express_in_frame`)."""
    G = np.empty((minimal_indices(model.joint_types).size, 6))
    for j in range(6):
        xi = np.zeros(6)
        xi[j] = eps
        vec = np.r_[xi[3:], xi[:3]]  # pose_from_vec takes [rotvec, translation]
        plus = express_in_frame(model, pose_from_vec(vec), like=model)
        minus = express_in_frame(model, pose_from_vec(-vec), like=model)
        G[:, j] = minimal_difference(plus, minus) / (2 * eps)
    return G


@dataclass(frozen=True)
class GaugeChoice:
    """The six MCPC parameters held to fix the world frame (see the module docstring).

    ``held``: names; ``method``: ``"alpha1-90"`` (beta1, ly1 by the SCORBOT argument) or
    ``"pivoted-qr"``; ``condition_number`` of the (unit-scaled) 6 x 6 block of the gauge
    directions at the held parameters (finite and moderate = transversal to the gauge orbit).
    """

    held: tuple[str, ...]
    method: str
    condition_number: float
