"""The simulated eccentric gear (selfcal/sim/gear.py): issue #29's misfit a link table cannot
express, in the tracker rows and in the simulator's actual robot."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy import scenario, simulated
from selfcal.benchmarks.tracker.accuracy import misfit
from selfcal.benchmarks.tracker.sim import make_case
from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.errors import UsageError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot
from selfcal.sim.compliance import SHOULDER
from selfcal.sim.gear import MIN_LEVER_M, TOOL_MOVE_M, EccentricGear, draw_gear
from selfcal.sim.kinematic_robot import KinematicRobot


def test_the_gear_turns_one_joint_by_the_sine_of_its_own_angle():
    gear = EccentricGear(1e-3, joint=2, phase_rad=0.3)
    q = np.array([[0.1, 0.3, 0.4, -1.0, 0.5, 2.0], [0.0, 0.2, -0.3, 0.0, 0.0, 0.0]])
    got = gear.bent(q)
    assert np.array_equal(np.delete(got, 2, axis=1), np.delete(q, 2, axis=1))
    assert got[:, 2] - q[:, 2] == pytest.approx(1e-3 * np.sin([0.7, 0.0]))
    assert gear.bent(q[0]).shape == (6,)
    with pytest.raises(UsageError, match="does not exist"):
        EccentricGear(1e-3, joint=6, phase_rad=0.0).bent(q)
    with pytest.raises(UsageError, match="finite"):
        EccentricGear(float("nan"), joint=0, phase_rad=0.0)


@pytest.mark.parametrize("name", ["er4u-paper", "ur5e", "kr6-r900"])
def test_the_gear_moves_the_tool_by_the_stated_amount_and_not_where_the_sine_vanishes(name):
    """Over a new workspace sample with the gear's joint where its sine is 1, the tool moves by
    TOOL_MOVE_M RMS (the amplitude was set on another sample of the same ranges); where the
    sine is 0 it does not move."""
    robot = load_robot(name)
    case = make_case(robot, seed=4)
    lim = np.clip(robot.limits, -np.radians(170.0), np.radians(170.0))
    q = np.random.default_rng(11).uniform(lim[:, 0], lim[:, 1], (400, robot.n))
    for seed in range(4):
        gear = draw_gear(case.true, robot.limits, seed)
        assert 0.0 < gear.amplitude_rad <= TOOL_MOVE_M / MIN_LEVER_M
        peak, zero = q.copy(), q.copy()
        peak[:, gear.joint] = np.pi / 2 - gear.phase_rad
        zero[:, gear.joint] = -gear.phase_rad
        for at in (peak, zero):  # the gear's sine repeats: any turn of the joint will do
            assert np.allclose(np.sin(at[:, gear.joint] + gear.phase_rad), at is peak)

        move = [np.linalg.norm(fk_tool(case.true, gear.bent(at))[:, :3, 3]
                               - fk_tool(case.true, at)[:, :3, 3], axis=1)
                for at in (peak, zero)]  # fmt: skip
        assert np.sqrt(np.mean(move[0] ** 2)) == pytest.approx(TOOL_MOVE_M, rel=0.15)
        assert np.max(move[1]) < 1e-12


def test_the_draw_is_one_per_truth_and_picks_a_joint_that_moves_the_tool():
    robot = load_robot("ur5e")
    case = make_case(robot, seed=1)
    gears = [draw_gear(case.true, robot.limits, s) for s in range(12)]
    assert gears[3] == draw_gear(case.true, robot.limits, 3)
    assert len({g.joint for g in gears}) >= 3 and len({g.phase_rad for g in gears}) == 12
    assert 5 not in {g.joint for g in gears}  # the wrist roll's lever at the tool is 35 mm


def test_a_tracker_calibration_cannot_absorb_the_gear():
    """The complete chain fitted to 60 tracker rows at 0.02 mm: with a rigid truth its residual
    is the noise (sigma0 ~1); with the gear it stays about three times the noise in each of
    four truths (the fit takes up part of the gear: its residual RMS is ~0.1 mm of 0.2 mm)."""
    robot = load_robot("ur5e")
    sigma = 2e-5
    for seed in range(4):
        case = make_case(robot, seed=seed)
        gear = draw_gear(case.true, robot.limits, seed)
        q = case.configurations(60, seed=9)
        rng = np.random.default_rng(5)
        got = []
        for bend in (q, gear.bent(q)):
            xyz = fk_tool(case.true, bend)[:, :3, 3] + rng.normal(0.0, sigma, (60, 3))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = identify_tracker(case.nominal, TrackerMeasurements(
                    q, xyz, None, None, None, None), sigma_t_m=sigma)  # fmt: skip
            got.append(res.sigma0)
        assert got[0] < 1.2 and got[1] > 2.5, (seed, got)


def test_the_benchmarks_give_the_gear_to_the_truth_only():
    """Tracker: the draw's misfit; board: the simulator's actual robot (its encoders read the
    commanded joints, its camera stands at the gear's)."""
    robot = load_robot("kr6-r900")
    case = make_case(robot, seed=2)
    assert misfit(case, "fits", 2) is None and misfit(case, "compliance", 2) is SHOULDER
    assert misfit(case, "gear", 2) == draw_gear(case.true, robot.limits, 2)
    with pytest.raises(UsageError, match="unknown model"):
        misfit(case, "wobble", 2)
    s = scenario("ur5e", 0.2, 3)
    setup = simulated(s, "gear")
    assert setup.compliance == draw_gear(setup.actual, setup.robot.limits, 3)
    arm = KinematicRobot(setup.robot, setup.actual, quantize=False, compliance=setup.compliance)
    q_deg = np.array([10.0, -80.0, 60.0, 5.0, -15.0, 30.0])
    arm.move_to(q_deg)
    q = np.radians(q_deg)
    assert np.allclose(arm.joints(), q_deg)
    T = arm.truth_frame()["T_world_cam_left"]
    assert np.allclose(T, fk_tool(setup.actual, setup.compliance.bent(q)[None])[0], atol=1e-12)
