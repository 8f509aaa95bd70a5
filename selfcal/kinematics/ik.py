"""Inverse kinematics of a 5-axis ER-type arm (SCORBOT ER-4u) in the controller's Cartesian pose.

The arm: joint 1 vertical (the DH base z-axis is the world z-axis); joints 2, 3, 4 horizontal and
parallel; joint 5 along the tool axis; ``a4 = a5 = d2 = d3 = d4 = 0``. A target is a tool point
(m) plus Cartesian pitch and roll (rad) as defined in :mod:`selfcal.kinematics.tool_pose`; five numbers for five
joints, so there are up to four exact solutions: base ``front``/``back`` (joint 1's x-axis towards
or away from the tool point) times ``elbow-up``/``elbow-down`` (the elbow counterclockwise /
clockwise of the shoulder-to-wrist line seen in the arm plane with ``r_hat`` to the right and z up,
i.e. above / below that line when the arm reaches outwards).

Joints 1-3 are solved in closed form (wrist centre = tool point - d5 * tool axis). Joints 4 and 5
are solved generically: the pitch and roll reached with ``q4 = q5 = 0`` are measured with forward
kinematics and subtracted, with the signs read from the joint axes, so DH offsets and sign
conventions need no special cases.

Units: metres and radians throughout; joint ranges are the robot's ``limits``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError, InternalError
from selfcal.kinematics.forward import fk_nominal
from selfcal.kinematics.tool_pose import AXIS_EPS_M, pitch_roll, tool_rotation
from selfcal.robot.definition import DHParams, RobotDef

__all__ = [
    "IKSolution",
    "UnreachableError",
    "IKStructureError",
    "check_er_structure",
    "ik",
    "ik_nearest",
    "nearest_reachable",
    "wrap_into_range",
]

_UP = np.array([0.0, 0.0, 1.0])
_LEN_TOL = 1e-12  # m: "zero" DH lengths
_ANG_TOL = 1e-9  # rad: "exact" DH twists
_RANGE_TOL = 1e-12  # rad: slack on joint ranges (as RobotDef.check_joints)


class UnreachableError(InputError):
    """No in-range joint solution exists for a Cartesian target.

    Attributes:
        distance_m: how far (m) the wrist centre lies outside the reach of the arm, or ``None`` when
            the target is geometrically reachable but every solution violates a joint range.
        blocked_by: for the latter case, one message per solution branch naming the violations.
    """

    def __init__(
        self, message: str, distance_m: float | None = None, blocked_by: tuple[str, ...] = ()
    ):
        super().__init__(message)
        self.distance_m = distance_m
        self.blocked_by = blocked_by


class IKStructureError(InputError):
    """The robot's DH table does not have the 5-axis ER structure this solver handles."""


@dataclass(frozen=True)
class IKSolution:
    """One exact IK solution.

    Attributes:
        joints: (n,) joint angles (rad), wrapped by +-360 deg into the joint ranges where possible.
        branch: ``"front/elbow-up"``, ``"front/elbow-down"``, ``"back/elbow-up"`` or
            ``"back/elbow-down"``.
        in_range: whether every joint is inside its range.
        violations: one message per joint outside its range (empty when ``in_range``).
    """

    joints: np.ndarray
    branch: str
    in_range: bool
    violations: tuple[str, ...]

    @property
    def joints_deg(self) -> np.ndarray:
        """The joint angles in degrees."""
        return np.degrees(self.joints)


def check_er_structure(robot: RobotDef) -> None:
    """Raise :class:`IKStructureError` unless ``robot`` is a 5-revolute ER-type arm (see module doc)."""
    problems = []
    if robot.n != 5 or any(t != "revolute" for t in robot.joint_types):
        problems.append(f"needs 5 revolute joints, has {robot.joint_types}")
    elif robot.dh is None or robot.dh.convention != "dh":
        problems.append(f"needs a standard-DH table, has a {robot.convention} description")
    else:
        al, a, d = robot.dh.alpha, robot.dh.a, robot.dh.d
        for name, val in (("a4", a[3]), ("a5", a[4]), ("d2", d[1]), ("d3", d[2]), ("d4", d[3])):
            if abs(val) > _LEN_TOL:
                problems.append(f"{name} = {val * 1000:.6g} mm must be 0")
        for i, want in ((0, 90.0), (3, 90.0)):
            if abs(abs(al[i]) - np.pi / 2) > _ANG_TOL:
                problems.append(f"alpha{i + 1} = {np.degrees(al[i]):.6g} deg must be +-{want:g}")
        for i in (1, 2, 4):
            if abs(al[i]) > _ANG_TOL:
                problems.append(f"alpha{i + 1} = {np.degrees(al[i]):.6g} deg must be 0")
        for i in (1, 2):
            if a[i] <= _LEN_TOL:
                problems.append(f"a{i + 1} = {a[i] * 1000:.6g} mm must be > 0")
    if problems:
        raise IKStructureError(
            f"{robot.name}: the analytic IK needs joint 1 vertical, joints 2-4 parallel and "
            f"horizontal, joint 5 along the tool axis and a4 = a5 = d2 = d3 = d4 = 0; "
            + "; ".join(problems)
        )


def _table(robot: RobotDef) -> DHParams:
    """The robot's standard-DH table, which the closed form reads (:func:`check_er_structure`)."""
    if robot.dh is None or robot.dh.convention != "dh":
        raise IKStructureError(
            f"{robot.name}: the analytic IK needs a standard-DH table, the robot has a "
            f"{robot.convention} description"
        )
    return robot.dh


def _wrap_pi(a: float) -> float:
    w = (a + np.pi) % (2 * np.pi) - np.pi
    return w + 2 * np.pi if w <= -np.pi else w


def wrap_into_range(
    value: float, lo: float, hi: float, reference: float | None = None
) -> tuple[float, bool]:
    """A +-k*360 deg equivalent of angle ``value`` (rad) inside ``[lo, hi]``.

    Among in-range equivalents, returns the one nearest ``reference`` (or, without a reference, the
    one nearest zero). Returns ``(angle, True)``, or ``(equivalent nearest the range, False)`` when
    none is in range.
    """
    base = _wrap_pi(value)
    k_lo = int(np.floor((lo - base) / (2 * np.pi))) - 1
    k_hi = int(np.ceil((hi - base) / (2 * np.pi))) + 1
    cands = base + 2 * np.pi * np.arange(k_lo, k_hi + 1)
    ok = (cands >= lo - _RANGE_TOL) & (cands <= hi + _RANGE_TOL)
    if np.any(ok):
        c = cands[ok]
        target = 0.0 if reference is None else reference
        return float(c[np.argmin(np.abs(c - target))]), True
    excess = np.maximum(lo - cands, cands - hi)
    return float(cands[np.argmin(excess)]), False


def _violation(robot: RobotDef, j: int, v: float) -> str:
    lo, hi = np.degrees(robot.limits[j])
    vd = np.degrees(v)
    by = max(lo - vd, vd - hi)
    return (
        f"joint {j + 1} ({robot.joint_names[j]}) = {vd:.3f} deg is outside its range "
        f"[{lo:.2f}, {hi:.2f}] deg by {by:.3f} deg"
    )


def _as_target(xyz_m, pitch_rad, roll_rad) -> tuple[np.ndarray, float, float]:
    p = np.asarray(xyz_m, dtype=float)
    if p.shape != (3,):
        raise InputError(f"xyz_m must be a 3-vector (m), got shape {p.shape}")
    pitch, roll = float(pitch_rad), float(roll_rad)
    if not (np.all(np.isfinite(p)) and np.isfinite(pitch) and np.isfinite(roll)):
        raise InputError(f"IK target must be finite, got xyz={p}, pitch={pitch}, roll={roll}")
    return p, pitch, roll


def _branch_frames(robot: RobotDef, p: np.ndarray, pitch: float, reference: np.ndarray | None):
    """r_hat, tool axis, wrist centre and the azimuth of r_hat for a target."""
    r = np.hypot(p[0], p[1])
    if r >= AXIS_EPS_M:
        az = float(np.arctan2(p[1], p[0]))
    else:  # on the base axis: the convention uses the arm's joint-1 direction
        ref = robot.home if reference is None else reference
        az = float(ref[0] + _table(robot).offset[0])
    r_hat = np.array([np.cos(az), np.sin(az), 0.0])
    z_tool = np.cos(pitch) * r_hat + np.sin(pitch) * _UP
    wrist = p - _table(robot).d[4] * z_tool
    return az, r_hat, wrist


def _planar(robot: RobotDef, q1: float, wrist: np.ndarray) -> tuple[float, float, float]:
    """Wrist centre in joint-1's frame: ``(x1, y1, reach excess (m, >= 0))``."""
    A1 = fk_nominal(robot, np.array([[q1, 0.0, 0.0, 0.0, 0.0]]))[0, 0]
    w1 = A1[:3, :3].T @ (wrist - A1[:3, 3])
    a2, a3 = _table(robot).a[1], _table(robot).a[2]
    rho = np.hypot(w1[0], w1[1])
    excess = max(rho - (a2 + a3), abs(a2 - a3) - rho, 0.0)
    return float(w1[0]), float(w1[1]), float(excess)


def ik(
    robot: RobotDef,
    xyz_m: np.ndarray,
    pitch_rad: float,
    roll_rad: float,
    reference: np.ndarray | None = None,
) -> list[IKSolution]:
    """Every exact joint solution for tool point ``xyz_m`` (m) with Cartesian pitch and roll (rad).

    Solutions outside the joint ranges are included and flagged (``in_range``, ``violations``). Each
    angle is wrapped by +-360 deg into its range where possible, choosing the equivalent nearest
    ``reference`` (rad, (n,)) when several are in range (roll's +-570 deg), else the one nearest 0.
    A target out of the arm's reach gives an empty list (:func:`ik_nearest` says how far out).
    On the base axis the azimuth of ``reference`` (default ``robot.home``) fixes ``r_hat``.

    Raises:
        IKStructureError: the robot is not a 5-axis ER-type arm.
        ValueError: a non-finite or malformed target.
    """
    check_er_structure(robot)
    p, pitch, roll = _as_target(xyz_m, pitch_rad, roll_rad)
    ref_q = None if reference is None else np.asarray(reference, dtype=float).reshape(robot.n)
    az, r_hat, wrist = _branch_frames(robot, p, pitch, ref_q)
    a2, a3 = _table(robot).a[1], _table(robot).a[2]
    off = _table(robot).offset
    h = np.cross(_UP, r_hat)
    z_goal = tool_rotation(pitch, roll, r_hat)[:, 2]
    out: list[IKSolution] = []
    for base_name, th1 in (("front", az), ("back", az + np.pi)):
        q1 = th1 - off[0]
        x, y, excess = _planar(robot, q1, wrist)
        if excess > 1e-12:
            continue
        # |theta3| from 1 - c3 and 1 + c3 in factored form (accurate near stretched/folded arms).
        rho = np.hypot(x, y)
        one_minus = max((a2 + a3 - rho) * (a2 + a3 + rho), 0.0)
        one_plus = max((rho - abs(a2 - a3)) * (rho + abs(a2 - a3)), 0.0)
        th3_abs = 2.0 * float(np.arctan2(np.sqrt(one_minus), np.sqrt(one_plus)))
        # Stretched or folded: the two elbow branches coincide (to rounding); keep one.
        signs = (1.0, -1.0) if min(th3_abs, np.pi - th3_abs) > 1e-7 else (1.0,)
        for sgn in signs:
            th3 = sgn * th3_abs
            th2 = np.arctan2(y, x) - np.arctan2(a3 * np.sin(th3), a2 + a3 * np.cos(th3))
            q = np.array([q1, th2 - off[1], th3 - off[2], 0.0, 0.0])
            F = fk_nominal(robot, q[None])[0]
            pitch0, roll0 = pitch_roll(F[4, :3, :3], r_hat)
            # d(pitch)/d(q4): joint-4 axis (z of frame 3) along r_hat x up = -h; d(roll)/d(q5): +-1.
            s4 = -float(F[2, :3, 2] @ h)
            s5 = float(F[3, :3, 2] @ F[4, :3, 2])
            if abs(abs(s4) - 1) > 1e-9 or abs(abs(s5) - 1) > 1e-9:
                raise IKStructureError(
                    f"{robot.name}: joint 4 is not perpendicular to the arm plane or joint 5 is "
                    f"not along the tool axis (s4={s4:.3g}, s5={s5:.3g})"
                )
            q[3] = np.sign(s4) * (pitch - float(pitch0))
            q[4] = np.sign(s5) * (roll - float(roll0))
            # Elbow up: the elbow lies counterclockwise of the shoulder->wrist line, seen in the arm
            # plane with r_hat to the right and z up (above the line when reaching outwards).
            s, e, w = F[0, :3, 3], F[1, :3, 3], F[2, :3, 3]
            sw, se = w - s, e - s
            side = (sw @ r_hat) * se[2] - sw[2] * (se @ r_hat)
            name = f"{base_name}/elbow-{'up' if side >= 0 else 'down'}"
            violations = []
            for j in range(robot.n):
                rj = None if ref_q is None else ref_q[j]
                lo, hi = robot.limits[j]
                q[j], ok = wrap_into_range(q[j], lo, hi, reference=rj)
                if not ok:
                    violations.append(_violation(robot, j, q[j]))
            # Guard against silent errors: the solution must reproduce the target.
            T = fk_nominal(robot, q[None])[0, -1]
            if np.linalg.norm(T[:3, 3] - p) > 1e-9 or np.linalg.norm(T[:3, 2] - z_goal) > 1e-9:
                raise InternalError(
                    f"{robot.name}: IK branch {name} does not reproduce the target "
                    f"(position error {np.linalg.norm(T[:3, 3] - p):.3g} m); this is a bug"
                )
            out.append(IKSolution(q.copy(), name, not violations, tuple(violations)))
    return out


def _reach_excess(robot: RobotDef, p: np.ndarray, pitch: float, reference) -> float:
    az, _, wrist = _branch_frames(robot, p, pitch, reference)
    return min(_planar(robot, th - _table(robot).offset[0], wrist)[2] for th in (az, az + np.pi))


def ik_nearest(
    robot: RobotDef,
    xyz_m: np.ndarray,
    pitch_rad: float,
    roll_rad: float,
    reference: np.ndarray | None = None,
) -> np.ndarray:
    """The in-range IK solution (rad, (n,)) nearest ``reference`` (default ``robot.home``).

    Distance is the Euclidean norm of joint differences (no wrapping: ranges are mechanical).

    Raises:
        UnreachableError: out of reach (message and ``distance_m`` say by how much the wrist centre
            misses) or reachable only outside the joint ranges (message names joint and range).
        IKStructureError: the robot is not a 5-axis ER-type arm.
    """
    ref = robot.home if reference is None else np.asarray(reference, dtype=float).reshape(robot.n)
    sols = ik(robot, xyz_m, pitch_rad, roll_rad, reference=ref)
    good = [s for s in sols if s.in_range]
    tgt = (
        f"target ({', '.join(f'{v * 1000:.2f}' for v in np.asarray(xyz_m, dtype=float))}) mm, "
        f"pitch {np.degrees(float(pitch_rad)):.3f} deg, roll {np.degrees(float(roll_rad)):.3f} deg"
    )
    if good:
        return min(good, key=lambda s: float(np.linalg.norm(s.joints - ref))).joints
    if not sols:
        p, pitch, _ = _as_target(xyz_m, pitch_rad, roll_rad)
        dist = _reach_excess(robot, p, pitch, ref)
        reach = (_table(robot).a[1] + _table(robot).a[2]) * 1000
        raise UnreachableError(
            f"{robot.name}: {tgt} is out of reach: the wrist centre (tool point minus "
            f"d5 = {_table(robot).d[4] * 1000:.2f} mm along the tool axis) lies {dist * 1000:.3f} mm "
            f"outside the shoulder-elbow workspace (reach {abs(_table(robot).a[1] - _table(robot).a[2]) * 1000:.1f}"
            f" to {reach:.1f} mm); move the target closer or change the pitch",
            distance_m=dist,
        )
    blocked = tuple(f"{s.branch}: " + "; ".join(s.violations) for s in sols)
    raise UnreachableError(
        f"{robot.name}: {tgt} is reachable only outside the joint ranges: " + " | ".join(blocked),
        distance_m=None,
        blocked_by=blocked,
    )


def _joint_index(robot: RobotDef, key: int | str) -> int:
    if isinstance(key, str):
        if key not in robot.joint_names:
            raise InputError(f"{robot.name}: unknown joint {key!r}; joints: {robot.joint_names}")
        return robot.joint_names.index(key)
    j = int(key)
    if not 0 <= j < robot.n:
        raise InputError(f"{robot.name}: joint index {key} must be in 0..{robot.n - 1} (0 = base)")
    return j


def nearest_reachable(
    robot: RobotDef,
    xyz_m: np.ndarray,
    fixed: Mapping[int | str, float] | None = None,
    n_starts: int = 24,
) -> tuple[np.ndarray, float]:
    """The in-range posture whose tool point is nearest ``xyz_m`` (m) with some joints held fixed.

    ``fixed`` maps joint index (0-based, 0 = base) or joint name to its value (rad). The free joints
    are optimised on the one solver inside their ranges (its bounds:
    :func:`selfcal.kinematics.least_squares.damped_least_squares`) from deterministic starts
    (home, mid-range, ``n_starts`` Halton points), keeping the best.

    Returns:
        ``(q (n,) rad, distance_m)``: the posture and its tool point's distance to the target.

    Raises:
        ValueError: malformed target, unknown joint, or a fixed value outside its joint's range.
    """
    # Only this function needs them, and they cost ~0.3 s (the solver's scipy.sparse) and ~1 s
    # (stats) to import, which `selfcal fk|ik` would otherwise pay (python -X importtime).
    from scipy.stats import qmc

    from selfcal.kinematics.least_squares import damped_least_squares

    p = np.asarray(xyz_m, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InputError(f"xyz_m must be a finite 3-vector (m), got {xyz_m!r}")
    q0 = np.clip(robot.home.astype(float), robot.limits[:, 0], robot.limits[:, 1])
    fixed_idx = []
    for key, val in (fixed or {}).items():
        j = _joint_index(robot, key)
        q0[j] = float(val)
        fixed_idx.append(j)
    robot.check_joints(q0)  # names a fixed joint outside its range
    free = np.array([j for j in range(robot.n) if j not in fixed_idx], dtype=int)
    if free.size == 0:
        return q0, float(np.linalg.norm(fk_nominal(robot, q0[None])[0, -1, :3, 3] - p))
    lo, hi = robot.limits[free, 0], robot.limits[free, 1]
    rev = np.array([t == "revolute" for t in robot.joint_types])

    def full(x: np.ndarray) -> np.ndarray:
        q = q0.copy()
        q[free] = x
        return q

    def resid(x: np.ndarray) -> np.ndarray:
        return fk_nominal(robot, full(x)[None])[0, -1, :3, 3] - p

    def jac(x: np.ndarray) -> np.ndarray:
        F = fk_nominal(robot, full(x)[None])[0]
        frames = np.concatenate([np.eye(4)[None], F[:-1]])  # frame before each joint
        tip = F[-1, :3, 3]
        z, o = frames[:, :3, 2], frames[:, :3, 3]
        J = np.where(rev[:, None], np.cross(z, tip - o), z)  # (n, 3)
        return J[free].T

    starts = [robot.home[free], 0.5 * (lo + hi)]
    if n_starts > 0:
        u = qmc.Halton(d=free.size, scramble=False).random(n_starts + 1)[1:]
        starts += list(lo + u * (hi - lo))
    box = np.column_stack([lo, hi])
    best_x, best_cost = starts[0], np.inf
    for x0 in starts:  # coarse pass from every start ...
        x, r, _ = damped_least_squares(resid, jac, x0, box, max_iter=100, tol=1e-9)
        if float(r @ r) < best_cost:
            best_x, best_cost = x, float(r @ r)
    # ... then polish the best to rounding level.
    best_x = damped_least_squares(resid, jac, best_x, box, max_iter=200, tol=1e-15)[0]
    q = full(np.clip(best_x, lo, hi))
    return q, float(np.linalg.norm(resid(q[free])))
