"""The "actual" robot: the nominal MCPC chain plus injected parameter errors, and its ground truth.

Errors are added to the MCPC parameters (``selfcal.kinematics.mcpc``; rad and m), so they include what DH cannot
express, e.g. a small ``beta`` between the parallel shoulder and elbow axes. The chain's tool is the
left camera (OpenCV frame), so errors of the last shape matrix are hand-eye errors.

The ground truth of a simulated run (:func:`make_truth`) is a :class:`selfcal.io.truth.Truth`,
written as ``truth.json`` by :func:`selfcal.io.truth.write_truth` and read by
:func:`selfcal.io.truth.read_truth` (its layout is in :mod:`selfcal.io.truth`).
"""

from __future__ import annotations

import re

import numpy as np

from selfcal.errors import InputError, UsageError
from selfcal.io.truth import Truth, error_table
from selfcal.kinematics.mcpc import (
    COLUMNS,
    MCPCModel,
    minimal_indices,
    param_is_angle,
    shape_matrices,
)
from selfcal.robot.definition import RobotDef
from selfcal.sim.link_frames import flange_in_last_link
from selfcal.sim.markers import MarkerField
from selfcal.sim.robot_mjcf import RigConfig
from selfcal.transforms import inv_pose

__all__ = [
    "param_index",
    "perturb",
    "apply_errors",
    "error_table",
    "true_hand_eye",
    "make_truth",
    "marker_field_of",
]

_NAME_RE = re.compile(r"^(alpha|beta|gamma|lx|ly|lz)(\d+)$")


def param_index(name: str, n: int) -> int:
    """Flat index into ``params.reshape(-1)`` of a parameter name such as ``"beta2"`` or ``"lx0"``
    for a chain of ``n`` joints (frames 0..n).

    Raises ``ValueError`` naming the valid pattern for a malformed or out-of-range name.
    """
    m = _NAME_RE.match(str(name))
    if m is None or int(m.group(2)) > n:
        raise InputError(
            f"unknown MCPC parameter {name!r}: expected <column><frame> with column in "
            f"{COLUMNS} and frame in 0..{n}, e.g. 'beta2' or 'lx1'"
        )
    return 6 * int(m.group(2)) + COLUMNS.index(m.group(1))


def perturb(model: MCPCModel, *, seed: int, translation_m: float, rotation_rad: float) -> MCPCModel:
    """``model`` with every parameter of the minimal identifiable set (``minimal_indices``) moved
    by an independent uniform error in ``[-rotation_rad, rotation_rad]`` (angles) or
    ``[-translation_m, translation_m]`` (lengths). Deterministic for a given ``seed``.

    Raises ``ValueError`` for negative or non-finite magnitudes.
    """
    for what, v in (("translation_m", translation_m), ("rotation_rad", rotation_rad)):
        if not np.isfinite(v) or v < 0:
            raise InputError(f"{what} must be a finite non-negative number, got {v}")
    idx = minimal_indices(model.joint_types)
    scale = np.where(param_is_angle(idx), float(rotation_rad), float(translation_m))
    rng = np.random.default_rng(seed)
    delta = rng.uniform(-1.0, 1.0, size=idx.size) * scale
    p = model.params.reshape(-1).copy()
    p[idx] += delta
    return model.with_params(p)


def apply_errors(model: MCPCModel, table: dict[str, float]) -> MCPCModel:
    """``model`` with explicit errors added: ``{"beta2": 1e-3, "lx1": 2e-4, ...}`` (rad, m).

    Any of the ``6 (n + 1)`` parameters may be named (non-minimal ones such as ``gamma1`` only
    re-gauge the chain). Raises ``ValueError`` for an unknown name or a non-finite value.
    """
    p = model.params.reshape(-1).copy()
    for name, value in table.items():
        v = float(value)
        if not np.isfinite(v):
            raise InputError(f"error for {name!r} must be finite, got {value}")
        p[param_index(name, model.n)] += v
    return model.with_params(p)


def true_hand_eye(robot: RobotDef, actual: MCPCModel) -> np.ndarray:
    """The actual robot's ``T_flange_cam`` (4, 4): the left camera (``V_n`` of ``actual``) seen from
    the nominal flange on the last link (``selfcal.sim.link_frames.flange_in_last_link``)."""
    return inv_pose(flange_in_last_link(robot, actual)) @ shape_matrices(actual.params[-1])


def make_truth(
    robot: RobotDef,
    nominal: MCPCModel,
    actual: MCPCModel,
    rig: RigConfig,
    field: MarkerField | None,
    meta: dict | None = None,
) -> Truth:
    """The ground-truth header for a simulated ``robot`` with chain ``actual`` (no frames yet)
    in the scene of the marker ``field`` (None: a scene without one, a board's)."""
    if nominal.joint_types != actual.joint_types or nominal.n != robot.n:
        raise UsageError("robot, nominal and actual models disagree on the joints")
    return Truth(
        robot_model=robot.name,
        joint_names=tuple(robot.joint_names),
        joint_types=tuple(actual.joint_types),
        joint_offsets_rad=np.asarray(actual.joint_offsets, float).copy(),
        nominal_params=nominal.params.copy(),
        true_params=actual.params.copy(),
        intrinsics_left=rig.intrinsics,
        intrinsics_right=rig.right,
        T_left_right=rig.T_left_right.copy(),
        T_flange_cam=true_hand_eye(robot, actual),
        T_flange_cam_nominal=robot.T_flange_cam.copy(),
        T_cam_tip=inv_pose(robot.T_flange_cam),
        marker_field=None if field is None else field.to_dict(),
        meta=dict(meta or {}),
    )


def marker_field_of(truth: Truth) -> MarkerField:
    """The marker field of a simulated run's truth as a :class:`selfcal.sim.markers.MarkerField`
    (a :class:`UsageError` when the scene had none: a board's)."""
    if truth.marker_field is None:
        raise UsageError("this run's truth has no marker field (its scene holds a board)")
    return MarkerField.from_dict(truth.marker_field)
