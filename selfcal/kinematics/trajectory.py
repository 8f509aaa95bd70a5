"""Calibration trajectories: postures that keep the target in view of every camera of the rig from
varied directions, and the check for the degenerate trajectory of self-calibration.

Planning uses only the nominal model and a rough description of where the target is (points on it,
world frame, m); it runs on the acquisition side and never sees the calibration's unknowns.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from selfcal.camera import CameraModel, Rig, Visibility
from selfcal.errors import EstimationError, InputError, SelfCalWarning
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.robot.definition import RobotDef

__all__ = [
    "PLANNING_VISIBILITY",
    "DegenerateTrajectoryError",
    "DegenerateTrajectoryWarning",
    "visible_counts",
    "home_target_center",
    "plan_postures",
    "optical_axes_convergence",
    "axes_convergence_m",
    "check_not_degenerate",
]


class DegenerateTrajectoryError(EstimationError, ValueError):
    """The postures cannot calibrate the camera (e.g. all optical axes meet in one point)."""


class DegenerateTrajectoryWarning(SelfCalWarning):
    """The postures are close to a degenerate configuration; results will be poorly conditioned."""


PLANNING_VISIBILITY = Visibility(
    margin_px=12.0, min_depth_m=0.12, max_depth_m=0.9, max_incidence_deg=65.0
)
"""What the planner asks of a target point: well inside the image, at a working distance, facing
the camera (stricter than what the simulator reports, so planned views are robust)."""


def home_target_center(robot: RobotDef, model_cam: MCPCModel) -> tuple[float, float]:
    """Where the home posture's optical axis meets the table (z = 0), ``(x, y)`` m in the world
    (base) frame: the centre of the target field, for any arm.

    ``model_cam``: the nominal chain whose tool is the (left) camera. The table must lie in front
    of the camera at a working distance of :data:`PLANNING_VISIBILITY` (depth along the optical
    axis); otherwise :class:`InputError` names the robot file's ``home_deg``.
    """
    T = fk_tool(model_cam, robot.home[None])[0]
    p, z = T[:3, 3], T[:3, 2]
    rule = PLANNING_VISIBILITY
    depth = -p[2] / z[2] if z[2] < -1e-9 else np.inf
    if not rule.min_depth_m <= depth <= rule.max_depth_m:
        seen = "does not look down at the table" if z[2] >= -1e-9 else f"sees it {depth:.2f} m away"
        raise InputError(
            f"{robot.name}: at the home posture the camera {seen}; the marker field is placed "
            f"where the home optical axis meets the table, {rule.min_depth_m:.2f} to "
            f"{rule.max_depth_m:.2f} m in front of the camera",
            fix=f"choose a home posture (home_deg in the robot file of {robot.name}) or a "
            "[camera_mount] whose camera looks down at the table in front of the robot",
        )
    hit = p + depth * z
    return float(hit[0]), float(hit[1])


def visible_counts(
    T_world_cam: np.ndarray,
    camera: CameraModel,
    points_world: np.ndarray,
    normals_world: np.ndarray | None = None,
    *,
    rule: Visibility = PLANNING_VISIBILITY,
) -> np.ndarray:
    """How many target points (k, 3) m (unit ``normals_world`` (k, 3) or None) each camera pose
    ``T_world_cam`` (m, 4, 4) sees by ``rule`` (:class:`selfcal.camera.Visibility`). Returns (m,)
    int."""
    return rule.points(camera, T_world_cam, points_world, normals_world).sum(axis=1)


_DRAWS = 4096
"""Postures :func:`plan_postures` draws at a time (the random sequence, and with it every plan,
depends on it)."""

_JUDGED = 512
"""Postures :func:`plan_postures` judges at a time: the default scenario keeps ~3 % of its draws,
so its 30 postures are found in the first ~1000 of a batch of :data:`_DRAWS`."""


def plan_postures(
    robot: RobotDef,
    model_cam: MCPCModel,
    rig: Rig,
    points_world: np.ndarray,
    n_poses: int,
    *,
    seed: int,
    min_visible: int,
    normals_world: np.ndarray | None = None,
    span: np.ndarray | None = None,
    max_candidates: int | None = None,
    collision_ok: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Random in-range postures around home in which every camera of ``rig`` sees
    ``min_visible`` points (:data:`PLANNING_VISIBILITY`) and, with ``collision_ok``, that are
    free of self-collision (e.g. :meth:`selfcal.kinematics.self_collision.CapsuleChain.ok`).

    Args:
        model_cam: nominal MCPC model whose tool is the rig's first camera (OpenCV frame).
        rig: the cameras and their extrinsics.
        points_world: (k, 3) points on the target (m), e.g. marker centres.
        span: (n,) half-width (rad, or m for a prismatic joint) of the window around home in
            which postures are drawn; default ``robot.planning_span`` (robot file
            ``[planning] span_deg``).
        collision_ok: ``(m, n) rad -> (m,) bool``, False for a posture in collision; None: no
            check. Rejected postures are dropped from the random sequence, so a check that passes
            every drawn posture leaves the plan unchanged.
        max_candidates: postures drawn at most; default ``max(200_000, 50 n_poses)`` (the
            default scenario keeps ~3 % of them: 10,000 postures need ~310,000; a larger budget
            changes no plan a smaller one found, the draws being the same sequence).
    Returns:
        (n_poses, n) joint vectors (rad), deterministic for a seed.
    Raises:
        DegenerateTrajectoryError: not enough such postures exist in the sampling window.
    """
    rng = np.random.default_rng(seed)
    if max_candidates is None:
        max_candidates = max(200_000, 50 * n_poses)
    span = robot.planning_span if span is None else np.asarray(span, dtype=float)
    lo = np.maximum(robot.limits[:, 0], robot.home - span)
    hi = np.minimum(robot.limits[:, 1], robot.home + span)
    found: list[np.ndarray] = []
    n_found = tried = 0
    while n_found < n_poses and tried < max_candidates:
        batch = rng.uniform(lo, hi, size=(_DRAWS, robot.n))
        tried += len(batch)
        # judged a slice at a time, up to the slice that completes the plan: the postures kept
        # are the same (each row is judged alone), the rest of the draws are never judged
        for start in range(0, _DRAWS, _JUDGED):
            q = batch[start : start + _JUDGED]
            seen = rig.visible_points(
                PLANNING_VISIBILITY, fk_tool(model_cam, q), points_world, normals_world
            )
            keep = (seen.sum(axis=2) >= min_visible).all(axis=1)
            if collision_ok is not None and keep.any():
                keep[keep] = np.asarray(collision_ok(q[keep]), dtype=bool)
            found.append(q[keep])
            n_found += int(keep.sum())
            if n_found >= n_poses:
                break
    allq = np.concatenate(found) if found else np.zeros((0, robot.n))
    if len(allq) < n_poses:
        raise DegenerateTrajectoryError(
            f"only {len(allq)} of {n_poses} postures found in which every camera sees "
            f"{min_visible} target points"
            + ("" if collision_ok is None else " without self-collision")
            + "; lower trajectory.min_markers, move the target, or widen the sampling window"
        )
    return allq[:n_poses]


def optical_axes_convergence(T_world_cam: np.ndarray) -> tuple[np.ndarray, float]:
    """Point (3,) closest (least squares) to all optical axes of ``T_world_cam`` (n, 4, 4) (poses
    with NaN are skipped) and the RMS distance of the axes from it (units of the poses).

    Near zero means every optical axis passes through one point: then the focal length cannot be
    recovered from the images (a known critical motion of self-calibration).
    """
    T = np.asarray(T_world_cam, dtype=float).reshape(-1, 4, 4)
    T = T[np.isfinite(T).all(axis=(1, 2))]
    C = T[:, :3, 3]
    d = T[:, :3, 2]
    P = np.eye(3) - d[:, :, None] * d[:, None, :]
    A = P.sum(axis=0)
    b = np.einsum("nij,nj->i", P, C)
    p = np.linalg.lstsq(A, b, rcond=None)[0]
    r = np.einsum("nij,nj->ni", P, p - C)
    return p, float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


def axes_convergence_m(T_world_cam: np.ndarray) -> float:
    """RMS distance (m) of the cameras' optical axes from the point nearest to all of them
    (:func:`optical_axes_convergence`)."""
    return optical_axes_convergence(T_world_cam)[1]


def check_not_degenerate(
    T_world_cam: np.ndarray, *, error_m: float = 0.002, warn_m: float = 0.01
) -> float:
    """Raise or warn if the optical axes (nearly) meet in one point; returns the RMS distance (m)."""
    if len(T_world_cam) < 3:
        raise DegenerateTrajectoryError(f"{len(T_world_cam)} postures: need at least 3 views")
    r = axes_convergence_m(T_world_cam)
    if r < error_m:
        raise DegenerateTrajectoryError(
            f"all optical axes pass within {r * 1000:.2f} mm of one point: the focal length is "
            "not recoverable from such views; vary the viewing directions (e.g. translate the "
            "camera sideways, not only rotate it about the target)"
        )
    if r < warn_m:
        warnings.warn(
            f"optical axes pass within {r * 1000:.1f} mm (RMS) of one point: close to the "
            "degenerate trajectory, the focal length will be poorly determined",
            DegenerateTrajectoryWarning,
            stacklevel=2,
        )
    return r
