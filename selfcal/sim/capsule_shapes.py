"""Simple link geometry for any serial arm, laid out from its kinematic chain.

A pedestal around joint 1's axis, and on every link a joint housing (a short cylinder along the
link's own joint axis) and a capsule from that joint to the next joint's frame origin (the last
link: to the flange, with a flange disc). One radius, scaled to the arm's size, for all of them.
Visual parts in the ``visual`` class, capsules and spheres carrying the mass in the ``collision``
class (``selfcal.sim.mjcf_geoms``). The SCORBOT keeps its hand-made layout (``selfcal.sim.robot_shapes``).
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.mcpc import MCPCModel, chain_transforms
from selfcal.sim.link_frames import next_joint
from selfcal.sim.mjcf_geoms import GeomBuilder

__all__ = ["link_radius", "shape_capsule_base", "shape_capsule_links"]

_MIN_SEGMENT_M = 1e-3  # shorter joint-to-joint segments get no capsule


def link_radius(model: MCPCModel, T_link_flange: np.ndarray) -> float:
    """Capsule radius (m): 3.5 % of the summed joint-to-joint distances, within [12, 50] mm."""
    length = sum(float(np.linalg.norm(next_joint(model, k)[0])) for k in range(model.n - 1))
    length += float(np.linalg.norm(T_link_flange[:3, 3]))
    return float(np.clip(0.035 * length, 0.012, 0.05))


def shape_capsule_base(b: GeomBuilder, body, model: MCPCModel, r: float) -> None:
    """A pedestal: a dark plate and a grey cylinder along joint 1's axis (placed by ``V_0``),
    from the base frame's origin up to ``2 r``."""
    V0 = chain_transforms(model)[0]
    o, z = V0[:3, 3], V0[:3, 2]
    b.cylinder(body, o, o + z * 0.006, 2.2 * r, "dark")
    b.cylinder(body, o + z * 0.006, o + z * 2 * r, 1.6 * r, "grey")
    b.cylinder(body, o, o + z * 2 * r, 1.6 * r, collision=True)


def shape_capsule_links(
    b: GeomBuilder, links: list, model: MCPCModel, T_link_flange: np.ndarray, r: float
) -> None:
    """Housing and capsule on every link body of ``links`` (link k's frame = MCPC frame ``F_k``);
    ``T_link_flange`` the flange in the last link's frame."""
    n = model.n
    for k, body in enumerate(links):
        b.cylinder(body, [0, 0, -1.15 * r], [0, 0, 1.15 * r], 1.1 * r, "grey")
        b.sphere(body, [0, 0, 0], 1.1 * r, collision=True)
        end = next_joint(model, k)[0] if k < n - 1 else T_link_flange[:3, 3]
        if np.linalg.norm(end) < _MIN_SEGMENT_M:
            continue
        b.capsule(body, [0, 0, 0], end, r, "orange")
        b.capsule(body, [0, 0, 0], end, r, collision=True)
    f, z = T_link_flange[:3, 3], T_link_flange[:3, 2]
    b.cylinder(links[-1], f - 0.006 * z, f, 0.8 * r, "dark")
