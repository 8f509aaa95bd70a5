"""The simulated joint compliance (selfcal/sim/compliance.py): the misfit of the accuracy
benchmarks (issue #29), in the tracker rows and in the simulator's actual robot."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy import scenario, simulated
from selfcal.benchmarks.board.compliance_reach import bend_spread
from selfcal.benchmarks.tracker.accuracy import coverage
from selfcal.errors import UsageError
from selfcal.kinematics.forward import fk_tool
from selfcal.sim.compliance import SHOULDER, JointCompliance
from selfcal.sim.kinematic_robot import KinematicRobot


def test_the_bend_moves_one_joint_by_the_cosine_of_the_coupled_ones():
    q = np.array([[0.1, 0.3, 0.4, -1.0, 0.5, 2.0], [0.0, np.pi / 4, np.pi / 4, 0.0, 0.0, 0.0]])
    got = SHOULDER.bent(q)
    assert np.array_equal(np.delete(got, 1, axis=1), np.delete(q, 1, axis=1))
    assert got[:, 1] - q[:, 1] == pytest.approx(np.radians(0.05) * np.cos([0.7, np.pi / 2]))
    assert SHOULDER.bent(q[0]).shape == (6,)  # one joint vector as well
    with pytest.raises(UsageError, match="do not exist"):
        JointCompliance(0.01, joint=1, coupled=(1, 6)).bent(q)
    with pytest.raises(UsageError, match="finite"):
        JointCompliance(float("nan"))


def test_the_simulated_arm_bends_while_its_encoders_read_the_command():
    """The compliant robot's camera stands where the actual chain puts it at the bent joints;
    its encoders (and truth's joints) read the commanded ones, the rigid robot's are the same."""
    rigid = KinematicRobot("er4u-paper", quantize=False)
    bent = KinematicRobot("er4u-paper", quantize=False, compliance=SHOULDER)
    q_deg = np.array([10.0, -20.0, 30.0, 5.0, -15.0])  # the ER-4u has five joints
    for r in (rigid, bent):
        r.move_to(q_deg)
    q = np.radians(q_deg)
    assert np.allclose(bent.joints(), q_deg) and np.allclose(bent.truth_frame()["joints_rad"], q)
    T = bent.truth_frame()["T_world_cam_left"]
    assert np.allclose(T, fk_tool(bent.actual, SHOULDER.bent(q)[None])[0], atol=1e-12)
    moved = np.linalg.norm(T[:3, 3] - rigid.truth_frame()["T_world_cam_left"][:3, 3])
    assert 1e-5 < moved < 1e-3  # 0.05 deg at an arm's reach: a fraction of a millimetre


def test_the_board_benchmark_gives_the_compliance_to_the_simulator_only_for_its_misfit():
    s = scenario("ur5e", 0.2, 3)
    assert s.robot.model == "ur5e" and s.noise.pixel_sigma == 0.2 and not s.noise.render
    assert simulated(s, "fits").compliance is None
    assert simulated(s, "compliance").compliance is SHOULDER
    with pytest.raises(UsageError, match="unknown model"):
        simulated(s, "wobble")


def test_the_benchmarks_row_statistics():
    """coverage(): two draws of (bound, bound without the model error, predicted RMS, true)."""
    d1 = np.array([[2.0, 2.0], [1.0, 1.0], [1.0, 1.0], [1.5, 3.0]])
    d2 = np.array([[2.0, 2.0], [2.0, 2.0], [2.0, 2.0], [1.0, 1.0]])
    got = coverage([d1, d2])
    assert got["coverage"] == 0.75 and got["coverage_covariance"] == 0.5
    assert got["ratio"] == pytest.approx(np.sqrt(10 / 13.25))
    assert got["true_rms_mm"] == pytest.approx(np.sqrt(13.25 / 4))
    r1, r2 = np.sqrt(1 / 5.625), 2.0  # the per-draw ratios
    assert got["ratio_10"] == pytest.approx(r1 + 0.1 * (r2 - r1))


def test_the_bends_spread_is_taken_from_its_mean_at_the_calibration_postures():
    """selfcal.benchmarks.board.compliance_reach: what a calibration could see of the bend (its spread
    over the postures, mean removed) against what a region holds (its deviation from that mean)."""
    q_cal = np.zeros((3, 6))
    q_cal[:, 1] = [0.0, 0.1, 0.2]  # q2 + q3 near 0: the bend near its largest
    far = np.zeros((2, 6))
    far[:, 1] = np.pi / 2  # q2 + q3 = 90 deg: no bend
    got = bend_spread(SHOULDER, q_cal, {"far": far})
    a = np.radians(0.05)
    mean = a * np.mean(np.cos([0.0, 0.1, 0.2]))
    assert got["postures"] == pytest.approx(a * np.cos([0.0, 0.1, 0.2]) - mean)
    assert got["far"] == pytest.approx([-mean, -mean], abs=1e-15)
