"""The fair nominal of the tracker route (selfcal/calibration/tracker/nominal.py): the robot file's chain with
the tracker frame and the tool fitted by the identification's objective."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.tracker.sim import make_case
from selfcal.calibration.tracker.calibration_file import TrackerCalibration
from selfcal.calibration.tracker.nominal import fit_nominal, pose_errors
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.transforms import make_pose, pose_from_vec


@pytest.mark.parametrize("poses", [False, True])
def test_a_robot_as_built_is_its_own_nominal(poses):
    """Noise-free data of the nominal chain itself, placed anywhere with any tool: the fit
    recovers the tracker frame and the tool, and predicts every pose (1e-9 mm / deg; measured
    4e-11 mm from positions, 5e-13 mm and 1e-14 deg from poses)."""
    robot = load_robot("ur5e")
    T_tb = pose_from_vec(np.array([0.3, -1.1, 2.0, 1.5, -0.4, 0.8]))
    tool = make_pose(pose_from_vec(np.array([0.2, 0.1, -0.3, 0, 0, 0]))[:3, :3], [0.03, -0.02, 0.1])
    built = nominal_mcpc(robot, T_tb, tool)
    q = np.random.default_rng(1).uniform(-2.0, 2.0, (12, 6))
    T = fk_tool(built, q)
    meas = TrackerMeasurements(q, T[:, :3, 3], T[:, :3, :3] if poses else None)
    nom = fit_nominal(nominal_mcpc(robot), meas)
    assert nom.converged and nom.rms_mm < 1e-9
    pos, ang = pose_errors(nom.predict_poses(q), T[:, :3, 3], T[:, :3, :3] if poses else None)
    assert pos.max() < 1e-9
    if poses:
        assert nom.rms_deg < 1e-9 and ang.max() < 1e-9
    else:
        assert ang is None and np.isnan(nom.rms_deg)


def test_distances_alone_fit_the_tool_point():
    """Ball-bar distances: no tracker frame (identity), the tool point fitted; a perturbed robot
    leaves a residual the calibration would remove."""
    case = make_case(load_robot("ur5e"), seed=2)
    rng = np.random.default_rng(3)
    qa, qb = rng.uniform(-2.0, 2.0, (2, 40, 6))
    d = np.linalg.norm(fk_tool(case.true, qa)[:, :3, 3] - fk_tool(case.true, qb)[:, :3, 3], axis=1)
    meas = TrackerMeasurements(np.zeros((0, 6)), np.zeros((0, 3)), None, qa, qb, d)
    nom = fit_nominal(case.nominal, meas)
    assert np.array_equal(nom.T_meas_fit, np.eye(4)) and np.isnan(nom.rms_mm)
    assert 0.4 < nom.rms_distance_mm < 3.3  # the robot's own errors: measured 1.11 mm


def test_the_nominal_survives_the_calibration_file(tmp_path):
    """``nominal`` in calibration.json: written and read back; a file without it (written before)
    reads with ``nominal`` None."""
    from selfcal.calibration.tracker.calibration_file import from_result, read_tracker_calibration
    from selfcal.calibration.tracker.calibration_file import write_tracker_calibration as write
    from selfcal.calibration.tracker.identify import identify_tracker

    robot = load_robot("tests/data/positioner2.toml")
    case = make_case(robot, seed=3)
    q = case.configurations(10, 1)
    T = fk_tool(case.true, q)
    meas = TrackerMeasurements(q, T[:, :3, 3], T[:, :3, :3])
    res = identify_tracker(case.nominal, meas)
    nom = fit_nominal(case.nominal, meas)
    kw = dict(robot=robot.name, robot_source="p", joint_names=robot.joint_names,
              joint_limits=robot.limits, joint_units="deg", sigmas={}, files={})  # fmt: skip
    back = read_tracker_calibration(write(tmp_path / "c.json", from_result(res, case.nominal,
                                                                           fair_nominal=nom, **kw)))  # fmt: skip
    assert back.poses and back.nominal is not None
    np.testing.assert_allclose(back.nominal.predict_poses(q), nom.predict_poses(q), atol=1e-12)
    assert back.nominal.rms_deg == pytest.approx(nom.rms_deg, rel=1e-12)
    doc = from_result(res, case.nominal, **kw).to_json()
    assert "nominal" not in doc
    assert TrackerCalibration.from_json(doc, "c.json").nominal is None


def test_the_pose_start_is_exact_from_three_poses_of_a_positioner():
    """Noise-free poses of a 2-axis positioner's nominal chain, placed and tooled anywhere:
    the closed-form start recovers both (1e-9; measured ~1e-15), where the positions' start
    settles in a wrong placement with 3 rows (the identification then ended 450 mm off)."""
    from selfcal.estimation.tracker_start import initial_placement, pose_placement

    robot = load_robot("tests/data/positioner2.toml")
    case = make_case(robot, seed=3)
    q = case.configurations(3, 3)
    tool = make_pose(
        pose_from_vec(np.array([0.4, -0.2, 0.9, 0, 0, 0]))[:3, :3], [0.03, -0.02, 0.08]
    )
    T = case.T_tracker_base @ fk_tool(case.nominal, q) @ tool
    B, X = pose_placement(case.nominal, q, T)
    assert np.abs(B - case.T_tracker_base).max() < 1e-9 and np.abs(X - tool).max() < 1e-9
    B_pos, _ = initial_placement(case.nominal, q, T[:, :3, 3])
    assert np.abs(B_pos - case.T_tracker_base).max() > 0.1  # what the positions' start gives
