"""The marker-field route's predicted tool-point accuracy (issue #29): the gauge it is given in,
its ``accuracy`` block, its reading back and its line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from selfcal.calibration.field.accuracy import (
    NOT_MEASURED,
    base_frame,
    field_accuracy,
    field_accuracy_line,
    field_error_model_from_json,
    gauge_projector,
    in_gauge_of,
)
from selfcal.calibration.field.joint_gauge import choose_gauge
from selfcal.errors import InputError
from selfcal.estimation.gauge import gauge_directions
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc, param_names
from selfcal.kinematics.tool_error import workspace_sample, workspace_summary
from selfcal.robot.definition import load_robot
from selfcal.transforms import pose_from_vec


@pytest.fixture(scope="module")
def chain():
    """The ER-4u's nominal chain seen from a camera frame somewhere above it (as a field
    calibration's world, the reference camera), its tool the camera; its gauge."""
    robot = load_robot("er4u-paper")
    T = pose_from_vec(np.array([0.3, -0.2, 2.5, 0.1, 0.2, 0.9]))
    model = express_in_frame(nominal_mcpc(robot).with_tool(robot.T_flange_cam), T)
    return robot, model, choose_gauge(model).held


def test_the_projector_removes_a_move_of_the_world_frame(chain):
    _, model, held = chain
    P = gauge_projector(model, held)
    names = param_names(minimal_indices(model.joint_types))
    h = [names.index(x) for x in held]
    G = gauge_directions(model)
    assert np.abs(P @ G).max() < 1e-9  # a pure move of the world frame is no error
    assert np.abs(P[h]).max() < 1e-12  # the held parameters do not change
    assert np.allclose(P @ P, P, atol=1e-9)  # a projection
    with pytest.raises(InputError, match="six minimal parameters"):
        gauge_projector(model, held[:5])


def test_in_gauge_of_matches_the_held_parameters(chain):
    _, model, held = chain
    moved = express_in_frame(model, pose_from_vec(np.array([0.01, -0.02, 0.01, 0.003, 0.0, 0.01])),
                             like=model)  # fmt: skip
    back = in_gauge_of(moved, model, held)
    q = np.zeros((1, model.n))
    # the same chain moved back: the tool pose as the model's (1e-12 m; found 1e-15)
    assert np.abs(fk_tool(back, q) - fk_tool(model, q)).max() < 1e-9


def test_the_block_is_finite_in_named_units_and_says_the_model_error_is_not_measured(chain):
    robot, model, held = chain
    rng = np.random.default_rng(3)
    k = minimal_indices(model.joint_types).size
    A = rng.normal(size=(k, k)) * 1e-4
    cov = A @ A.T  # any positive covariance of the minimal parameters (rad, m)
    q_cal = rng.uniform(robot.limits[:, 0] / 2, robot.limits[:, 1] / 2, (20, robot.n))
    tip = np.linalg.inv(robot.T_flange_cam)
    acc = field_accuracy(model, cov, held, (), q_cal, robot.limits, tip, count=64)
    block = json.loads(json.dumps(acc.to_json()))  # as calibration.json holds it
    assert block["model_error"] is None and block["model_error_note"] == NOT_MEASURED
    assert set(held).isdisjoint(block["estimated"]) and len(block["estimated"]) == k - 6
    assert block["gauge_held"] == list(held) and "mm and deg" in block["units"]
    for name in ("inside", "edge", "workspace", "calibration_postures"):
        r = block["regions"][name]
        for key in ("position_95_mm_max", "position_95_mm_median", "position_rms_mm",
                    "orientation_95_deg_max"):  # fmt: skip
            assert np.isfinite(r[key]) and r[key] > 0, (name, key)
        assert r["position_95_mm_median"] <= r["position_95_mm_max"]
    # read back from the file: the same regions (the one path of every route's block)
    em = field_error_model_from_json(block, model, "calibration.json")
    sample = workspace_sample(q_cal, robot.limits, count=64)
    again = workspace_summary(em, sample, q_cal)
    assert again["inside"]["position_95_mm_max"] == pytest.approx(
        block["regions"]["inside"]["position_95_mm_max"], rel=1e-9)  # fmt: skip
    # the line never gives the covariance alone as the whole prediction
    line = field_accuracy_line(again, block)
    assert line.startswith("tool point within ") and line.endswith(NOT_MEASURED)
    # the points are given in the base frame: z along joint 1's axis
    z = (base_frame(model) @ fk_tool(model, np.zeros((1, robot.n)))[0])[:3, 3]
    assert np.isfinite(z).all()


def test_a_malformed_block_is_named(chain):
    robot, model, held = chain
    k = minimal_indices(model.joint_types).size
    with pytest.raises(InputError, match="covariance"):
        field_accuracy(model, np.full((k, k), np.nan), held, (), np.zeros((8, robot.n)),
                       robot.limits, np.eye(4))  # fmt: skip
    with pytest.raises(InputError, match="T_tool_point_si"):
        field_error_model_from_json({"T_tool_point_si": [[1.0]]}, model, "cal.json")
