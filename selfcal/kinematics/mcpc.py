"""Zhuang's MCPC parameterisation (paper eqs. 1-5, 10) and its exact conversion from a robot's
nominal chain (DH, modified DH or URDF).

A chain of ``n`` joints is ``T = V_0 Q_1 V_1 Q_2 ... Q_n V_n`` with motion matrices
``Q_i = Rz(q_i + o_i)`` (revolute, ``o_i`` the nominal joint offset, a fixed constant) or
``Tz(q_i)`` (prismatic) and shape matrices
``V_i = Rx(alpha_i) Ry(beta_i) Rz(gamma_i) Trans(lx_i, ly_i, lz_i)``.

Parameters are stored as an ``(n + 1, 6)`` array with columns ``[alpha, beta, gamma, lx, ly, lz]``
(rad, m). ``V_0`` maps the world (measurement) frame to joint 1, ``V_n`` maps joint n to the tool.

Gauge: the frame before joint ``i + 1`` may rotate about and slide along that joint's axis without
changing the chain, so ``gamma_i = lz_i = 0`` for ``i < n`` (and, before a prismatic joint, also
``lx_i = ly_i = 0``). What is left is the minimal identifiable set of eq. 10: ``alpha_i, beta_i,
lx_i, ly_i`` for ``i = 0..n`` plus ``gamma_n, lz_n`` -- ``4R + 2P + 6`` parameters, 26 for 5 revolute
joints. Unlike DH this stays continuous when consecutive axes are (nearly) parallel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError, UsageError
from selfcal.robot.definition import RobotDef
from selfcal.transforms import (
    rot_x,
    rot_y,
    rot_z,
    trans,
    xyz_euler_from_matrix,
)

__all__ = [
    "COLUMNS",
    "MCPCModel",
    "shape_matrices",
    "nominal_mcpc",
    "gauge_fix",
    "base_offset_for",
    "chain_transforms",
    "minimal_indices",
    "param_names",
    "chain_param_names",
    "param_is_angle",
]

COLUMNS = ("alpha", "beta", "gamma", "lx", "ly", "lz")


@dataclass(frozen=True)
class MCPCModel:
    """An MCPC chain: ``params`` (n + 1, 6) in rad and m, the joint types and nominal offsets.

    ``joint_offsets`` (n,) are constants added to revolute joint readings inside ``Q_i``; keeping
    them out of the shape matrices keeps ``V_i`` away from the Euler singularity (a 90 deg offset
    would otherwise put ``beta`` at 90 deg). Errors of the offsets are absorbed by the parameters.
    ``base_offset`` (rad) is the base's counterpart: a constant rotation about the world z-axis
    before ``V_0`` (``G_0 = Rz(base_offset) V_0``), a multiple of 90 deg chosen where joint 1's
    axis lies near the world x-axis (:func:`base_offset_for`), so that any chain in any world
    frame has well-conditioned base parameters.
    """

    params: np.ndarray
    joint_types: tuple[str, ...]
    joint_offsets: np.ndarray
    base_offset: float = 0.0

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_types)

    def with_params(self, params: np.ndarray) -> MCPCModel:
        """A copy with other parameters (same joint types)."""
        params = np.asarray(params, dtype=float).reshape(self.n + 1, 6)
        return MCPCModel(params.copy(), self.joint_types, self.joint_offsets, self.base_offset)

    def with_tool(self, T_flange_tool: np.ndarray) -> MCPCModel:
        """The same chain with ``T_flange_tool`` appended to the last shape matrix ``V_n``."""
        G = chain_transforms(self)
        return _from_chain([*G[:-1], G[-1] @ T_flange_tool], self.joint_types)

    def with_base(self, T_world_base: np.ndarray) -> MCPCModel:
        """The same chain placed at ``T_world_base`` (prepended to ``V_0``)."""
        G = chain_transforms(self)
        return _from_chain([T_world_base @ G[0], *G[1:]], self.joint_types)


def shape_matrices(params: np.ndarray) -> np.ndarray:
    """``V = Rx(alpha) Ry(beta) Rz(gamma) Trans(l)`` for params (..., 6); shape (..., 4, 4)."""
    p = np.asarray(params, dtype=float)
    return rot_x(p[..., 0]) @ rot_y(p[..., 1]) @ rot_z(p[..., 2]) @ trans(p[..., 3:6])


def _decompose_conditioned(g: np.ndarray, free_offset: bool) -> tuple[float, np.ndarray]:
    """Choose ``c`` in {0, 90, -90, 180} deg so ``Rz(-c) g`` is far from the Euler singularity.

    Returns ``(c, Rz(-c) g)``; ``c = 0`` whenever ``|beta| <= 45 deg`` already.
    """
    if not free_offset or abs(g[0, 2]) <= np.sqrt(0.5):
        return 0.0, g
    best = min((abs((rot_z(-c) @ g)[0, 2]), c) for c in (0.0, np.pi / 2, -np.pi / 2, np.pi))[1]
    return best, rot_z(-best) @ g


def base_offset_for(G0: np.ndarray) -> float:
    """The base offset (rad; 0, 90, -90 or 180 deg) for the first chain transform ``G0`` (4, 4):
    ``Rz(-c) G0`` has joint 1's axis within 45 deg of the world's y-z plane, away from ``V_0``'s
    Euler singularity; 0 whenever ``G0`` is there already."""
    return _decompose_conditioned(np.asarray(G0, dtype=float), True)[0]


def gauge_fix(
    G: list[np.ndarray] | np.ndarray,
    joint_types: tuple[str, ...],
    offsets: np.ndarray | None = None,
    base_offset: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Exact MCPC form of the chain ``G_0 Q_1 G_1 ... Q_n G_n`` of rigid ``G_i``, ``Q_i = Rz(q_i)``.

    Works from the base outwards: the part of ``G_i`` that commutes with ``Q_{i+1}`` (rotation
    about and translation along the joint axis; any translation for a prismatic joint) is pushed
    into ``G_{i+1}``, so the result satisfies the gauge described in the module docstring. Where a
    shape matrix would sit near the Euler singularity (``|beta| > 45 deg``), a constant multiple of
    90 deg is moved into the preceding revolute joint's offset instead -- unless ``offsets`` (n,)
    are given, which are then imposed (so that two models of nearly the same robot get directly
    comparable parameters). ``base_offset``: the model's constant rotation about the world z-axis
    before ``V_0`` (:func:`base_offset_for` chooses it).

    Returns:
        ``(params (n + 1, 6), joint_offsets (n,))`` in rad and m.
    """
    n = len(joint_types)
    G = [np.asarray(g, dtype=float) for g in G]
    if len(G) != n + 1:
        raise UsageError(f"need {n + 1} transforms for {n} joints, got {len(G)}")
    out = np.zeros((n + 1, 6))
    impose = offsets is not None
    offsets = np.zeros(n) if offsets is None else np.asarray(offsets, dtype=float).copy()
    carry = rot_z(-base_offset)
    if abs((carry @ G[0])[0, 2]) > 0.999:
        raise InputError(
            "the world frame's x-axis is (nearly) parallel to joint 1's axis: the MCPC base "
            "parameters are singular there; give a base_offset (selfcal.kinematics.mcpc.base_offset_for)"
        )
    for i in range(n + 1):
        revolute_before = i > 0 and joint_types[i - 1] == "revolute"
        if impose:
            g = rot_z(-offsets[i - 1]) @ carry @ G[i] if revolute_before else carry @ G[i]
        else:
            c, g = _decompose_conditioned(carry @ G[i], revolute_before)
            if i > 0:
                offsets[i - 1] = c
        a, b, gam = xyz_euler_from_matrix(g[:3, :3])
        if i == n:
            out[i, :3] = a, b, gam
            out[i, 3:] = g[:3, :3].T @ g[:3, 3]
            break
        Rab = (rot_x(a) @ rot_y(b))[:3, :3]
        u = Rab.T @ g[:3, 3]
        if joint_types[i] == "revolute":
            out[i] = a, b, 0.0, u[0], u[1], 0.0
            carry = trans(np.array([0.0, 0.0, u[2]])) @ rot_z(gam)
        else:
            out[i] = a, b, 0.0, 0.0, 0.0, 0.0
            carry = trans(u) @ rot_z(gam)
    return out, offsets


def chain_transforms(model: MCPCModel) -> list[np.ndarray]:
    """The chain as ``G_0 Q_1 G_1 ...`` with offset-free ``Q_i`` (offsets folded into ``G_i``)."""
    V = shape_matrices(model.params)
    return [rot_z(model.base_offset) @ V[0]] + [
        rot_z(o) @ v for o, v in zip(model.joint_offsets, V[1:])
    ]


def nominal_mcpc(
    robot: RobotDef,
    T_world_base: np.ndarray | None = None,
    T_flange_tool: np.ndarray | None = None,
) -> MCPCModel:
    """Exact MCPC form of a robot's nominal chain ``robot.chain`` (``G_0 Q_1 G_1 ... Q_n G_n``,
    from its DH, modified-DH or URDF description), optionally with base and tool transforms (m):
    ``T_world_base @ G_0 ...  G_n @ T_flange_tool``.

    The resulting chain gives the same tool pose as the nominal chain for every joint vector, and
    each MCPC joint frame lies on the same joint axis as the corresponding nominal joint frame.
    """
    G = robot.chain
    base = np.eye(4) if T_world_base is None else np.asarray(T_world_base, dtype=float)
    tool = np.eye(4) if T_flange_tool is None else np.asarray(T_flange_tool, dtype=float)
    return _from_chain([base @ G[0], *G[1:-1], G[-1] @ tool], robot.joint_types)


def _from_chain(G: list[np.ndarray], joint_types: tuple[str, ...]) -> MCPCModel:
    base = base_offset_for(G[0])
    params, offsets = gauge_fix(G, joint_types, base_offset=base)
    return MCPCModel(params, joint_types, offsets, base)


def minimal_indices(joint_types: tuple[str, ...]) -> np.ndarray:
    """Flat indices into ``params.reshape(-1)`` of the minimal identifiable set, eq. 10 order.

    Order: ``alpha_0..n, beta_0..n, gamma_n, lx_0..n, ly_0..n, lz_n`` (``lx_i, ly_i`` omitted for a
    frame that precedes a prismatic joint).
    """
    n = len(joint_types)
    idx = [6 * i + 0 for i in range(n + 1)]
    idx += [6 * i + 1 for i in range(n + 1)]
    idx += [6 * n + 2]
    keep_l = [i == n or joint_types[i] == "revolute" for i in range(n + 1)]
    idx += [6 * i + 3 for i in range(n + 1) if keep_l[i]]
    idx += [6 * i + 4 for i in range(n + 1) if keep_l[i]]
    idx += [6 * n + 5]
    return np.array(idx, dtype=int)


def param_names(indices: np.ndarray) -> list[str]:
    """Names such as ``alpha0``, ``lx1``, ``gamma5`` for flat parameter indices."""
    return [f"{COLUMNS[k % 6]}{k // 6}" for k in np.asarray(indices)]


def chain_param_names(joint_types: tuple[str, ...]) -> tuple[str, ...]:
    """The minimal parameters of the joints' chain: all but the base (row 0) and the tool
    (row n), i.e. what a nominal model keeps at the drawing's values."""
    n = len(joint_types)
    idx = minimal_indices(joint_types)
    return tuple(param_names(np.array([k for k in idx if k // 6 not in (0, n)])))


def param_is_angle(indices: np.ndarray) -> np.ndarray:
    """Boolean mask: which flat parameter indices are angles (rad) rather than lengths (m)."""
    return np.asarray(indices) % 6 < 3
