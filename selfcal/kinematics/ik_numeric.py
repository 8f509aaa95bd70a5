"""Numerical inverse kinematics of any serial arm on its MCPC chain (damped least squares).

The target is a tool pose: a tool point (m, world frame of the chain) and, optionally, a full tool
orientation (a 3x3 rotation). The residual is ``[p(q) - p_goal; rotvec(R(q) R_goal^T) * s]`` with
``s`` = :data:`ANGLE_SCALE_M` metres per radian weighing orientation against position; its
Jacobian is the chain's geometric Jacobian (joint axes from :func:`selfcal.kinematics.forward.fk_frames`),
exact at the solution. The one solver's Levenberg-Marquardt loop minimises it, the joint ranges
as its bounds (:func:`selfcal.kinematics.least_squares.damped_least_squares`, which the
calibrated-model compensation, :mod:`selfcal.export.compensate`, calls too).

Joint ranges: each start is solved without them first and the result wrapped by +-360 deg into
the ranges (:func:`selfcal.kinematics.ik.wrap_into_range`, so solutions on a range's end are found); when that
lands outside a range, the start is solved again with every step projected onto the ranges.
Several starts (the reference posture, home, then seeded random in-range postures) make the solver
robust to the basins of a 6-axis arm. A target no start reaches raises :class:`selfcal.kinematics.ik.UnreachableError`.

Units: metres and radians inside (metres for a prismatic joint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_frames
from selfcal.kinematics.ik import (
    IKStructureError,
    UnreachableError,
    check_er_structure,
    ik_nearest,
    wrap_into_range,
)
from selfcal.kinematics.least_squares import damped_least_squares
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.kinematics.tool_pose import tool_pose
from selfcal.robot.definition import RobotDef
from selfcal.transforms import make_pose

__all__ = [
    "ANGLE_SCALE_M",
    "ToolTarget",
    "NumericIK",
    "pose_residual",
    "pose_jacobian",
    "solve_ik",
    "ik_robot",
]

ANGLE_SCALE_M = 0.1
"""Metres per radian: how orientation errors weigh against position errors in the steps."""
STALL_TOL = 1e-6
"""m and rad: at a singular posture the steps stall short of :func:`solve_ik`'s ``tol`` (1e-9 m,
8e-8 rad measured at the UR5e's wrist singularity); a solution that close (a thousandth of an
arm's repeatability) is returned with its errors instead of calling the target out of reach."""


@dataclass(frozen=True)
class ToolTarget:
    """A tool pose to reach: ``position`` (3,) m and ``rotation`` (3, 3) or ``None`` (any
    orientation), both in the chain's world frame."""

    position: np.ndarray
    rotation: np.ndarray | None = None

    @staticmethod
    def checked(position, rotation=None) -> ToolTarget:
        """A target from user input; :class:`selfcal.errors.InputError` for non-finite values, a
        wrong shape or a matrix that is not a rotation."""
        p = np.asarray(position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InputError(f"tool point must be a finite 3-vector (m), got {position!r}")
        if rotation is None:
            return ToolTarget(p, None)
        R = np.asarray(rotation, dtype=float)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise InputError(f"tool orientation must be a finite 3x3 rotation, got {rotation!r}")
        if np.max(np.abs(R.T @ R - np.eye(3))) > 1e-9 or np.linalg.det(R) < 0:
            raise InputError("tool orientation is not a rotation matrix (orthonormal, det +1)")
        return ToolTarget(p, R)

    @property
    def rows(self) -> int:
        """Residual rows: 3 (position) or 6 (pose)."""
        return 3 if self.rotation is None else 6

    def describe(self) -> str:
        """The target in mm and (for a pose) xyz Euler angles in deg, for messages."""
        text = "(" + ", ".join(f"{v * 1000:.3f}" for v in self.position) + ") mm"
        if self.rotation is not None:
            rpy = Rotation.from_matrix(self.rotation).as_euler("xyz", degrees=True)
            text += ", rpy (" + ", ".join(f"{v:.3f}" for v in rpy) + ") deg"
        return text


@dataclass(frozen=True)
class NumericIK:
    """One solution of :func:`solve_ik`.

    Attributes:
        joints: (n,) joint values (rad / m) inside the joint ranges.
        position_error_m: remaining tool-point distance from the target.
        angle_error_rad: remaining rotation angle from the target orientation (0 without one).
        start: which start converged: ``"reference"``, ``"home"`` or ``"random <k>"``.
        iterations: LM iterations of that start.
    """

    joints: np.ndarray
    position_error_m: float
    angle_error_rad: float
    start: str
    iterations: int


def pose_residual(model: MCPCModel, q: np.ndarray, target: ToolTarget) -> np.ndarray:
    """Residuals (m, 3 or 6) at joint vectors ``q`` (m, n): tool-point error (m, world frame),
    then the orientation error as a world-frame rotation vector times :data:`ANGLE_SCALE_M`."""
    T = fk_frames(model, np.atleast_2d(q))[:, -1]
    dp = T[:, :3, 3] - target.position
    if target.rotation is None:
        return dp
    E = T[:, :3, :3] @ target.rotation.T
    return np.column_stack([dp, ANGLE_SCALE_M * Rotation.from_matrix(E).as_rotvec()])


def pose_jacobian(model: MCPCModel, q: np.ndarray, rows: int = 6) -> np.ndarray:
    """Geometric Jacobian (m, rows, n) of :func:`pose_residual` at joint vectors ``q`` (m, n):
    d(tool point)/dq (m per rad or per m) and ``ANGLE_SCALE_M`` * d(rotation)/dq (world frame)."""
    F = fk_frames(model, np.atleast_2d(q))
    z, o, tip = F[:, :-1, :3, 2], F[:, :-1, :3, 3], F[:, -1:, :3, 3]
    rev = np.array([t == "revolute" for t in model.joint_types])[None, :, None]
    lin = np.where(rev, np.cross(z, tip - o), z)
    J = lin if rows == 3 else np.concatenate([lin, ANGLE_SCALE_M * np.where(rev, z, 0.0)], axis=2)
    return np.swapaxes(J, 1, 2)


def _reach_bound(model: MCPCModel, limits: np.ndarray) -> float:
    """An upper bound (m) of the tool point's distance from the world origin: the lengths of the
    shape matrices' translations plus each prismatic joint's largest travel."""
    lengths = np.linalg.norm(model.params[:, 3:], axis=1).sum()
    travel = sum(
        float(np.max(np.abs(limits[j])))
        for j, t in enumerate(model.joint_types)
        if t == "prismatic"
    )
    return float(lengths + travel)


def _errors(r: np.ndarray) -> tuple[float, float]:
    return float(np.linalg.norm(r[:3])), float(np.linalg.norm(r[3:]) / ANGLE_SCALE_M)


def solve_ik(
    model: MCPCModel,
    limits: np.ndarray,
    target: ToolTarget,
    *,
    reference: np.ndarray | None = None,
    home: np.ndarray | None = None,
    n_random: int = 64,
    seed: int = 0,
    tol: float = 1e-10,
    name: str = "robot",
) -> NumericIK:
    """Joint values (rad / m) that put ``model``'s tool on ``target`` within ``tol`` (m and rad),
    inside ``limits`` (n, 2).

    Starts, in order: ``reference``, ``home``, then ``n_random`` uniform in-range postures
    (``seed``). The first start that converges wins (the reference's basin gives the solution
    nearest the current posture). When none converges to ``tol`` but one stalls within
    :data:`STALL_TOL` inside the ranges (a singular posture: the Jacobian loses rank at the
    solution), the closest such one is returned; its ``position_error_m`` and
    ``angle_error_rad`` say how close.

    Raises:
        UnreachableError: no start converges; ``distance_m`` = the best remaining position error
            plus :data:`ANGLE_SCALE_M` times the angle error.
    """
    limits = np.asarray(limits, dtype=float)
    if (
        limits.shape != (model.n, 2)
        or not np.all(np.isfinite(limits))
        or np.any(limits[:, 0] > limits[:, 1])
    ):
        raise InputError(
            f"{name}: joint ranges must be {model.n} finite [lower, upper] pairs, got "
            f"{limits.tolist()}",
            fix=f"check the joint ranges in {name}'s robot file",
        )
    if not np.all(np.isfinite(model.params)):
        raise InputError(
            f"{name}: the kinematic model holds NaN or inf parameters",
            fix="check the robot file or calibration.json the model comes from",
        )
    lo, hi = limits[:, 0], limits[:, 1]
    starts: list[tuple[str, np.ndarray]] = []
    for label, q in (("reference", reference), ("home", home)):
        if q is not None:
            q = np.asarray(q, dtype=float).reshape(model.n)
            if not np.all(np.isfinite(q)):
                raise InputError(
                    f"{name}: the {label} posture for IK holds NaN or inf: {q.tolist()}",
                    fix="read the joints again (a failed read-back gives NaN)",
                )
            starts.append((label, q))
    rng = np.random.default_rng(seed)
    starts += [(f"random {k}", rng.uniform(lo, hi)) for k in range(n_random)]
    if not starts:
        starts = [("mid-range", 0.5 * (lo + hi))]

    def residual(q):
        return pose_residual(model, q, target)[0]

    def jacobian(q):
        return pose_jacobian(model, q, target.rows)[0]

    def converged(r):
        e_pos, e_ang = _errors(r)
        return e_pos < tol and e_ang < tol

    reach = _reach_bound(model, limits)
    far = float(np.linalg.norm(target.position)) - reach
    if far > tol:
        raise UnreachableError(
            f"{name}: tool target {target.describe()} is out of reach: {far * 1000:.3f} mm "
            f"beyond the arm's longest possible reach ({reach * 1000:.1f} mm from the base "
            "origin, the sum of its link lengths); move the target closer",
            distance_m=far,
        )
    rev = [t == "revolute" for t in model.joint_types]
    ref = None if reference is None else np.asarray(reference, dtype=float).reshape(model.n)
    best = np.inf
    near: NumericIK | None = None  # the closest stalled solution inside the ranges

    def consider(q: np.ndarray, r: np.ndarray, label: str, it: int) -> None:
        nonlocal near
        e = _errors(r)
        if max(e) < STALL_TOL and (
            near is None or max(e) < max(near.position_error_m, near.angle_error_rad)
        ):
            near = NumericIK(np.asarray(q, dtype=float), *e, label, it)

    for label, q0 in starts:
        q, r, it = damped_least_squares(residual, jacobian, q0, None)
        if not converged(r) and max(_errors(r)) >= STALL_TOL:
            # not even without the ranges: the projected solve would not get there either
            best = min(best, float(np.linalg.norm(r)))
            continue
        wrapped = [
            wrap_into_range(v, l_, h_, None if ref is None else ref[j]) if rev[j] else (v, True)
            for j, (v, l_, h_) in enumerate(zip(q, lo, hi))
        ]
        qw = np.clip([w for w, _ in wrapped], lo, hi)
        rw = residual(qw)
        if all(ok for _, ok in wrapped):
            if converged(rw):
                return NumericIK(qw, *_errors(rw), label, it)
            consider(qw, rw, label, it)
        q, r, it = damped_least_squares(residual, jacobian, q0, limits)
        if converged(r):
            return NumericIK(q, *_errors(r), label, it)
        consider(q, r, label, it)
        best = min(best, float(np.linalg.norm(r)))
    if near is not None:  # a singular posture: the steps stall short of tol, well below a micron
        return near
    raise UnreachableError(
        f"{name}: tool target {target.describe()} is out of reach: from {len(starts)} starts "
        f"the closest tool pose stays {best * 1000:.3f} mm (position + "
        f"{ANGLE_SCALE_M * 1000:.0f} mm per rad of orientation) from it within the joint ranges; "
        "move the target closer or change its orientation",
        distance_m=best,
    )


def ik_robot(
    robot: RobotDef,
    target: ToolTarget,
    *,
    reference: np.ndarray | None = None,
    model: MCPCModel | None = None,
    tol: float = 1e-10,
) -> NumericIK:
    """Joint values reaching ``target`` (base frame, tool = flange = last DH frame) for a robot
    definition, nearest ``reference`` (default home). Any serial arm.

    Without ``model`` (the nominal chain) and for an ER-type arm with a full orientation, the
    closed-form IK (:func:`selfcal.kinematics.ik.ik_nearest`) is tried first (``start = "analytic"``); otherwise,
    or when it finds no solution reproducing the target within ``tol``, :func:`solve_ik` on
    ``model`` (default the nominal chain ``nominal_mcpc(robot)``) with starts ``reference`` and home.
    """
    ref = robot.home if reference is None else np.asarray(reference, dtype=float)
    if model is None:
        model = nominal_mcpc(robot)
        fast = _analytic(robot, model, target, ref, tol)
        if fast is not None:
            return fast
    return solve_ik(
        model, robot.limits, target, reference=ref, home=robot.home, tol=tol, name=robot.name
    )


def _analytic(
    robot: RobotDef, model: MCPCModel, target: ToolTarget, ref: np.ndarray, tol: float
) -> NumericIK | None:
    """The ER-4u closed form for a full pose target, or None (not an ER-type arm, no
    orientation, no in-range solution, or the pose is not one the 5-axis arm can take)."""
    if target.rotation is None:
        return None
    try:
        check_er_structure(robot)
        offset0 = robot.dh.offset[0] if robot.dh is not None else 0.0  # an ER arm has a DH table
        T = make_pose(target.rotation, target.position)
        _, pitch, roll = tool_pose(T[None], azimuth_rad=np.array([ref[0] + offset0]))
        q = ik_nearest(robot, target.position, float(pitch[0]), float(roll[0]), reference=ref)
    except (IKStructureError, UnreachableError, ValueError):
        return None
    r = pose_residual(model, q, target)[0]
    e_pos, e_ang = _errors(r)
    if e_pos < tol and e_ang < tol:
        return NumericIK(q, e_pos, e_ang, "analytic", 0)
    return None
