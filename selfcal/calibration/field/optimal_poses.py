"""Calibration postures chosen for information: D-optimal selection from a feasible candidate pool.

Criterion: D-optimality of the *identifiable kinematic parameters* -- ``log det`` of the Fisher
information of the free minimal MCPC parameters (the gauge-held six of
:func:`selfcal.calibration.field.joint_refine.choose_gauge` excluded: they only place the robot in an arbitrary world
frame). ``log det`` is invariant to the units of the parameters, so angles and lengths need no
weighting. (The bound of the tool tip is what the report measures; it is evaluated afterwards
with the full model of :mod:`selfcal.calibration.field.bounds`, not optimised directly.)

Information proxy (cheap, additive over postures): the two-stage view. Posture ``i`` measures the
first camera's pose; its precision is predicted from the planning grid -- the target-region points
each camera of the rig sees at that posture (the same visibility rule as the random planner,
:data:`selfcal.kinematics.trajectory.PLANNING_VISIBILITY`), each worth ``corners_per_point`` corners of
``pixel_sigma_px`` noise -- as the pose-from-known-points Fisher information of the rig ``I_i``
(6 x 6, in the first camera's body twist), plus the read-back noise propagated through the
chain: ``Sigma_i = I_i^-1 + J_q diag(joint_sigma^2) J_q^T``. The information about the kinematic
parameters is then ``F = sum_i J_i^T Sigma_i^-1 J_i`` with ``J_i`` the identification Jacobian
(:func:`selfcal.kinematics.forward.identification_jacobian`) at the posture. It ignores what the
self-calibration must also estimate (focal length, aspect ratio, rig, points, scale), so it ranks
postures; the bound of a plan is computed with :mod:`selfcal.calibration.field.bounds`.

Selection: greedy (each step adds the candidate with the largest ``log det(I + L^T F^-1 L)``,
``Sigma^-1 = L L^T``, the determinant lemma) from a slightly regularised start, then exchange
passes (swap a chosen posture for a candidate while ``log det F`` grows). Candidates are random
in-range postures of the planner's sampling window in which every camera sees ``min_visible`` grid
points (:func:`selfcal.kinematics.trajectory.plan_postures`), minus those the optional ``collision_ok``
callback rejects (self-collision; the MuJoCo check lives outside the mathematics).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.field.joint_refine import choose_gauge, encoder_sigma
from selfcal.camera import CameraModel, Rig
from selfcal.errors import InputError, UsageError
from selfcal.kinematics.forward import fk_frames, fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.kinematics.trajectory import (
    PLANNING_VISIBILITY,
    DegenerateTrajectoryError,
    check_not_degenerate,
    plan_postures,
)
from selfcal.robot.definition import RobotDef
from selfcal.transforms import adjoint, inv_pose, skew

__all__ = [
    "OptimalPlan",
    "pose_information",
    "kinematic_information",
    "select_d_optimal",
    "plan_optimal_postures",
]


@dataclass
class OptimalPlan:
    """A D-optimal plan: ``q`` (n_poses, n) rad; ``logdet`` of the proxy information of the
    free kinematic parameters (``free`` names); ``candidates`` in the pool after the collision
    check (``rejected_collision`` removed); ``exchanges`` made; ``logdet_random`` of the first
    ``n_poses`` pool postures (a random plan of the same size, for contrast); ``pool`` (c, n)
    rad the candidates after the collision check and ``chosen`` (n_poses,) the indices of
    ``q`` in it."""

    q: np.ndarray
    logdet: float
    logdet_random: float
    free: tuple[str, ...]
    candidates: int
    rejected_collision: int
    exchanges: int
    pool: np.ndarray
    chosen: np.ndarray


def _camera_info(
    T_world_cam: np.ndarray, camera: CameraModel, X: np.ndarray, vis: np.ndarray
) -> np.ndarray:
    """(m, 6, 6) information on the camera body twist ``[v; w]`` per unit pixel variance from
    the points ``X`` (k, 3) m visible (``vis`` (m, k)) from poses ``T_world_cam`` (m, 4, 4)."""
    T_cw = inv_pose(T_world_cam)
    Xc = np.einsum("mij,kj->mki", T_cw[:, :3, :3], X) + T_cw[:, None, :3, 3]
    Xs = Xc.copy()
    Xs[..., 2] = np.where(vis, Xc[..., 2], 1.0)  # finite Jacobians where not seen (weight 0)
    _, A, _ = camera.project_jacobians(Xs)
    D = np.concatenate([np.broadcast_to(-np.eye(3), Xc.shape[:2] + (3, 3)), skew(Xc)], axis=-1)
    G = A @ D * vis[..., None, None]  # (m, k, 2, 6)
    return np.einsum("mkai,mkaj->mij", G, G)


def pose_information(
    model_cam: MCPCModel,
    rig: Rig,
    q: np.ndarray,
    points_world: np.ndarray,
    normals_world: np.ndarray | None = None,
    *,
    pixel_sigma_px: float = 0.5,
    corners_per_point: float = 1.0,
    joint_sigma: np.ndarray | None = None,
) -> np.ndarray:
    """(m, 6, 6) inverse covariance of the first camera's pose (body twist ``[v; w]``, m / rad)
    predicted at joints ``q`` (m, n): the rig's pose-from-points information of the visible grid
    points (each ``corners_per_point`` corners of ``pixel_sigma_px``), with the read-back noise
    ``joint_sigma`` (n,) propagated through the chain when given."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T_first = fk_tool(model_cam, q)
    X = np.asarray(points_world, dtype=float)
    w = corners_per_point / pixel_sigma_px**2
    T = rig.T_world_cams(T_first)
    vis = rig.visible_points(PLANNING_VISIBILITY, T_first, X, normals_world)
    total = _camera_info(T[:, 0], rig.cameras[0], X, vis[:, 0])
    for c in range(1, rig.n_cameras):
        Ad = adjoint(inv_pose(rig.T_first_cam[c]))  # camera body twist = Ad first body twist
        total = total + Ad.T @ _camera_info(T[:, c], rig.cameras[c], X, vis[:, c]) @ Ad
    info = w * total
    scale = np.maximum(np.trace(info, axis1=1, axis2=2) / 6, 1e-300)
    info = info + 1e-9 * scale[:, None, None] * np.eye(6)
    if joint_sigma is None:
        return info
    js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (model_cam.n,))
    F = fk_frames(model_cam, q)
    Xj = inv_pose(F[:, -1:]) @ F[:, :-1]  # joint frames in the tool frame (m, n, 4, 4)
    ax = Xj[..., :3, 2]
    tw = np.concatenate([np.cross(Xj[..., :3, 3], ax), ax], axis=-1)  # body twist per joint
    pris = np.array([t == "prismatic" for t in model_cam.joint_types])
    tw[:, pris] = np.concatenate([ax[:, pris], 0 * ax[:, pris]], axis=-1)
    Jq = np.swapaxes(tw, 1, 2)  # (m, 6, n)
    cov = np.linalg.inv(info) + np.einsum("mik,k,mjk->mij", Jq, js**2, Jq)
    return np.linalg.inv(cov)


def kinematic_information(
    model_cam: MCPCModel, q: np.ndarray, W: np.ndarray, free_idx: np.ndarray
) -> np.ndarray:
    """(m, k, 6) factors ``B_i = J_i^T L_i`` (``W_i = L_i L_i^T``): posture ``i`` adds
    ``B_i B_i^T`` to the information of the free parameters (flat indices ``free_idx``)."""
    J = identification_jacobian(model_cam, np.atleast_2d(q))[:, :, free_idx]  # (m, 6, k)
    L = np.linalg.cholesky(0.5 * (W + np.swapaxes(W, 1, 2)))
    return np.swapaxes(J, 1, 2) @ L


def _gains(B: np.ndarray, Finv: np.ndarray) -> np.ndarray:
    M = np.swapaxes(B, 1, 2) @ Finv @ B  # (N, 6, 6)
    sign, ld = np.linalg.slogdet(np.eye(B.shape[2]) + M)
    return np.where(sign > 0, ld, -np.inf)


def select_d_optimal(
    B: np.ndarray, n: int, *, max_passes: int = 4, reg: float = 1e-6
) -> tuple[np.ndarray, float, int]:
    """Greedy + exchange D-optimal choice of ``n`` of the candidates with factors ``B`` (N, k, r).

    Returns ``(indices (n,), log det F, exchanges)``; ``F = reg * mean_diag * I + sum B B^T``
    over the chosen ones (the small ``reg`` only matters while fewer postures than needed for
    full rank are chosen)."""
    N, k, _ = B.shape
    if n > N:
        raise InputError(f"cannot choose {n} postures from {N} candidates; enlarge the pool")
    BBt = np.einsum("nir,njr->nij", B, B)
    F0 = reg * np.mean(np.diagonal(BBt, axis1=1, axis2=2)) * np.eye(k)
    F = F0.copy()
    chosen: list[int] = []
    free = np.ones(N, bool)
    for _ in range(n):
        g = _gains(B, np.linalg.inv(F))
        g[~free] = -np.inf
        b = int(np.argmax(g))
        chosen.append(b)
        free[b] = False
        F += BBt[b]
    exchanges = 0
    for _ in range(max_passes):
        changed = False
        for pos in range(n):
            s = chosen[pos]
            Fm = F - BBt[s]
            Fminv = np.linalg.inv(Fm)
            g = _gains(B, Fminv)
            g_s = g[s]
            g[~free] = -np.inf
            c = int(np.argmax(g))
            if g[c] > g_s + 1e-9:
                chosen[pos] = c
                free[s], free[c] = True, False
                F = Fm + BBt[c]
                exchanges += 1
                changed = True
        if not changed:
            break
    return np.asarray(chosen), float(np.linalg.slogdet(F)[1]), exchanges


def plan_optimal_postures(
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
    n_candidates: int = 3000,
    collision_ok: Callable[[np.ndarray], np.ndarray] | None = None,
    pixel_sigma_px: float = 0.5,
    corners_per_point: float = 1.0,
    joint_sigma: np.ndarray | None | str = "encoder",
    max_passes: int = 4,
) -> OptimalPlan:
    """D-optimal calibration postures (see the module docstring); same inputs as
    :func:`selfcal.kinematics.trajectory.plan_postures` plus:

    Args:
        n_candidates: size of the random feasible pool (before the collision check).
        collision_ok: ``(m, n) rad -> (m,) bool``, False for a posture in collision (e.g. a
            MuJoCo contact check of the nominal robot); None: no check.
        pixel_sigma_px, corners_per_point: corner noise and corners per grid point of the
            information proxy (e.g. ``4 * markers / len(points_world)``).
        joint_sigma: read-back noise (n,) rad; ``"encoder"`` (default) the robot's encoder
            quantisation (:func:`selfcal.calibration.field.joint_refine.encoder_sigma`); None: exact.
    Returns:
        :class:`OptimalPlan` (``q`` deterministic for a seed).
    Raises:
        DegenerateTrajectoryError: too few feasible candidates, or the chosen optical axes all
            meet in one point.
    """
    if isinstance(joint_sigma, str):
        if joint_sigma != "encoder":
            raise InputError(
                f"joint_sigma must be 'encoder', an array or None, not {joint_sigma!r}"
            )
        joint_sigma = encoder_sigma(robot)
    pool = plan_postures(
        robot,
        model_cam,
        rig,
        points_world,
        max(n_candidates, n_poses),
        seed=seed,
        min_visible=min_visible,
        normals_world=normals_world,
        span=span,
    )
    rejected = 0
    if collision_ok is not None:
        ok = np.asarray(collision_ok(pool), dtype=bool)
        if ok.shape != (len(pool),):
            raise UsageError("collision_ok must return one bool per posture")
        rejected = int((~ok).sum())
        pool = pool[ok]
    if len(pool) < n_poses:
        raise DegenerateTrajectoryError(
            f"only {len(pool)} collision-free candidate postures for {n_poses} poses; raise "
            "n_candidates or widen the sampling window"
        )
    idx = minimal_indices(model_cam.joint_types)
    names = param_names(idx)
    held = set(choose_gauge(model_cam).held)
    free = np.array([nm not in held for nm in names])
    W = pose_information(
        model_cam,
        rig,
        pool,
        points_world,
        normals_world,
        pixel_sigma_px=pixel_sigma_px,
        corners_per_point=corners_per_point,
        joint_sigma=joint_sigma,
    )
    B = kinematic_information(model_cam, pool, W, idx[free])
    chosen, logdet, exch = select_d_optimal(B, n_poses, max_passes=max_passes)
    Fr = np.einsum("nir,njr->ij", B[:n_poses], B[:n_poses])
    chosen = np.sort(chosen)
    q = pool[chosen]
    check_not_degenerate(fk_tool(model_cam, q))
    return OptimalPlan(
        q=q,
        logdet=logdet,
        logdet_random=float(np.linalg.slogdet(Fr)[1]),
        free=tuple(n for n, f in zip(names, free) if f),
        candidates=int(len(pool)),
        rejected_collision=rejected,
        exchanges=exch,
        pool=pool,
        chosen=chosen,
    )
