"""Predicted tool-point accuracy of a marker-field self-calibration over the workspace (issue #29).

The tool point is the flange (the robot file's flange -> camera mount seen from the left
camera, the chain's tool). Its error is predicted as every route's is
(:mod:`selfcal.calibration.accuracy`, :class:`selfcal.kinematics.tool_error.ToolErrorModel`),
from what this route provides:

- the estimation error: the Cramer-Rao covariance of the minimal parameters at the final
  estimate (:mod:`selfcal.calibration.field.bounds`: the camera, the rig, the joint read-back
  errors and the unknown marker corners marginalised, with the fit's corner noise) carried
  through the chain. The calibration's world frame is a camera (the reference one) whose pose
  relative to the robot is itself estimated, and a tool point's error in that frame is mostly
  where that camera stands; the error that matters is the tool point's relative to the robot's
  base, so the covariance is taken in the gauge the one-step refinement fixes its world frame
  with (:func:`selfcal.calibration.field.joint_gauge.choose_gauge`: the six base parameters
  that place joint 1's axis, its zero direction and height, held): ``Pi C Pi^T``, ``Pi`` the
  first-order re-expression (:func:`gauge_projector`) that moves the world frame (the gauge
  directions, :func:`selfcal.estimation.gauge.gauge_directions`) until those six parameters
  are unchanged. The predicted tool points are drawn in the chain's base frame
  (:func:`base_frame`: z along joint 1's axis); the error's norm does not depend on that
  choice of axes.
- the model error: NOT measured. The field route has no cross-validation folds (its held-out
  check, :mod:`selfcal.calibration.field.holdout`, is a fresh calibration of a subset that
  ``selfcal report`` runs on real data and measures in pixels). The block says so
  (``model_error`` null, ``model_error_note``) and so does the line
  (:data:`NOT_MEASURED`): the prediction is the covariance alone, which is optimistic wherever
  the model misfits (a compliance, a link the chain cannot express).

SI inside; ``_mm`` / ``_deg`` in the block. Nothing here reads truth.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.accuracy import SAMPLE_COUNT, Accuracy, error_model_from_json
from selfcal.errors import InputError
from selfcal.estimation.gauge import gauge_directions
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.mcpc import MCPCModel, chain_transforms, minimal_indices, param_names
from selfcal.kinematics.tool_error import (
    EDGE_FRACTION,
    ToolErrorModel,
    accuracy_line,
    workspace_sample,
    workspace_summary,
)
from selfcal.transforms import inv_pose, pose_from_vec

__all__ = [
    "NOT_MEASURED",
    "base_frame",
    "field_accuracy",
    "field_accuracy_line",
    "field_error_model_from_json",
    "gauge_projector",
    "in_gauge_of",
]

_FIX = "re-run `selfcal calibrate DIR` to write DIR/calibration.json again"

NOT_MEASURED = (
    "model error not measured (the field route has no cross-validation folds): the estimate's "
    "covariance alone, optimistic wherever the model misfits"
)
"""What the field route's block and line say of its model error (module docstring)."""


def gauge_projector(model: MCPCModel, held: tuple[str, ...]) -> np.ndarray:
    """(P, P) ``Pi``: a small change ``delta`` of ``model``'s minimal parameters (eq. 10 order,
    SI) re-expressed in the world frame, moved by the gauge directions ``G`` (P, 6), that leaves
    the six parameters ``held`` unchanged: ``Pi = I - G G_h^-1 E_h`` (first order; ``Pi delta``
    is zero at ``held``).

    Raises:
        InputError: ``held`` are not six of the model's minimal parameters, or do not fix the
            world frame (their block of the gauge directions is singular).
    """
    names = param_names(minimal_indices(model.joint_types))
    unknown = [h for h in held if h not in names]
    if len(held) != 6 or unknown:
        raise InputError(f"the gauge must hold six minimal parameters of the chain, not "
                         f"{list(held)}", fix=_FIX)  # fmt: skip
    h = np.array([names.index(x) for x in held])
    G = gauge_directions(model)
    Gh = G[h]
    if np.linalg.cond(Gh) > 1e10:
        raise InputError(f"the held parameters {list(held)} do not fix the world frame",
                         fix=_FIX)  # fmt: skip
    E = np.zeros((6, len(names)))
    E[np.arange(6), h] = 1.0
    return np.eye(len(names)) - G @ np.linalg.solve(Gh, E)


def in_gauge_of(other: MCPCModel, model: MCPCModel, held: tuple[str, ...], *,
                rounds: int = 6) -> MCPCModel:  # fmt: skip
    """``other`` (a chain of the same robot in ``model``'s world frame and offset convention,
    e.g. the simulator's truth) with its world frame moved until its six parameters ``held``
    equal ``model``'s: the frame in which :func:`field_accuracy` predicts ``model``'s tool error
    (Gauss-Newton on the gauge directions, ``rounds`` steps; converged to 1e-15 in two on the
    ER-4u). Tests and benchmarks compare a calibration with the truth there.

    Raises:
        InputError: ``held`` does not fix the world frame (:func:`gauge_projector`).
    """
    gauge_projector(model, held)  # checks the held set
    names = param_names(minimal_indices(model.joint_types))
    h = np.array([names.index(x) for x in held])
    for _ in range(rounds):
        d = minimal_difference(other, model)[h]
        xi = np.linalg.solve(gauge_directions(other)[h], -d)  # [v; w] of the world's move
        other = express_in_frame(other, pose_from_vec(np.r_[xi[3:], xi[:3]]), like=model)
    return other


def base_frame(model: MCPCModel) -> np.ndarray:
    """(4, 4) the chain's base frame (before joint 1: z along its axis) <- its world frame: the
    frame the field route's predicted tool points are given in."""
    return inv_pose(chain_transforms(model)[0])


def _what(gauge: tuple[str, ...], tool_point: str) -> str:
    return (
        f"predicted error of the calibrated tool point ({tool_point}) and tool orientation "
        "against the true ones, relative to the robot's base as the chain defines it (the "
        f"world frame's gauge: {', '.join(gauge)} held), points given in the chain's base frame "
        "(z along joint 1's axis): the Cramer-Rao covariance at the estimate carried through "
        f"the chain; {NOT_MEASURED} (docs/tool-accuracy.md); 95 % bounds of the error's norm per "
        "joint vector, summarised per region: inside = joint vectors within the calibration "
        f"postures' joint ranges, edge = beyond them by up to {EDGE_FRACTION:.0%} of each "
        "joint's range, workspace = within the joint limits"
    )


def field_accuracy(
    model: MCPCModel,
    covariance: np.ndarray,
    gauge: tuple[str, ...],
    held: tuple[str, ...],
    q_cal: np.ndarray,
    limits: np.ndarray,
    T_tool_point: np.ndarray,
    *,
    tool_point: str = "the flange",
    count: int = SAMPLE_COUNT,
) -> Accuracy:
    """The predicted accuracy of a field calibration (module docstring): ``model`` its chain
    (world = the reference camera, tool = the left camera; the file's), ``covariance`` (P, P)
    the Cramer-Rao covariance of every minimal parameter in that frame
    (:attr:`selfcal.calibration.field.bounds.CramerRao.cov_ref`), ``gauge`` the six parameters
    that fix the world frame, ``held`` the further ones the calibration held (not estimated),
    ``q_cal`` (m, n) rad / m the calibration postures, ``limits`` (n, 2) the joint limits,
    ``T_tool_point`` the tool point in the chain's tool frame (m), ``tool_point`` what it is in
    words; ``count`` joint vectors per region.

    Raises:
        InputError: the covariance is not (P, P) and finite, or the gauge is not one
            (:func:`gauge_projector`).
    """
    idx = minimal_indices(model.joint_types)
    names = param_names(idx)
    cov = np.asarray(covariance, dtype=float)
    if cov.shape != (idx.size, idx.size) or not np.all(np.isfinite(cov)):
        raise InputError(f"the field calibration's covariance must be {idx.size} x {idx.size} "
                         f"and finite, not {cov.shape}", fix=_FIX)  # fmt: skip
    P = gauge_projector(model, gauge)
    cov = P @ cov @ P.T
    est = np.array([n not in gauge and n not in held for n in names])
    em = ToolErrorModel(model, base_frame(model), idx[est], cov[np.ix_(est, est)], 0.0, 0.0,
                        np.asarray(T_tool_point, float))  # fmt: skip
    q_cal = np.atleast_2d(np.asarray(q_cal, dtype=float))
    sample = workspace_sample(q_cal, limits, count=count)
    extra = {
        "tool_point": tool_point,
        "T_tool_point_si": np.asarray(T_tool_point, float).tolist(),
        "joint_limits_si": np.asarray(limits, float).tolist(),
        "gauge_held": list(gauge),
        "frame": "the chain's base frame (before joint 1, z along its axis), the error relative "
        "to the robot's base as the held parameters (gauge_held) fix it",
    }
    return Accuracy(em, tuple(np.asarray(names)[est].tolist()), None,
                    workspace_summary(em, sample, q_cal), sample, q_cal,
                    _what(gauge, tool_point), NOT_MEASURED, extra)  # fmt: skip


def field_error_model_from_json(block: dict, model: MCPCModel, where: str) -> ToolErrorModel:
    """The :class:`ToolErrorModel` of a field ``calibration.json``'s ``accuracy`` block (its
    model error, not measured, is zero: :data:`NOT_MEASURED`); ``model`` the file's chain.

    Raises:
        InputError: the block is malformed (named).
    """
    names = tuple(param_names(minimal_indices(model.joint_types)))
    tip = np.asarray(block.get("T_tool_point_si", np.eye(4)), dtype=float)
    if tip.shape != (4, 4) or not np.all(np.isfinite(tip)):
        raise InputError(f"{where}: accuracy.T_tool_point_si must be a 4 x 4 pose", fix=_FIX)
    return error_model_from_json(block, model, base_frame(model), names, True, where, fix=_FIX,
                                 T_tool_point=tip)  # fmt: skip


def field_accuracy_line(regions: dict, block: dict) -> str:
    """The one line of a field calibration's predicted accuracy: the shared line
    (:func:`selfcal.kinematics.tool_error.accuracy_line`) and, when the block's model error is
    not measured, that it is not (never a covariance-only number read as the whole prediction)."""
    line = accuracy_line(regions)
    if block.get("model_error") is None:
        line += f"; {block.get('model_error_note') or NOT_MEASURED}"
    return line
