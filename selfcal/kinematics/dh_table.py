"""DH table of an MCPC model in the robot's own convention, and the world-independent base frame.

The table is standard DH for a robot given in standard DH and modified DH (Craig) for one given in
modified DH; a URDF robot has none. Both come from one construction on the identified joint axes:
the common normals of consecutive axes. The modified table is the standard one shifted by a row
(``alpha_{i-1}, a_{i-1}`` of the modified row i are ``alpha_{i-1}, a_{i-1}`` of the standard row
i - 1, since ``Rx`` and ``Tx`` commute), so a modified-DH robot is handled through its standard
"view" (:func:`standard_view`).

DH is discontinuous at parallel consecutive axes; where a model is near that, no table is returned
and the reason names the joints (the MCPC parameters stay the continuous description).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError, SelfCalWarning
from selfcal.kinematics.forward import fk_frames
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.definition import DHParams, RobotDef
from selfcal.transforms import inv_pose, make_pose, rot_x, rot_z, trans

__all__ = [
    "DHNotRepresentableWarning",
    "DHTable",
    "to_dh",
    "dh_table",
    "canonical_base",
    "standard_view",
]


class DHNotRepresentableWarning(SelfCalWarning):
    """A model has (nearly but not exactly) parallel consecutive axes: no continuous DH table."""


@dataclass(frozen=True)
class DHTable:
    """DH or modified-DH equivalent of an MCPC model (SI units).

    ``T_world_cam(q) = T_world_base @ prod_i A_i(q_i) @ T_flange_tool`` with
    ``A_i = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` (``convention = "dh"``) or
    ``A_i = Rx(alpha_i) Tx(a_i) Rz(q_i + offset_i) Tz(d_i)`` (``"mdh"``: row i holds
    ``alpha_{i-1}, a_{i-1}``).

    Attributes:
        offset, d, a, alpha: (n,) rows (rad, m, m, rad).
        T_world_base: (DH or Craig's) frame 0 in the model's world frame.
        T_flange_tool: the tool (camera) in the last frame (the flange).
        convention: ``"dh"`` or ``"mdh"``.
    """

    offset: np.ndarray
    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    T_world_base: np.ndarray
    T_flange_tool: np.ndarray
    convention: str = "dh"

    def params(self) -> DHParams:
        """The rows as :class:`selfcal.robot.chain.DHParams` (for :func:`selfcal.robot.chain.dh_frames`)."""
        return DHParams(self.convention, self.alpha, self.a, self.d, self.offset)

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
    convention: str | None = None,
) -> DHTable | None:
    """The DH table equivalent to ``model`` (revolute joints) in ``convention`` (default: the
    robot's own, ``robot.convention``), or None where none is sound.

    Frames follow the usual construction on the joint axes at ``q = 0``: ``z_i`` = axis ``i + 1``,
    ``x_i`` along the common normal of axes ``i`` and ``i + 1`` (sign chosen closest to the nominal
    table of ``robot``). The free choices are fixed like the nominal table: DH frame 0 is placed so
    that row 1 has the nominal ``offset_1`` and ``d_1`` (both are gauge with an arbitrary world,
    see the module docstring), the last frame is the nominal last row on top of frame ``n - 1``, and
    the remainder goes to ``T_flange_tool``. For exactly parallel consecutive axes (angle below
    ``exact_parallel_rad``) the common normal is taken through the previous origin (``d_i = 0``).
    A modified-DH table is the same construction on the robot's standard view
    (:func:`standard_view`), shifted by a row; its first row keeps the nominal ``alpha_0, a_0``.

    Parallel axes: DH is discontinuous there. For two axes at a small angle ``theta`` the common
    normal lies at a distance ~ (offset) / theta along the axes, so ``d`` jumps from 0 to huge values
    and back as ``theta`` passes through zero: a 0.01 deg misalignment of the SCORBOT's parallel
    joints 2, 3, 4 cannot be written as a small DH change. Such models return ``None`` and a
    :class:`DHNotRepresentableWarning` naming the joints and the angle; the MCPC ``beta`` (like
    Hayati's parameter) is the continuous description. A URDF robot has no table: None and a
    warning saying so.

    Raises:
        ValueError: prismatic joints (not supported) or a joint count different from ``robot``'s.
    """
    table, why = dh_table(
        model,
        robot,
        parallel_tol_deg=parallel_tol_deg,
        exact_parallel_rad=exact_parallel_rad,
        convention=convention,
    )
    if why is not None:
        warnings.warn(why, DHNotRepresentableWarning, stacklevel=2)
    return table


NO_TABLE_FOR_URDF = (
    "the robot is described by a URDF, not a DH table, so none is given; the MCPC parameters and "
    "the URDF / MJCF exports describe the calibrated chain"
)


def standard_view(robot: RobotDef) -> tuple[DHParams, np.ndarray] | None:
    """The robot's table as standard DH, and standard frame 0 in the robot's base frame.

    Standard DH: the table itself and the identity. Modified DH: rows ``offset_i, d_i`` with
    ``a_i, alpha_i`` of modified row ``i + 1`` (zero for the last row), frame 0 at
    ``Rx(alpha_0) Tx(a_0)`` -- the same chain, since ``Rx`` and ``Tx`` commute. None for a URDF
    robot.
    """
    dh = robot.dh
    if dh is None:
        return None
    if dh.convention == "dh":
        return dh, np.eye(4)
    view = DHParams(
        "dh", np.append(dh.alpha[1:], 0.0), np.append(dh.a[1:], 0.0), dh.d.copy(), dh.offset.copy()
    )
    return view, rot_x(dh.alpha[0]) @ trans(np.array([dh.a[0], 0.0, 0.0]))


def dh_table(
    model: MCPCModel,
    robot: RobotDef,
    *,
    parallel_tol_deg: float = 1.0,
    exact_parallel_rad: float = 1e-9,
    convention: str | None = None,
) -> tuple[DHTable | None, str | None]:
    """:func:`to_dh` without the warning: ``(table, None)``, or ``(None, why)`` naming the
    nearly parallel joints and their angle when no sound DH table exists, or saying that a URDF
    robot has none. ``convention``: ``"dh"`` or ``"mdh"`` (default: the robot's own).

    Raises:
        ValueError: prismatic joints (not supported), a joint count different from ``robot``'s or
            an unknown convention.
    """
    view = standard_view(robot)
    if view is None:
        return None, NO_TABLE_FOR_URDF
    convention = robot.convention if convention is None else convention
    if convention not in ("dh", "mdh"):
        raise InputError(f"convention must be 'dh' or 'mdh', got {convention!r}")
    nominal, frame0 = view
    out = _dh_impl(model, nominal, parallel_tol_deg, exact_parallel_rad)
    if isinstance(out, str):
        return None, out
    if convention == "dh":
        return out, None
    if robot.dh is not None and robot.dh.convention == "mdh":
        first = (robot.dh.alpha[:1], robot.dh.a[:1])
    else:  # a standard-DH robot asked for a modified table: Craig's frame 0 = DH frame 0
        first, frame0 = (np.zeros(1), np.zeros(1)), np.eye(4)
    return (
        DHTable(
            offset=out.offset,
            d=out.d,
            a=np.concatenate([first[1], out.a[:-1]]),
            alpha=np.concatenate([first[0], out.alpha[:-1]]),
            T_world_base=out.T_world_base @ inv_pose(frame0),
            T_flange_tool=_last_frame_shift(out) @ out.T_flange_tool,
            convention="mdh",
        ),
        None,
    )


def _last_frame_shift(table: DHTable) -> np.ndarray:
    """Standard frame n -> Craig's frame n: undo the last standard row's ``Tx(a_n) Rx(alpha_n)``
    (zero for a modified-DH robot's view)."""
    return trans(np.array([table.a[-1], 0.0, 0.0])) @ rot_x(table.alpha[-1])


def _axes_frame(model: MCPCModel, parallel_tol_deg: float) -> np.ndarray:
    """The frame on axes 1 and 2 at q = 0 (world, m): z = axis 1, x = the unit common normal
    ``z_1 x z_2``, origin = the normal's foot on axis 1."""
    F = fk_frames(model, np.zeros((1, model.n)))[0]
    z1, z2, p1, p2 = F[0, :3, 2], F[1, :3, 2], F[0, :3, 3], F[1, :3, 3]
    c = np.cross(z1, z2)
    s = float(np.linalg.norm(c))
    if s < np.sin(np.radians(parallel_tol_deg)):
        raise InputError(
            f"axes of joints 1 and 2 are {np.degrees(np.arcsin(min(s, 1.0))):.4g} deg from "
            f"parallel (< {parallel_tol_deg} deg): their common normal is undefined"
        )
    b, w0 = z1 @ z2, p1 - p2
    t = (b * (z2 @ w0) - z1 @ w0) / (1.0 - b * b)
    x = c / s
    return make_pose(np.column_stack([x, np.cross(z1, x), z1]), p1 + t * z1)


def canonical_base(
    model: MCPCModel, robot: RobotDef, *, parallel_tol_deg: float = 1.0
) -> np.ndarray:
    """``T_world_base`` of a world-independent frame attached to the robot's first two axes.

    The frame on the model's axes 1 and 2 (z = axis 1, x along their common normal, origin at its
    foot on axis 1) composed with the inverse of the same frame of the NOMINAL robot in its base
    frame: for the nominal robot it IS the nominal base frame (for a DH robot DH frame 0, with the
    nominal ``offset_1`` and ``d_1``), for an identified one the same construction on the measured
    axes -- for any robot description. Expressing a model there,
    ``express_in_frame(model, inv_pose(canonical_base(model, robot)), like=ref)``, removes the
    world gauge: the resulting parameters no longer depend on the measurement frame, so models
    identified in different reconstruction frames can be compared one to one (what is lost is
    exactly what is unobservable with an unknown scene: joint 1's zero and the height of the base
    along axis 1). Needs axes 1 and 2 not nearly parallel (true for the SCORBOT and 6-axis arms).

    Raises:
        ValueError: prismatic joints, or axes 1 and 2 nearly parallel.
    """
    if any(t != "revolute" for t in model.joint_types[:2]):
        kinds = " and ".join(model.joint_types[:2])
        raise InputError(
            f"no canonical base frame: joints 1 and 2 must be revolute ({robot.name}'s are "
            f"{kinds}): the robot's base frame is rebuilt on two revolute axes",
            fix="a chain that starts with a prismatic joint (an arm on a track, a virtual chain "
            "standing in for flange poses) has no such frame: export the hand-eye alone "
            "(selfcal export DIR --format tf, easy_handeye or matrix), or import flange poses "
            "as they are with selfcal import --poses (docs/handeye.md)",
        )
    nominal = _axes_frame(nominal_mcpc(robot), parallel_tol_deg)
    try:
        return _axes_frame(model, parallel_tol_deg) @ inv_pose(nominal)
    except ValueError as exc:
        raise InputError(f"no canonical base frame: {exc}") from exc


def _dh_impl(
    model: MCPCModel,
    nominal: DHParams,
    parallel_tol_deg: float,
    exact_parallel_rad: float,
) -> DHTable | str:
    """The standard-DH table, or the reason why none exists (a string naming the nearly parallel
    axes). ``nominal``: the robot's standard-DH rows (free choices and signs follow them)."""
    if any(t != "revolute" for t in model.joint_types):
        raise InputError("to_dh supports revolute joints only")
    n = model.n
    if nominal.n != n:
        raise InputError(f"model has {n} joints, the robot's table {nominal.n}")
    F = fk_frames(model, np.zeros((1, n)))[0]
    z = [F[k, :3, 2] for k in range(n)]  # axis k+1 direction
    p = [F[k, :3, 3] for k in range(n)]  # a point on axis k+1
    tol = np.sin(np.radians(parallel_tol_deg))
    for k in range(n - 1):
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
                raise InputError(f"axes of joints {k + 1} and {k + 2} coincide: DH undefined")
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
            abs(_wrap(r[0] - nominal.offset[i]))
            + abs(_wrap(r[3] - nominal.alpha[i]))
            + abs(r[2] - nominal.a[i]) / 0.1
        )

    offs, ds, as_, als = [], [], [], []
    # frame 1 from axes 1, 2 -- it fixes frame 0 (nominal offset_1 and d_1)
    x1, foot, o1 = normal(0, None)
    z0 = z[0]
    first = []
    for sgn in (1.0, -1.0):
        xi = sgn * x1
        # x0: xi rotated about z0 by -offset_1 (Rodrigues), so row 1 has the nominal offset
        c, s_ = np.cos(-nominal.offset[0]), np.sin(-nominal.offset[0])
        x0 = c * xi + s_ * np.cross(z0, xi) + (1 - c) * (z0 @ xi) * z0
        o0 = foot - nominal.d[0] * z0
        first.append((row(x0, z0, o0, xi, z[1], foot, o1), x0, o0, xi, o1))
    # the closer of the two signs to the nominal row (the first on a tie)
    r, x0, o0, x_prev, o_prev = min(first, key=lambda c: closeness(c[0], 0))
    T_world_base = make_pose(np.column_stack([x0, np.cross(z0, x0), z0]), o0)
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
    offs.append(float(nominal.offset[-1]))
    ds.append(float(nominal.d[-1]))
    as_.append(float(nominal.a[-1]))
    als.append(float(nominal.alpha[-1]))
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
