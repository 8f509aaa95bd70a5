"""How far an arm's geometry may lie from its drawing: the prior on the kinematic parameters'
deviation that ``selfcal plan``'s prediction and a board calibration's held parameters share
(issues #29, #30). Every minimal parameter uniform within +-``translation_m`` (lengths) or
+-``rotation_rad`` (angles), independently: what the simulator draws
(:func:`selfcal.sim.actual.perturb`, ``[perturbation]``; by default 1 mm and 0.5 deg). Units: SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.kinematics.mcpc import minimal_indices, param_is_angle

__all__ = ["Deviation"]


@dataclass(frozen=True)
class Deviation:
    """How far the arm's geometry may lie from its drawing (module docstring): every inner
    minimal parameter uniform within +-``translation_m`` (m) or +-``rotation_rad`` (rad)."""

    translation_m: float = 1e-3
    rotation_rad: float = float(np.radians(0.5))

    def drawn_variance(self, joint_types: tuple[str, ...]) -> np.ndarray:
        """(k,) the variance of every minimal parameter's deviation, the placement's included
        (m^2, rad^2; the order of :func:`selfcal.kinematics.mcpc.minimal_indices`): what
        :func:`selfcal.sim.actual.perturb` draws, uniform within the half-widths."""
        idx = minimal_indices(joint_types)
        a = np.where(param_is_angle(idx), self.rotation_rad, self.translation_m)
        return a**2 / 3.0

    def variance(self, joint_types: tuple[str, ...]) -> np.ndarray:
        """(k,) :meth:`drawn_variance` with zero for the placement, whose deviation every
        calibration estimates (a prior on it would be wrong: the board may lie anywhere)."""
        var = self.drawn_variance(joint_types)
        var[np.isin(minimal_indices(joint_types), placement_indices(len(joint_types)))] = 0.0
        return var
