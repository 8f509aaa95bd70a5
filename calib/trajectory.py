"""Calibration trajectories: postures that keep the target in view of both cameras from varied
directions, and the check for the degenerate trajectory of self-calibration.

Planning uses only the nominal model and a rough description of where the target is (points on it,
world frame, m); it runs on the acquisition side and never sees the calibration's unknowns.
"""

from __future__ import annotations

import warnings

import numpy as np

from calib.camera import Intrinsics
from calib.errors import EstimationError, SelfCalWarning
from calib.kinematics import fk_tool
from calib.mcpc import MCPCModel
from calib.robot_def import RobotDef
from calib.transforms import inv_pose

__all__ = [
    "DegenerateTrajectoryError",
    "DegenerateTrajectoryWarning",
    "visible_counts",
    "plan_postures",
    "axes_convergence_m",
    "check_not_degenerate",
]


class DegenerateTrajectoryError(EstimationError, ValueError):
    """The postures cannot calibrate the camera (e.g. all optical axes meet in one point)."""


class DegenerateTrajectoryWarning(SelfCalWarning):
    """The postures are close to a degenerate configuration; results will be poorly conditioned."""


def visible_counts(
    T_world_cam: np.ndarray,
    intr: Intrinsics,
    points_world: np.ndarray,
    normals_world: np.ndarray | None = None,
    *,
    depth_m: tuple[float, float] = (0.12, 0.9),
    margin_px: float = 12.0,
    max_incidence_deg: float = 65.0,
) -> np.ndarray:
    """How many target points each camera (m, 4, 4) sees: in front, inside the image with a margin,
    within the depth range and (with normals) facing the camera. Returns (m,) int."""
    T_cam_world = inv_pose(T_world_cam)
    Xc = (
        np.einsum("mij,kj->mki", T_cam_world[:, :3, :3], points_world) + T_cam_world[:, None, :3, 3]
    )
    z = Xc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intr.fx * Xc[..., 0] / z + intr.cx
        v = intr.fy * Xc[..., 1] / z + intr.cy
    ok = (z > depth_m[0]) & (z < depth_m[1])
    ok &= (u > margin_px) & (u < intr.width - 1 - margin_px)
    ok &= (v > margin_px) & (v < intr.height - 1 - margin_px)
    if normals_world is not None:
        to_cam = T_world_cam[:, None, :3, 3] - points_world[None]
        cosang = np.einsum("mkj,kj->mk", to_cam, normals_world) / np.linalg.norm(to_cam, axis=-1)
        ok &= cosang > np.cos(np.radians(max_incidence_deg))
    return ok.sum(axis=1)


def plan_postures(
    robot: RobotDef,
    model_cam: MCPCModel,
    T_left_right: np.ndarray,
    intr: Intrinsics,
    points_world: np.ndarray,
    n_poses: int,
    *,
    seed: int,
    min_visible: int,
    normals_world: np.ndarray | None = None,
    span: np.ndarray | None = None,
    max_candidates: int = 200_000,
) -> np.ndarray:
    """Random in-range postures around home in which both cameras see ``min_visible`` points.

    Args:
        model_cam: nominal MCPC model whose tool is the left camera (OpenCV frame).
        T_left_right: pose of the right camera in the left camera's frame.
        points_world: (k, 3) points on the target (m), e.g. marker centres.
        span: (n,) half-width (rad, or m for a prismatic joint) of the window around home in
            which postures are drawn; default ``robot.planning_span`` (robot file
            ``[planning] span_deg``).
    Returns:
        (n_poses, n) joint vectors (rad), deterministic for a seed.
    Raises:
        DegenerateTrajectoryError: not enough such postures exist in the sampling window.
    """
    rng = np.random.default_rng(seed)
    span = robot.planning_span if span is None else np.asarray(span, dtype=float)
    lo = np.maximum(robot.limits[:, 0], robot.home - span)
    hi = np.minimum(robot.limits[:, 1], robot.home + span)
    found: list[np.ndarray] = []
    tried = 0
    while sum(len(f) for f in found) < n_poses and tried < max_candidates:
        q = rng.uniform(lo, hi, size=(4096, robot.n))
        tried += len(q)
        T_left = fk_tool(model_cam, q)
        T_right = T_left @ T_left_right
        ok = visible_counts(T_left, intr, points_world, normals_world) >= min_visible
        ok &= visible_counts(T_right, intr, points_world, normals_world) >= min_visible
        found.append(q[ok])
    allq = np.concatenate(found) if found else np.zeros((0, robot.n))
    if len(allq) < n_poses:
        raise DegenerateTrajectoryError(
            f"only {len(allq)} of {n_poses} postures found in which both cameras see "
            f"{min_visible} target points; lower trajectory.min_markers, move the target, or "
            "widen the sampling window"
        )
    return allq[:n_poses]


def axes_convergence_m(T_world_cam: np.ndarray) -> float:
    """RMS distance (m) of the cameras' optical axes from the point nearest to all of them.

    Near zero means every optical axis passes through one point: then the focal length cannot be
    recovered from the images (a known critical motion of self-calibration).
    """
    c = T_world_cam[:, :3, 3]
    d = T_world_cam[:, :3, 2]
    P = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    A = P.sum(axis=0)
    b = np.einsum("mij,mj->i", P, c)
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    r = np.einsum("mij,mj->mi", P, x[None] - c)
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


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
