"""An eccentric gear: a joint's periodic transmission error, a misfit no link table expresses
(issue #29's "wrong link the model cannot express").

The true robot's joint ``joint`` turns ``theta + amplitude_rad * sin(theta + phase_rad)`` for the
reading ``theta`` (rad): an output gear mounted off its centre turns its joint ahead and behind
its motor once per revolution. The encoder reads the motor, so the joints a calibration is given
are the readings while the links stand at :meth:`EccentricGear.bent` of them.

Why this and not a wrong link: the complete (MCPC) chain holds, between every two joints, a
constant rigid transform of its own, and a joint offset; a rigid link of other lengths or
angles is such a transform, so the calibration fits it exactly (it is not a misfit). A joint
angle that depends on the reading other than by a constant is not: a link table can absorb
only what of the sine a constant offset and the links' shape matrices mimic over the calibration
postures, and the rest stays a model error.

The amplitude is set so that the tool moves by about :data:`TOOL_MOVE_M` where the sine is
largest: :func:`draw_gear` divides it by the joint's lever arm at the tool (the tool point's
motion per radian of the joint, RMS over a workspace sample of the joint ranges).

Used by the accuracy benchmarks (``--models gear``) through the simulator's actual robot
(:class:`selfcal.sim.kinematic_robot.KinematicRobot`'s ``compliance``: the joints the links stand
at) and on tracker rows. Simulation only: a dataset never carries it, and ``truth.json``'s true
chain is the chain without it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import UsageError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel

__all__ = ["EccentricGear", "draw_gear", "lever_arms", "MIN_LEVER_M", "TOOL_MOVE_M"]

TOOL_MOVE_M = 2e-4
"""The tool's motion (m) where the gear's sine is largest, at the joint's RMS lever arm."""
MIN_LEVER_M = 0.05
"""A joint is drawn only when its RMS lever arm at the tool is at least this (m): a wrist roll
whose axis passes near the tool point would need degrees of gear error to move it 0.2 mm."""
SAMPLE = 256
"""Joint vectors of the workspace sample the lever arms are taken over."""
_SEED = 7919
"""Mixed into a truth's seed so the gear's draw is its own stream."""


@dataclass(frozen=True)
class EccentricGear:
    """Joint ``joint`` (0-based, revolute) turns ``amplitude_rad * sin(q[joint] + phase_rad)``
    past its reading (rad)."""

    amplitude_rad: float
    joint: int
    phase_rad: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.amplitude_rad) and np.isfinite(self.phase_rad)):
            raise UsageError(f"EccentricGear: amplitude_rad and phase_rad must be finite, got "
                             f"{self.amplitude_rad}, {self.phase_rad}")  # fmt: skip

    def bent(self, q: np.ndarray) -> np.ndarray:
        """The joints (..., n) the links stand at for the readings ``q`` (..., n) rad / m."""
        q = np.asarray(q, dtype=float)
        if not 0 <= self.joint < q.shape[-1]:
            raise UsageError(f"EccentricGear: joint {self.joint} does not exist in a chain of "
                             f"{q.shape[-1]} joints")  # fmt: skip
        out = q.copy()
        out[..., self.joint] += self.amplitude_rad * np.sin(q[..., self.joint] + self.phase_rad)
        return out


def lever_arms(chain: MCPCModel, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """(m, n) m per rad: how fast the tool point of ``chain`` moves as each joint turns, at the
    joint vectors ``q`` (m, n) rad (central differences of :func:`fk_tool`; a prismatic joint's
    column is its m per m, 1)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.empty(q.shape)
    for j in range(q.shape[1]):
        dq = np.zeros(q.shape[1])
        dq[j] = step
        move = fk_tool(chain, q + dq)[:, :3, 3] - fk_tool(chain, q - dq)[:, :3, 3]
        out[:, j] = np.linalg.norm(move, axis=1) / (2 * step)
    return out


def draw_gear(chain: MCPCModel, limits: np.ndarray, seed: int,
              tool_move_m: float = TOOL_MOVE_M) -> EccentricGear:  # fmt: skip
    """A truth's gear (deterministic for ``seed``): the joint drawn uniformly among the revolute
    joints of ``chain`` whose RMS lever arm (:func:`lever_arms` over :data:`SAMPLE` joint vectors
    uniform in ``limits`` (n, 2) rad, at most +-170 deg) is at least :data:`MIN_LEVER_M`, the
    phase uniform in a turn, the amplitude ``tool_move_m`` over that lever arm (rad)."""
    rng = np.random.default_rng([_SEED, int(seed)])
    lim = np.clip(np.asarray(limits, dtype=float), -np.radians(170.0), np.radians(170.0))
    q = rng.uniform(lim[:, 0], lim[:, 1], (SAMPLE, chain.n))
    lever = np.sqrt(np.mean(lever_arms(chain, q) ** 2, axis=0))
    revolute = np.array([t == "revolute" for t in chain.joint_types])
    eligible = np.flatnonzero(revolute & (lever >= MIN_LEVER_M))
    if eligible.size == 0:
        raise UsageError(f"draw_gear: no revolute joint moves the tool by {MIN_LEVER_M} m per "
                         f"rad (RMS lever arms {np.round(lever, 3).tolist()} m)")  # fmt: skip
    joint = int(rng.choice(eligible))
    return EccentricGear(tool_move_m / float(lever[joint]), joint,
                         float(rng.uniform(-np.pi, np.pi)))  # fmt: skip
