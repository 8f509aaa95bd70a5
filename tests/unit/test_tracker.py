"""Tracker residual blocks (analytic Jacobians) and the identification from tracker data."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from selfcal.benchmarks.tracker.compare import (
    BEGIN,
    END,
    combine,
    mdh_table,
    run,
    table,
    write_docs,
)
from selfcal.benchmarks.tracker.sim import RRPRR_DH, dh_robot, make_case, measure
from selfcal.calibration.identify import IdentificationWarning
from selfcal.calibration.tracker.identify import (
    TrackerIdentificationError,
    TrackerMeasurements,
    identify_tracker,
)
from selfcal.estimation.tracker import (
    ChainLayout,
    TrackerDistanceBlock,
    TrackerPoseBlock,
    TrackerPositionBlock,
)
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.forward import fk_nominal, fk_tool
from selfcal.kinematics.mcpc import chain_transforms, minimal_indices, param_is_angle
from selfcal.robot.definition import list_robots, load_robot
from selfcal.solver import ParameterBlock, Problem
from selfcal.transforms import inv_pose, pose_from_vec, rot_x, rot_z, trans

ROBOTS = {
    "rrprr": lambda: dh_robot("rrprr", **RRPRR_DH),
}
# and every robot file of the project (the reference robots)
ROBOTS |= {name: (lambda name=name: load_robot(name)) for name in list_robots()}


def _layout_problem(case, with_frame_point: bool):
    """A problem over part of the MCPC parameters (block 'kin', every other one), and with
    ``with_frame_point`` a tracker frame, a tool point and a tool frame block."""
    model = case.true
    P = 6 * (model.n + 1)
    free = np.arange(0, P, 2)
    coords = -np.ones(P, np.int64)
    coords[free] = np.arange(free.size)
    blocks = [ParameterBlock("kin", model.params.reshape(-1)[free] + 1e-3)]
    kw = {}
    if with_frame_point:
        kw = dict(frame="frame", frame0=pose_from_vec([0.3, -0.2, 0.1, 0.5, 0.2, -0.1]))
        kw |= dict(point="point", tool="tool", tool0=pose_from_vec([1.0, 0.5, -2.0, 0, 0, 0.1]))
        blocks += [
            ParameterBlock("frame", [0.02, -0.01, 0.03, 0.01, 0.0, -0.02]),
            ParameterBlock("point", [0.01, 0.02, 0.05]),
            ParameterBlock("tool", [0.1, -0.2, 0.05, 0.01, 0.03, -0.02]),
        ]
    return ChainLayout(model, "kin", coords, **kw), blocks


@pytest.mark.parametrize("with_frame_point", [False, True])
def test_tracker_blocks_jacobians_match_finite_differences(with_frame_point):
    case = make_case(ROBOTS["ur5e"]())
    layout, params = _layout_problem(case, with_frame_point)
    q = case.configurations(5, 1)
    q2 = case.configurations(5, 2)
    T = fk_tool(case.true, q) @ pose_from_vec([0.01, 0.02, -0.01, 0.002, 0.0, 0.001])
    blocks = [
        TrackerPositionBlock(layout, q, T[:, :3, 3] + 0.01, 1e-4),
        TrackerPoseBlock(layout, q, T, 1e-4, 1e-3),
        TrackerDistanceBlock(layout, q, q2, np.full(5, 0.4), 1e-4),
    ]
    prob = Problem(params, blocks)
    x = prob.x0
    J = prob.jacobian(x).toarray()
    eps = 1e-7
    num = np.column_stack(
        [
            (prob.residual_vector(x + eps * e) - prob.residual_vector(x - eps * e)) / (2 * eps)
            for e in np.eye(prob.n)
        ]
    )
    # measured: relative agreement 2.1e-9 (central differences, step 1e-7)
    assert np.abs(J - num).max() <= 6e-9 * np.abs(num).max()


@pytest.mark.parametrize("name", list(ROBOTS))
def test_noise_free_positions_recover_every_identifiable_parameter(name):
    robot = ROBOTS[name]()
    case = make_case(robot, seed=3)
    q = case.configurations(60, 5)
    xyz, _ = measure(case, q, 0.0, 1)
    res = identify_tracker(case.nominal, TrackerMeasurements(q, xyz))
    n = robot.n
    # found numerically: positions do not see the orientation of the tool frame
    assert set(res.held) == {f"alpha{n}", f"beta{n}", f"gamma{n}"}
    assert res.rank == res.n_params - 3 == res.estimated.sum()
    # the truth in the estimate's world frame and joint-offset convention (gauge alignment)
    truth = express_in_frame(case.true, inv_pose(res.T_meas_fit), like=res.model)
    idx = minimal_indices(robot.joint_types)
    err = truth.params.reshape(-1)[idx] - res.values
    err = np.where(param_is_angle(idx), np.degrees(err), err * 1e3)  # deg, mm
    inner = res.estimated & (idx // 6 < n)
    # measured: <= 7e-11 mm / deg on these robots (the fit stops at a 1e-8 relative cost change)
    assert np.abs(err[inner]).max() <= 1e-6
    # V_n: the tool point on the last link is what positions determine
    tool_err = chain_transforms(truth)[-1][:3, 3] - chain_transforms(res.model)[-1][:3, 3]
    assert np.abs(tool_err).max() * 1e3 <= 1e-6
    q_new = case.configurations(40, 6)
    assert np.abs(res.predict(q_new) - fk_tool(case.true, q_new)[:, :3, 3]).max() <= 1e-9


def test_noise_free_poses_identify_every_minimal_parameter():
    case = make_case(ROBOTS["kr6-r900"](), seed=2)
    q = case.configurations(30, 5)
    xyz, R = measure(case, q, 0.0, 1, poses=True)
    res = identify_tracker(case.nominal, TrackerMeasurements(q, xyz, R))
    assert res.held == () and res.rank == res.n_params == 30
    truth = express_in_frame(case.true, inv_pose(res.T_meas_fit), like=res.model)
    idx = minimal_indices(case.robot.joint_types)
    err = truth.params.reshape(-1)[idx] - res.values
    err = np.where(param_is_angle(idx), np.degrees(err), err * 1e3)
    assert np.abs(err).max() <= 1e-6  # measured ~7e-12


def test_noisy_positions_reach_the_noise_floor_on_held_out_configurations():
    case = make_case(ROBOTS["ur5e"](), seed=4)
    sigma = 1e-4
    q = case.configurations(100, 7)
    xyz, _ = measure(case, q, sigma, 8)
    res = identify_tracker(case.nominal, TrackerMeasurements(q, xyz), sigma_t_m=sigma)
    q_new = case.configurations(300, 9)
    x_new, _ = measure(case, q_new, sigma, 10)
    e = np.linalg.norm(res.predict(q_new) - x_new, axis=1)
    floor = np.sqrt(3) * sigma  # RMS norm of the measurement noise alone
    rms = float(np.sqrt(np.mean(e**2)))
    # measured: 1.035 x the floor (the model's own error ~ sigma sqrt(p / N) adds in quadrature)
    assert floor <= rms <= 1.1 * floor
    assert 0.85 <= res.sigma0 <= 1.15  # measured 1.04


def test_too_few_positions_say_how_many_are_needed():
    case = make_case(ROBOTS["ur5e"]())
    q = case.configurations(8, 1)
    xyz, _ = measure(case, q, 0.0, 1)
    with pytest.raises(TrackerIdentificationError, match="need at least 10 positions") as exc:
        identify_tracker(case.nominal, TrackerMeasurements(q, xyz))
    assert exc.value.exit_code == 3 and "27 parameters" in str(exc.value)


def test_a_joint_that_never_moves_is_held_with_a_warning():
    case = make_case(ROBOTS["ur5e"]())
    q = case.configurations(40, 1)
    q[:, 5] = 0.3
    xyz, _ = measure(case, q, 0.0, 1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = identify_tracker(case.nominal, TrackerMeasurements(q, xyz))
    assert any(issubclass(w.category, IdentificationWarning) for w in caught)
    # the message names the joint that never moves (a check of the data, not a guess)
    note = next(str(w.message) for w in caught if issubclass(w.category, IdentificationWarning))
    assert "j6 never moves (17.189 deg in every row)" in note, note
    assert "e.g." not in note
    assert res.held_reason["alpha6"].startswith("not identifiable from position")
    data_held = [k for k, v in res.held_reason.items() if v == "unidentifiable from this data"]
    assert data_held and all(nm.endswith("5") for nm in data_held)  # joint 6's axis
    assert res.rms_mm < 1e-6


def test_a_rank_loss_with_every_joint_moving_says_so():
    """Every joint moves, but only within a few degrees of one posture: no joint is blamed for
    never moving, and the message names the joints' spread and the fix."""
    case = make_case(ROBOTS["ur5e"]())
    q = case.configurations(1, 1) + np.random.default_rng(4).normal(0, 1e-3, (40, 6))
    xyz, _ = measure(case, q, 0.0, 1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        identify_tracker(case.nominal, TrackerMeasurements(q, xyz))
    notes = [str(w.message) for w in caught if issubclass(w.category, IdentificationWarning)]
    assert notes and "never moves" not in notes[0], notes
    assert "every joint moves" in notes[0] and "spread the configurations" in notes[0], notes


def test_distances_and_positions_combine():
    case = make_case(ROBOTS["ur5e"](), seed=5)
    q = case.configurations(30, 1)
    xyz, _ = measure(case, q, 0.0, 1)
    qa, qb = case.configurations(10, 2), case.configurations(10, 3)
    d = np.linalg.norm(fk_tool(case.true, qa)[:, :3, 3] - fk_tool(case.true, qb)[:, :3, 3], axis=1)
    meas = TrackerMeasurements(q, xyz, q_a=qa, q_b=qb, d=d)
    res = identify_tracker(case.nominal, meas)
    assert res.kinds == ("position", "distance")
    assert res.rms_mm < 1e-9 and res.rms_distance_mm < 1e-9


def test_benchmark_mdh_table_and_a_run_without_pybotics(tmp_path):
    for robot in (ROBOTS["ur5e"](), ROBOTS["kr6-r900"]()):  # standard and modified DH
        mdh, tail = mdh_table(robot)
        q = make_case(robot).configurations(5, 1)
        for qi, F in zip(q, fk_nominal(robot, q)[:, -1]):
            T = np.eye(4)
            for (alpha, a, theta, d), qj in zip(mdh, qi):  # Craig: Rx Tx Rz Tz
                T = T @ rot_x(alpha) @ trans(np.array([a, 0, 0])) @ rot_z(theta + qj)
                T = T @ trans(np.array([0, 0, d]))
            T = T @ tail
            np.testing.assert_allclose(T[:3, :3], F[:3, :3], atol=1e-12)
            np.testing.assert_allclose(T[:3, 3], F[:3, 3] * 1e3, atol=1e-9)
    rows, note = run(sizes=(30,), repeats_ours=1, pybotics=False)
    text = table(rows, note)
    assert "| 30 |" in text and "n/a" in text
    assert rows[0]["ours_mm"] < 0.25 < 2.0 < rows[0]["nominal_mm"]  # measured 0.19, 2.03
    # several rounds: median times and speed-up with its range, pybotics's best held-out error
    times = [(0.004, 0.6, 0.70), (0.006, 0.9, 0.65), (0.005, 0.5, 0.66)]
    rounds = [
        [{**rows[0], "ours_s": t, "pyb_s": p, "pyb_mm": e, "pyb_truth_mm": e}
         | {"ours_cpu_s": t / 2, "pyb_cpu_s": p / 4}]
        for t, p, e in times
    ]  # fmt: skip
    (row,) = combine(rounds)
    assert row["ours_s"] == 0.005 and row["pyb_s"] == 0.6 and row["pyb_mm"] == 0.65
    assert row["ours_cpu_s"] == 0.0025 and row["pyb_cpu_s"] == 0.15
    assert row["speed_ups"] == [100.0, 150.0, 150.0]
    assert row["cpu_speed_ups"] == [50.0, 75.0, 75.0]
    assert "| 5.0 (2.5) | 600 (150) | 150x (100-150x) | 75x (50-75x) |" in table([row], note)
    doc = tmp_path / "doc.md"
    doc.write_text(f"intro\n{BEGIN}\nold\n{END}\nrest\n")
    write_docs(text, doc)
    assert doc.read_text() == f"intro\n{BEGIN}\n{text}\n{END}\nrest\n"
