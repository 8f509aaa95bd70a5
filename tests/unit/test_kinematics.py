"""Kinematics acceptance tests: DH vs MCPC, identification Jacobian, gauge fixing, identifiability.

Ground truth is the DH table itself (``fk_nominal``), central finite differences, and chains of random
rigid transforms multiplied out directly. Tolerances are stated per test.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from selfcal.kinematics.forward import (
    fk_frames,
    fk_nominal,
    fk_tool,
    identification_jacobian,
    pose_error,
)
from selfcal.kinematics.mcpc import MCPCModel, gauge_fix, minimal_indices, nominal_mcpc
from selfcal.kinematics.tool_pose import tool_pose
from selfcal.robot.definition import RobotDefinitionError, list_robots, load_robot
from selfcal.transforms import make_pose, rot_z

ROBOTS = ("er4u-paper", "er4u-vendor")
DEG = np.pi / 180
SETTINGS = settings(
    max_examples=examples(40),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
)


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param)


def _robot(name: str):
    return load_robot(name)


def random_q(robot, rng: np.random.Generator, m: int) -> np.ndarray:
    """``m`` joint vectors drawn uniformly inside the joint ranges (rad)."""
    return rng.uniform(robot.limits[:, 0], robot.limits[:, 1], size=(m, robot.n))


def random_pose(rng: np.random.Generator, scale_m: float = 0.5) -> np.ndarray:
    """A random rigid transform: uniform rotation, translation up to ``scale_m`` per axis."""
    R = Rotation.random(random_state=rng).as_matrix()
    return make_pose(R, rng.uniform(-scale_m, scale_m, 3))


seeds = st.integers(min_value=0, max_value=2**32 - 1)


# --------------------------------------------------------------------------------------------
# DH and MCPC describe the same robot
# --------------------------------------------------------------------------------------------


def _check_same_robot(robot, model: MCPCModel, T_base: np.ndarray, T_tool: np.ndarray, q):
    """Tool frames equal (1e-12) and each MCPC link frame sits on the DH joint axis (1e-12)."""
    dh = T_base @ fk_nominal(robot, q)  # DH frames 1..n, in world
    mc = fk_frames(model, q)  # MCPC link frames F_1..F_n, then the tool
    np.testing.assert_allclose(mc[:, -1], dh[:, -1] @ T_tool, rtol=0, atol=1e-12)
    # Joint k's axis is the z-axis of DH frame k-1 (frame 0 = base).
    before = np.concatenate([np.broadcast_to(T_base, (len(q), 1, 4, 4)), dh[:, :-1]], axis=1)
    z_dh, o_dh = before[..., :3, 2], before[..., :3, 3]
    z_mc, o_mc = mc[:, :-1, :3, 2], mc[:, :-1, :3, 3]
    np.testing.assert_allclose(z_mc, z_dh, rtol=0, atol=1e-12)
    off_axis = np.cross(o_mc - o_dh, z_dh)
    np.testing.assert_allclose(off_axis, 0.0, atol=1e-12)


@SETTINGS
@given(seed=seeds, name=st.sampled_from(ROBOTS))
def test_dh_and_mcpc_agree(seed, name):
    robot = _robot(name)
    rng = np.random.default_rng(seed)
    q = random_q(robot, rng, 8)
    _check_same_robot(robot, nominal_mcpc(robot), np.eye(4), np.eye(4), q)


@SETTINGS
@given(seed=seeds, name=st.sampled_from(ROBOTS))
def test_dh_and_mcpc_agree_with_base_and_tool(seed, name):
    robot = _robot(name)
    rng = np.random.default_rng(seed)
    q = random_q(robot, rng, 8)
    Tb, Tt = random_pose(rng, 1.0), random_pose(rng, 0.2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a gimbal-lock warning from the Euler split would fail
        _check_same_robot(robot, nominal_mcpc(robot, Tb, Tt), Tb, Tt, q)
        _check_same_robot(robot, nominal_mcpc(robot).with_base(Tb).with_tool(Tt), Tb, Tt, q)
        _check_same_robot(robot, nominal_mcpc(robot).with_tool(Tt).with_base(Tb), Tb, Tt, q)


def test_camera_tool_matches_dh(robot):
    q = random_q(robot, np.random.default_rng(1), 20)
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    np.testing.assert_allclose(
        fk_tool(model, q), fk_nominal(robot, q)[:, -1] @ robot.T_flange_cam, rtol=0, atol=1e-12
    )


# --------------------------------------------------------------------------------------------
# Identification Jacobian vs finite differences of pose_error
# --------------------------------------------------------------------------------------------


def _perturbed(model: MCPCModel, rng: np.random.Generator) -> MCPCModel:
    """Every parameter moved by up to 0.5 deg (angles) or 1 mm (lengths)."""
    d = np.empty_like(model.params)
    d[:, :3] = rng.uniform(-0.5, 0.5, (model.n + 1, 3)) * DEG
    d[:, 3:] = rng.uniform(-1e-3, 1e-3, (model.n + 1, 3))
    return model.with_params(model.params + d)


@settings(max_examples=examples(25), deadline=None, derandomize=True)
@given(seed=seeds, name=st.sampled_from(ROBOTS), camera=st.booleans())
def test_identification_jacobian_matches_finite_differences(seed, name, camera):
    robot = _robot(name)
    rng = np.random.default_rng(seed)
    model = nominal_mcpc(robot)
    if camera:
        model = model.with_tool(robot.T_flange_cam)
    model = _perturbed(model, rng)
    q = random_q(robot, rng, 3)
    J = identification_jacobian(model, q)  # (m, 6, P)
    T0 = fk_tool(model, q)
    flat = model.params.reshape(-1)
    h = 1e-6
    J_fd = np.empty_like(J)
    for k in range(flat.size):
        e = np.zeros_like(flat)
        e[k] = h
        yp = pose_error(T0, fk_tool(model.with_params(flat + e), q))
        ym = pose_error(T0, fk_tool(model.with_params(flat - e), q))
        J_fd[:, :, k] = (yp - ym) / (2 * h)
    # Relative error per configuration and column (columns are O(1): m/rad, rad/rad, m/m).
    err = np.linalg.norm(J - J_fd, axis=1)
    scale = np.maximum(np.linalg.norm(J_fd, axis=1), 1e-3)
    assert np.max(err / scale) < 1e-6, f"worst relative error {np.max(err / scale):.2e}"


# --------------------------------------------------------------------------------------------
# Gauge fixing and identifiability
# --------------------------------------------------------------------------------------------


@SETTINGS
@given(seed=seeds, prismatic=st.lists(st.booleans(), min_size=5, max_size=5))
def test_gauge_fix_round_trip(seed, prismatic):
    """Random rigid G_0..G_n: the gauge-fixed params reproduce G_0 Q_1 G_1 ... Q_n G_n exactly."""
    rng = np.random.default_rng(seed)
    types = tuple("prismatic" if p else "revolute" for p in prismatic)
    n = len(types)
    G = [random_pose(rng, 0.4) for _ in range(n + 1)]
    params, offsets = gauge_fix(G, types)
    model = MCPCModel(params, types, offsets)
    # Gauge: gamma_i = lz_i = 0 before every joint; lx_i = ly_i = 0 before a prismatic one.
    assert np.all(params[:n, 2] == 0) and np.all(params[:n, 5] == 0)
    for i, t in enumerate(types):
        if t == "prismatic":
            assert np.all(params[i, 3:5] == 0)
    q = rng.uniform(-np.pi, np.pi, (6, n))
    q[:, np.array(prismatic)] = rng.uniform(-0.3, 0.3, (6, int(np.sum(prismatic))))
    T = np.broadcast_to(G[0], (len(q), 4, 4))
    for k in range(n):
        if types[k] == "revolute":
            Q = rot_z(q[:, k])
        else:
            Q = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
            Q[:, 2, 3] = q[:, k]
        T = T @ Q @ G[k + 1]
    np.testing.assert_allclose(fk_tool(model, q), T, rtol=0, atol=1e-12)


def test_minimal_set_has_26_parameters(robot):
    idx = minimal_indices(robot.joint_types)
    assert idx.size == 26 == 4 * robot.n + 6
    assert len(set(idx.tolist())) == 26


@pytest.mark.parametrize("camera", [False, True])
def test_minimal_jacobian_has_full_rank(robot, camera):
    """26 minimal columns over 30 random postures: rank 26; all 36 columns: still rank 26."""
    model = nominal_mcpc(robot)
    if camera:
        model = model.with_tool(robot.T_flange_cam)
    q = random_q(robot, np.random.default_rng(7), 30)
    J = identification_jacobian(model, q).reshape(-1, 6 * (robot.n + 1))
    idx = minimal_indices(robot.joint_types)
    s = np.linalg.svd(J[:, idx], compute_uv=False)
    assert s[-1] / s[0] > 1e-6, f"minimal Jacobian nearly singular: cond = {s[0] / s[-1]:.3g}"
    assert np.linalg.matrix_rank(J[:, idx]) == 26
    # The 10 gauge columns add nothing: the full Jacobian has the same rank.
    assert np.linalg.matrix_rank(J) == 26


# --------------------------------------------------------------------------------------------
# Vendor geometry and bad input
# --------------------------------------------------------------------------------------------


def test_vendor_home_pose():
    """Vendor toolbox (acl-notes.md): home (0, 120.28, -95.02, -88.81, 0) deg -> TCP (169.1, 0,
    504.2) mm, pitch -63.5 deg. Tolerances: 0.5 mm, 0.1 deg (the sources print one decimal)."""
    robot = load_robot("er4u-vendor")
    q = np.array([0.0, 120.28, -95.02, -88.81, 0.0]) * DEG
    np.testing.assert_allclose(robot.home, q, atol=1e-12)
    T = fk_tool(nominal_mcpc(robot), q)[0]
    xyz, pitch, roll = tool_pose(T)
    np.testing.assert_allclose(xyz * 1000, [169.1, 0.0, 504.2], atol=0.5)
    assert abs(np.degrees(pitch) - (-63.5)) < 0.1
    assert abs(np.degrees(roll)) < 1e-9


def test_unknown_model_lists_known_ones():
    with pytest.raises(RobotDefinitionError) as exc:
        load_robot("er4u-nonexistent")
    msg = str(exc.value)
    assert "er4u-nonexistent" in msg
    for name in list_robots():
        assert name in msg
    assert set(ROBOTS) <= set(list_robots())


def test_out_of_range_joint_names_joint_and_range():
    robot = load_robot("er4u-paper")
    q = robot.home.copy()
    q[1] = 140 * DEG
    with pytest.raises(
        ValueError, match=r"joint 2 \(shoulder\) = 140\.000 deg .*\[-35\.00, 130\.00\]"
    ):
        robot.check_joints(q)
    with pytest.raises(ValueError, match="expected 5 joint values"):
        robot.check_joints(q[:4])


def test_fk_rejects_wrong_joint_count(robot):
    with pytest.raises(ValueError, match=r"shape \(m, 5\)"):
        fk_frames(nominal_mcpc(robot), np.zeros((3, 4)))
