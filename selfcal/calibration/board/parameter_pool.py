"""Which kinematic parameters the postures can determine: step 1 of the board route's parameter
selection (:mod:`selfcal.calibration.board.param_selection`), the rank and conditioning test.

The pool, in order: the placement (``V_0``: the board pose, ``V_n``: the hand-eye; always
estimated, :func:`selfcal.calibration.board.nominal_fit.placement_indices`), the zero offsets of
the revolute joints, then the remaining minimal MCPC parameters of the chain (``V_1 .. V_{n-1}``)
in the order of a pivoted QR factorisation of the identification Jacobian (the tool-pose Jacobian
of :func:`selfcal.kinematics.forward.identification_jacobian` at the fair nominal, rows weighted
as :func:`selfcal.kinematics.identifiability.analyse_identifiability`'s, columns scaled to unit
norm); measurement terms (:mod:`selfcal.calibration.board.terms`) add their rows, what they tell
of the chain beyond their own unknowns (:func:`selfcal.calibration.board.terms.identification_rows`).
A parameter whose column adds nothing to the span of those before it is held for *rank* (its
orthogonal part below :data:`RANK_TOL`), one that adds too little for *conditioning* (below
:data:`COND_TOL`: its variance would grow by more than ``1 / COND_TOL**2``). Nothing here reads
truth.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.terms import identification_rows
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import identification_jacobian
from selfcal.kinematics.identifiability import pose_sigmas, triangular_factor
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.terms.base import Term

__all__ = [
    "COND_TOL",
    "NAMES_SHOWN",
    "RANK_TOL",
    "identified_words",
    "ColumnSpan",
    "ParameterPool",
    "determined",
    "determined_each",
    "offset_name",
    "parameter_indices",
    "parameter_pool",
]

RANK_TOL = 1e-8
"""Orthogonal part (of a unit column) at or below which a parameter is not identifiable."""
COND_TOL = 1e-3
"""Orthogonal part below which a parameter is held for conditioning (variance x 1e6)."""


@dataclass(frozen=True)
class ParameterPool:
    """The parameters offered (:func:`parameter_pool`): ``order`` the accepted ones as
    ``(name, kind, index)`` (``kind`` ``"mcpc"``: a flat MCPC index; ``"offset"``: a joint, 0
    based) in the order offered; ``n_placement``, ``n_offsets`` how many of them are the
    placement and the joint offsets; ``held`` the others by name with the reason."""

    order: tuple[tuple[str, str, int], ...]
    n_placement: int
    n_offsets: int
    held: dict[str, str]


def offset_name(j: int) -> str:
    """The name of joint ``j``'s (0 based) zero offset as a parameter: ``offset_j<j + 1>``."""
    return f"offset_j{j + 1}"


class ColumnSpan:
    """The rank and conditioning test (module docstring) over the columns of ``R`` (the triangular
    factor of the scaled identification Jacobian): :meth:`offer` accepts a column when its part
    outside the span of those accepted before is large enough, else gives the reason."""

    def __init__(self, R: np.ndarray):
        self.R = R
        self.basis = np.zeros((R.shape[0], 0))

    def orth(self, k: int) -> np.ndarray:
        c = self.R[:, k] / max(float(np.linalg.norm(self.R[:, k])), 1e-300)
        for _ in range(2):  # re-orthogonalise once for stability
            c = c - self.basis @ (self.basis.T @ c)
        return c

    def offer(self, k: int, c: np.ndarray | None = None) -> str | None:
        """None when column ``k`` (its orthogonal part ``c``) is accepted, else why not."""
        c = self.orth(k) if c is None else c
        s = float(np.linalg.norm(c))
        if s <= RANK_TOL:
            return "rank: not identifiable from these postures (a combination of the others)"
        if s < COND_TOL:
            return (f"conditioning: adds {s:.1e} of its column to the others' span "
                    f"(limit {COND_TOL:g})")  # fmt: skip
        self.basis = np.column_stack([self.basis, c / s])
        return None


NAMES_SHOWN = 8
"""Parameter names :func:`identified_words` lists before it counts the rest."""

_UNIDENTIFIABLE = ("rank:", "conditioning:")
"""The reasons :meth:`ColumnSpan.offer` gives for a parameter the postures cannot identify."""


def identified_words(extra: list[str], held: dict[str, str]) -> str:
    """`` (lx1, alpha1; 4 not identifiable from these postures: offset_j1, ...)``: the
    parameters identified beyond the placement (``extra``) and those the postures cannot
    identify (the selection's ``held`` with the rank or conditioning reason), by name, for
    calibrate's line (a 2-joint arm's said only "2 kinematic parameter(s)"); "" with neither."""

    def names(xs: list[str]) -> str:
        more = f" and {len(xs) - NAMES_SHOWN} more" if len(xs) > NAMES_SHOWN else ""
        return ", ".join(xs[:NAMES_SHOWN]) + more

    lost = [k for k, why in held.items() if why.startswith(_UNIDENTIFIABLE)]
    parts = [names(extra)] if extra else []
    if lost:
        parts.append(f"{len(lost)} not identifiable from these postures: {names(lost)}")
    return f" ({'; '.join(parts)})" if parts else ""


def _offered(model: MCPCModel) -> tuple[np.ndarray, list[int], np.ndarray]:
    """The parameters offered, by kind: the placement's flat MCPC indices, the revolute joints
    (0 based; their zero offsets) and the inner minimal parameters' flat indices."""
    n = model.n
    inner = np.array([k for k in minimal_indices(model.joint_types) if 0 < k // 6 < n], int)
    revolute = [j for j, t in enumerate(model.joint_types) if t == "revolute"]
    return placement_indices(n), revolute, inner


def parameter_indices(model: MCPCModel, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The flat MCPC indices and the joints (0 based) of the zero offsets among the parameters
    ``names`` (the pool's names, e.g. a candidate's) of ``model``'s chain, each in the order of
    ``names``.

    Raises:
        KeyError: a name that is no parameter offered on this chain.
    """
    place, revolute, inner = _offered(model)
    at: dict[str, tuple[str, int]] = {
        nm: ("mcpc", int(k)) for nm, k in zip(param_names(np.r_[place, inner]), np.r_[place, inner])
    }
    at.update({offset_name(j): ("offset", j) for j in revolute})
    kinds = [at[nm] for nm in names]
    return (np.array([i for k, i in kinds if k == "mcpc"], dtype=np.int64),
            np.array([i for k, i in kinds if k == "offset"], dtype=np.int64))  # fmt: skip


def _columns(model: MCPCModel, q: np.ndarray, terms: Sequence[Term] = ()
             ) -> tuple[list[str], list[str], list[int], np.ndarray]:  # fmt: skip
    """Every parameter offered (names, kinds, indices: placement, joint offsets, the inner
    minimal parameters) and the triangular factor of their scaled identification Jacobian at
    ``model`` and the joints ``q`` (m, n) rad (the module docstring), with the rows
    of the measurement ``terms`` (what they tell of the chain beyond their own unknowns,
    :func:`selfcal.calibration.board.terms.identification_rows`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    place, revolute, inner = _offered(model)
    J = identification_jacobian(model, q)
    cols = [J[:, :, place], joint_twists(model, q)[:, :, revolute], J[:, :, inner]]
    A = np.concatenate(cols, axis=2) / pose_sigmas(1e-4, 1e-3, len(q))[:, :, None]
    A = A.reshape(-1, A.shape[2])
    if terms:  # their columns [placement, inner, offsets] in the order of A's
        T = identification_rows(terms, model, np.r_[place, inner], np.array(revolute, int))
        order = np.r_[np.arange(len(place)), len(place) + len(inner) + np.arange(len(revolute)),
                      len(place) + np.arange(len(inner))]  # fmt: skip
        A = np.concatenate([A, T[:, order]])
    norm = np.linalg.norm(A, axis=0)
    R = triangular_factor(A / np.where(norm > 0, norm, 1.0))
    names = ([*param_names(place)] + [offset_name(j) for j in revolute]
             + [*param_names(inner)])  # fmt: skip
    kinds = ["mcpc"] * len(place) + ["offset"] * len(revolute) + ["mcpc"] * len(inner)
    index = [*place.tolist(), *revolute, *inner.tolist()]
    return names, kinds, index, R


def parameter_pool(model: MCPCModel, q: np.ndarray, terms: Sequence[Term] = ()) -> ParameterPool:
    """The pool (module docstring) at ``model`` (world = board frame, tool = camera)
    and the joints ``q`` (m, n) rad of the frames used, with the rows of the measurement
    ``terms``."""
    names, kinds, index, R = _columns(model, q, terms)
    n_place = len(placement_indices(model.n))
    n_rev = kinds.count("offset")
    groups = [range(n_place), range(n_place, n_place + n_rev)]
    rest = list(range(n_place + n_rev, len(names)))
    span = ColumnSpan(R)
    order: list[tuple[str, str, int]] = []
    held: dict[str, str] = {}
    counts = []

    def offer(k: int, c: np.ndarray | None = None) -> bool:
        why = span.offer(k, c)
        if why is not None:
            held[names[k]] = why
            return False
        order.append((names[k], kinds[k], index[k]))
        return True

    for g in groups:
        counts.append(sum(offer(k) for k in g))
    while rest:  # pivoted QR: the column with the largest part outside the span next
        parts = [span.orth(k) for k in rest]
        best = int(np.argmax([np.linalg.norm(p) for p in parts]))
        k = rest.pop(best)
        if not offer(k, parts[best]):
            for r in rest:  # every further one adds less still
                offer(r)
            break
    return ParameterPool(tuple(order), counts[0], counts[1], held)


def determined(model: MCPCModel, q: np.ndarray, names: tuple[str, ...],
               terms: Sequence[Term] = ()) -> dict[str, str]:  # fmt: skip
    """Which of the parameters ``names`` (a candidate's, in its order) the joints ``q`` (m, n)
    rad and the measurement ``terms`` cannot determine, by the rank and conditioning test
    offered in that order at ``model``: name -> reason (empty when they determine
    all)."""
    return determined_each(model, q, [names], terms)[0]


def determined_each(model: MCPCModel, q: np.ndarray, names: Sequence[tuple[str, ...]],
                    terms: Sequence[Term] = ()) -> list[dict[str, str]]:  # fmt: skip
    """:func:`determined` of every parameter tuple in ``names`` (e.g. each nested candidate's)
    at the same joints ``q``, from one identification Jacobian."""
    all_names, _, _, R = _columns(model, q, terms)
    at = {nm: k for k, nm in enumerate(all_names)}
    out = []
    for group in names:
        span = ColumnSpan(R)
        out.append({nm: why for nm in group if (why := span.offer(at[nm])) is not None})
    return out
