"""Inverse kinematics with a calibrated model: joint commands that put the REAL tool where asked.

The controller (and :func:`selfcal.kinematics.ik.ik_nearest`) solves the nominal DH arm, so the real tool tip
misses a Cartesian target by the arm's kinematic errors (~1 mm and more for the SCORBOT). With the
calibrated chain of :func:`selfcal.export.deploy.deploy` (base frame -> tool tip, see that module for the
frames), :func:`compensated_ik` finds the joint readings at which the *calibrated* chain reaches
the target exactly; sending those to the controller as joint commands compensates the errors up to
the calibration's own accuracy.

Target: tool-tip position ``xyz_m`` in the robot's base frame (m) and the controller's Cartesian
``pitch`` / ``roll`` (rad, :mod:`selfcal.kinematics.tool_pose`) -- five numbers for five joints. For the
calibrated arm the tool axis need not lie exactly in the vertical plane through the base axis and
the tool point; pitch is measured in that plane (its out-of-plane component, fixed by the arm's
geometry, is ignored, as :func:`selfcal.kinematics.tool_pose.pitch_roll` does).

Any arm (:func:`solve_compensated_pose`): the target is a tool-tip position and optionally a full
orientation (:class:`selfcal.kinematics.ik_numeric.ToolTarget`); the nominal numerical IK gives the start and
:func:`selfcal.kinematics.ik_numeric.solve_ik` solves the calibrated chain. The ER-type arm's pitch/roll target
(:func:`solve_compensated`) works as follows.

Method: start from the nominal analytic IK (:func:`selfcal.kinematics.ik.ik`, the requested branch or the
in-range solution nearest ``reference``), then Levenberg-Marquardt / Newton on the calibrated chain
(residual: position in m and pitch, roll in rad, central-difference Jacobian) until both are below
``tol`` (default 1e-9 m / 1e-9 rad), and wrap the result into the joint ranges. Targets the nominal
arm cannot reach are tried from the home posture too (the real arm may reach a little farther).

Raises :class:`selfcal.kinematics.ik.UnreachableError` (a ``ValueError``) saying how far the calibrated chain
stays from the target or which joint range blocks it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError
from selfcal.export.deploy import DeployedModel, as_deployed
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.ik import UnreachableError, ik, ik_nearest, wrap_into_range
from selfcal.kinematics.ik_numeric import (
    ANGLE_SCALE_M,
    ToolTarget,
    ik_robot,
    solve_ik,
)
from selfcal.kinematics.least_squares import damped_least_squares
from selfcal.kinematics.tool_pose import tool_pose
from selfcal.robot.definition import RobotDef

__all__ = [
    "CompensatedIK",
    "compensated_ik",
    "solve_compensated",
    "solve_compensated_pose",
    "tool_target_residual",
]

_FD_STEP = 1e-6  # rad / m: central differences


@dataclass(frozen=True)
class CompensatedIK:
    """Result of :func:`solve_compensated`.

    Attributes:
        joints: (n,) joint commands (rad / m) for the real robot, inside the joint ranges.
        nominal_joints: (n,) what the nominal IK gives for the same target (rad / m).
        branch: the nominal IK branch it started from (``"front/elbow-up"``, ...) or ``"home"``.
        position_error_m: remaining tool-tip distance of the calibrated chain from the target.
        angle_error_rad: remaining max(|pitch error|, |roll error|).
        iterations: Newton / LM iterations used.
    """

    joints: np.ndarray
    nominal_joints: np.ndarray | None
    branch: str
    position_error_m: float
    angle_error_rad: float
    iterations: int


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def tool_target_residual(
    dep: DeployedModel, q: np.ndarray, xyz_m: np.ndarray, pitch_rad: float, roll_rad: float
) -> np.ndarray:
    """``[dx, dy, dz (m), dpitch, droll (rad)]`` (m, 5) of the calibrated tool tip at joints ``q``
    (m, n) against the target (angle differences wrapped to (-pi, pi])."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T = fk_tool(dep.model, q)
    xyz, pitch, roll = tool_pose(T, azimuth_rad=q[:, 0] + dep.model.joint_offsets[0])
    return np.column_stack(
        [xyz - np.asarray(xyz_m, float), _wrap(pitch - pitch_rad), _wrap(roll - roll_rad)]
    )


def _solve(dep, q0, xyz, pitch, roll, max_iter=60):
    """Damped Newton (LM on the one solver,
    :func:`selfcal.kinematics.least_squares.damped_least_squares`) from ``q0`` on the pitch/roll
    residual, central-difference Jacobian; returns (q, position error, angle error, iterations)."""
    n = dep.n
    w = np.array([1.0, 1.0, 1.0, ANGLE_SCALE_M, ANGLE_SCALE_M])
    eye = np.eye(n)

    def residual(q):
        return tool_target_residual(dep, q, xyz, pitch, roll)[0] * w

    def jacobian(q):
        qs = np.concatenate([q + _FD_STEP * eye, q - _FD_STEP * eye])
        rs = tool_target_residual(dep, qs, xyz, pitch, roll)
        return ((rs[:n] - rs[n:]) / (2 * _FD_STEP)).T * w[:, None]  # (5, n)

    q, r, iterations = damped_least_squares(residual, jacobian, q0, None, max_iter=max_iter)
    return q, float(np.linalg.norm(r[:3])), float(np.max(np.abs(r[3:] / w[3:]))), iterations


def _target_text(xyz, pitch, roll) -> str:
    return (
        f"target ({', '.join(f'{v * 1000:.3f}' for v in np.asarray(xyz, float))}) mm, pitch "
        f"{np.degrees(pitch):.3f} deg, roll {np.degrees(roll):.3f} deg"
    )


def solve_compensated(
    calibration,
    robot: RobotDef,
    xyz_m: np.ndarray,
    pitch_rad: float,
    roll_rad: float,
    *,
    reference: np.ndarray | None = None,
    branch: str | None = None,
    tol: float = 1e-9,
) -> CompensatedIK:
    """Joint commands reaching a Cartesian target with the calibrated model (module docstring).

    ``calibration``: a :class:`selfcal.io.calibration.CalibrationResult`, a
    :class:`selfcal.export.deploy.DeployedModel`, or an MCPC model already base frame -> tool tip.
    ``xyz_m`` (3,) m in the robot's base frame,
    ``pitch_rad`` / ``roll_rad`` as in :mod:`selfcal.kinematics.tool_pose`. ``reference`` (default home): pick
    the solution nearest this posture; ``branch``: start from that nominal IK branch only.

    Raises:
        UnreachableError: the calibrated chain cannot reach the target within ``tol`` (the message
            and ``distance_m`` give the best remaining distance) or only outside the joint ranges.
        ValueError: malformed target or unknown branch.
    """
    dep = as_deployed(calibration, robot)
    xyz = np.asarray(xyz_m, dtype=float)
    if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
        raise InputError(f"xyz_m must be a finite 3-vector (m), got {xyz_m!r}")
    pitch, roll = float(pitch_rad), float(roll_rad)
    ref = dep.home if reference is None else np.asarray(reference, dtype=float).reshape(dep.n)
    sols = ik(robot, xyz, pitch, roll, reference=ref)
    if branch is not None:
        names = sorted({s.branch for s in sols})
        sols = [s for s in sols if s.branch == branch]
        if not sols:
            raise InputError(
                f"branch {branch!r} has no nominal IK solution for this target; available: {names}"
            )
    # in-range nominal solutions first, nearest the reference first
    sols.sort(key=lambda s: (not s.in_range, float(np.linalg.norm(s.joints - ref))))
    seeds = [(s.joints, s.branch) for s in sols]
    nominal = next((s.joints for s in sols if s.in_range), None)
    if branch is None:
        seeds.append((np.clip(ref, dep.limits[:, 0], dep.limits[:, 1]), "home"))
    best_err, blocked = np.inf, []
    for q0, name in seeds:
        q, e_pos, e_ang, it = _solve(dep, q0, xyz, pitch, roll)
        if not (e_pos < tol and e_ang < tol):
            best_err = min(best_err, e_pos + ANGLE_SCALE_M * e_ang)
            continue
        bad = []
        for j in range(dep.n):
            q[j], ok = wrap_into_range(q[j], dep.limits[j, 0], dep.limits[j, 1], reference=ref[j])
            if not ok:
                u, s = ("deg", 180 / np.pi) if dep.joint_types[j] == "revolute" else ("mm", 1e3)
                lo, hi = dep.limits[j] * s
                bad.append(
                    f"joint {j + 1} ({dep.joint_names[j]}) = {q[j] * s:.3f} {u} outside "
                    f"[{lo:.2f}, {hi:.2f}] {u}"
                )
        if bad:
            blocked.append(f"{name}: " + "; ".join(bad))
            continue
        return CompensatedIK(q, nominal, name, e_pos, e_ang, it)
    tgt = _target_text(xyz, pitch, roll)
    if blocked:
        raise UnreachableError(
            f"{dep.robot_name} (calibrated): {tgt} is reachable only outside the joint ranges: "
            + " | ".join(blocked),
            distance_m=None,
            blocked_by=tuple(blocked),
        )
    nominal_says = ""
    if not sols:
        try:
            ik_nearest(robot, xyz, pitch, roll, reference=ref)
        except UnreachableError as exc:
            nominal_says = f" (nominal model: {exc})"
    raise UnreachableError(
        f"{dep.robot_name} (calibrated): {tgt} is out of reach: the calibrated chain stays "
        f"{best_err * 1000:.3f} mm (position + {ANGLE_SCALE_M * 1000:.0f} mm per rad of pitch/roll) "
        f"from it; move the target closer or change the pitch{nominal_says}",
        distance_m=float(best_err),
    )


def compensated_ik(
    calibration,
    robot: RobotDef,
    xyz_m: np.ndarray,
    pitch_rad: float,
    roll_rad: float,
    *,
    reference: np.ndarray | None = None,
    branch: str | None = None,
    tol: float = 1e-9,
) -> np.ndarray:
    """Joint commands (n,) rad reaching the target with the calibrated model: the ``joints`` of
    :func:`solve_compensated` (same arguments and errors)."""
    return solve_compensated(
        calibration,
        robot,
        xyz_m,
        pitch_rad,
        roll_rad,
        reference=reference,
        branch=branch,
        tol=tol,
    ).joints


def solve_compensated_pose(
    calibration,
    robot: RobotDef,
    target: ToolTarget,
    *,
    reference: np.ndarray | None = None,
    tol: float = 1e-9,
) -> CompensatedIK:
    """Joint commands reaching a tool pose (or tool point) with the calibrated model, any arm.

    ``calibration`` as in :func:`solve_compensated`; ``target`` in the robot's base frame, tool
    tip (:class:`selfcal.kinematics.ik_numeric.ToolTarget`: position, optional full orientation). The nominal
    numerical IK (:func:`selfcal.kinematics.ik_numeric.ik_robot`, nearest ``reference``, default home) gives
    the first start; then :func:`selfcal.kinematics.ik_numeric.solve_ik` on the calibrated chain (starts: that
    solution, home, seeded random in-range postures). ``branch`` of the result names the start
    (``"nominal"``, ``"home"``, ``"random <k>"``).

    Raises:
        UnreachableError: the calibrated chain cannot reach the target within ``tol``.
    """
    dep = as_deployed(calibration, robot)
    ref = dep.home if reference is None else np.asarray(reference, dtype=float).reshape(dep.n)
    try:
        nominal: np.ndarray | None = ik_robot(robot, target, reference=ref).joints
    except UnreachableError:
        nominal = None
    res = solve_ik(
        dep.model,
        dep.limits,
        target,
        reference=ref if nominal is None else nominal,
        home=dep.home,
        tol=tol,
        name=f"{dep.robot_name} (calibrated)",
    )
    start = "nominal" if (res.start == "reference" and nominal is not None) else res.start
    return CompensatedIK(
        res.joints, nominal, start, res.position_error_m, res.angle_error_rad, res.iterations
    )
