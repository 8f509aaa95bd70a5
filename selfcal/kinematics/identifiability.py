"""Identifiability of MCPC parameters from a set of robot configurations (before estimating).

The analysis works on the *row-weighted, column-scaled* identification Jacobian of the minimal
parameter set (eq. 10): rows ``[d; delta]`` of every pose divided by their standard deviations
(``sigma_t`` m, ``sigma_r`` rad), every column scaled to unit Euclidean norm. Column scaling makes
the numbers independent of the parameter units (m vs rad) and is the scaling under which the
condition number is (within a factor sqrt(L)) the smallest achievable by any diagonal scaling
(van der Sluis), the usual choice in Hollerbach & Wampler's identification-Jacobian analysis.

Reported quantities:
- ``singular_values`` of that matrix, the numerical ``rank`` (singular values above
  ``rank_rtol * sigma_max``) and the ``condition_number`` ``sigma_max / sigma_min``;
- ``o3`` = Nahvi & Hollerbach's minimum-singular-value index ``sigma_min / sigma_max`` (= 1 / cond)
  of the same matrix;
- ``o1`` = Borm & Menq's index ``(prod sigma_i)^(1/L) / sqrt(m)`` of the row-weighted Jacobian with
  *physical* column scaling (1 mm for lengths, 1 mrad for angles): roughly "measurement sigmas of
  pose error per pose caused by a 1 mm / 1 mrad parameter error, geometric mean over the parameter
  space directions". It grows with better-spread configurations and tighter measurements.

Selecting what to hold: parameters are taken in a priority order -- the base frame ``V_0`` first,
then the tool frame ``V_n``, then the internal frames ``V_1 .. V_{n-1}``, each in eq. 10 order --
and a parameter is kept only if its scaled column adds to the span of the columns already kept
(a QR factorisation without pivoting, with rejection). The rejected ones are unidentifiable from
this data; holding exactly those keeps the outer transforms (world->base, flange->camera) free and
fixes the internal ones at nominal, which is the physically sensible choice when, e.g., the last
joint never moves (then ``V_{n-1}`` -- the position of that joint's axis -- is held and ``V_n``
absorbs the constant link-to-camera transform). If this ordered selection does not reproduce the
SVD rank (which only happens in borderline, nearly rank-deficient cases) the columns are chosen by
pivoted QR (``scipy.linalg.qr(pivoting=True)``) instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from selfcal.errors import InputError, UsageError
from selfcal.kinematics.forward import identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_is_angle, param_names

__all__ = [
    "Identifiability",
    "analyse_identifiability",
    "numerical_rank",
    "pose_sigmas",
    "priority_order",
    "select_identifiable",
    "still_joints",
    "triangular_factor",
]

#: A joint whose readings spread by less than this (rad; m for a prismatic joint, scaled by
#: ``STILL_M_PER_RAD``) over every configuration counts as one that never moves: 0.001 deg,
#: below any arm's repeatability, above a controller's last printed digit.
STILL_RAD = np.radians(1e-3)
STILL_M_PER_RAD = 1e-3 / np.radians(1.0)  # 1 mm of a prismatic joint counts as 1 deg

#: Physical column scale for the Borm & Menq index: 1 mm for lengths, 1 mrad for angles.
O1_SCALE_M = 1e-3
O1_SCALE_RAD = 1e-3


@dataclass(frozen=True)
class Identifiability:
    """Identifiability of the minimal parameters from given configurations.

    Attributes:
        names: all minimal parameter names, eq. 10 order.
        considered: boolean mask (over ``names``) of parameters that were analysed (not held
            explicitly).
        identifiable: boolean mask of the parameters selected for estimation (subset of
            ``considered``); ``considered & ~identifiable`` cannot be identified from this data.
        rank: numerical rank of the scaled Jacobian of the considered parameters.
        singular_values: of the scaled Jacobian of the considered parameters (descending).
        condition_number: ``sigma_max / sigma_min`` of the scaled Jacobian of the *selected*
            parameters (finite when the selection is full rank).
        o1: Borm & Menq index of the selected parameters (see module docstring).
        o3: Nahvi's ``sigma_min / sigma_max`` of the selected parameters (= 1 / condition_number).
        method: ``"ordered-qr"`` or ``"pivoted-qr"``: how the selection was made.
    """

    names: tuple[str, ...]
    considered: np.ndarray
    identifiable: np.ndarray
    rank: int
    singular_values: np.ndarray
    condition_number: float
    o1: float
    o3: float
    method: str

    @property
    def unidentifiable(self) -> tuple[str, ...]:
        """Names of the analysed parameters that cannot be identified from this data."""
        bad = self.considered & ~self.identifiable
        return tuple(n for n, b in zip(self.names, bad) if b)


def pose_sigmas(
    sigma_t_m: float | np.ndarray, sigma_r_rad: float | np.ndarray, m: int
) -> np.ndarray:
    """Per-row standard deviations (m, 6) from scalar, per-pose (m,) or per-axis (m, 3) values.

    Raises:
        ValueError: non-positive / non-finite sigmas or a shape that does not broadcast to (m, 3).
    """
    out = np.empty((m, 6))
    for cols, s, what in (
        (slice(0, 3), sigma_t_m, "sigma_t_m"),
        (slice(3, 6), sigma_r_rad, "sigma_r_rad"),
    ):
        s = np.asarray(s, dtype=float)
        if s.ndim == 1:
            s = s[:, None]
        try:
            out[:, cols] = np.broadcast_to(s, (m, 3))
        except ValueError as exc:
            raise UsageError(
                f"{what} must be a scalar, shape ({m},) or ({m}, 3); got shape {s.shape}"
            ) from exc
    if not np.all(np.isfinite(out)) or np.any(out <= 0):
        raise InputError("sigma_t_m and sigma_r_rad must be positive and finite")
    return out


def priority_order(joint_types: tuple[str, ...]) -> np.ndarray:
    """Positions (into the minimal set) in the order they are offered for estimation.

    ``V_0`` parameters first, then ``V_n``, then ``V_1 .. V_{n-1}``; eq. 10 order within a group.
    """
    n = len(joint_types)
    frame = minimal_indices(joint_types) // 6
    group = np.where(frame == 0, 0, np.where(frame == n, 1, 2))
    return np.argsort(group, kind="stable")


def numerical_rank(A: np.ndarray, rank_rtol: float) -> tuple[int, float]:
    """The numerical rank of ``A``: its singular values above ``rank_rtol * sigma_max(A)``,
    and that threshold (0 for an empty ``A``). The one rank rule of the identification."""
    s = np.linalg.svd(A, compute_uv=False)
    if not s.size:
        return 0, 0.0
    tol = rank_rtol * float(s[0])
    return int(np.sum(s > tol)), tol


def select_identifiable(
    A: np.ndarray, order: np.ndarray, rank_rtol: float
) -> tuple[np.ndarray, int, str]:
    """Choose a maximal set of linearly independent columns of ``A`` (unit-norm columns).

    Columns are offered in ``order``; one is kept if the norm of its component orthogonal to the
    kept ones exceeds ``rank_rtol * sigma_max(A)``. Falls back to pivoted QR when the count does not
    match the SVD rank. Returns ``(mask of kept columns, rank, method)``.
    """
    rank, tol = numerical_rank(A, rank_rtol)
    keep = np.zeros(A.shape[1], dtype=bool)
    basis = np.zeros((A.shape[0], 0))
    for k in order:
        c = A[:, k]
        for _ in range(2):  # re-orthogonalise once for stability
            c = c - basis @ (basis.T @ c)
        nrm = np.linalg.norm(c)
        if nrm > tol:
            keep[k] = True
            basis = np.column_stack([basis, c / nrm])
    if int(keep.sum()) == rank:
        return keep, rank, "ordered-qr"
    _, _, piv = scipy.linalg.qr(A, mode="economic", pivoting=True)
    keep = np.zeros(A.shape[1], dtype=bool)
    keep[piv[:rank]] = True
    return keep, rank, "pivoted-qr"


def still_joints(q: np.ndarray, joint_types: tuple[str, ...]) -> str:
    """What the configurations ``q`` (m, n; rad, m for prismatic joints) show about a rank loss,
    in words for a message: the joints that never move (``"j6 never moves (17.189 deg in every
    row)"``, deg or mm), else that every joint moves and by how much at most (a check of the
    data, so a message never guesses at the cause). Empty for no configurations."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.size == 0:
        return ""
    prism = np.array([t == "prismatic" for t in joint_types])
    scale = np.where(prism, 1e3, np.degrees(1.0))  # rad -> deg, m -> mm
    unit = ["mm" if p else "deg" for p in prism]
    spread = q.max(axis=0) - q.min(axis=0)
    still = spread < np.where(prism, STILL_RAD * STILL_M_PER_RAD, STILL_RAD)
    if still.any():
        return "; ".join(
            f"j{j + 1} never moves ({q[0, j] * scale[j]:.3f} {unit[j]} in every row)"
            for j in np.flatnonzero(still)
        )
    parts = ", ".join(f"j{j + 1} {spread[j] * scale[j]:.3g} {unit[j]}" for j in range(q.shape[1]))
    return (
        f"every joint moves, by at most {parts}: spread the configurations over the joints' ranges"
    )


def triangular_factor(A: np.ndarray) -> np.ndarray:
    """``R`` of ``A = Q R`` (Householder, shape (min(rows, cols), cols)): same singular values,
    normal equations and column dependencies as ``A``, but small."""
    R: np.ndarray = np.linalg.qr(A, mode="r")  # type: ignore[assignment]  # mode "r": R only
    return R


def _scaled(A: np.ndarray) -> np.ndarray:
    nrm = np.linalg.norm(A, axis=0)
    return A / np.where(nrm > 0, nrm, 1.0)


def analyse_identifiability(
    model: MCPCModel,
    q: np.ndarray,
    *,
    sigma_t_m: float | np.ndarray = 1e-4,
    sigma_r_rad: float | np.ndarray = 1e-3,
    hold: tuple[str, ...] | list[str] = (),
    rank_rtol: float = 1e-9,
) -> Identifiability:
    """Which minimal parameters of ``model`` can be identified from tool poses at ``q`` (m, n).

    ``hold`` names parameters excluded beforehand (e.g. ``["beta1"]``). Units: SI throughout.

    Raises:
        ValueError: a name in ``hold`` that is not a minimal parameter (the message lists them).
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(model.joint_types)
    names = tuple(param_names(idx))
    unknown = [h for h in hold if h not in names]
    if unknown:
        raise InputError(f"cannot hold {unknown}: not minimal parameters; valid names: {names}")
    considered = np.array([nm not in set(hold) for nm in names])
    sig = pose_sigmas(sigma_t_m, sigma_r_rad, q.shape[0])
    J = identification_jacobian(model, q)[:, :, idx] / sig[:, :, None]
    J = J.reshape(-1, idx.size)
    # Everything below depends on J only through J^T J: work on the small triangular factor of
    # the unit-column-scaled Jacobian (R has the same singular values and column dependencies).
    col = np.linalg.norm(J, axis=0)
    col = np.where(col > 0, col, 1.0)
    R = triangular_factor(J / col)
    cons = np.flatnonzero(considered)
    A = _scaled(R[:, cons])
    order_all = priority_order(model.joint_types)
    pos_in_cons = {k: i for i, k in enumerate(cons)}
    order = np.array([pos_in_cons[k] for k in order_all if k in pos_in_cons], dtype=int)
    keep, rank, method = select_identifiable(A, order, rank_rtol)
    s_all = np.linalg.svd(A, compute_uv=False)
    identifiable = np.zeros(idx.size, dtype=bool)
    identifiable[cons[keep]] = True
    sel = np.flatnonzero(identifiable)
    s_sel = np.linalg.svd(_scaled(R[:, sel]), compute_uv=False)
    cond = float(s_sel[0] / s_sel[-1]) if s_sel.size and s_sel[-1] > 0 else float("inf")
    phys = np.where(param_is_angle(idx[sel]), O1_SCALE_RAD, O1_SCALE_M)
    s_phys = np.linalg.svd(R[:, sel] * (col[sel] * phys), compute_uv=False)
    with np.errstate(divide="ignore"):
        o1 = float(np.exp(np.mean(np.log(s_phys))) / np.sqrt(q.shape[0])) if s_phys.size else 0.0
    return Identifiability(
        names=names,
        considered=considered,
        identifiable=identifiable,
        rank=rank,
        singular_values=s_all,
        condition_number=cond,
        o1=o1,
        o3=1.0 / cond,
        method=method,
    )
