"""The simulated robot behind the ``selfcal.robot.interface.Robot`` interface."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.camera import project
from selfcal.kinematics.forward import fk_frames
from selfcal.robot.interface import Robot, RobotError, StereoPair
from selfcal.sim.actual import apply_errors, perturb
from selfcal.sim.link_frames import nominal_camera_model
from selfcal.sim.markers import make_marker_field
from selfcal.sim.render import apply_noise, noise_field
from selfcal.sim.sim_robot import SimRobot
from selfcal.transforms import inv_pose


@pytest.fixture(scope="module")
def sim():
    from selfcal.robot.definition import load_robot

    robot = load_robot("er4u-paper")
    actual = apply_errors(
        perturb(nominal_camera_model(robot), seed=5, translation_m=1e-3, rotation_rad=1e-3),
        {"beta2": 1e-3},
    )
    r = SimRobot("er4u-paper", actual=actual, image_sigma=0.0, seed=1)
    yield r
    r.close()


def test_is_a_robot(sim):
    assert isinstance(sim, Robot)
    assert sim.model_name == "er4u-paper"


def test_move_and_quantised_read_back(sim):
    robot = sim.robot
    enc = robot.encoder
    step = np.degrees(enc.count_step)  # one motor count, deg
    zero = np.degrees(enc.zero)
    p, r = enc.differential  # pitch, roll: from the two wrist motors' counts
    rng = np.random.default_rng(0)
    for _ in range(20):
        q_deg = np.degrees(rng.uniform(robot.limits[:, 0], robot.limits[:, 1]))
        sim.move_to(q_deg)
        # the true posture is the command; the read-back is on the motors' count grid from the
        # encoder zero, within half a count of each motor
        np.testing.assert_allclose(np.degrees(sim.true_joints()), q_deg, atol=1e-12)
        read = sim.joints()
        counts = (read - zero) / step
        motors = counts.copy()
        motors[[p, r]] = counts[p] + counts[r], counts[r] - counts[p]
        np.testing.assert_allclose(motors, np.round(motors), atol=1e-6)
        true = (q_deg - zero) / step
        true[[p, r]] = true[p] + true[r], true[r] - true[p]
        assert np.all(np.abs(motors - true) <= 0.5 + 1e-6)
    sim.home()
    np.testing.assert_allclose(sim.true_joints(), robot.home, atol=1e-15)
    # the encoders read zero at their zero (er4u-paper: home), and 0.2 counts off it still (the
    # wrist motors turn by the sum and the difference of pitch and roll: 0.4 and 0 counts)
    np.testing.assert_allclose(sim.joints(), np.degrees(robot.home), atol=1e-9)
    sim.move_to(np.degrees(robot.home + 0.2 * enc.count_step))
    np.testing.assert_allclose(sim.joints(), np.degrees(robot.home), atol=1e-9)


def test_out_of_range_is_refused_before_moving(sim):
    sim.home()
    before = sim.true_joints()
    bad = np.degrees(sim.robot.home)
    bad[1] = -40.0  # shoulder range is [-35, 130] deg
    with pytest.raises(ValueError, match=r"joint 2 \(shoulder\).*\[-35\.00, 130\.00\] deg"):
        sim.move_to(bad)
    with pytest.raises(ValueError, match="5 joint values"):
        sim.move_to([0.0, 0.0, 0.0])
    nan = np.degrees(sim.robot.home)
    nan[3] = np.nan
    with pytest.raises(ValueError, match="joint 4"):
        sim.move_to(nan)
    np.testing.assert_array_equal(sim.true_joints(), before)


def test_truth_frame_matches_fk_of_the_actual_robot(sim):
    rng = np.random.default_rng(3)
    T_cam_tip = inv_pose(sim.robot.T_flange_cam)
    for _ in range(10):
        q = rng.uniform(sim.robot.limits[:, 0], sim.robot.limits[:, 1])
        sim.move_to(np.degrees(q))
        fr = sim.truth_frame()
        np.testing.assert_allclose(fr["joints_rad"], q, atol=1e-12)
        T = fk_frames(sim.actual, fr["joints_rad"])[0, -1]
        np.testing.assert_allclose(fr["T_world_cam_left"], T, atol=1e-9)
        np.testing.assert_allclose(fr["T_world_cam_right"], T @ sim.rig.T_left_right, atol=1e-9)
        np.testing.assert_allclose(fr["tool_tip_m"], (T @ T_cam_tip)[:3, 3], atol=1e-9)
        # and it is the actual robot, not the nominal one
        T_nom = fk_frames(sim.nominal, fr["joints_rad"])[0, -1]
        assert np.abs(T_nom[:3, 3] - T[:3, 3]).max() > 1e-5
    truth = sim.truth()
    assert truth.robot_model == "er4u-paper" and truth.frames == ()
    np.testing.assert_array_equal(truth.true_params, sim.actual.params)


def test_closed_robot_refuses():
    r = SimRobot("er4u-vendor", field=make_marker_field(n_markers=4, seed=1))
    r.close()
    r.close()  # idempotent
    with pytest.raises(RobotError, match="closed"):
        r.move_to(np.degrees(r.robot.home))


def test_bad_construction():
    with pytest.raises(ValueError, match="unknown robot model"):
        SimRobot("er4u-nonexistent")
    with pytest.raises(ValueError, match="image_sigma"):
        SimRobot("er4u-paper", image_sigma=-1.0)


@pytest.mark.render
def test_capture_and_markers_visible_at_home(sim):
    from selfcal.target.aruco_detect import detect_markers

    sim.home()
    pair = sim.capture()
    assert isinstance(pair, StereoPair)
    W, H = sim.rig.intrinsics.width, sim.rig.intrinsics.height
    for img in (pair.left, pair.right):
        assert img.shape == (H, W, 3) and img.dtype == np.uint8
    assert pair.meta["model_name"] == "er4u-paper"
    np.testing.assert_allclose(pair.meta["joints_deg"], sim.joints())
    # markers are visible and where the TRUE camera pose says they are (within 1 px)
    fr = sim.truth_frame()
    corners = sim.field.corners_world()
    for img, T_wc in ((pair.left, fr["T_world_cam_left"]), (pair.right, fr["T_world_cam_right"])):
        found = detect_markers(img, sim.field.dictionary)
        assert len(found) >= 3, sorted(found)
        for mid, c in found.items():
            row = sim.field.index_of(mid)
            uv = project(sim.rig.intrinsics, inv_pose(T_wc), corners[row])
            assert np.abs(uv - c).max() < 1.0, (mid, uv, c)
    # a second capture without noise is identical
    again = sim.capture()
    np.testing.assert_array_equal(again.left, pair.left)
    assert again.meta["index"] == pair.meta["index"] + 1


@pytest.mark.render
def test_capture_noise_is_seeded():
    field = make_marker_field(n_markers=6, seed=2)
    imgs = []
    for seed in (7, 7, 8):
        with SimRobot("er4u-paper", field=field, image_sigma=3.0, seed=seed) as r:
            imgs.append(r.capture().left.astype(int))
    np.testing.assert_array_equal(imgs[0], imgs[1])
    diff = imgs[0] - imgs[2]
    assert 2.0 < diff.std() < 6.0  # difference of two sigma-3 noises: ~4.2 before clipping


@pytest.mark.render
def test_noisy_captures_take_the_generators_draws_in_order():
    """The first capture's noise is drawn while the renderer starts, each next one's during the
    capture before (on a worker thread): the images are still the noiseless ones plus the seeded
    generator's draws, image after image (left, right, left, right)."""
    field = make_marker_field(n_markers=6, seed=2)
    with SimRobot("er4u-paper", field=field, image_sigma=3.0, seed=7) as r:
        noisy = [r.capture() for _ in range(2)]
    with SimRobot("er4u-paper", field=field, seed=7) as r:
        clean = [r.capture() for _ in range(2)]
    rng = np.random.default_rng(7)
    for n, c in zip(noisy, clean, strict=True):
        for a, b in ((n.left, c.left), (n.right, c.right)):
            np.testing.assert_array_equal(a, apply_noise(b, noise_field(b.shape, 3.0, rng)))
