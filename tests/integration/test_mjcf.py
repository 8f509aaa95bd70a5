"""The robot's MJCF model: MuJoCo's frames are the MCPC frames, the model is clean, the committed
XML is up to date, and the cameras see the marker field, not the robot."""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from selfcal.camera import Intrinsics
from selfcal.kinematics.forward import fk_frames, fk_nominal
from selfcal.robot.definition import load_robot, models_dir
from selfcal.sim.actual import apply_errors, perturb
from selfcal.sim.build_models import ROBOT_MODELS, mjcf_entries, write_models
from selfcal.sim.link_frames import link_body_names, nominal_camera_model
from selfcal.sim.markers import make_marker_field
from selfcal.sim.mj_camera import T_world_cam_cv, intrinsics_from_model
from selfcal.sim.robot_mjcf import RigConfig, add_robot, robot_spec, scene_with_robot
from selfcal.transforms import inv_pose, trans

MODEL_DIR = models_dir() / "scorbot_er4u"  # the SCORBOT folder
TOL = 1e-9  # m, and for rotation-matrix entries
ROBOT_BODIES = ("base", "link1", "link2", "link3", "link4", "link5", "rig")  # the SCORBOT's
COMMITTED = [  # (file under models/, robot): every committed robot model and scene
    (f"{e.folder.relative_to(models_dir())}/{f}", e.name)
    for e in mjcf_entries()
    for f in ([f"{e.name}.xml"] + (["scene.xml"] if e.scene else []))
]


@pytest.fixture
def warnings_log():
    """Collect MuJoCo warnings raised while the test runs: the legacy ``mju_user_warning``
    callback and the Python ``warnings`` MuJoCo 4 emits for compiler messages."""
    log: list[str] = []
    old = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(log.append)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield log
    log.extend(str(w.message) for w in caught)
    mujoco.set_mju_user_warning(old)
    assert log == [], log


def _models(name: str):
    robot = load_robot(name)
    nominal = nominal_camera_model(robot)
    actual = apply_errors(
        perturb(nominal, seed=7, translation_m=2e-3, rotation_rad=3e-3),
        {"beta2": 2e-3, "lx1": 1e-3},  # non-parallel shoulder/elbow axes: not DH-representable
    )
    return robot, {"nominal": nominal, "perturbed": actual}


def _random_q(robot, m: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.limits[:, 0], robot.limits[:, 1], size=(m, robot.n))


def _pose(data: mujoco.MjData, body: str) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = data.body(body).xmat.reshape(3, 3)
    T[:3, 3] = data.body(body).xpos
    return T


def _site_pose(data: mujoco.MjData, site: str) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = data.site(site).xmat.reshape(3, 3)
    T[:3, 3] = data.site(site).xpos
    return T


def _frame_errors(model, data, robot, mcpc, q, rig: RigConfig) -> dict[str, float]:
    """Max abs deviation of MuJoCo's frames from selfcal.kinematics.forward over configurations q."""
    F = fk_frames(mcpc, q)
    T_cam_tip = inv_pose(robot.T_flange_cam)
    err = {"links": 0.0, "rig": 0.0, "cam_left": 0.0, "cam_right": 0.0, "tool_tip": 0.0}
    for i in range(q.shape[0]):
        data.qpos[: robot.n] = q[i]
        mujoco.mj_forward(model, data)
        for k in range(robot.n):
            err["links"] = max(err["links"], np.abs(_pose(data, f"link{k + 1}") - F[i, k]).max())
        tool = F[i, robot.n]
        err["rig"] = max(err["rig"], np.abs(_pose(data, "rig") - tool).max())
        err["cam_left"] = max(
            err["cam_left"], np.abs(T_world_cam_cv(model, data, "cam_left") - tool).max()
        )
        err["cam_right"] = max(
            err["cam_right"],
            np.abs(T_world_cam_cv(model, data, "cam_right") - tool @ rig.T_left_right).max(),
        )
        err["tool_tip"] = max(
            err["tool_tip"], np.abs(_site_pose(data, "tool_tip") - tool @ T_cam_tip).max()
        )
    return err


@pytest.mark.parametrize("name", ROBOT_MODELS)
@pytest.mark.parametrize("which", ["nominal", "perturbed"])
def test_body_frames_are_mcpc_frames(name, which):
    robot, models = _models(name)
    mcpc = models[which]
    rig = RigConfig(T_left_right=trans(np.array([0.06, 0.002, -0.001])))
    model = robot_spec(robot, mcpc, rig).compile()
    data = mujoco.MjData(model)
    q = _random_q(robot, 100, seed=11)
    err = _frame_errors(model, data, robot, mcpc, q, rig)
    assert max(err.values()) < TOL, err


def test_prismatic_joint_becomes_a_slide():
    """A chain with a prismatic joint (synthetic: the paper arm with a sliding elbow) gets a slide
    joint and still reproduces the MCPC frames."""
    import dataclasses

    r = load_robot("er4u-paper")
    lim, home = r.limits.copy(), r.home.copy()
    lim[2], home[2] = (0.0, 0.1), 0.05
    robot = dataclasses.replace(
        r,
        joint_types=("revolute", "revolute", "prismatic", "revolute", "revolute"),
        limits=lim,
        home=home,
    )
    mcpc = perturb(nominal_camera_model(robot), seed=1, translation_m=1e-3, rotation_rad=1e-3)
    model = robot_spec(robot, mcpc).compile()
    assert model.jnt_type[2] == mujoco.mjtJoint.mjJNT_SLIDE
    err = _frame_errors(
        model, mujoco.MjData(model), robot, mcpc, _random_q(robot, 30, 2), RigConfig()
    )
    assert max(err.values()) < TOL, err


@pytest.mark.parametrize("name", ROBOT_MODELS)
def test_flange_site_is_last_dh_frame(name):
    """At nominal the flange site is the DH chain's last frame, and the tool tip sits on it."""
    robot, models = _models(name)
    model = robot_spec(robot, models["nominal"]).compile()
    data = mujoco.MjData(model)
    q = _random_q(robot, 50, seed=3)
    dh = fk_nominal(robot, q)[:, -1]
    for i in range(q.shape[0]):
        data.qpos[:] = q[i]
        mujoco.mj_forward(model, data)
        assert np.abs(_site_pose(data, "flange") - dh[i]).max() < TOL
        assert np.abs(data.site("tool_tip").xpos - dh[i, :3, 3]).max() < TOL


def test_paper_home_tool_tip_is_table_ii():
    """Table I's theta column as joint angles puts the tool tip at Table II, row 1 (mm, 0.1)."""
    robot = load_robot("er4u-paper")
    model = robot_spec(robot, nominal_camera_model(robot)).compile()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(
        data.site("tool_tip").xpos * 1000, [315.60, 247.90, 190.30], atol=0.1
    )


def _noisy_step(model: mujoco.MjModel, seconds: float = 1.0, seed: int = 0) -> mujoco.MjData:
    """Menagerie's smoke test: from ``home``, step with noisy in-range controls."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    rng = np.random.default_rng(seed)
    lo, hi = model.actuator_ctrlrange.T
    home = model.key("home").ctrl.copy()
    while data.time < seconds:
        data.ctrl[:] = np.clip(home + rng.normal(0.0, 0.05, size=model.nu), lo, hi)
        mujoco.mj_step(model, data)
    return data


@pytest.mark.parametrize("name", ROBOT_MODELS)
def test_loads_and_steps_without_warnings(name, warnings_log):
    robot, models = _models(name)
    field = make_marker_field(n_markers=6, seed=2)
    for spec in (
        robot_spec(robot, models["nominal"]),
        robot_spec(robot, models["perturbed"]),
        scene_with_robot(robot, models["perturbed"], None, field),
    ):
        model = spec.compile()
        data = _noisy_step(model)
        assert [w.number for w in data.warning] == [0] * len(data.warning)
        assert np.all(np.isfinite(data.qpos))
        # position servos hold the arm near the commanded posture (rad)
        assert np.abs(data.qpos - model.key("home").qpos).max() < 0.2
    assert warnings_log == []


def test_warning_capture_sees_mujoco_warnings():
    """The mechanism of ``warnings_log`` does catch a MuJoCo compiler warning."""
    log: list[str] = []
    old = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(log.append)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            parent, child = mujoco.MjSpec(), mujoco.MjSpec()
            child.option.timestep = 0.005  # conflicts with the parent's 0.002
            body = child.worldbody.add_body(name="b")
            body.add_geom(size=[0.1, 0.0, 0.0])
            parent.worldbody.add_frame().attach_body(body, "p_", "")
            parent.compile()
    finally:
        mujoco.set_mju_user_warning(old)
    assert log and caught


@pytest.mark.parametrize("file", [f for f, _ in COMMITTED])
def test_committed_xml_loads_and_steps(file, warnings_log):
    model = mujoco.MjModel.from_xml_path(str(models_dir() / file))
    data = _noisy_step(model)
    assert [w.number for w in data.warning] == [0] * len(data.warning)
    assert warnings_log == []


def _normalise(text: str) -> list[str]:
    return [" ".join(line.split()) for line in text.strip().splitlines() if line.strip()]


def test_committed_xml_is_regenerated_exactly(tmp_path: Path):
    written = write_models(tmp_path)
    assert written
    for p in written:
        rel = p.relative_to(tmp_path)
        committed = models_dir() / rel
        assert committed.is_file(), f"{committed} missing: run `python -m selfcal.sim.build_models`"
        if p.suffix == ".xml":
            assert _normalise(p.read_text()) == _normalise(committed.read_text()), (
                f"{rel} is stale: run `python -m selfcal.sim.build_models`"
            )
        else:
            import cv2

            a, b = cv2.imread(str(p)), cv2.imread(str(committed))
            assert a is not None and b is not None and np.array_equal(a, b), f"{rel} differs"


@pytest.mark.parametrize("file,name", COMMITTED)
def test_committed_xml_reproduces_mcpc_frames(file, name):
    """Full float64 precision of the committed files: same frames as the MCPC model."""
    if file.endswith("scene.xml"):  # the scene includes the robot of its folder's scene entry
        name = next(e.name for e in mjcf_entries() if e.scene and file.startswith(e.folder.name))
    robot = load_robot(name)
    mcpc = nominal_camera_model(robot)
    model = mujoco.MjModel.from_xml_path(str(models_dir() / file))
    data = mujoco.MjData(model)
    q = _random_q(robot, 30, seed=5)
    err = _frame_errors(model, data, robot, mcpc, q, RigConfig())
    assert max(err.values()) < 1e-12, err


@pytest.mark.parametrize("name", ROBOT_MODELS)
def test_model_elements(name):
    robot, models = _models(name)
    rig = RigConfig(
        intrinsics=Intrinsics(810.0, 1.01, 300.0, 250.0, 640, 480),
        intrinsics_right=Intrinsics(790.0, 0.99, 330.0, 230.0, 640, 480),
    )
    model = robot_spec(robot, models["nominal"], rig).compile()
    assert model.njnt == robot.n and model.nu == robot.n and model.nq == robot.n
    for k in range(robot.n):
        j = model.joint(robot.joint_names[k])
        assert j.type[0] == mujoco.mjtJoint.mjJNT_HINGE
        assert model.jnt_limited[j.id]
        np.testing.assert_array_equal(model.jnt_range[j.id], robot.limits[k])
        assert model.body(j.bodyid[0]).name == f"link{k + 1}"
        np.testing.assert_array_equal(j.axis, [0.0, 0.0, 1.0])
        a = model.actuator(robot.joint_names[k])
        assert a.trnid[0] == j.id
        np.testing.assert_array_equal(model.actuator_ctrlrange[a.id], robot.limits[k])
        assert model.actuator_gainprm[a.id, 0] > 0  # position servo: bias = -kp q
        assert model.actuator_biasprm[a.id, 1] == -model.actuator_gainprm[a.id, 0]
    key = model.key("home")
    np.testing.assert_array_equal(key.qpos, robot.home)
    np.testing.assert_array_equal(key.ctrl, robot.home)
    for site in ("flange", "tool_tip"):
        assert model.site(site).id >= 0
    assert model.body(model.site("tool_tip").bodyid[0]).name == "rig"
    assert model.body(model.site("flange").bodyid[0]).name == f"link{robot.n}"
    for cam, intr in (("cam_left", rig.intrinsics), ("cam_right", rig.right)):
        assert model.body(model.camera(cam).bodyid[0]).name == "rig"
        got = intrinsics_from_model(model, cam)
        np.testing.assert_allclose(
            [got.fx, got.fy, got.cx, got.cy], [intr.fx, intr.fy, intr.cx, intr.cy], rtol=1e-6
        )
        assert (got.width, got.height) == (intr.width, intr.height)
    # visual and collision geometry never mix
    n_vis = n_col = 0
    for g in range(model.ngeom):
        assert model.geom_group[g] in (2, 3), f"geom {g} in group {model.geom_group[g]}"
        if model.geom_group[g] == 2:
            n_vis += 1
            assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0
        else:
            n_col += 1
            assert model.geom_contype[g] != 0 or model.geom_conaffinity[g] != 0
    assert n_vis > 2 * robot.n and n_col >= robot.n + 2  # each link: a housing and a body
    # every moving body has mass and a positive-definite inertia
    for b in (*link_body_names(robot.n), "rig"):
        assert model.body(b).mass[0] > 0 and np.all(model.body(b).inertia > 0)


def test_bad_inputs_are_refused():
    robot = load_robot("er4u-paper")
    vendor = load_robot("er4u-vendor")
    spec = robot_spec(robot, nominal_camera_model(robot))
    with pytest.raises(ValueError, match="already contains a robot"):
        add_robot(spec, robot, nominal_camera_model(robot), RigConfig())
    bad = nominal_camera_model(robot)
    bad = type(bad)(bad.params[:-1], bad.joint_types[:-1], bad.joint_offsets[:-1])
    with pytest.raises(ValueError, match="joint types"):
        robot_spec(vendor, bad)
    with pytest.raises(ValueError, match="rigid"):
        RigConfig(T_left_right=np.diag([2.0, 1.0, 1.0, 1.0]))


# ---------------------------------------------------------------------------- rendering

_WORKING_SPAN_DEG = np.array([30.0, 20.0, 20.0, 30.0, 90.0])


def _around_home(robot, span: np.ndarray, m: int, seed: int) -> list[np.ndarray]:
    """Home and ``m`` postures drawn uniformly within home +- ``span`` (clipped to the ranges)."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    return [robot.home] + [
        np.clip(robot.home + span * rng.uniform(-1, 1, robot.n), lo, hi) for _ in range(m)
    ]


def _robot_pixels(model, data, renderer, bodies: set[int]) -> dict[str, int]:
    out = {}
    for cam in ("cam_left", "cam_right"):
        renderer.update_scene(data, cam)
        seg = renderer.render()
        ids, types = seg[..., 0], seg[..., 1]
        is_geom = (types == mujoco.mjtObj.mjOBJ_GEOM) & (ids >= 0)
        body = model.geom_bodyid[np.where(is_geom, ids, 0)]
        out[cam] = int(np.count_nonzero(is_geom & np.isin(body, list(bodies))))
    return out


@pytest.mark.render
@pytest.mark.parametrize(
    "name,hidden",
    [
        ("er4u-paper", ROBOT_BODIES),  # the whole arm stays out of view
        ("er4u-vendor", ("link4", "link5", "rig")),  # wrist, gripper, rig never in view
    ],
)
@pytest.mark.slow
def test_cameras_do_not_see_the_robot(name, hidden):
    """Home and random working postures (home +-30/20/20/30/90 deg): segmentation rendering of
    both cameras contains no pixel of the listed robot bodies. (The vendor home looks down near
    the base, so its base can enter the view; the gripper and rig never do.)"""
    robot = load_robot(name)
    model = scene_with_robot(
        robot, nominal_camera_model(robot), None, make_marker_field()
    ).compile()
    data = mujoco.MjData(model)
    bodies = {model.body(b).id for b in hidden}
    qs = _around_home(robot, np.radians(_WORKING_SPAN_DEG), 5, seed=4)
    with mujoco.Renderer(model, 480, 640) as renderer:
        renderer.enable_segmentation_rendering()
        for q in qs:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            px = _robot_pixels(model, data, renderer, bodies)
            assert px == {"cam_left": 0, "cam_right": 0}, (np.degrees(q).round(1), px)
            # sanity: the segmentation does see the scene (table, markers)
            renderer.update_scene(data, "cam_left")
            assert np.any(renderer.render()[..., 0] >= 0)


@pytest.mark.slow  # default tier budget (~90 s): 2-5 s each
@pytest.mark.render
@pytest.mark.parametrize("name", ["kr6-r900", "ur5e"])
def test_generic_arm_wrist_camera_sees_the_target_not_the_arm(name):
    """The KR 6 R900 and the UR5e (capsule links) over their committed scenes' marker field (the
    default one; for the UR5e centred on the home view, ``[mjcf] field = "home"``): at home and at
    postures within the planning window, both wrist cameras see marker tiles (>= 2 % of the
    image; measured KR 6 6-27 %, 15-19 % at home; UR5e 21-31 %, 24-31 % at home) and no pixel of the wrist
    links or the rig."""
    robot = load_robot(name)
    entry = next(e for e in mjcf_entries() if e.name == name)
    model = scene_with_robot(
        robot, nominal_camera_model(robot), None, entry.marker_field()
    ).compile()
    data = mujoco.MjData(model)
    markers = {g for g in range(model.ngeom) if (model.geom(g).name or "").startswith("aruco_")}
    wrist = {model.body(b).id for b in ("link5", "link6", "rig")}
    qs = _around_home(robot, 0.5 * robot.planning_span, 3, seed=5)
    with mujoco.Renderer(model, 480, 640) as renderer:
        renderer.enable_segmentation_rendering()
        for q in qs:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            for cam in ("cam_left", "cam_right"):
                renderer.update_scene(data, cam)
                seg = renderer.render()
                is_geom = (seg[..., 1] == mujoco.mjtObj.mjOBJ_GEOM) & (seg[..., 0] >= 0)
                ids = np.where(is_geom, seg[..., 0], 0)
                on_marker = is_geom & np.isin(ids, list(markers))
                on_wrist = is_geom & np.isin(model.geom_bodyid[ids], list(wrist))
                assert on_marker.mean() > 0.02, (cam, np.degrees(q).round(1), on_marker.mean())
                assert not on_wrist.any(), (cam, np.degrees(q).round(1))
