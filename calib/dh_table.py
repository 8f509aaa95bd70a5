"""Standard-DH equivalent of an MCPC model, and the world-independent base frame on axes 1 and 2.

DH is discontinuous at parallel consecutive axes; where a model is near that, no table is returned
and the reason names the joints (the MCPC parameters stay the continuous description).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from calib.errors import SelfCalWarning
from calib.kinematics import fk_frames
from calib.mcpc import MCPCModel
from calib.robot_def import RobotDef
from calib.transforms import inv_pose, make_pose, rot_x, rot_z, trans

__all__ = ["DHNotRepresentableWarning", "DHTable", "to_dh", "dh_table", "canonical_base"]


class DHNotRepresentableWarning(SelfCalWarning):
    """A model has (nearly but not exactly) parallel consecutive axes: no continuous DH table."""


@dataclass(frozen=True)
class DHTable:
    """Standard-DH equivalent of an MCPC model (SI units).

    ``T_world_cam(q) = T_world_base @ prod_i A_i(q_i) @ T_flange_tool`` with
    ``A_i = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``.

    Attributes:
        offset, d, a, alpha: (n,) DH rows (rad, m, m, rad).
        T_world_base: DH frame 0 in the model's world frame.
        T_flange_tool: the tool (camera) in the last DH frame.
    """

    offset: np.ndarray
    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    T_world_base: np.ndarray
    T_flange_tool: np.ndarray

    def rows(self) -> list[tuple[float, float, float, float]]:
        """``[(offset, d, a, alpha), ...]`` per joint (rad, m, m, rad)."""
        return [
            (float(o), float(d), float(a), float(al))
            for o, d, a, al in zip(self.offset, self.d, self.a, self.alpha)
        ]


def _angle_about(u: np.ndarray, v: np.ndarray, axis: np.ndarray) -> float:
    """Signed angle (rad) rotating unit ``u`` to unit ``v`` about unit ``axis`` (both normal to it)."""
    return float(np.arctan2(np.cross(u, v) @ axis, u @ v))


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def to_dh(
    model: MCPCModel,
    robot: RobotDef,
    *,
    parallel_tol_deg: float = 1.0,
    exact_parallel_rad: float = 1e-9,
) -> DHTable | None:
    """The standard-DH table equivalent to ``model`` (revolute joints), or None where none is sound.

    Frames follow the usual construction on the joint axes at ``q = 0``: ``z_i`` = axis ``i + 1``,
    ``x_i`` along the common normal of axes ``i`` and ``i + 1`` (sign chosen closest to the nominal
    table of ``robot``). The free choices are fixed like the nominal table: DH frame 0 is placed so
    that row 1 has the nominal ``offset_1`` and ``d_1`` (both are gauge with an arbitrary world,
    see the module docstring), the last frame is the nominal last row on top of frame ``n - 1``, and
    the remainder goes to ``T_flange_tool``. For exactly parallel consecutive axes (angle below
    ``exact_parallel_rad``) the common normal is taken through the previous origin (``d_i = 0``).

    Parallel axes: DH is discontinuous there. For two axes at a small angle ``theta`` the common
    normal lies at a distance ~ (offset) / theta along the axes, so ``d`` jumps from 0 to huge values
    and back as ``theta`` passes through zero: a 0.01 deg misalignment of the SCORBOT's parallel
    joints 2, 3, 4 cannot be written as a small DH change. Such models return ``None`` and a
    :class:`DHNotRepresentableWarning` naming the joints and the angle; the MCPC ``beta`` (like
    Hayati's parameter) is the continuous description.

    Raises:
        ValueError: prismatic joints (not supported) or a joint count different from ``robot``'s.
    """
    table, why = dh_table(
        model, robot, parallel_tol_deg=parallel_tol_deg, exact_parallel_rad=exact_parallel_rad
    )
    if why is not None:
        warnings.warn(why, DHNotRepresentableWarning, stacklevel=2)
    return table


def dh_table(
    model: MCPCModel,
    robot: RobotDef,
    *,
    parallel_tol_deg: float = 1.0,
    exact_parallel_rad: float = 1e-9,
) -> tuple[DHTable | None, str | None]:
    """:func:`to_dh` without the warning: ``(table, None)``, or ``(None, why)`` naming the
    nearly parallel joints and their angle when no sound DH table exists.

    Raises:
        ValueError: prismatic joints (not supported) or a joint count different from ``robot``'s.
    """
    out = _dh_impl(model, robot, parallel_tol_deg, exact_parallel_rad, frame0_only=False)
    if isinstance(out, str):
        return None, out
    assert isinstance(out, DHTable)
    return out, None


def canonical_base(
    model: MCPCModel, robot: RobotDef, *, parallel_tol_deg: float = 1.0
) -> np.ndarray:
    """``T_world_base`` of a world-independent frame attached to the robot's first two axes.

    z = joint 1's axis; x and the origin are those of DH frame 0 as in :func:`to_dh` (from the
    common normal of axes 1 and 2 at q = 0, with the nominal ``offset_1`` and ``d_1``). Expressing
    a model there, ``express_in_frame(model, inv_pose(canonical_base(model, robot)), like=ref)``,
    removes the world gauge: the resulting parameters no longer depend on the measurement frame,
    so models identified in different reconstruction frames can be compared one to one (what is
    lost is exactly what is unobservable with an unknown scene: joint 1's zero and the height of
    the base along axis 1). Needs axes 1 and 2 not nearly parallel (true for the SCORBOT).

    Raises:
        ValueError: prismatic joints, or axes 1 and 2 nearly parallel.
    """
    out = _dh_impl(model, robot, parallel_tol_deg, 1e-9, frame0_only=True)
    if isinstance(out, str):
        raise ValueError(f"no canonical base frame: {out}")
    return out.T_world_base if isinstance(out, DHTable) else out


def _dh_impl(
    model: MCPCModel,
    robot: RobotDef,
    parallel_tol_deg: float,
    exact_parallel_rad: float,
    frame0_only: bool,
) -> DHTable | np.ndarray | str:
    """The DH table (or, ``frame0_only``, DH frame 0 as ``T_world_base``), or the reason why
    none exists (a string naming the nearly parallel axes)."""
    if any(t != "revolute" for t in model.joint_types):
        raise ValueError("to_dh supports revolute joints only")
    n = model.n
    if robot.n != n:
        raise ValueError(f"model has {n} joints, robot {robot.name} has {robot.n}")
    F = fk_frames(model, np.zeros((1, n)))[0]
    z = [F[k, :3, 2] for k in range(n)]  # axis k+1 direction
    p = [F[k, :3, 3] for k in range(n)]  # a point on axis k+1
    tol = np.sin(np.radians(parallel_tol_deg))
    for k in range(1 if frame0_only else n - 1):
        s = np.linalg.norm(np.cross(z[k], z[k + 1]))
        if np.sin(exact_parallel_rad) <= s < tol:
            return (
                f"axes of joints {k + 1} and {k + 2} are {np.degrees(np.arcsin(s)):.4g} deg from "
                f"parallel (< {parallel_tol_deg} deg): no continuous DH table exists; use the MCPC "
                "parameters (beta) instead"
            )

    def normal(k: int, origin_prev: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Common normal of axes k+1, k+2 (0-based k): (unit x, foot on axis k+1, point on k+2)."""
        zi, zj = z[k], z[k + 1]
        c = np.cross(zi, zj)
        if np.linalg.norm(c) < np.sin(exact_parallel_rad):
            base = p[k] if origin_prev is None else origin_prev
            w = p[k + 1] - base
            w = w - (w @ zi) * zi
            if np.linalg.norm(w) < 1e-12:
                raise ValueError(f"axes of joints {k + 1} and {k + 2} coincide: DH undefined")
            return w / np.linalg.norm(w), base, base + w
        # closest points P = p_k + t zi, Q = p_{k+1} + u zj
        b = zi @ zj
        w0 = p[k] - p[k + 1]
        dd, e = zi @ w0, zj @ w0
        den = 1.0 - b * b
        t = (b * e - dd) / den
        u = (e - b * dd) / den
        P, Q = p[k] + t * zi, p[k + 1] + u * zj
        return c / np.linalg.norm(c), P, Q

    def row(x_prev, z_prev, o_prev, x_i, z_i, foot, o_i) -> tuple[float, float, float, float]:
        th = _angle_about(x_prev, x_i, z_prev)
        d = float((foot - o_prev) @ z_prev)
        a = float((o_i - foot) @ x_i)
        al = _angle_about(z_prev, z_i, x_i)
        return th, d, a, al

    def closeness(r: tuple[float, float, float, float], i: int) -> float:
        return (
            abs(_wrap(r[0] - robot.dh.offset[i]))
            + abs(_wrap(r[3] - robot.dh.alpha[i]))
            + abs(r[2] - robot.dh.a[i]) / 0.1
        )

    offs, ds, as_, als = [], [], [], []
    # frame 1 from axes 1, 2 -- it fixes frame 0 (nominal offset_1 and d_1)
    x1, foot, o1 = normal(0, None)
    z0 = z[0]
    first = []
    for sgn in (1.0, -1.0):
        xi = sgn * x1
        # x0: xi rotated about z0 by -offset_1 (Rodrigues), so row 1 has the nominal offset
        c, s_ = np.cos(-robot.dh.offset[0]), np.sin(-robot.dh.offset[0])
        x0 = c * xi + s_ * np.cross(z0, xi) + (1 - c) * (z0 @ xi) * z0
        o0 = foot - robot.dh.d[0] * z0
        first.append((row(x0, z0, o0, xi, z[1], foot, o1), x0, o0, xi, o1))
    # the closer of the two signs to the nominal row (the first on a tie)
    r, x0, o0, x_prev, o_prev = min(first, key=lambda c: closeness(c[0], 0))
    T_world_base = make_pose(np.column_stack([x0, np.cross(z0, x0), z0]), o0)
    if frame0_only:
        return T_world_base
    offs.append(r[0])
    ds.append(r[1])
    as_.append(r[2])
    als.append(r[3])  # noqa: E702
    z_prev = z[1]
    for k in range(1, n - 1):
        xk, foot, ok = normal(k, o_prev)
        rows = [
            (row(x_prev, z_prev, o_prev, sgn * xk, z[k + 1], foot, ok), sgn * xk)
            for sgn in (1.0, -1.0)
        ]
        r, x_prev = min(rows, key=lambda c: closeness(c[0], k))
        o_prev, z_prev = ok, z[k + 1]
        offs.append(r[0])
        ds.append(r[1])
        as_.append(r[2])
        als.append(r[3])  # noqa: E702
    # last row: nominal, on top of frame n-1
    offs.append(float(robot.dh.offset[-1]))
    ds.append(float(robot.dh.d[-1]))
    as_.append(float(robot.dh.a[-1]))
    als.append(float(robot.dh.alpha[-1]))
    T_prev = make_pose(np.column_stack([x_prev, np.cross(z_prev, x_prev), z_prev]), o_prev)
    A_n = (
        rot_z(offs[-1])
        @ trans(np.array([0.0, 0.0, ds[-1]]))
        @ trans(np.array([as_[-1], 0.0, 0.0]))
        @ rot_x(als[-1])
    )
    T_flange_tool = inv_pose(T_prev @ A_n) @ F[n]
    return DHTable(
        offset=np.array([_wrap(v) for v in offs]),
        d=np.array(ds),
        a=np.array(as_),
        alpha=np.array([_wrap(v) for v in als]),
        T_world_base=T_world_base,
        T_flange_tool=T_flange_tool,
    )
