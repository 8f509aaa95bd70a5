"""The "actual" robot: injected MCPC errors and the truth.json record."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from selfcal.io.truth import TRUTH_FORMAT, TruthFileError, read_truth, write_truth
from selfcal.kinematics.forward import fk_frames
from selfcal.kinematics.mcpc import minimal_indices, param_is_angle
from selfcal.robot.definition import load_robot
from selfcal.sim.actual import (
    apply_errors,
    error_table,
    make_truth,
    marker_field_of,
    param_index,
    perturb,
    true_hand_eye,
)
from selfcal.sim.link_frames import nominal_camera_model
from selfcal.sim.markers import make_marker_field
from selfcal.sim.robot_mjcf import RigConfig, robot_spec
from selfcal.transforms import inv_pose, trans


@pytest.fixture(scope="module")
def paper():
    robot = load_robot("er4u-paper")
    return robot, nominal_camera_model(robot)


def test_perturb_touches_only_the_minimal_set_within_bounds(paper):
    _, nom = paper
    idx = minimal_indices(nom.joint_types)
    ang = param_is_angle(idx)
    t, r = 2e-3, 5e-4
    other = np.setdiff1d(np.arange(nom.params.size), idx)
    deltas = []
    for seed in range(400):
        a = perturb(nom, seed=seed, translation_m=t, rotation_rad=r)
        d = (a.params - nom.params).reshape(-1)
        assert np.all(d[other] == 0.0)
        assert np.all(np.abs(d[idx][ang]) <= r) and np.all(np.abs(d[idx][~ang]) <= t)
        np.testing.assert_array_equal(a.joint_offsets, nom.joint_offsets)
        deltas.append(d[idx] / np.where(ang, r, t))
    u = np.asarray(deltas)  # should be U(-1, 1): mean 0, std 1/sqrt(3), fills the interval
    assert np.abs(u.mean(axis=0)).max() < 0.2  # 400 samples: 4.5 sigma of the mean
    assert np.abs(u.std(axis=0) - 1 / np.sqrt(3)).max() < 0.07
    assert u.max() > 0.95 and u.min() < -0.95
    # independent across parameters
    c = np.corrcoef(u.T) - np.eye(idx.size)
    assert np.abs(c).max() < 0.2


def test_perturb_is_deterministic_and_validates(paper):
    _, nom = paper
    a = perturb(nom, seed=3, translation_m=1e-3, rotation_rad=1e-3)
    b = perturb(nom, seed=3, translation_m=1e-3, rotation_rad=1e-3)
    c = perturb(nom, seed=4, translation_m=1e-3, rotation_rad=1e-3)
    np.testing.assert_array_equal(a.params, b.params)
    assert not np.array_equal(a.params, c.params)
    z = perturb(nom, seed=3, translation_m=0.0, rotation_rad=0.0)
    np.testing.assert_array_equal(z.params, nom.params)
    with pytest.raises(ValueError, match="translation_m"):
        perturb(nom, seed=0, translation_m=-1e-3, rotation_rad=0.0)
    with pytest.raises(ValueError, match="rotation_rad"):
        perturb(nom, seed=0, translation_m=0.0, rotation_rad=float("nan"))


def test_apply_errors_explicit_table(paper):
    _, nom = paper
    a = apply_errors(nom, {"beta2": 1e-3, "lx1": -2e-4, "gamma5": 3e-4})
    d = a.params - nom.params
    assert d[2, 1] == pytest.approx(1e-3, abs=1e-15)
    assert d[1, 3] == pytest.approx(-2e-4, abs=1e-15)
    assert d[5, 2] == pytest.approx(3e-4, abs=1e-15)
    assert np.count_nonzero(d) == 3
    assert param_index("beta2", 5) == 13 and param_index("lz5", 5) == 35
    with pytest.raises(ValueError, match="unknown MCPC parameter"):
        apply_errors(nom, {"delta2": 1e-3})
    with pytest.raises(ValueError, match="frame in 0..5"):
        apply_errors(nom, {"beta6": 1e-3})
    with pytest.raises(ValueError, match="finite"):
        apply_errors(nom, {"beta2": float("inf")})


def test_beta_error_makes_parallel_axes_non_parallel(paper):
    """A beta on frame 2 tilts joint 3's axis against joint 2's by exactly that angle (DH cannot
    express this: it is why the paper uses MCPC)."""
    robot, nom = paper
    q = np.random.default_rng(0).uniform(robot.limits[:, 0], robot.limits[:, 1], (20, robot.n))
    for model, expect in ((nom, 0.0), (apply_errors(nom, {"beta2": 1.5e-3}), 1.5e-3)):
        F = fk_frames(model, q)
        cosang = np.einsum("mi,mi->m", F[:, 1, :3, 2], F[:, 2, :3, 2])
        np.testing.assert_allclose(np.arccos(np.clip(cosang, -1, 1)), expect, atol=1e-7)


def test_error_table_round_trip(paper):
    _, nom = paper
    a = perturb(nom, seed=9, translation_m=1e-3, rotation_rad=1e-3)
    table = error_table(nom, a)
    assert len(table) == minimal_indices(nom.joint_types).size == 26
    np.testing.assert_allclose(apply_errors(nom, table).params, a.params, atol=1e-16)


def test_true_hand_eye(paper):
    """Nominal: the TOML mount. Perturbed: the left camera seen from the flange site, as MuJoCo
    places them (mj_forward of the actual robot)."""
    robot, nom = paper
    np.testing.assert_allclose(true_hand_eye(robot, nom), robot.T_flange_cam, atol=1e-15)
    act = perturb(nom, seed=1, translation_m=2e-3, rotation_rad=2e-3)
    model = robot_spec(robot, act).compile()
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home
    mujoco.mj_forward(model, data)
    T_world_flange = np.eye(4)
    T_world_flange[:3, :3] = data.site("flange").xmat.reshape(3, 3)
    T_world_flange[:3, 3] = data.site("flange").xpos
    T_world_cam = fk_frames(act, robot.home)[0, -1]
    expect = inv_pose(T_world_flange) @ T_world_cam
    np.testing.assert_allclose(true_hand_eye(robot, act), expect, atol=1e-12)
    assert np.abs(expect - robot.T_flange_cam).max() > 1e-4  # the error is really there


def test_truth_json_round_trip(tmp_path, paper):
    robot, nom = paper
    act = perturb(nom, seed=2, translation_m=1e-3, rotation_rad=1e-3)
    rig = RigConfig(T_left_right=trans(np.array([0.061, 0.001, 0.0])))
    field = make_marker_field(n_markers=5, seed=3)
    truth = make_truth(robot, nom, act, rig, field, meta={"seed": 2, "translation_m": 1e-3})
    rng = np.random.default_rng(0)
    for k in range(3):
        q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1])
        T = fk_frames(act, q)[0, -1]
        truth = truth.with_frame(
            {
                "joints_rad": q,
                "joints_deg": np.degrees(q),
                "T_world_cam_left": T,
                "T_world_cam_right": T @ rig.T_left_right,
                "tool_tip_m": (T @ truth.T_cam_tip)[:3, 3],
            },
            frame_index=10 + k,
        )
    path = write_truth(tmp_path / "run" / "truth.json", truth)
    doc = json.loads(path.read_text())
    assert doc["format"] == TRUTH_FORMAT and doc["robot_model"] == "er4u-paper"
    assert doc["mcpc"]["units"] == ["rad", "rad", "rad", "m", "m", "m"]
    assert set(doc["mcpc"]["errors"]) == set(doc["mcpc"]["minimal_names"])
    back = read_truth(path)
    for attr in (
        "joint_offsets_rad",
        "nominal_params",
        "true_params",
        "T_left_right",
        "T_flange_cam",
        "T_flange_cam_nominal",
        "T_cam_tip",
    ):
        np.testing.assert_array_equal(getattr(back, attr), getattr(truth, attr), err_msg=attr)
    assert back.joint_names == robot.joint_names and back.joint_types == robot.joint_types
    assert back.intrinsics_left == rig.intrinsics and back.intrinsics_right == rig.right
    assert back.errors == truth.errors and back.meta == truth.meta
    np.testing.assert_array_equal(back.true_model.params, act.params)
    np.testing.assert_array_equal(marker_field_of(back).T_world_marker, field.T_world_marker)
    assert len(back.frames) == 3
    for a, b in zip(back.frames, truth.frames, strict=True):
        assert a.index == b.index and a.frame_index == b.frame_index
        for k in ("joints_rad", "T_world_cam_left", "T_world_cam_right", "tool_tip_m"):
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k))


def test_read_truth_rejects_other_files(tmp_path):
    p = tmp_path / "x.json"
    p.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(TruthFileError, match="not a"):
        read_truth(p)
    p.write_text(json.dumps({"format": TRUTH_FORMAT, "robot_model": "x"}))
    with pytest.raises(TruthFileError, match="missing key 'joints'"):
        read_truth(p)
