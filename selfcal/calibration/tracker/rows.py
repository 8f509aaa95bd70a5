"""How many tracker measurements identify a chain: the one rule the tracker route refuses data
by and the tracker planner refuses counts by (issue #30).

The count of minimal MCPC parameters measurements of some kinds (positions, poses, distances)
identify on a chain is the numerical rank of their weighted, column-scaled Jacobian at
well-spread noise-free configurations (:func:`spread_measurements`), the route's rank
tolerance; the data need more equations than that (:func:`rows_needed`). The count is the
generic one, the larger of the chain's as given and with its tool point moved by
:data:`GENERIC_TOOL_SHIFT_M`: the tool point is estimated, and one exactly on the last joint's
axis (a reflector at the flange's origin on a nominal arm: 25 parameters on the UR5e instead of
27) is an accident of the start that no measured arm's fit reproduces; it must not change how
many rows are asked for (the route asked 9 positions of a nominal arm's data and 10 of a
measured one's with the same reflector). The route
(:func:`selfcal.calibration.tracker.identify.identify_tracker`) asks it at its placed start, the
planner (:func:`selfcal.calibration.tracker.plan.minimum_count`) at its nominal chain with the
planned tool point: one function, so the planner's refusal and the route's error agree by
construction. Units: SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import InputError
from selfcal.estimation.tracker import (
    ChainLayout,
    TrackerDistanceBlock,
    TrackerMeasurements,
    TrackerPoseBlock,
    TrackerPositionBlock,
)
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.identifiability import numerical_rank, triangular_factor
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.transforms import make_pose, trans

__all__ = [
    "GENERIC_TOOL_SHIFT_M",
    "RowsNeeded",
    "rows_needed",
    "rows_needed_at",
    "considered_mask",
    "measurement_blocks",
    "dense_jacobian",
    "scaled_factor",
    "configurations",
    "spread_measurements",
]


GENERIC_TOOL_SHIFT_M = np.array([0.011, 0.013, 0.017])
"""(3,) m, in the tool frame: where :func:`rows_needed` also counts the parameters when the
chain's tool point hides some (no special value: about a centimetre off in every direction)."""


def measurement_blocks(
    layout: ChainLayout, meas: TrackerMeasurements, sig: tuple[float, float, float]
) -> list:
    """The residual blocks of ``meas`` over ``layout`` (positions or poses, and distances),
    weighted by ``sig`` = (m, rad, m) the standard deviations of a position coordinate, a
    rotation-vector coordinate and a distance."""
    st, sr, sd = sig
    blocks: list = []
    if meas.m and meas.R is not None:
        T = make_pose(meas.R, meas.xyz)
        blocks.append(TrackerPoseBlock(layout, meas.q, T, st, sr))
    elif meas.m:
        blocks.append(TrackerPositionBlock(layout, meas.q, meas.xyz, st))
    if meas.k:
        blocks.append(TrackerDistanceBlock(layout, *meas.distances(), sd))
    return blocks


def dense_jacobian(blocks: list, values: dict, flat: np.ndarray) -> np.ndarray:
    """The weighted Jacobian (rows, len(flat)) of the blocks w.r.t. the coordinates ``flat`` of
    their chain block (over a whole-chain layout: the flat MCPC parameters), dense: small
    problems need no sparse assembly."""
    out = []
    for b in blocks:
        (piece,) = b.evaluate(values, True).pieces
        k, d, c = piece.J.shape
        out.append(piece.J.reshape(k * d, c)[:, flat])
    return np.vstack(out)


def scaled_factor(model: MCPCModel, meas: TrackerMeasurements, sig, cons: np.ndarray) -> np.ndarray:
    """The triangular factor of the blocks' weighted Jacobian w.r.t. the minimal parameters
    ``cons`` (positions into the minimal set), each column scaled to unit norm (columns that are
    zero up to rounding, e.g. the base for distances, stay zero)."""
    idx = minimal_indices(model.joint_types)
    blocks = measurement_blocks(ChainLayout.whole(model), meas, sig)
    J = dense_jacobian(blocks, {"mcpc": model.params.reshape(-1)}, idx[cons])
    col = np.linalg.norm(J, axis=0)
    col = np.where(col > 1e-10 * col.max(initial=0.0), col, np.inf)
    return triangular_factor(J / col)


def configurations(meas: TrackerMeasurements) -> np.ndarray:
    """Every configuration (rad / m, (k, n)) the measurements were taken at: the rows' and
    both ends of every distance."""
    return np.concatenate([a for a in (meas.q, meas.q_a, meas.q_b) if a is not None and len(a)])


def spread_measurements(model: MCPCModel, meas: TrackerMeasurements, p: int) -> TrackerMeasurements:
    """Noise-free measurements of the same kinds at ``p + 10`` well-spread random
    configurations (revolute joints over a full turn, prismatic ones over the data's range
    +- 0.1 m), deterministic: what these kinds of measurement identify on this chain."""
    rng = np.random.default_rng(0)
    rows = p + 10
    data_q = configurations(meas)
    lo, hi = data_q.min(axis=0) - 0.1, data_q.max(axis=0) + 0.1
    rev = np.array([t == "revolute" for t in model.joint_types])

    def draw(k: int) -> np.ndarray:
        return np.where(
            rev, rng.uniform(-np.pi, np.pi, (k, model.n)), rng.uniform(lo, hi, (k, model.n))
        )

    q = draw(rows)
    T = fk_tool(model, q)
    return TrackerMeasurements(
        q=q if meas.m else q[:0],
        xyz=T[:, :3, 3] if meas.m else np.zeros((0, 3)),
        R=T[:, :3, :3] if meas.R is not None else None,
        q_a=draw(rows) if meas.k else None,
        q_b=draw(rows) if meas.k else None,
        d=np.ones(rows) if meas.k else None,
    )


def considered_mask(model: MCPCModel, hold: tuple[str, ...] | list[str]) -> np.ndarray:
    """(k,) bool over the minimal parameters of ``model``: those not named in ``hold``.

    Raises:
        InputError: a name in ``hold`` that is not a minimal parameter of the chain.
    """
    names = tuple(param_names(minimal_indices(model.joint_types)))
    unknown = [h for h in hold if h not in names]
    if unknown:
        raise InputError(
            f"cannot hold {unknown}: not minimal parameters of this robot",
            fix=f"name parameters among {', '.join(names)}",
        )
    return np.array([nm not in set(hold) for nm in names], bool)


@dataclass(frozen=True)
class RowsNeeded:
    """How many measurements the tracker route identifies from (module docstring).

    Attributes:
        rank: the count of minimal parameters these kinds of measurement identify on this chain
            (the numerical rank of their column-scaled Jacobian at well-spread configurations).
        need: the fewest rows of the kind ``what`` with which the equations exceed ``rank``
            (the data's other kinds, e.g. distances beside positions, counted as given).
        what: ``"positions"``, ``"poses"`` or ``"distances"``: the kind whose rows ``need``
            counts (the first of these the data hold).
        equations: the data's equations (3 a position, 6 a pose, 1 a distance).
    """

    rank: int
    need: int
    what: str
    equations: int

    @property
    def enough(self) -> bool:
        """More equations than parameters to identify: the route goes on."""
        return self.equations > self.rank


def rows_needed_at(
    model: MCPCModel,
    meas: TrackerMeasurements,
    sig: tuple[float, float, float],
    cons: np.ndarray,
    rank_rtol: float,
) -> tuple[RowsNeeded, np.ndarray, int]:
    """:func:`rows_needed` for the considered minimal positions ``cons`` (into the minimal set)
    and the weights ``sig`` (m, rad, m), with the triangular factor (scaled columns ``cons``)
    of ``model`` itself at the well-spread configurations and that factor's rank.

    The count (``RowsNeeded.rank``) is the generic one; the factor and its rank are the chain's
    as given: with its tool point exactly on the last joint's axis they count fewer, and the
    route's structural selection and its rank warning must compare the data with this chain,
    not with a moved one (else a nominal arm's data would be told to spread configurations
    that cannot help)."""
    A_own = scaled_factor(model, spread_measurements(model, meas, cons.size), sig, cons)
    rank_own = numerical_rank(A_own, rank_rtol)[0]
    rank = rank_own
    if rank < cons.size:  # the generic count: a tool point exactly on an axis counts fewer
        moved = model.with_tool(trans(GENERIC_TOOL_SHIFT_M))
        A_moved = scaled_factor(moved, spread_measurements(moved, meas, cons.size), sig, cons)
        rank = max(rank, numerical_rank(A_moved, rank_rtol)[0])
    n_eq = meas.equations()
    per = 6 if meas.R is not None else 3 if meas.m else 1
    what = "poses" if meas.R is not None else "positions" if meas.m else "distances"
    need = (rank - (n_eq - per * (meas.m if meas.m else meas.k))) // per + 1
    return RowsNeeded(rank=rank, need=need, what=what, equations=n_eq), A_own, rank_own


def rows_needed(
    model: MCPCModel,
    meas: TrackerMeasurements,
    *,
    sigmas: tuple[float, float, float] = (1e-4, 1e-4, 1e-4),
    hold: tuple[str, ...] | list[str] = (),
    rank_rtol: float = 1e-9,
) -> RowsNeeded:
    """The one rule of how many measurements the tracker route needs: the count of the
    considered minimal parameters (all but ``hold``) that measurements of ``meas``'s kinds
    identify on ``model`` (the rank of their weighted, column-scaled Jacobian at ``p + 10``
    well-spread noise-free configurations, ``p`` the considered parameters; singular values
    above ``rank_rtol`` of the largest) and the fewest rows with more equations than that.

    :func:`selfcal.calibration.tracker.identify.identify_tracker` refuses data with no more
    equations than ``rank`` through this rule, ``model`` its placed start (the nominal chain,
    the tool point fitted to the data); the planner asks it with the nominal chain and the
    planned tool point. The count is the generic one (module docstring): a tool point exactly
    on the last joint's axis does not lower it.

    Args:
        model: the chain in the measurements' frame, its tool the measured tool point (tool
            frame for poses); SI.
        meas: the measurements: only their kinds, counts and (for prismatic joints) the range
            of their configurations are used.
        sigmas: the standard deviations (m, rad, m) of a position coordinate, a rotation-vector
            coordinate and a distance (``identify_tracker``'s ``sigma_t_m``, ``sigma_r_rad``,
            ``sigma_d_m``: they weigh the kinds against each other).
        hold, rank_rtol: as ``identify_tracker``'s.

    Raises:
        InputError: malformed measurements or unknown ``hold`` names.
    """
    meas.check(model.n)
    cons = np.flatnonzero(considered_mask(model, hold))
    sig = (float(sigmas[0]), float(sigmas[1]), float(sigmas[2]))
    return rows_needed_at(model, meas, sig, cons, rank_rtol)[0]
