"""A serial robot's nominal chain, convention-free, and the DH / modified-DH tables that give it.

Every robot, whatever file it comes from, is the product

    T_base_flange(q) = G_0 Q_1(q_1) G_1 Q_2(q_2) ... Q_n(q_n) G_n

of fixed rigid transforms ``G_0 .. G_n`` (metres) and joint motions ``Q_i = Rz(q_i)`` (revolute,
rad) or ``Tz(q_i)`` (prismatic, m): each joint turns about / slides along the z axis of the frame
it acts in. :func:`selfcal.kinematics.mcpc.nominal_mcpc` turns this chain into the MCPC model.

Tables (one row per joint, SI units):

- standard (distal) DH, ``convention = "dh"``: ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``
  with ``theta_i = q_i + offset_i`` (revolute) or ``d_i + q_i`` (prismatic, ``offset_i`` its
  constant theta). So ``G_0 = I`` and ``G_i = Rz(offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``.
- modified DH (Craig), ``convention = "mdh"``: ``A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i)
  Tz(d_i)``; row ``i`` holds ``alpha_{i-1}, a_{i-1}, d_i, offset_i``. So ``G_0 = Rx(alpha_0)
  Tx(a_0)``, ``G_i = Rz(offset_i) Tz(d_i) Rx(alpha_i) Tx(a_i)`` (with row ``i + 1``'s alpha and a)
  and ``G_n = Rz(offset_n) Tz(d_n)``: the flange is Craig's frame n.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError
from selfcal.transforms import rot_x, rot_z, trans

__all__ = ["CONVENTIONS", "DHParams", "dh_chain", "dh_frames", "chain_frames"]

CONVENTIONS = ("dh", "mdh")
"""Table conventions: standard (distal) DH and modified (proximal, Craig) DH."""


@dataclass(frozen=True, eq=False)
class DHParams:
    """A DH or modified-DH table (rad, m), one row per joint.

    Attributes:
        convention: ``"dh"`` (standard) or ``"mdh"`` (modified, Craig); see the module docstring.
        alpha: (n,) link twists (``mdh``: row i holds ``alpha_{i-1}``), rad.
        a: (n,) link lengths (``mdh``: row i holds ``a_{i-1}``), m.
        d: (n,) link offsets along the joint axis, m.
        offset: (n,) zero offset of a revolute joint angle, or a prismatic joint's constant theta,
            rad.
    """

    convention: str
    alpha: np.ndarray
    a: np.ndarray
    d: np.ndarray
    offset: np.ndarray

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise InputError(f"convention must be one of {CONVENTIONS}, got {self.convention!r}")
        shapes = {np.shape(v) for v in (self.alpha, self.a, self.d, self.offset)}
        if len(shapes) != 1 or len(shapes.pop()) != 1:
            raise InputError("alpha, a, d and offset must be 1-D arrays of one length")

    @property
    def n(self) -> int:
        """Number of rows (joints)."""
        return len(self.alpha)


def _tz(d: np.ndarray) -> np.ndarray:
    z = np.zeros_like(d)
    return trans(np.stack([z, z, d], axis=-1))


def _tx(a: np.ndarray) -> np.ndarray:
    z = np.zeros_like(a)
    return trans(np.stack([a, z, z], axis=-1))


def dh_chain(dh: DHParams) -> np.ndarray:
    """The fixed transforms ``G_0 .. G_n`` (n + 1, 4, 4) of a DH or modified-DH table (m)."""
    n = dh.n
    G = np.empty((n + 1, 4, 4))
    if dh.convention == "dh":
        G[0] = np.eye(4)
        G[1:] = rot_z(dh.offset) @ _tz(dh.d) @ _tx(dh.a) @ rot_x(dh.alpha)
        return G
    G[0] = rot_x(dh.alpha[0]) @ _tx(dh.a[:1])[0]
    G[1:n] = rot_z(dh.offset[:-1]) @ _tz(dh.d[:-1]) @ rot_x(dh.alpha[1:]) @ _tx(dh.a[1:])
    G[n] = rot_z(dh.offset[-1]) @ _tz(dh.d[-1:])[0]
    return G


def dh_frames(dh: DHParams, joint_types: tuple[str, ...], q: np.ndarray) -> np.ndarray:
    """The table's own frames 1..n (m, n, 4, 4) in the base frame, straight from the table rows.

    Standard DH: ``A_1 ... A_k``; modified DH: Craig's frame k (on joint k's axis). Frame n is the
    flange in both. ``q`` (m, n) joint values (rad or m). An independent cross-check of the chain.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    rev = np.array([t == "revolute" for t in joint_types])
    theta = dh.offset + np.where(rev, q, 0.0)
    d = dh.d + np.where(rev, 0.0, q)
    zeros = np.zeros_like(d)
    a = np.broadcast_to(dh.a, d.shape)
    alpha = np.broadcast_to(dh.alpha, d.shape)
    if dh.convention == "dh":
        A = (
            rot_z(theta)
            @ trans(np.stack([zeros, zeros, d], axis=-1))
            @ trans(np.stack([a, zeros, zeros], axis=-1))
            @ rot_x(alpha)
        )
    else:
        A = (
            rot_x(alpha)
            @ trans(np.stack([a, zeros, zeros], axis=-1))
            @ rot_z(theta)
            @ trans(np.stack([zeros, zeros, d], axis=-1))
        )
    out = np.empty_like(A)
    P = np.eye(4)
    for k in range(dh.n):
        P = P @ A[:, k]
        out[:, k] = P
    return out


def chain_frames(chain: np.ndarray, joint_types: tuple[str, ...], q: np.ndarray) -> np.ndarray:
    """Joint frames of the chain ``G_0 Q_1 G_1 ...`` (m, n, 4, 4): frame k = ``G_0 Q_1 ... Q_k``
    (z = joint k's axis) for k < n, and the flange ``... Q_n G_n`` for k = n (m)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = len(joint_types)
    out = np.empty((q.shape[0], n, 4, 4))
    P = np.broadcast_to(chain[0], (q.shape[0], 4, 4))
    for k, kind in enumerate(joint_types):
        if kind == "revolute":
            Q = rot_z(q[:, k])
        else:
            Q = _tz(q[:, k])
        P = P @ Q
        out[:, k] = P if k < n - 1 else P @ chain[n]
        P = P @ chain[k + 1]
    return out
