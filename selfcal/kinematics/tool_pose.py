"""The controller's Cartesian tool pose: position, pitch and roll of a 5-axis ER-type arm.

Convention (world frame: z up along the base axis, metres and radians):

- ``r_hat`` is the horizontal unit vector from the base axis towards the tool point. When the tool
  point is on the base axis (closer than :data:`AXIS_EPS_M`), the caller supplies the azimuth of the
  arm's joint-1 direction instead (``azimuth_rad``; for a DH robot ``q_1 + offset_1``).
- ``pitch`` is the angle of the tool axis (z-axis of the tool frame = last DH frame) in the vertical
  plane spanned by ``r_hat`` and ``z_world``, measured from ``r_hat`` (horizontal, pointing away from
  the base axis), positive upwards, in ``(-pi, pi]``.
- ``roll`` is the rotation of the tool x-axis about the tool axis, measured from the reference
  direction ``ref = z_tool x h`` with ``h = z_world x r_hat``, in ``(-pi, pi]``.

For the SCORBOT models in ``models/<folder>/`` this gives ``roll = theta_5 + offset_5`` whenever the
tool point lies on the side of the base axis that joint 1's x-axis points to (the "front" branch),
and ``roll = theta_5 + offset_5 + pi`` on the back branch. The paper's model (Table I) at joint zero
has the tool axis pointing straight down (pitch -90 deg); the vendor model at joint zero has it
horizontal (pitch 0).

Note: the seed paper's Table II column "Pitch (theta4)" is joint 4's angle (-63.54 deg), not this
Cartesian pitch: with Table I's frames, the tool axis at Table I's posture points down and back
towards the base, a Cartesian pitch of about -138.5 deg.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import InputError, UsageError

__all__ = ["AXIS_EPS_M", "tool_pose", "tool_rotation", "tool_frame", "pitch_roll", "radial_dir"]

#: Tool points closer than this to the base axis (m) use the supplied joint-1 azimuth for ``r_hat``.
AXIS_EPS_M = 1e-9

_UP = np.array([0.0, 0.0, 1.0])


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped into ``(-pi, pi]``."""
    w = np.mod(np.asarray(a, dtype=float) + np.pi, 2 * np.pi) - np.pi
    return np.where(w <= -np.pi, w + 2 * np.pi, w)


def radial_dir(xyz_m: np.ndarray, azimuth_rad: np.ndarray | float | None = None) -> np.ndarray:
    """Horizontal unit vectors ``r_hat`` (..., 3) from the base axis towards points ``xyz_m`` (..., 3).

    Points on the base axis (within :data:`AXIS_EPS_M`) use ``azimuth_rad`` (the joint-1 direction).

    Raises:
        ValueError: a point lies on the base axis and no ``azimuth_rad`` was given.
    """
    xyz = np.asarray(xyz_m, dtype=float)
    r = np.hypot(xyz[..., 0], xyz[..., 1])
    on_axis = r < AXIS_EPS_M
    az = np.arctan2(xyz[..., 1], xyz[..., 0])
    if np.any(on_axis):
        if azimuth_rad is None:
            raise InputError(
                "tool point lies on the base axis, where pitch/roll are measured from the arm's "
                "joint-1 direction: pass azimuth_rad (for a DH robot q_1 + offset_1)"
            )
        az = np.where(on_axis, np.broadcast_to(np.asarray(azimuth_rad, dtype=float), az.shape), az)
    return np.stack([np.cos(az), np.sin(az), np.zeros_like(az)], axis=-1)


def pitch_roll(R_world_tool: np.ndarray, r_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pitch and roll (rad, in ``(-pi, pi]``) of tool rotations (..., 3, 3) for given ``r_hat`` (..., 3).

    The tool axis' component along ``h = z_world x r_hat`` (zero for an ER-type arm) is ignored by
    the pitch.

    Raises:
        ValueError: the tool axis is (nearly) parallel to ``h``, where roll is undefined.
    """
    R = np.asarray(R_world_tool, dtype=float)
    r_hat = np.asarray(r_hat, dtype=float)
    z = R[..., :, 2]
    x = R[..., :, 0]
    pitch = np.arctan2(z[..., 2], np.sum(z * r_hat, axis=-1))
    h = np.cross(_UP, r_hat)
    ref = np.cross(z, h)
    nrm = np.linalg.norm(ref, axis=-1)
    if np.any(nrm < 1e-9):
        raise InputError(
            "tool axis is perpendicular to the vertical plane through the base axis and the tool "
            "point: roll is undefined there"
        )
    ref = ref / nrm[..., None]
    roll = np.arctan2(np.sum(x * np.cross(z, ref), axis=-1), np.sum(x * ref, axis=-1))
    return _wrap(pitch), _wrap(roll)


def tool_pose(
    T_world_tool: np.ndarray, azimuth_rad: np.ndarray | float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cartesian pose ``(xyz_m (..., 3), pitch_rad (...), roll_rad (...))`` of tool frames (..., 4, 4).

    ``azimuth_rad`` (joint-1 direction, rad) is only used where the tool point lies on the base
    axis. See the module docstring for the convention.

    Raises:
        ValueError: tool point on the base axis without ``azimuth_rad``, or roll undefined.
    """
    T = np.asarray(T_world_tool, dtype=float)
    if T.shape[-2:] != (4, 4):
        raise UsageError(f"T_world_tool must have shape (..., 4, 4), got {T.shape}")
    xyz = T[..., :3, 3]
    pitch, roll = pitch_roll(T[..., :3, :3], radial_dir(xyz, azimuth_rad))
    return xyz.copy(), pitch, roll


def tool_rotation(pitch_rad: np.ndarray | float, roll_rad: np.ndarray | float, r_hat: np.ndarray):
    """Tool rotations ``R_world_tool`` (..., 3, 3) with the given pitch and roll (rad) at ``r_hat``."""
    p = np.asarray(pitch_rad, dtype=float)[..., None]
    r = np.asarray(roll_rad, dtype=float)[..., None]
    r_hat = np.asarray(r_hat, dtype=float)
    z = np.cos(p) * r_hat + np.sin(p) * _UP
    h = np.cross(_UP, r_hat)
    ref = np.cross(z, h)
    x = np.cos(r) * ref + np.sin(r) * np.cross(z, ref)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def tool_frame(
    xyz_m: np.ndarray,
    pitch_rad: np.ndarray | float,
    roll_rad: np.ndarray | float,
    azimuth_rad: np.ndarray | float | None = None,
) -> np.ndarray:
    """Inverse of :func:`tool_pose`: tool frames ``T_world_tool`` (..., 4, 4).

    Raises:
        ValueError: a tool point on the base axis without ``azimuth_rad``.
    """
    xyz = np.asarray(xyz_m, dtype=float)
    R = tool_rotation(pitch_rad, roll_rad, radial_dir(xyz, azimuth_rad))
    shape = np.broadcast_shapes(R.shape[:-2], xyz.shape[:-1])
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = xyz
    T[..., 3, 3] = 1.0
    return T
