"""Rigid alignment of kinematic models and the MCPC world gauge, as pure functions (SI units).

The world frame an identification works in is free (see :mod:`selfcal.calibration.identify`): these functions
re-express a model in another world frame and joint-offset convention so that two models of (nearly)
the same robot can be compared parameter by parameter.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import UsageError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import (
    MCPCModel,
    base_offset_for,
    chain_transforms,
    gauge_fix,
    minimal_indices,
    param_is_angle,
)
from selfcal.transforms import inv_pose, kabsch

__all__ = [
    "AXIS_TIPS",
    "fit_rigid_transform",
    "PLACEMENT_ROUNDS",
    "PLACEMENT_RTOL",
    "fit_placement_and_hand_eye",
    "regauge",
    "wrap_params",
    "minimal_difference",
    "express_in_frame",
    "align_truth",
]


AXIS_TIPS = np.array([[0, 0, 0, 1], [0.1, 0, 0, 1], [0, 0.1, 0, 1], [0, 0, 0.1, 1]], float).T
"""A pose's origin and the tips of its axes at 0.1 m, as homogeneous columns (4, 4):
``((T_a - T_b) @ AXIS_TIPS)[..., :3, :]`` compares two poses by position and orientation (an
orientation error of 1 rad weighs like 0.1 m, as in :func:`fit_rigid_transform`)."""


def fit_rigid_transform(T_a: np.ndarray, T_b: np.ndarray, length_m: float = 0.1) -> np.ndarray:
    """Least-squares rigid ``T_a_b`` with ``T_a_b @ T_b[i] ~ T_a[i]`` (poses (m, 4, 4) in two frames).

    Closed form (Kabsch/Umeyama without scale) on virtual points: each pose contributes its origin
    and the three points ``origin + length_m * axis``, so positions and orientations both count
    (an orientation error of 1 rad weighs like ``length_m`` metres).
    """
    T_a = np.asarray(T_a, dtype=float).reshape(-1, 4, 4)
    T_b = np.asarray(T_b, dtype=float).reshape(-1, 4, 4)
    return _rigid_fits(T_a, T_b, length_m)


def _rigid_fits(T_a: np.ndarray, T_b: np.ndarray, length_m: float = 0.1) -> np.ndarray:
    """:func:`fit_rigid_transform` of each pair of pose sets (..., m, 4, 4) (broadcast over the
    leading axes): (..., 4, 4)."""
    T_a, T_b = np.broadcast_arrays(T_a, T_b)

    def pts(T: np.ndarray) -> np.ndarray:
        o = T[..., :3, 3]
        ax = np.swapaxes(T[..., :3, :3], -1, -2) * length_m  # rows: scaled axes
        tips = (o[..., None, :] + ax).reshape(T.shape[:-3] + (-1, 3))
        return np.concatenate([o, tips], axis=-2)

    return kabsch(pts(T_b), pts(T_a))


PLACEMENT_ROUNDS = 1000
"""The most rounds of :func:`fit_placement_and_hand_eye` (each round two 3 x 3 SVDs); it
descends linearly. Measured on the Nachi MZ25 photoneo set's first 6, 9 and 12 calibration rows
(the camera stage's poses; ``tests/real/test_real_subset.py`` calibrates the 12) from the robot
file's camera mount, a quarter turn about the optical axis off the real one: the misfit 0.2 -
0.9 m^2 after the first round, 1.4e-6 - 6e-6 m^2 where it stops, after 370, 195 and 150
rounds."""

PLACEMENT_RTOL = 1e-4
""":func:`fit_placement_and_hand_eye` stops when a round lowers its misfit by less than this
fraction of it."""


def fit_placement_and_hand_eye(
    T_world_cam: np.ndarray,
    T_base_flange: np.ndarray,
    T_flange_cam: np.ndarray,
    rounds: int = PLACEMENT_ROUNDS,
) -> tuple[np.ndarray, np.ndarray]:
    """``(B, C)`` with ``B @ T_base_flange[i] @ C ~ T_world_cam[i]`` (poses (m, 4, 4)): the
    placement ``B`` (world <- base) and hand-eye ``C`` (flange <- camera) fitted in turn by
    :func:`fit_rigid_transform`, from the hand-eye guess ``T_flange_cam``; a start for a
    joint least-squares fit. Each step is the exact least-squares one of the one misfit (the
    origins and axis tips of ``B F C`` against ``T``'s, :data:`AXIS_TIPS`), so every round
    lowers it (the hand-eye fitted on the inverted poses, another misfit, could climb away from a
    guess a quarter turn off); rounds until it falls by less than :data:`PLACEMENT_RTOL` of
    itself, at most ``rounds`` (at least 1: :class:`~selfcal.errors.UsageError` otherwise).

    ``T_flange_cam`` may be several guesses (s, 4, 4): each descends on its own, as it would
    alone (the same rounds and stop), the ones still descending in one array pass per round
    (:func:`selfcal.calibration.board.nominal_fit.placement`'s 24 starts: one round of all of
    them costs little more than one round of one); ``B`` and ``C`` then are (s, 4, 4)."""
    if rounds < 1:
        raise UsageError(
            f"fit_placement_and_hand_eye needs at least one round, got rounds={rounds}"
        )
    T = np.asarray(T_world_cam, dtype=float)
    F = np.asarray(T_base_flange, dtype=float)
    guess = np.asarray(T_flange_cam, dtype=float)
    C = guess.reshape(-1, 4, 4).copy()
    B = np.empty_like(C)
    eye = np.broadcast_to(np.eye(4), T.shape)
    last = np.full(len(C), np.inf)
    going = np.arange(len(C))  # the guesses still descending
    for _ in range(rounds):
        B_now = _rigid_fits(T, F @ C[going, None])  # the best B for each C
        BF = B_now[:, None] @ F
        # the best C for this B: sum |B F C e - T e|^2 = sum |C e - (B F)^-1 T e|^2
        C_now = _rigid_fits(inv_pose(BF) @ T, eye)
        now = np.sum(((BF @ C_now[:, None] - T) @ AXIS_TIPS)[..., :3, :] ** 2, axis=(1, 2, 3))
        B[going], C[going] = B_now, C_now
        lower = now < last[going] * (1.0 - PLACEMENT_RTOL)
        last[going] = now
        going = going[lower]
        if not going.size:
            break
    return B.reshape(guess.shape), C.reshape(guess.shape)


def regauge(
    chain: list[np.ndarray],
    joint_types: tuple[str, ...],
    joint_offsets: np.ndarray,
    base_offset: float | None = None,
) -> MCPCModel:
    """The MCPC model of the chain ``G_0 Q_1 G_1 ... Q_n G_n`` using *given* joint offsets.

    Same gauge as :func:`selfcal.kinematics.mcpc.gauge_fix` (gamma_i = lz_i = 0 for i < n), but the constant
    offsets are imposed rather than chosen for conditioning, so two models of (nearly) the same
    robot get comparable parameters. Angles are wrapped to (-pi, pi]. ``base_offset``: imposed
    too, or None to choose it (:func:`selfcal.kinematics.mcpc.base_offset_for`).
    """
    base = base_offset_for(chain[0]) if base_offset is None else float(base_offset)
    params, offsets = gauge_fix(chain, tuple(joint_types), offsets=joint_offsets, base_offset=base)
    return MCPCModel(wrap_params(params), tuple(joint_types), offsets, base)


def wrap_params(params: np.ndarray) -> np.ndarray:
    """Parameters (n + 1, 6) with the angle columns wrapped to (-pi, pi] (same chain)."""
    p = np.array(params, dtype=float, copy=True)
    p[:, :3] = -((-p[:, :3] + np.pi) % (2 * np.pi) - np.pi)
    return p


def minimal_difference(a: MCPCModel, b: MCPCModel) -> np.ndarray:
    """``a - b`` over the minimal parameters (eq. 10 order, SI), angles wrapped to (-pi, pi].

    Raises:
        ValueError: different joint types or joint (or base) offsets (re-express one with
            :func:`express_in_frame` ``like=`` the other first).
    """
    if a.joint_types != b.joint_types:
        raise UsageError("models have different joint types")
    if not np.allclose(np.r_[a.joint_offsets, a.base_offset], np.r_[b.joint_offsets, b.base_offset],
                       atol=1e-12):  # fmt: skip
        raise UsageError(
            "models use different joint offsets, so their parameters are not comparable; "
            "re-express one with express_in_frame(model, T, like=other)"
        )
    idx = minimal_indices(a.joint_types)
    d = a.params.reshape(-1)[idx] - b.params.reshape(-1)[idx]
    ang = param_is_angle(idx)
    d[ang] = (d[ang] + np.pi) % (2 * np.pi) - np.pi
    return d


def express_in_frame(
    model: MCPCModel, T_new_old: np.ndarray, *, like: MCPCModel | None = None
) -> MCPCModel:
    """The same physical chain with its world frame changed: ``T_new_tool = T_new_old T_old_tool``.

    Without ``like`` this is ``model.with_base(T_new_old)`` (joint offsets re-chosen for
    conditioning); with ``like`` the joint offsets of ``like`` are imposed (:func:`regauge`), so the
    result's minimal parameters are directly comparable with ``like``'s.
    """
    T_new_old = np.asarray(T_new_old, dtype=float)
    if like is None:
        return model.with_base(T_new_old)
    G = chain_transforms(model)
    return regauge(
        [T_new_old @ G[0], *G[1:]], model.joint_types, like.joint_offsets, like.base_offset
    )


def align_truth(
    true_model: MCPCModel,
    est_model: MCPCModel,
    q_ref: np.ndarray,
    *,
    length_m: float = 0.1,
) -> MCPCModel:
    """The true model expressed in the estimate's world frame, in the estimate's offset convention.

    The world transform is the best rigid fit (:func:`fit_rigid_transform`) between the two models'
    tool poses at ``q_ref`` (m, n) rad -- use configurations where both models are meaningful, e.g.
    the measurement configurations (if a joint never moved there, the two models only agree for that
    joint value). When the true world -> measurement transform is known (simulation), prefer
    ``express_in_frame(true_model, T_meas_trueworld, like=est_model)``: it does not mix estimation
    error into the alignment. See the module docstring for which parameters are gauge.
    """
    T = fit_rigid_transform(fk_tool(est_model, q_ref), fk_tool(true_model, q_ref), length_m)
    return express_in_frame(true_model, T, like=est_model)
