"""Simulated tracker measurements of a robot whose kinematics differ from nominal (tests and the
tracker benchmark).

A *case* is a true chain (the nominal MCPC chain of a robot with every minimal parameter moved by
a uniform error, a tool point on the flange and an arbitrary tracker frame), joint configurations
drawn within the robot's ranges and the tool-point positions (or poses) the tracker would measure,
with Gaussian noise. Robots are robot files (``models/<folder>/``) or standard-DH tables given here
(:func:`dh_robot`). Units: SI inside; the DH tables in mm and deg like the robot files.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.chain import DHParams, dh_chain
from selfcal.robot.definition import RobotDef, SimulationGains
from selfcal.sim.actual import perturb
from selfcal.transforms import make_pose, pose_from_vec

__all__ = [
    "dh_robot",
    "RRPRR_DH",
    "TrackerCase",
    "make_case",
    "measure",
]

RRPRR_DH: dict[str, Any] = {
    "alpha_deg": [90.0, 0.0, -90.0, 90.0, 0.0],
    "a_mm": [50.0, 300.0, 0.0, 0.0, 0.0],
    "d_mm": [400.0, 0.0, 200.0, 0.0, 80.0],
    "prismatic": (2,),
}
"""A 5-joint arm whose third joint is prismatic (illustrative numbers)."""


def dh_robot(
    name: str,
    alpha_deg: list[float],
    a_mm: list[float],
    d_mm: list[float],
    offset_deg: list[float] | None = None,
    range_deg: float = 170.0,
    prismatic: tuple[int, ...] = (),
) -> RobotDef:
    """An arm from a standard-DH table (mm, deg): revolute joints in ``+-range_deg``, the
    0-based joints ``prismatic`` sliding 0 .. 300 mm (their ``d_mm`` is the constant part); home
    at zero, no encoder quantisation; the camera mount is the flange (unused by the tracker)."""
    n = len(alpha_deg)
    off = np.zeros(n) if offset_deg is None else np.radians(offset_deg)
    types = tuple("prismatic" if i in prismatic else "revolute" for i in range(n))
    a, d = np.asarray(a_mm, dtype=float) / 1e3, np.asarray(d_mm, dtype=float) / 1e3
    dh = DHParams("dh", np.radians(alpha_deg), a, d, off)
    limits = np.tile(np.radians([-range_deg, range_deg]), (n, 1))
    limits[list(prismatic)] = (0.0, 0.3)
    return RobotDef(
        name=name,
        description=f"{name} (standard DH, built in code)",
        joint_names=tuple(f"j{i + 1}" for i in range(n)),
        joint_types=types,
        chain=dh_chain(dh),
        dh=dh,
        limits=limits,
        home=np.zeros(n),
        counts_per_unit=np.full(n, np.inf),
        T_flange_cam=np.eye(4),
        planning_span=np.full(n, np.radians(range_deg)),
        simulation=SimulationGains(np.ones(n), np.ones(n), np.ones(n)),
    )


@dataclass(frozen=True)
class TrackerCase:
    """A simulated robot: ``nominal`` (flange tool, base frame), ``true`` (perturbed, tool point,
    in the tracker frame), ``T_tracker_base`` and the tool point ``tool_m`` on the true flange."""

    robot: RobotDef
    nominal: MCPCModel
    true: MCPCModel
    T_tracker_base: np.ndarray
    tool_m: np.ndarray

    def configurations(self, m: int, seed: int) -> np.ndarray:
        """``m`` joint vectors (rad) uniform within the joint ranges (at most +-170 deg)."""
        rng = np.random.default_rng(seed)
        lim = np.clip(self.robot.limits, -np.radians(170.0), np.radians(170.0))
        return rng.uniform(lim[:, 0], lim[:, 1], (m, self.robot.n))


def make_case(
    robot: RobotDef,
    *,
    seed: int = 1,
    translation_mm: float = 1.0,
    rotation_deg: float = 0.2,
    tool_mm: tuple[float, float, float] = (30.0, -20.0, 80.0),
) -> TrackerCase:
    """The nominal chain of ``robot`` moved by uniform errors (every minimal parameter, within
    ``+-translation_mm`` / ``+-rotation_deg``), with the tool point ``tool_mm`` on the flange and
    a tracker frame ~2 m away, rotated arbitrarily (deterministic for ``seed``)."""
    nominal = nominal_mcpc(robot)
    rng = np.random.default_rng(seed + 1000)
    T_tracker_base = pose_from_vec(
        np.r_[rng.uniform(-np.pi, np.pi, 3) * 0.5, rng.uniform(-2.0, 2.0, 3)]
    )
    wrong = perturb(
        nominal,
        seed=seed,
        translation_m=translation_mm / 1e3,
        rotation_rad=np.radians(rotation_deg),
    )
    tool = np.asarray(tool_mm, dtype=float) / 1e3
    true = wrong.with_tool(make_pose(np.eye(3), tool)).with_base(T_tracker_base)
    return TrackerCase(robot, nominal, true, T_tracker_base, tool)


def measure(
    case: TrackerCase, q: np.ndarray, sigma_m: float, seed: int, *, poses: bool = False
) -> tuple[np.ndarray, np.ndarray | None]:
    """Tracker positions (m, 3) m with i.i.d. Gaussian noise ``sigma_m`` per coordinate and, with
    ``poses``, the noise-free tool orientations (m, 3, 3)."""
    T = fk_tool(case.true, q)
    rng = np.random.default_rng(seed)
    xyz = T[:, :3, 3] + rng.normal(0.0, sigma_m, (len(q), 3))
    return xyz, (T[:, :3, :3] if poses else None)
