"""The robot's shapes, laid out from its kinematic chain (no hand-typed geometry).

Base, turret, upper arm, forearm, wrist, two-finger gripper and camera rig, in SCORBOT orange and
greys: every link tube runs from its joint to the next joint's origin, the fingers end at the tool
tip. Each shape has a visual part (``visual`` class) and a simple collision part (``collision``
class, carrying the mass); see ``selfcal.sim.mjcf_geoms``.
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.mcpc import MCPCModel, chain_transforms
from selfcal.sim.link_frames import next_joint
from selfcal.sim.mjcf_geoms import GeomBuilder, box_frame, unit

__all__ = ["shape_base", "shape_turret", "shape_arm", "shape_wrist", "shape_hand", "shape_rig"]


def shape_base(b: GeomBuilder, body, model: MCPCModel, h_base: float) -> None:
    """Grey pedestal around joint 1's axis (placed by ``V_0``), from the floor up to ``h_base``."""
    V0 = chain_transforms(model)[0]
    o, z = V0[:3, 3], V0[:3, 2]
    b.box(body, o + z * 0.006, V0[:3, :3], [0.13, 0.13, 0.006], "dark")
    b.cylinder(body, o + z * 0.012, o + z * h_base, 0.105, "grey")
    b.cylinder(body, o + z * 0.012, o + z * h_base, 0.105, collision=True)


def shape_turret(b: GeomBuilder, body, model: MCPCModel, h_base: float) -> None:
    """Orange body rotating about z from the pedestal to the shoulder axis (+ shoulder motor)."""
    p, a = next_joint(model, 0)
    h = float(p[2])
    col_top = max(h - 0.06, h_base + 0.02)
    b.cylinder(body, [0, 0, h_base + 0.002], [0, 0, h_base + 0.02], 0.10, "dark")
    b.cylinder(body, [0, 0, h_base + 0.02], [0, 0, col_top], 0.075, "orange")
    # yoke from the column top out to the shoulder axis, and the shoulder housing along it
    radial = np.array([p[0], p[1], 0.0])
    if np.linalg.norm(radial) > 1e-3:  # shoulder axis offset from the turret axis (DH a_1)
        r = unit(radial)
        b.box_between(body, [0, 0, h] - 0.035 * r, p + 0.04 * r, 0.06, 0.05, [0, 0, 1], "orange")
    b.cylinder(body, [0, 0, col_top - 0.01], [0, 0, h], 0.065, "orange")
    b.cylinder(body, p - 0.075 * a, p + 0.075 * a, 0.055, "grey")
    b.cylinder(body, p + 0.075 * a, p + 0.085 * a, 0.035, "dark")
    b.cylinder(body, [0, 0, h_base + 0.02], [0, 0, h], 0.075, collision=True)
    b.cylinder(body, p - 0.075 * a, p + 0.075 * a, 0.055, collision=True)


def shape_arm(
    b: GeomBuilder, body, model: MCPCModel, k: int, width: float, height: float, r_joint: float
) -> None:
    """Upper arm / forearm: an orange beam from this joint to the next, grey joint housings."""
    p, a = next_joint(model, k)
    b.cylinder(body, [0, 0, -width - 0.012], [0, 0, width + 0.012], r_joint, "grey")
    if np.linalg.norm(p) < 1e-3:  # next joint at this origin (e.g. before a prismatic joint)
        b.sphere(body, [0, 0, 0], r_joint, collision=True)
        return
    b.box_between(body, [0, 0, 0], p, height, width, [0, 0, 1], "orange")
    b.cylinder(body, p - (width + 0.008) * a, p + (width + 0.008) * a, r_joint * 0.85, "grey")
    b.capsule(body, [0, 0, 0], p, max(width, height), collision=True)


def shape_wrist(b: GeomBuilder, body, model: MCPCModel, k: int) -> None:
    """Wrist pitch link: a dark gearbox about the pitch axis, a stub along the roll axis."""
    p, a = next_joint(model, k)
    b.cylinder(body, [0, 0, -0.042], [0, 0, 0.042], 0.034, "dark")
    b.cylinder(body, p + 0.0 * a, p + 0.035 * a, 0.03, "grey")
    b.sphere(body, [0, 0, 0], 0.045, collision=True)


def shape_hand(b: GeomBuilder, body, tip: np.ndarray, cam: np.ndarray) -> None:
    """Roll link: roll housing along z up to the gripper palm, two fingers ending at ``tip``.

    The fingers open along the direction perpendicular to the tool axis and to the camera's
    offset from it, so they stay out of the camera's view.
    """
    z = np.array([0.0, 0.0, 1.0])
    tip = np.asarray(tip, float)
    L = float(tip[2])
    axis_pt = np.array([tip[0], tip[1], 0.0])  # the gripper's centre line, parallel to z
    off = np.asarray(cam, float) - tip
    off[2] = 0.0
    u = unit(np.cross(z, off)) if np.linalg.norm(off) > 1e-3 else np.array([1.0, 0.0, 0.0])
    v = np.cross(z, u)
    finger_len = min(0.045, 0.35 * L)
    palm_len = min(0.02, 0.15 * L)
    z_f = L - finger_len  # finger root
    z_p = z_f - palm_len  # palm root
    R_hand = np.column_stack([u, v, z])
    b.cylinder(body, [0, 0, 0.035], axis_pt + z * (z_p - 0.004), 0.028, "grey")
    b.cylinder(body, axis_pt + z * (z_p - 0.004), axis_pt + z * z_p, 0.032, "steel")
    b.box(body, axis_pt + z * (z_p + palm_len / 2), R_hand, [0.03, 0.016, palm_len / 2], "dark")
    for s in (-1.0, 1.0):
        root = axis_pt + z * z_f + s * 0.016 * u
        b.box(
            body,
            root + z * (finger_len / 2 - 0.001),
            R_hand,
            [0.004, 0.003, finger_len / 2 + 0.001],
            "black",
        )
        # a finger pad, ending exactly at the tool tip
        b.box(
            body,
            axis_pt + s * 0.0105 * u + z * (L - 0.009),
            R_hand,
            [0.0015, 0.003, 0.009],
            "steel",
        )
    b.capsule(body, [0, 0, 0.035], axis_pt + z * z_p, 0.028, collision=True)
    b.box(
        body,
        axis_pt + z * (z_f + finger_len / 2 - palm_len / 2),
        R_hand,
        [0.022, 0.012, (finger_len + palm_len) / 2],
        collision=True,
    )


def shape_rig(b: GeomBuilder, body, T_left_right: np.ndarray, T_cam_link: np.ndarray) -> None:
    """Stereo camera bar behind both camera centres (z_cam < 0: never in view), a bracket towards
    the last link's axis. ``T_cam_link``: last link frame in the rig (camera) frame."""
    c_r = T_left_right[:3, 3]
    centre = c_r / 2.0
    x_dir = c_r if np.linalg.norm(c_r) > 1e-6 else np.array([1.0, 0.0, 0.0])
    R = box_frame(x_dir, np.array([0.0, 0.0, 1.0]))
    half_len = float(np.linalg.norm(c_r)) / 2.0 + 0.02
    back = np.array([0.0, 0.0, -0.021])
    b.box(body, centre + back, R, [half_len, 0.017, 0.016], "dark")
    b.box(body, centre + back, R, [half_len, 0.017, 0.016], collision=True)
    for c in (np.zeros(3), c_r):
        b.cylinder(body, c + [0, 0, -0.0052], c + [0, 0, -0.0047], 0.011, "steel")
        b.cylinder(body, c + [0, 0, -0.0047], c + [0, 0, -0.0042], 0.008, "black")
    # bracket: from the bar to the nearest point of the last link's axis, kept behind the cameras
    o, a = T_cam_link[:3, 3], T_cam_link[:3, 2]
    start = centre + back
    foot = o + ((start - o) @ a) * a
    foot[2] = min(foot[2], back[2])
    if np.linalg.norm(foot - start) > 0.01:
        b.box_between(body, start, foot, 0.012, 0.006, [0, 0, 1], "grey")
