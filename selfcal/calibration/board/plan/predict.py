"""The tool-point error a board calibration reaches with the parameters its selection keeps: the
prediction of ``selfcal plan`` (issue #30).

A board calibration estimates the kinematic parameters its identifiability selection keeps
(:mod:`selfcal.calibration.board.param_selection`); every other minimal parameter stays at the
drawing's value, and its deviation from the drawing is an error the estimated parameters only
partly absorb. To first order, with ``F`` (p, p) the Fisher information of the camera's free
parameters and every minimal kinematic parameter
(:func:`selfcal.calibration.board.plan.information.frame_information`), ``M`` (p, e) the estimated
parameters' directions among them (the camera's own; the kinematic ones by
:func:`selfcal.calibration.board.bounds.to_minimal`) and ``S`` (p, p) the covariance of the
minimal parameters' deviation from the drawing::

    error = -(I - P) d + noise,   P = M (M^T F M)^-1 M^T F       (d ~ S: the deviation)
    Cov(error) = (I - P) S (I - P)^T + M (M^T F M)^-1 M^T

and the predicted RMS of the tool point over the workspace is ``sqrt(trace(G Cov))``, ``G`` the
aligned tool-point weight (:func:`selfcal.estimation.joint_report.aligned_tool_weight`) on the
kinematic block. With every minimal parameter kept ``P = I``: the Cramer-Rao bound.

Which parameters a plan's calibration keeps: those step 1 of the selection accepts at its
postures (rank and conditioning of the identification Jacobian at the nominal,
:func:`selfcal.calibration.board.parameter_pool.parameter_pool`); its cross-validation, which
needs the images, may hold more (their deviation is then a further error the prediction does
not see). A calibrated dataset's: those its ``calibration.json`` names as identified.

The deviation from the drawing (:class:`selfcal.calibration.board.deviation.Deviation`): every minimal parameter uniform within
+-``translation_m`` (lengths) or +-``rotation_rad`` (angles), i.e. the standard deviation
``a / sqrt(3)``, independently: what the simulator draws (:func:`selfcal.sim.actual.perturb`,
``[perturbation]``; by default 1 mm and 0.5 deg, the simulated robots' own,
:class:`selfcal.config.scenario.PerturbationConfig`). The placement's deviation (the board pose
and the hand-eye, which every calibration estimates) leaves no error where the placement is
estimated, so the predictions use :meth:`Deviation.variance` (the inner parameters'); it does
show where nothing is fitted, in the chain as drawn
(:mod:`selfcal.calibration.board.plan.reference`: :meth:`Deviation.drawn_variance`). Units: SI.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.board.bounds import to_minimal
from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.parameter_pool import parameter_pool
from selfcal.errors import UsageError
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices

__all__ = [
    "Directions",
    "kept_by_rank",
    "error_covariance",
    "estimated_directions",
    "linear_estimator",
    "prior_information",
    "predicted_with_held",
]


def kept_by_rank(model: MCPCModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kinematic parameters the selection's rank and conditioning test accepts at the
    joints ``q`` (m, n) rad of ``model`` (world = board, tool = camera): flat MCPC indices and
    the revolute joints (0 based) whose zero offsets are estimated."""
    pool = parameter_pool(model, np.atleast_2d(np.asarray(q, dtype=float)))
    free = [i for _, kind, i in pool.order if kind == "mcpc"]
    offsets = [i for _, kind, i in pool.order if kind == "offset"]
    return np.array(free, np.int64), np.array(offsets, np.int64)


def estimated_directions(
    model: MCPCModel, free_idx: np.ndarray, offset_joints: np.ndarray
) -> np.ndarray:
    """(k, e) the directions among the minimal parameters (the order of
    :func:`selfcal.kinematics.mcpc.minimal_indices`) that the estimated flat MCPC parameters
    ``free_idx`` and joint offsets ``offset_joints`` move, at ``model`` (first order)."""
    poses = KinematicPoses(model, np.zeros((1, model.n)), np.asarray(free_idx, np.int64),
                           np.zeros((0, 4, 4)), np.ones(1, bool),
                           offset_joints=np.asarray(offset_joints, np.int64))  # fmt: skip
    return to_minimal(poses)


class Directions:
    """:func:`estimated_directions` of every minimal parameter, the placement's and every
    revolute joint's offset of ``model`` (all the selection offers), computed once: each column depends on its own parameter alone (a
    derivative at the model), so any set's directions are a choice of these columns."""

    def __init__(self, model: MCPCModel):
        self.free = np.union1d(minimal_indices(model.joint_types), placement_indices(model.n))
        self.offsets = np.array(
            [j for j, t in enumerate(model.joint_types) if t == "revolute"], np.int64
        )
        self.M = estimated_directions(model, self.free, self.offsets)

    def of(self, free_idx: np.ndarray, offset_joints: np.ndarray) -> np.ndarray:
        """(k, e) the directions of the flat MCPC parameters ``free_idx`` and
        the joint offsets ``offset_joints``, in that order."""
        at = {int(i): c for c, i in enumerate(self.free.tolist())}
        off = {int(j): len(self.free) + c for c, j in enumerate(self.offsets.tolist())}
        try:
            cols = [at[int(i)] for i in np.asarray(free_idx).tolist()]
            cols += [off[int(j)] for j in np.asarray(offset_joints).tolist()]
        except KeyError as exc:
            raise UsageError(f"parameter {exc} is not one the selection offers") from None
        return self.M[:, cols]


def prior_information(variance: np.ndarray, n_cam: int) -> np.ndarray:
    """(p, p) the information of the deviation's prior on ``[camera (n_cam), minimal]``:
    ``1 / variance`` on the kinematic diagonal where it is positive, zero elsewhere."""
    v = np.asarray(variance, dtype=float)
    d = np.concatenate([np.zeros(n_cam), np.where(v > 0, 1.0 / np.where(v > 0, v, 1.0), 0.0)])
    return np.diag(d)


def error_covariance(
    F: np.ndarray, n_cam: int, M: np.ndarray, variance: np.ndarray
) -> np.ndarray | None:
    """(p, p) the covariance of the estimate's error (module docstring) on ``[camera (n_cam),
    minimal (k)]``: ``F`` (p, p) the information, ``M`` (k, e) the estimated kinematic
    directions, ``variance`` (k,) the deviation's; None when the estimated parameters'
    information is singular."""
    k = len(variance)
    if F.shape[0] != n_cam + k:
        raise UsageError(f"shapes do not match: F {F.shape}, k {k}")
    got = linear_estimator(F, n_cam, M)
    if got is None:
        return None
    C, R = got
    S = np.zeros(n_cam + k)
    S[n_cam:] = variance
    return (R * S) @ R.T + C


def linear_estimator(
    F: np.ndarray, n_cam: int, M: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """The first-order estimate on ``[camera (n_cam), minimal (k)]`` that fits the camera's
    free parameters and the kinematic directions ``M`` (k, e) to data of information ``F``
    (p, p) (module docstring): ``(C, R)``, ``C`` (p, p) its covariance ``Mf (Mf^T F Mf)^-1
    Mf^T`` (also the map of the data's information-weighted noise ``g ~ N(0, F)`` to the
    estimate's error, ``C g``) and ``R = I - C F`` (what it leaves of a deviation ``d``: the
    error is ``-R d + C g``); None when the estimated parameters' information is singular."""
    k = F.shape[0] - n_cam
    if F.shape != (n_cam + k, n_cam + k) or M.shape[0] != k:
        raise UsageError(f"shapes do not match: F {F.shape}, M {M.shape}, k {k}")
    Mf = np.zeros((n_cam + k, n_cam + M.shape[1]))
    Mf[:n_cam, :n_cam] = np.eye(n_cam)
    Mf[n_cam:, n_cam:] = M
    A = Mf.T @ F @ Mf
    d = np.sqrt(np.maximum(np.abs(np.diag(A)), 1e-300))
    As = A / np.outer(d, d)
    if not np.all(np.isfinite(As)) or np.linalg.cond(As) > 1e12:
        return None
    C = Mf @ (np.linalg.inv(As) / np.outer(d, d)) @ Mf.T  # the estimate's covariance
    return C, np.eye(n_cam + k) - C @ F  # I - P: what the estimate leaves of a deviation


def predicted_with_held(
    F: np.ndarray, G: np.ndarray, n_cam: int, M: np.ndarray, variance: np.ndarray
) -> float:
    """The predicted RMS tool-point error (m, module docstring): ``F`` (p, p) the information
    on ``[camera (n_cam), minimal (k)]``, ``G`` (k, k) the aligned tool weight, ``M`` (k, e)
    the estimated kinematic directions, ``variance`` (k,) the deviation's; infinite when the
    estimated parameters' information is singular."""
    k = len(variance)
    if G.shape != (k, k):
        raise UsageError(f"shapes do not match: G {G.shape}, k {k}")
    cov = error_covariance(F, n_cam, M, variance)
    if cov is None:
        return float("inf")
    return float(np.sqrt(max(np.trace(G @ cov[n_cam:, n_cam:]), 0.0)))
