"""The convention-free nominal chain (selfcal.robot.chain) and its DH / modified-DH loaders.

Ground truth: the table rows multiplied out directly (``fk_nominal`` -> ``dh_frames``), and for the
KR 6 R900 the datasheet's dimensions added up by hand at the KUKA HOME posture.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from selfcal.kinematics.dh_table import dh_table
from selfcal.kinematics.forward import fk_frames, fk_nominal
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.chain import DHParams, chain_frames, dh_chain, dh_frames
from selfcal.robot.definition import (
    RobotDefinitionError,
    list_robots,
    load_robot,
    robot_files,
    with_dh,
)
from selfcal.transforms import make_pose, rot_x, rot_z, trans

DEG = np.pi / 180


def _q(robot, m, rng):
    return rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (m, robot.n))


@pytest.mark.parametrize("name", list_robots())
def test_nominal_mcpc_reproduces_the_description(name):
    """MCPC tool pose = the table's flange, and every MCPC joint frame lies on the table's joint
    axis, at 50 random postures (achieved 2.2e-16 m; tolerance 1e-14, a few dozen roundings)."""
    robot = load_robot(name)
    q = _q(robot, 50, np.random.default_rng(0))
    own = fk_nominal(robot, q)
    mcpc = fk_frames(nominal_mcpc(robot), q)
    assert np.abs(mcpc[:, -1] - own[:, -1]).max() < 1e-14
    chain = chain_frames(robot.chain, robot.joint_types, q)
    assert np.abs(chain[:, -1] - own[:, -1]).max() < 1e-14
    for k in range(robot.n):  # same axis: same z, origin offset along z
        assert np.abs(mcpc[:, k, :3, 2] - chain[:, k, :3, 2]).max() < 1e-14
        dp = mcpc[:, k, :3, 3] - chain[:, k, :3, 3]
        along = np.einsum("mi,mi->m", dp, chain[:, k, :3, 2])[:, None] * chain[:, k, :3, 2]
        assert np.abs(dp - along).max() < 1e-14


@settings(max_examples=examples(25), deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    prismatic=st.lists(st.booleans(), min_size=1, max_size=12),
    convention=st.sampled_from(["dh", "mdh"]),
)
def test_tables_multiply_out_like_their_formula(seed, prismatic, convention):
    """Random DH / MDH tables of 1..12 joints, prismatic or revolute: the chain G_0 Q_1 ... G_n
    equals the product of the textbook link transforms (tolerance 1e-13, achieved ~1e-15)."""
    rng = np.random.default_rng(seed)
    n = len(prismatic)
    types = tuple("prismatic" if p else "revolute" for p in prismatic)
    dh = DHParams(
        convention,
        rng.uniform(-np.pi, np.pi, n),
        rng.uniform(-0.5, 0.5, n),
        rng.uniform(-0.5, 0.5, n),
        rng.uniform(-np.pi, np.pi, n),
    )
    q = rng.uniform(-1, 1, (4, n))
    T = np.tile(np.eye(4), (4, 1, 1))
    for i in range(n):
        th = dh.offset[i] + (0.0 if prismatic[i] else q[:, i])
        d = dh.d[i] + (q[:, i] if prismatic[i] else 0.0)
        tz = trans(np.stack([0 * d, 0 * d, d], -1))
        th = np.broadcast_to(th, (4,))
        tx = trans(np.array([dh.a[i], 0.0, 0.0]))
        if convention == "dh":
            T = T @ rot_z(th) @ tz @ tx @ rot_x(dh.alpha[i])
        else:
            T = T @ rot_x(dh.alpha[i]) @ tx @ rot_z(th) @ tz
    flange = chain_frames(dh_chain(dh), types, q)[:, -1]
    assert np.abs(flange - T).max() < 1e-13


def test_kr6_home_matches_the_datasheet_dimensions():
    """KUKA HOME (0, -90, 90, 0, 0, 0) deg: wrist centre at (25 + 420, 0, 400 + 455 + 35) mm, the
    flange 80 mm further along a forward-pointing z axis, upper arm vertical."""
    robot = load_robot("kr6-r900")
    assert robot.convention == "mdh" and robot.n == 6
    F = fk_nominal(robot, np.radians([0, -90, 90, 0, 0, 0]))[0]
    np.testing.assert_allclose(F[2, :3, 3] * 1000, [25, 0, 400 + 455], atol=1e-9)  # axis 3
    np.testing.assert_allclose(F[3, :3, 3] * 1000, [25 + 420, 0, 890], atol=1e-9)  # wrist
    np.testing.assert_allclose(F[5, :3, 3] * 1000, [25 + 420 + 80, 0, 890], atol=1e-9)
    np.testing.assert_allclose(F[5, :3, 2], [1, 0, 0], atol=1e-12)
    # spherical wrist: axes 4, 5, 6 meet in the wrist centre at any posture
    q = _q(robot, 20, np.random.default_rng(1))
    W = fk_nominal(robot, q)
    assert np.abs(W[:, 4, :3, 3] - W[:, 3, :3, 3]).max() < 1e-12


def _variant(tmp_path, edit):
    text = (robot_files()["kr6-r900"]).read_text()
    p = tmp_path / "arm.toml"
    p.write_text(edit(text))
    return p


def test_unknown_convention_names_the_key(tmp_path):
    p = _variant(tmp_path, lambda t: t.replace('convention = "mdh"', 'convention = "craig"'))
    with pytest.raises(RobotDefinitionError, match="arm.toml: convention must be one of") as exc:
        load_robot(p)
    assert "mdh" in exc.value.fix


def _chain_file(tmp_path, n: int, prismatic: tuple[int, ...] = ()) -> Path:
    """A robot TOML of ``n`` joints (standard DH, no camera mount), the 0-based ``prismatic``."""
    rows = []
    for i in range(n):
        alpha = 90.0 if i % 2 else -90.0
        if i in prismatic:
            rows.append(f'[[joint]]\ntype = "prismatic"\nalpha_deg = {alpha}\na_mm = 0.0\n'
                        "d_mm = 100.0\nrange_mm = [0.0, 1500.0]\n")  # fmt: skip
        else:
            rows.append(f"[[joint]]\nalpha_deg = {alpha}\na_mm = {50 + 10 * i}.0\n"
                        f"d_mm = {20 * i}.0\nrange_deg = [-170.0, 170.0]\n")  # fmt: skip
    p = tmp_path / "arm.toml"
    p.write_text("\n".join(rows))
    return p


@pytest.mark.parametrize(("n", "prismatic"), [(1, ()), (2, ()), (12, (0,))])
def test_chains_of_1_to_12_joints_load_and_give_fk(tmp_path, n, prismatic):
    """A one-joint turntable, a two-axis positioner and a 11-axis arm on a linear track (12
    joints) load, and their flange is the product of the table's link transforms (before: refused
    outside 3 to 7 joints)."""
    robot = load_robot(_chain_file(tmp_path, n, prismatic))
    assert robot.n == n and robot.joint_types[0] == ("prismatic" if prismatic else "revolute")
    q = _q(robot, 5, np.random.default_rng(n))
    T = np.tile(np.eye(4), (5, 1, 1))
    for i in range(n):
        pr = i in prismatic
        th = np.broadcast_to(robot.dh.offset[i] + (0.0 if pr else q[:, i]), (5,))
        d = np.broadcast_to(robot.dh.d[i] + (q[:, i] if pr else 0.0), (5,))
        T = T @ rot_z(th) @ trans(np.stack([0 * d, 0 * d, d], -1))
        T = T @ trans(np.array([robot.dh.a[i], 0.0, 0.0])) @ rot_x(robot.dh.alpha[i])
    np.testing.assert_allclose(fk_nominal(robot, q)[:, -1], T, atol=1e-13)
    np.testing.assert_allclose(fk_frames(nominal_mcpc(robot), q)[:, -1], T, atol=1e-12)


@pytest.mark.parametrize(
    ("n", "match"),
    [(0, "needs at least one \\[\\[joint\\]\\] table"), (13, "13 joints; a robot needs 1 to 12")],
)
def test_joint_count_outside_1_to_12_is_refused(tmp_path, n, match):
    mount = "[camera_mount]\nxyz_mm = [0, 0, 0]\nx_axis = [1, 0, 0]\nz_axis = [0, 0, 1]\n"
    p = _chain_file(tmp_path, n)
    p.write_text(p.read_text() + mount)
    with pytest.raises(RobotDefinitionError, match="arm.toml: " + match):
        load_robot(p)


def _with_tilted_last_row(robot):
    """A standard-DH robot whose last row has a non-zero a and alpha (the flange off the last
    axis): exercises the shift between the standard and Craig's last frame."""
    dh = robot.dh
    return with_dh(
        robot, DHParams("dh", np.r_[dh.alpha[:-1], 0.3], np.r_[dh.a[:-1], 0.02], dh.d, dh.offset)
    )


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("name", [*list_robots(), "er4u-paper+tilted-flange"])
def test_dh_table_in_either_convention_reproduces_the_model(name, convention):
    """Every table robot, placed at a random pose with its lengths perturbed by +-1 mm (axes keep
    their directions, so parallel axes stay parallel): the table's own product, with its base and
    tool transforms, gives the model's tool pose (tolerance 1e-12 m, achieved ~1e-15); the nominal
    model in its own convention gives back the file's rows (1e-12)."""
    robot = load_robot(name.split("+")[0])
    if name.endswith("+tilted-flange"):
        robot = _with_tilted_last_row(robot)
    rng = np.random.default_rng(7)
    T_w = make_pose(Rotation.from_rotvec(rng.normal(size=3)).as_matrix(), rng.uniform(-1, 1, 3))
    model = nominal_mcpc(robot, T_w, robot.T_flange_cam)
    p = model.params.copy()
    p[:, 3:5] += rng.uniform(-1e-3, 1e-3, (robot.n + 1, 2)) * (p[:, 3:5] != 0)
    model = model.with_params(p)
    table, why = dh_table(model, robot, convention=convention)
    assert why is None and table.convention == convention
    q = _q(robot, 20, rng)
    F = dh_frames(table.params(), robot.joint_types, q)[:, -1]
    got = table.T_world_base @ F @ table.T_flange_tool
    assert np.abs(got - fk_frames(model, q)[:, -1]).max() < 1e-12
    if convention == robot.convention:
        own, _ = dh_table(nominal_mcpc(robot), robot)
        for k in ("alpha", "a", "d", "offset"):
            assert np.abs(getattr(own, k) - getattr(robot.dh, k)).max() < 1e-12, k


def test_camera_mount_is_optional_and_then_the_flange(tmp_path):
    row = "[[joint]]\nalpha_deg = 90.0\na_mm = 100.0\nd_mm = 0.0\nrange_deg = [-90.0, 90.0]\n"
    p = tmp_path / "arm.toml"
    p.write_text(row * 4)
    np.testing.assert_array_equal(load_robot(p).T_flange_cam, np.eye(4))
    p.write_text('camera_mount = "flange"\n' + row * 4)
    with pytest.raises(RobotDefinitionError, match="camera_mount must be a table"):
        load_robot(p)
