"""Deployable exports of a calibration: base-frame chain, MJCF, URDF and TOML reproduce the model.

Ground truth here is the calibrated model itself (selfcal.kinematics.forward.fk_frames of the deployed
chain): each export must reproduce its link frames and tool tip to 1e-9 m for random in-range
joint readings. The base-frame construction is checked against the nominal robot, whose base frame
and tool tip are known exactly (the DH frame 0 and the last DH frame).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.cli.deploy import register
from selfcal.config.scenario import load_scenario
from selfcal.export.deploy import (
    FIXED_BY_BASE_FRAME,
    DeployError,
    as_deployed,
    deploy,
    deploy_chain,
    nominal_deployed_params,
)
from selfcal.export.robot_toml import from_toml, to_toml
from selfcal.export.urdf import to_urdf
from selfcal.io.calibration import read_calibration
from selfcal.kinematics.forward import fk_frames, fk_nominal
from selfcal.kinematics.mcpc import minimal_indices, param_names
from selfcal.pipeline.run import run_acquire, run_calibrate
from selfcal.robot.chain import chain_frames
from selfcal.robot.definition import load_robot, models_dir
from selfcal.robot.urdf import urdf_chain
from selfcal.sim.actual import perturb
from selfcal.sim.export_mjcf import calibrated_mjcf
from selfcal.sim.link_frames import nominal_camera_model
from selfcal.transforms import make_pose, rot_x, rot_z, trans

TOL_M = 1e-9
ROBOT = load_robot("er4u-paper")


@pytest.fixture(scope="module")
def calibration(default_analytic_15):
    """A real calibration (folder, result read back from calibration.json) from a small analytic
    scenario (15 postures), the one the main job's tests report (tests/conftest.py, built once per
    test run). Read only: the exports are written elsewhere."""
    out, _ = default_analytic_15
    return out, read_calibration(out)


@pytest.fixture(scope="module")
def deployed(calibration):
    return deploy(calibration[1], source="test")


def random_q(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (n, 5))


# ----------------------------------------------------------------------------- base frame


def test_nominal_robot_deploys_to_the_nominal_dh_chain_wherever_it_is_placed():
    """The base frame of the nominal arm is its DH frame 0 and the tool its last DH frame, for any
    placement of the arm in the source model's world (the construction sees only the axes)."""
    q = random_q(50)
    T_place = make_pose(Rotation.from_rotvec([0.3, -1.2, 2.0]).as_matrix(), [0.4, -0.1, 1.3])
    for T in (np.eye(4), T_place):
        dep = deploy_chain(nominal_camera_model(ROBOT).with_base(T), ROBOT)
        assert np.abs(dep.T_world_base - T).max() < 1e-12
        assert np.abs(dep.model.params - nominal_deployed_params(ROBOT)).max() < 1e-12
        assert np.abs(dep.tool_tip(q) - fk_nominal(ROBOT, q)[:, -1]).max() < 1e-12
        # link frame k sits on joint k's axis: the origin of DH frame k - 1 lies on it too
        F = dep.frames(q)[:, :-1]
        dh_prev = np.concatenate(
            [np.tile(np.eye(4), (len(q), 1, 1, 1)), fk_nominal(ROBOT, q)[:, :-1]], 1
        )
        assert np.abs(F[..., :3, 2] - dh_prev[..., :3, 2]).max() < 1e-12
        off = dh_prev[..., :3, 3] - F[..., :3, 3]
        assert np.abs(np.cross(off, F[..., :3, 2])).max() < 1e-12
        # the camera chain shares the link frames and ends at the nominal camera
        cam = fk_frames(dep.camera_model(), q)
        assert np.abs(cam[:, :-1] - dep.frames(q)[:, :-1]).max() < 1e-12
        assert np.abs(cam[:, -1] - fk_nominal(ROBOT, q)[:, -1] @ ROBOT.T_flange_cam).max() < 1e-12


def test_deployed_chain_is_the_same_physical_robot(deployed, calibration):
    """Placed back with T_world_base, the deployed chain gives the calibration's camera poses."""
    q = random_q(30, seed=1)
    est = calibration[1].model
    cam_world = deployed.T_world_base @ fk_frames(deployed.camera_model(), q)[:, -1]
    assert np.abs(cam_world - fk_frames(est, q)[:, -1]).max() < 1e-12
    # and independent of the world the identified model happens to live in
    T = make_pose(rot_x(0.7)[:3, :3], [0.2, 0.3, -0.5])
    again = deploy_chain(est.with_base(T), ROBOT)
    assert np.abs(again.tool_tip(q) - deployed.tool_tip(q)).max() < 1e-12


def test_parameters_fixed_by_the_base_frame(deployed):
    idx = dict(
        zip(param_names(minimal_indices(ROBOT.joint_types)), minimal_indices(ROBOT.joint_types))
    )
    p = deployed.model.params.reshape(-1)
    for name in ("alpha0", "beta0", "lx0", "ly0", "beta1"):
        assert abs(p[idx[name]]) < 1e-12, name
    assert abs(p[idx["ly1"]] - ROBOT.dh.d[0] * np.sin(p[idx["alpha1"]])) < 1e-12
    assert set(FIXED_BY_BASE_FRAME) == {"alpha0", "beta0", "lx0", "ly0", "beta1", "ly1"}
    # the calibrated arm differs from the nominal one (else the tests below prove little)
    assert np.abs(deployed.model.params - nominal_deployed_params(ROBOT)).max() > 1e-4


# ----------------------------------------------------------------------------- MJCF


def _mj_frames(model: mujoco.MjModel, q: np.ndarray) -> np.ndarray:
    """Bodies link1..link<n>, site tool_tip, cameras cam_left/right as (m, n + 3, 4, 4) world
    poses."""
    n = model.njnt
    data = mujoco.MjData(model)
    out = np.tile(np.eye(4), (len(q), n + 3, 1, 1))
    for i, qi in enumerate(q):
        data.qpos[:] = qi
        mujoco.mj_forward(model, data)  # mj_kinematics alone leaves the cameras unset
        for k in range(n):
            b = model.body(f"link{k + 1}").id
            out[i, k, :3, :3] = data.xmat[b].reshape(3, 3)
            out[i, k, :3, 3] = data.xpos[b]
        s = model.site("tool_tip").id
        out[i, n, :3, :3] = data.site_xmat[s].reshape(3, 3)
        out[i, n, :3, 3] = data.site_xpos[s]
        for j, name in enumerate(("cam_left", "cam_right")):
            c = model.camera(name).id
            # MuJoCo cameras look down -z, y up: back to OpenCV (x right, y down, z forward)
            out[i, n + 1 + j, :3, :3] = data.cam_xmat[c].reshape(3, 3) @ np.diag([1.0, -1.0, -1.0])
            out[i, n + 1 + j, :3, 3] = data.cam_xpos[c]
    return out


def _mjcf_errors(dep, robot, q) -> tuple[float, float]:
    """(position m, rotation-entry) worst deviation of the exported MJCF from ``dep``."""
    model = mujoco.MjModel.from_xml_string(calibrated_mjcf(dep, robot))
    n = dep.n
    got = _mj_frames(model, q)
    want = dep.frames(q)  # link frames and tool tip
    cam = fk_frames(dep.camera_model(), q)[:, -1]
    pos_err = max(
        np.abs(got[:, : n + 1, :3, 3] - want[:, :, :3, 3]).max(),
        np.abs(got[:, n + 1, :3, 3] - cam[:, :3, 3]).max(),
        np.abs(got[:, n + 2] - cam @ dep.T_left_right).max(),
    )
    rot_err = max(
        np.abs(got[:, : n + 1, :3, :3] - want[:, :, :3, :3]).max(),
        np.abs(got[:, n + 1, :3, :3] - cam[:, :3, :3]).max(),
    )
    return float(pos_err), float(rot_err)


def test_mjcf_reproduces_calibrated_frames(deployed):
    pos_err, rot_err = _mjcf_errors(deployed, None, random_q(100, seed=2))
    print(
        f"MJCF vs calibrated model, 100 postures: position {pos_err:.2e} m, rotation {rot_err:.2e}"
    )
    assert pos_err < TOL_M and rot_err < 1e-9
    # calibrated intrinsics carried into the camera
    model = mujoco.MjModel.from_xml_string(calibrated_mjcf(deployed))
    c = model.camera("cam_left").id
    assert np.allclose(model.cam_intrinsic[c][:2], [deployed.intrinsics.fx, deployed.intrinsics.fy])


def test_mjcf_matches_the_nominal_file_names_and_nominal_geometry():
    """Same element names as models/scorbot_er4u/er4u-paper.xml (drop-in), and for the nominal
    chain the same body frames as that file."""
    original = mujoco.MjModel.from_xml_path(str(models_dir() / "scorbot_er4u" / "er4u-paper.xml"))
    nominal = deploy_chain(nominal_camera_model(ROBOT), ROBOT)
    exported = mujoco.MjModel.from_xml_string(calibrated_mjcf(nominal, ROBOT))

    def names(m, kind, count):
        return [getattr(m, kind)(i).name for i in range(count)]

    for kind, attr in (("body", "nbody"), ("joint", "njnt"), ("site", "nsite")):
        assert names(exported, kind, getattr(exported, attr)) == names(
            original, kind, getattr(original, attr)
        )
    assert names(exported, "camera", exported.ncam) == names(original, "camera", original.ncam)
    assert names(exported, "actuator", exported.nu) == names(original, "actuator", original.nu)
    assert exported.ngeom == original.ngeom
    assert np.abs(exported.body_pos - original.body_pos).max() < 1e-12
    assert np.abs(np.abs((exported.body_quat * original.body_quat).sum(1)) - 1).max() < 1e-12
    assert np.abs(exported.site_pos - original.site_pos).max() < 1e-12


# ----------------------------------------------------------------------------- URDF


def _origin(el: ET.Element) -> np.ndarray:
    o = el.find("origin")
    xyz = [float(v) for v in o.get("xyz").split()]
    rpy = [float(v) for v in o.get("rpy").split()]
    return make_pose(Rotation.from_euler("xyz", rpy).as_matrix(), xyz)  # R = Rz Ry Rx (URDF)


def _urdf_errors(dep, q) -> float:
    """Worst deviation (m / rotation entries) of the exported URDF's link frames, tool tip and
    left camera from ``dep``, multiplying out its joint origins (revolute joints)."""
    root = ET.fromstring(to_urdf(dep))
    joints = {j.get("name"): j for j in root.findall("joint")}
    movable = [joints[name] for name in dep.joint_names]
    want = dep.frames(q)
    cam = fk_frames(dep.camera_model(), q)[:, -1]
    worst = 0.0
    for i in range(len(q)):
        T = np.eye(4)
        for k, j in enumerate(movable):
            T = T @ _origin(j) @ rot_z(q[i, k])
            worst = max(worst, np.abs(T - want[i, k]).max())
        tip = T @ _origin(joints["tool_tip_joint"])
        cam_left = T @ _origin(joints["cam_left_joint"])
        worst = max(worst, np.abs(tip - want[i, -1]).max(), np.abs(cam_left - cam[i]).max())
    return float(worst)


def test_urdf_chain_reproduces_tool_tip(deployed):
    root = ET.fromstring(to_urdf(deployed))
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {lk.get("name") for lk in root.findall("link")}
    assert links == {
        "base_link",
        *(f"link{k}" for k in range(1, 6)),
        "tool_tip",
        "cam_left",
        "cam_right",
    }
    for k, name in enumerate(ROBOT.joint_names):
        j = joints[name]
        assert j.get("type") == "revolute"
        assert j.find("parent").get("link") == ("base_link" if k == 0 else f"link{k}")
        assert j.find("child").get("link") == f"link{k + 1}"
        assert j.find("axis").get("xyz") == "0 0 1"
        lim = j.find("limit")
        assert np.allclose(
            [float(lim.get("lower")), float(lim.get("upper"))], ROBOT.limits[k], 0, 1e-15
        )
    worst = _urdf_errors(deployed, random_q(100, seed=3))
    print(f"URDF chain vs calibrated model, 100 postures: {worst:.2e} (m / rotation entries)")
    assert worst < TOL_M


def test_a_single_camera_is_not_called_left(deployed, calibration):
    """A calibration of one camera (the rig all NaN in calibration.json, as a one-camera field
    calibration writes it) deploys (it raised "rig.T_left_right_m must be a finite 4x4
    transform") and its URDF names the camera's optical frame camera_optical_frame, not
    cam_left (new user's trip, session 25); the pair keeps cam_left / cam_right, and a bag's
    frame_id and /tf_static name the same links (selfcal/ros/bag_chain.py)."""
    from selfcal.io.calibration_blocks import Rig
    from selfcal.ros.bag_chain import camera_frames, static_edges

    one = dataclasses.replace(calibration[1], rig=Rig(np.full((4, 4), np.nan)))
    mono = deploy(one, source="test")
    assert mono.T_left_right is None
    root = ET.fromstring(to_urdf(mono))
    links = {lk.get("name") for lk in root.findall("link")}
    joints = {j.get("name"): j for j in root.findall("joint")}
    assert "camera_optical_frame" in links and not links & {"cam_left", "cam_right"}
    cam = joints["camera_optical_frame_joint"]
    assert cam.find("child").get("link") == "camera_optical_frame"
    np.testing.assert_allclose(_origin(cam), _origin(joints["tool_tip_joint"]) @ mono.T_tip_cam,
                               atol=1e-12)  # fmt: skip
    assert camera_frames(("cam0",)) == {"cam0": "camera_optical_frame"}
    assert {e[1] for e in static_edges(mono, ("cam0",))} == {"tool_tip", "camera_optical_frame"}
    assert camera_frames(("left", "right", "c")) == {"left": "cam_left", "right": "cam_right",
                                                     "c": "c"}  # fmt: skip
    pair = {e[:2] for e in static_edges(deployed, ("left", "right"))}
    assert ("cam_left", "cam_right") in pair
    # a bag's nominal URDF of a stereo dataset (no rig in the nominal chain) names cam_left
    stereo = ET.fromstring(to_urdf(mono, calibrated=False, cameras=2))
    assert "cam_left" in {lk.get("name") for lk in stereo.findall("link")}


# ----------------------------------------------------------------------------- TOML


def test_toml_round_trips_to_the_same_model(deployed):
    text = to_toml(deployed, ROBOT)
    back = from_toml(text)
    q = random_q(100, seed=4)
    assert back.robot_name == ROBOT.name and back.joint_names == tuple(ROBOT.joint_names)
    assert np.abs(back.model.params - deployed.model.params).max() < 1e-14
    assert np.abs(back.model.joint_offsets - deployed.model.joint_offsets).max() < 1e-15
    assert np.abs(back.tool_tip(q) - deployed.tool_tip(q)).max() < 1e-12
    assert np.abs(back.T_tip_cam - deployed.T_tip_cam).max() < 1e-12
    assert np.abs(back.limits - deployed.limits).max() < 1e-12
    assert back.intrinsics == deployed.intrinsics
    # std: every estimated parameter not fixed by the frame keeps its calibration.json value
    assert set(back.std) == set(deployed.std) - set(FIXED_BY_BASE_FRAME)
    for k, v in back.std.items():
        assert v == pytest.approx(deployed.std[k], rel=1e-12)
    # the perturbed arm's parallel axes have no DH table: the file says so instead
    assert "no DH table" in text and "parallel" in text


def test_toml_keeps_the_right_cameras_own_intrinsics(deployed):
    """A rig whose cameras have their own intrinsics (#12): [camera.right] holds the right's and
    reads back; a shared camera's file has none (and says "both cameras")."""
    from selfcal.camera import Intrinsics

    assert "[camera.right]" not in to_toml(deployed, ROBOT) and deployed.intrinsics_right is None
    right = Intrinsics(812.25, 1.004, 310.5, 247.0, 640, 480)
    own = dataclasses.replace(deployed, intrinsics_right=right)
    text = to_toml(own, ROBOT)
    assert "[camera.right]" in text and "both cameras" not in text
    back = from_toml(text)
    assert back.intrinsics_right == right and back.intrinsics == deployed.intrinsics


def test_toml_dh_table_of_the_nominal_robot():
    """Where a DH table exists it is in the file and reproduces the tool tip."""
    import tomllib

    nominal = deploy_chain(nominal_camera_model(ROBOT), ROBOT)
    d = tomllib.loads(to_toml(nominal, ROBOT))
    rows = d["dh"]["rows"]
    assert np.allclose([r["a_mm"] for r in rows], ROBOT.dh.a * 1000, atol=1e-9)
    assert np.allclose([r["d_mm"] for r in rows], ROBOT.dh.d * 1000, atol=1e-9)
    assert np.allclose([r["alpha_deg"] for r in rows], np.degrees(ROBOT.dh.alpha), atol=1e-9)
    q = random_q(20, seed=5)
    ft = d["dh"]["T_flange_tool"]
    T_ft = make_pose(np.array(ft["R"]), np.array(ft["xyz_mm"]) / 1000)
    for qi, want in zip(q, nominal.tool_tip(q)):
        T = np.eye(4)
        for r, qk in zip(rows, qi):
            T = (
                T
                @ rot_z(qk + np.radians(r["theta_offset_deg"]))
                @ trans([r["a_mm"] / 1000, 0, r["d_mm"] / 1000])
                @ rot_x(np.radians(r["alpha_deg"]))
            )
        assert np.abs(T @ T_ft - want).max() < TOL_M


def test_perturbed_arm_with_dh_table_round_trips():
    """An arm perturbed off the nominal without parallel-axis trouble still round-trips exactly."""
    model = perturb(nominal_camera_model(ROBOT), seed=3, translation_m=1e-3, rotation_rad=0.0)
    dep = deploy_chain(model, ROBOT)
    back = from_toml(to_toml(dep, ROBOT))
    q = random_q(20, seed=6)
    assert np.abs(back.tool_tip(q) - dep.tool_tip(q)).max() < 1e-12


def test_bad_inputs_name_the_problem(tmp_path):
    with pytest.raises(DeployError, match="CalibrationResult"):
        as_deployed({"format": "something else"})
    with pytest.raises(DeployError, match="format"):
        from_toml('format = "nope"\n')
    with pytest.raises(DeployError, match="not valid TOML"):
        from_toml("= =")
    other = dataclasses.replace(ROBOT, joint_types=("revolute",) * 4 + ("prismatic",))
    with pytest.raises(DeployError, match="do not match"):
        deploy_chain(nominal_camera_model(ROBOT), other)


# ----------------------------------------------------------------------------- CLI


def _parser():
    p = argparse.ArgumentParser(prog="selfcal")
    sub = p.add_subparsers(dest="command", required=True)
    register(sub)
    return p


@pytest.mark.parametrize("fmt", ["mjcf", "urdf", "toml"])
def test_cli_export(calibration, tmp_path, capsys, fmt):
    root, _ = calibration
    out = tmp_path / f"robot.{ {'mjcf': 'xml', 'urdf': 'urdf', 'toml': 'toml'}[fmt] }"
    args = _parser().parse_args(["export", str(root), "--format", fmt, "--out", str(out)])
    assert args.func(args) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == fmt and info["out"] == str(out)
    dep = deploy(read_calibration(root))
    q = random_q(5, seed=7)
    if fmt == "mjcf":
        got = _mj_frames(mujoco.MjModel.from_xml_path(str(out)), q)[:, 5]
    elif fmt == "toml":
        got = from_toml(out.read_text()).tool_tip(q)
    else:
        root_el = ET.fromstring(out.read_text())
        js = {j.get("name"): j for j in root_el.findall("joint")}
        got = []
        for qi in q:
            T = np.eye(4)
            for name, qk in zip(ROBOT.joint_names, qi):
                T = T @ _origin(js[name]) @ rot_z(qk)
            got.append(T @ _origin(js["tool_tip_joint"]))
        got = np.array(got)
    assert np.abs(got[:, :3, 3] - dep.tool_tip(q)[:, :3, 3]).max() < TOL_M


def test_cli_export_errors(tmp_path):
    from selfcal.cli.main import CliError

    p = _parser()
    args = p.parse_args(["export", str(tmp_path), "--format", "mjcf", "--out",
                         str(tmp_path / "x.xml")])  # fmt: skip
    with pytest.raises(CliError, match="calibration.json"):
        args.func(args)
    for name in ("x.xml", "x.bin"):  # a suffix never chooses the format
        args = p.parse_args(["export", str(tmp_path), "--out", str(tmp_path / name)])
        with pytest.raises(CliError, match="give --format"):
            args.func(args)


# ----------------------------------------------------------------------------- any arm

ARMS = ["kr6-r900", str(models_dir().parent / "tests" / "data" / "kr6_urdf.toml")]
"""The 6-axis arm in modified DH and the same arm from a URDF fixture."""


def _placed(robot, rotation_rad: float, seed: int):
    """The nominal camera chain of ``robot`` with every shape parameter perturbed (+-1 mm, and
    +-``rotation_rad``), placed at a random pose: a stand-in for an identified model."""
    model = perturb(
        nominal_camera_model(robot), seed=seed, translation_m=1e-3, rotation_rad=rotation_rad
    )
    rng = np.random.default_rng(seed)
    T = make_pose(Rotation.from_rotvec(rng.normal(size=3)).as_matrix(), rng.uniform(-1, 1, 3))
    return model.with_base(T)


def _arm_q(robot, m: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (m, robot.n))


@pytest.mark.parametrize("name", ARMS, ids=["mdh", "urdf"])
def test_any_arm_nominal_deploys_to_its_own_base_and_flange(name):
    """The base frame of the nominal arm is its own base frame and the tool tip its flange, for
    any placement (1e-12; achieved ~1e-15)."""
    robot = load_robot(name)
    q = _arm_q(robot, 50, 1)
    T_place = make_pose(Rotation.from_rotvec([0.3, -1.2, 2.0]).as_matrix(), [0.4, -0.1, 1.3])
    for T in (np.eye(4), T_place):
        dep = deploy_chain(nominal_camera_model(robot).with_base(T), robot)
        assert np.abs(dep.T_world_base - T).max() < 1e-12
        assert np.abs(dep.tool_tip(q) - fk_nominal(robot, q)[:, -1]).max() < 1e-12


@pytest.mark.parametrize("name", ARMS, ids=["mdh", "urdf"])
def test_any_arm_exports_reproduce_the_calibrated_frames(name, tmp_path):
    """A perturbed 6-axis arm: deployed chain, MJCF, URDF (also read back through yourdfpy as a
    robot) and TOML reproduce its frames at 50 random postures (1e-9 m; achieved ~1e-15)."""
    robot = load_robot(name)
    model = _placed(robot, 1e-3, seed=4)
    dep = dataclasses.replace(deploy_chain(model, robot), T_left_right=trans([0.06, 0, 0]))
    q = _arm_q(robot, 50, 2)
    cam = dep.T_world_base @ fk_frames(dep.camera_model(), q)[:, -1]
    assert np.abs(cam - fk_frames(model, q)[:, -1]).max() < 1e-12
    pos_err, rot_err = _mjcf_errors(dep, robot, q)
    assert pos_err < TOL_M and rot_err < 1e-9
    assert _urdf_errors(dep, q) < TOL_M
    path = tmp_path / "calibrated.urdf"
    path.write_text(to_urdf(dep))
    (tmp_path / "calibrated.toml").write_text(
        '[urdf]\nfile = "calibrated.urdf"\nbase_link = "base_link"\ntool_link = "tool_tip"\n'
        "[camera_mount]\nxyz_mm = [0, 0, 0]\nx_axis = [1, 0, 0]\nz_axis = [0, 0, 1]\n"
    )
    again = load_robot(tmp_path / "calibrated.toml")
    assert np.abs(fk_nominal(again, q)[:, -1] - dep.tool_tip(q)).max() < TOL_M
    back = from_toml(to_toml(dep, robot))
    assert np.abs(back.tool_tip(q) - dep.tool_tip(q)).max() < 1e-12


def _craig(table: dict, q: np.ndarray) -> np.ndarray:
    """Tool tips from an exported modified-DH [dh] table, multiplied out row by row."""

    def pose(t):
        return make_pose(np.array(t["R"]), np.array(t["xyz_mm"]) / 1000)

    out = []
    for qi in q:
        T = pose(table["T_world_base"])
        for r, qk in zip(table["rows"], qi):
            T = (
                T
                @ rot_x(np.radians(r["alpha_deg"]))
                @ trans([r["a_mm"] / 1000, 0, 0])
                @ rot_z(qk + np.radians(r["theta_offset_deg"]))
                @ trans([0, 0, r["d_mm"] / 1000])
            )
        out.append(T @ pose(table["T_flange_tool"]))
    return np.array(out)


def test_modified_dh_table_of_the_industrial_arm():
    """The KR 6 R900 exports its table in its own convention (modified DH): the nominal arm gives
    back its file's rows, and an arm perturbed without tilting its parallel axes 2, 3 a table whose
    Craig product reproduces the tool tip (1e-9 m; achieved ~1e-15). Tilted axes: no table, and the
    file says why."""
    import tomllib

    robot = load_robot("kr6-r900")
    q = _arm_q(robot, 20, 3)
    nominal = deploy_chain(nominal_camera_model(robot), robot)
    d = tomllib.loads(to_toml(nominal, robot))["dh"]
    assert d["convention"] == "mdh"
    rows = d["rows"]
    assert np.allclose([r["a_mm"] for r in rows], robot.dh.a * 1000, atol=1e-9)
    assert np.allclose([r["d_mm"] for r in rows], robot.dh.d * 1000, atol=1e-9)
    assert np.allclose([r["alpha_deg"] for r in rows], np.degrees(robot.dh.alpha), atol=1e-9)
    assert np.allclose(
        [r["theta_offset_deg"] for r in rows], np.degrees(robot.dh.offset), atol=1e-9
    )
    assert np.abs(_craig(d, q) - nominal.tool_tip(q)).max() < TOL_M
    dep = deploy_chain(_placed(robot, 0.0, seed=5), robot)
    d = tomllib.loads(to_toml(dep, robot))["dh"]
    assert "rows" in d and np.abs(_craig(d, q) - dep.tool_tip(q)).max() < TOL_M
    tilted = deploy_chain(_placed(robot, 1e-3, seed=5), robot)
    assert "no DH table" in to_toml(tilted, robot) and "joints 2 and 3" in to_toml(tilted, robot)


def test_urdf_robot_has_no_dh_table():
    robot = load_robot(ARMS[1])
    text = to_toml(deploy_chain(nominal_camera_model(robot), robot), robot)
    assert "no DH table: the robot is described by a URDF" in text


@pytest.mark.slow
def test_industrial_arm_calibration_exports_through_the_cli(tmp_path, capsys):
    """A real (analytic, 15-posture) calibration of the KR 6 R900: `selfcal export` writes MJCF,
    URDF and TOML that reproduce the deployed calibrated chain at random postures (1e-9 m), and
    the TOML carries the modified-DH table or says why there is none (~7 s)."""
    root = tmp_path / "ds"
    s = load_scenario(
        overrides={
            "robot": {"model": "kr6-r900"},
            "noise": {"render": False},
            "trajectory": {"poses": 15},
            "validation": {"poses": 4},
        }
    )
    run_acquire(s, root, quiet=True)
    run_calibrate(root, quiet=True)
    robot = load_robot("kr6-r900")
    dep = deploy(read_calibration(root))
    assert dep.n == 6 and dep.robot_name == "kr6-r900"
    q = _arm_q(robot, 20, 8)
    outs = {}
    for fmt, suffix in (("mjcf", "xml"), ("urdf", "urdf"), ("toml", "toml")):
        outs[fmt] = tmp_path / f"robot.{suffix}"
        args = _parser().parse_args(["export", str(root), "--format", fmt, "--out",
                                     str(outs[fmt])])  # fmt: skip
        assert args.func(args) == 0
        assert json.loads(capsys.readouterr().out)["format"] == fmt
    got = _mj_frames(mujoco.MjModel.from_xml_path(str(outs["mjcf"])), q)[:, : robot.n + 1]
    assert np.abs(got - dep.frames(q)).max() < TOL_M
    urdf = urdf_chain(outs["urdf"], base_link="base_link", tool_link="tool_tip")  # via yourdfpy
    tips = chain_frames(urdf.chain, urdf.joint_types, q)[:, -1]
    assert np.abs(tips - dep.tool_tip(q)).max() < TOL_M
    text = outs["toml"].read_text()
    assert np.abs(from_toml(text).tool_tip(q) - dep.tool_tip(q)).max() < 1e-12
    assert 'convention = "mdh"' in text or "no DH table: axes of joints" in text
