"""The predicted tool error over the workspace (selfcal.kinematics.tool_error, issue #29)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, gauge_fix, minimal_indices, nominal_mcpc
from selfcal.kinematics.tool_error import (
    Reach,
    ToolErrorModel,
    accuracy_line,
    joint_spans,
    norm_quantile,
    posture_distance,
    revolute_joints,
    workspace_sample,
    workspace_summary,
)
from selfcal.robot.definition import load_robot
from selfcal.transforms import pose_from_vec


def test_norm_quantile_isotropic_and_one_dimensional():
    s = 0.3
    assert norm_quantile(s**2 * np.eye(3)) == pytest.approx(s * np.sqrt(chi2.ppf(0.95, 3)))
    assert norm_quantile(np.diag([s**2, 0.0, 0.0])) == pytest.approx(1.959964 * s, rel=1e-6)
    assert norm_quantile(np.zeros((3, 3))) == 0.0


def test_norm_quantile_against_samples_of_an_anisotropic_covariance():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    cov = A @ A.T + np.diag([0.01, 0.2, 1.0])
    e = rng.multivariate_normal(np.zeros(3), cov, 400_000)
    sampled = np.quantile(np.linalg.norm(e, axis=1), 0.95)
    assert norm_quantile(cov) == pytest.approx(sampled, rel=0.02)


@pytest.fixture(scope="module")
def er4u():
    return load_robot("er4u-paper")


def _error_model(robot, rng, model_error_m=0.0, model_error_rad=None):
    model = nominal_mcpc(robot)
    cols = minimal_indices(model.joint_types)[::2]
    A = rng.normal(size=(cols.size, cols.size)) * 1e-4
    T = pose_from_vec(np.r_[0.3, -0.2, 1.0, 1.5, -0.4, 0.2])
    return ToolErrorModel(model, T, cols, A @ A.T, model_error_m, model_error_rad)


@pytest.mark.parametrize("point", [False, True])
def test_estimation_covariance_is_the_parameters_carried_through_the_chain(er4u, point):
    """Against central differences of the tool pose in the output frame (and of a tool point
    away from the tool frame, as the board route's flange seen from its camera)."""
    rng = np.random.default_rng(0)
    em = _error_model(er4u, rng)
    if point:
        em = dataclasses.replace(
            em, T_tool_point=pose_from_vec(np.r_[0.05, -0.02, -0.12, 0.3, 0.1, -0.2])
        )
    tip = np.eye(4) if em.T_tool_point is None else em.T_tool_point
    q = rng.uniform(er4u.limits[:, 0], er4u.limits[:, 1], (4, er4u.n))
    h = 1e-6
    J = np.zeros((len(q), 6, em.columns.size))
    T0 = em.T_out_world @ fk_tool(em.model, q) @ tip
    assert np.allclose(em.tool_positions(q), T0[:, :3, 3])
    for k, c in enumerate(em.columns):
        p = em.model.params.reshape(-1).copy()
        p[c] += h
        Tp = em.T_out_world @ fk_tool(em.model.with_params(p.reshape(-1, 6)), q) @ tip
        p[c] -= 2 * h
        Tm = em.T_out_world @ fk_tool(em.model.with_params(p.reshape(-1, 6)), q) @ tip
        J[:, :3, k] = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        W = (Tp[:, :3, :3] - Tm[:, :3, :3]) / (2 * h) @ np.swapaxes(T0[:, :3, :3], 1, 2)
        J[:, 3:, k] = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)  # world rotation
    want = J @ em.covariance @ np.swapaxes(J, 1, 2)
    got = em.estimation_covariance(q)
    assert np.abs(got - want).max() < 1e-6 * np.abs(want).max()


def test_predicted_adds_the_model_error(er4u):
    rng = np.random.default_rng(1)
    em0 = _error_model(er4u, rng)
    em = ToolErrorModel(em0.model, em0.T_out_world, em0.columns, em0.covariance, 2e-4, 1e-4)
    q = rng.uniform(er4u.limits[:, 0], er4u.limits[:, 1], (5, er4u.n))
    p0, p = em0.predicted(q), em.predicted(q)
    assert np.all(np.isnan(p0["orientation_95_deg"])) and np.all(p["orientation_95_deg"] > 0)
    assert np.allclose(p["estimation_95_mm"], p0["position_95_mm"])
    assert np.all(p["position_95_mm"] > p0["position_95_mm"])
    S = em0.estimation_covariance(q)[:, :3, :3]
    rms = np.sqrt(np.trace(S, axis1=1, axis2=2) + 3 * 2e-4**2) * 1e3
    assert np.allclose(p["position_rms_mm"], rms)


def test_workspace_sample_regions(er4u):
    rng = np.random.default_rng(2)
    lim = er4u.limits
    mid, half = lim.mean(axis=1), 0.3 * (lim[:, 1] - lim[:, 0])
    q_cal = rng.uniform(mid - half, mid + half, (20, er4u.n))
    s = workspace_sample(q_cal, lim, count=100)
    assert np.allclose(s.box, np.c_[q_cal.min(0), q_cal.max(0)])
    assert s.in_box(s.inside).all() and not s.in_box(s.edge).any()
    outside = (s.edge < s.box[:, 0]) | (s.edge > s.box[:, 1])
    assert np.all(outside.sum(axis=1) == 1)
    band = 0.1 * (lim[:, 1] - lim[:, 0])
    assert np.all(s.edge >= s.box[:, 0] - band - 1e-12) and np.all(
        s.edge <= s.box[:, 1] + band + 1e-12
    )
    assert np.all(s.workspace >= lim[:, 0]) and np.all(s.workspace <= lim[:, 1])
    again = workspace_sample(q_cal, lim, count=100)
    assert np.array_equal(again.edge, s.edge)
    corners = np.array([lim[:, 0], lim[:, 1]])  # the box is the whole workspace: no edge
    assert workspace_sample(corners, lim, count=10).edge.shape == (0, er4u.n)


def test_summary_and_line(er4u):
    rng = np.random.default_rng(4)
    em = _error_model(er4u, rng, 1e-4, 1e-4)
    q_cal = rng.uniform(er4u.limits[:, 0] / 2, er4u.limits[:, 1] / 2, (12, er4u.n))
    s = workspace_sample(q_cal, er4u.limits, count=50)
    summ = workspace_summary(em, s, q_cal)
    inside = em.predicted(s.inside)["position_95_mm"]
    assert summ["inside"]["position_95_mm_max"] == pytest.approx(inside.max())
    assert len(summ["calibration_postures"]["position_95_mm"]) == 12
    line = accuracy_line(summ)
    assert line.startswith(f"tool point within {inside.max():.3f} mm (95 %) inside")
    assert f"{summ['edge']['position_95_mm_max']:.3f} mm at its edge" in line
    assert "orientation within" in line


def test_posture_distance_is_to_the_nearest_posture_in_units_of_the_spans():
    q_ref = np.array([[0.0, 0.0], [1.0, 1.0]])
    span = np.array([2.0, 0.5])
    q = np.array([[0.2, 0.0], [1.0, 0.9], [0.0, 0.5]])
    d = posture_distance(q, q_ref, span)
    assert d == pytest.approx([0.1, 0.2, 1.0])


def test_the_distance_unit_is_a_joint_s_distinct_postures():
    """1 = one joint moved across all its distinct postures (review 21, finding 3): a revolute
    joint's span is its range capped at a turn (the distance wraps its difference to at most
    pi), so a UR5e joint (+-360 deg) moved by pi is 0.5, not 0.25; a prismatic joint is neither
    capped nor wrapped; a narrow revolute range is kept; a multi-turn joint on a mixed arm (the
    KR6's joint 6, 700 deg) weighs as much per radian as its single-turn joint 4 (370 deg: a
    turn); without the joint types (an older file's unit) the full ranges."""
    ur5e = load_robot("ur5e")
    wrap = revolute_joints(ur5e.joint_types)
    span = joint_spans(ur5e.limits, wrap)
    assert span == pytest.approx(np.full(6, 2 * np.pi))
    q = np.zeros((1, 6))
    q[0, 2] = np.pi
    assert posture_distance(q, np.zeros((1, 6)), span, wrap) == pytest.approx([0.5])
    assert joint_spans(ur5e.limits, None) == pytest.approx(np.full(6, 4 * np.pi))
    kr6 = load_robot("kr6-r900")
    s = joint_spans(kr6.limits, revolute_joints(kr6.joint_types))
    assert s[5] == pytest.approx(s[3]) == pytest.approx(2 * np.pi)
    assert s[4] == pytest.approx(np.radians(240.0))  # its 240 deg kept
    mixed = np.array([[-np.pi, np.pi], [-2.0, 2.0]])  # a revolute turn and a 4 m prismatic axis
    s = joint_spans(mixed, np.array([True, False]))
    assert s == pytest.approx([2 * np.pi, 4.0])
    far = np.array([[np.pi, 2 * np.pi]])
    assert posture_distance(far, np.zeros((1, 2)), s, np.array([True, False])) == pytest.approx(
        [np.hypot(0.5, 0.5 * np.pi)]
    )
    assert joint_spans(np.array([[0.0, 0.0]]), np.array([True])) is None


def test_a_revolute_joint_a_turn_away_is_at_the_same_posture(er4u):
    """Readings a whole turn apart put the links at the same pose: the distance wraps a
    revolute joint's difference to -pi..pi (the UR5e's joints turn +-360 deg), not a prismatic
    one's."""
    span = np.array([4 * np.pi, 4 * np.pi, 1.0])
    q_ref = np.array([[0.0, 0.0, 0.0]])
    q = np.array([[2 * np.pi, 0.0, 0.0], [0.0, 1.5 * np.pi, 0.0], [0.0, 0.0, 2 * np.pi]])
    revolute = np.array([True, True, False])
    assert posture_distance(q, q_ref, span, revolute) == pytest.approx([0.0, 0.125, 2 * np.pi])
    assert posture_distance(q, q_ref, span) == pytest.approx([0.5, 0.375, 2 * np.pi])
    # the chain's own joints: every ER-4u joint is revolute, and its model error wraps them
    em0 = _error_model(er4u, np.random.default_rng(5))
    assert revolute_joints(em0.model.joint_types).all()
    q_cal = np.zeros((1, er4u.n))
    turned = q_cal.copy()
    turned[0, -1] = 2 * np.pi  # the wrist roll a turn on: the same pose
    em = dataclasses.replace(em0, model_error_m=2e-4, reach_postures=q_cal,
                             reach_span=np.diff(er4u.limits, axis=1)[:, 0], reach_distance=0.05,
                             measured_to=0.01)  # fmt: skip
    assert em.model_error_factor(turned) == pytest.approx([0.0])
    assert not em.unmeasured(turned).any()


def test_the_joints_a_model_error_wraps_are_its_chain_s_revolute_ones():
    """One source for which joints wrap: the chain's ``joint_types``. A revolute joint a turn
    on is at the calibration posture; a prismatic joint moved by the same number (m) is half its
    span away, beyond the folds' reach; a :class:`Reach` set on the model and read back carries
    the same factor."""
    types = ("revolute", "revolute", "prismatic", "revolute")
    rng = np.random.default_rng(7)
    G = [pose_from_vec(rng.normal(size=6) * 0.3) for _ in range(len(types) + 1)]
    params, offsets = gauge_fix(G, types)
    model = MCPCModel(params, types, offsets)
    cols = minimal_indices(types)[:2]
    em = ToolErrorModel(model, np.eye(4), cols, 1e-8 * np.eye(cols.size), 2e-4)
    reach = Reach(np.zeros((1, 4)), np.full(4, 4 * np.pi), 0.05, 0.0, 0.3)
    em = em.with_reach(reach)
    q = np.zeros((3, 4))
    q[0, 1], q[1, 2], q[2, 3] = 2 * np.pi, 2 * np.pi, -2 * np.pi
    held = (0.3 / 0.05) ** 2  # the prismatic joint 0.5 span away: held at the measured 0.3
    assert em.model_error_factor(q) == pytest.approx([0.0, held, 0.0], abs=1e-12)
    assert em.unmeasured(q).tolist() == [False, True, False]
    assert em.reach is not None
    assert em.reach.factor(q, model.joint_types) == pytest.approx(em.model_error_factor(q))


def test_a_grown_model_error_is_none_at_the_calibration_postures_and_grows_with_the_distance(er4u):
    rng = np.random.default_rng(2)
    em0 = _error_model(er4u, rng)
    span = er4u.limits[:, 1] - er4u.limits[:, 0]
    q_cal = rng.uniform(er4u.limits[:, 0], er4u.limits[:, 1], (4, er4u.n))
    m, rot, reach = 2e-4, 1e-4, 0.05
    em = dataclasses.replace(em0, model_error_m=m, model_error_rad=rot, reach_postures=q_cal,
                             reach_span=span, reach_distance=reach)  # fmt: skip
    flat = dataclasses.replace(em0, model_error_m=m, model_error_rad=rot)
    q = q_cal[:1].copy()
    q[0, 0] += 0.1 * span[0]  # 2 reach from the first posture, farther from the others
    assert posture_distance(q, q_cal, span) == pytest.approx([0.1])
    S = em0.estimation_covariance(q)[:, :3, :3]
    p, p_flat = em.predicted(q), flat.predicted(q)
    assert p["position_rms_mm"] == pytest.approx(np.sqrt(np.trace(S[0]) + 3 * (2 * m) ** 2) * 1e3)
    assert p_flat["position_rms_mm"] == pytest.approx(np.sqrt(np.trace(S[0]) + 3 * m**2) * 1e3)
    assert p["orientation_95_deg"][0] > p_flat["orientation_95_deg"][0]
    at_cal = em.predicted(q_cal)  # the fit saw these: the covariance alone
    assert np.allclose(at_cal["position_95_mm"], at_cal["estimation_95_mm"])
    assert np.allclose(flat.model_error_factor(q), 1.0)
    # the board route's Reach is the same three numbers, typed: the same factor both ways
    assert em.reach is not None and flat.reach is None
    assert em.reach.factor(q, er4u.joint_types) == pytest.approx([4.0])
    assert np.allclose(em.reach.factor(q_cal, er4u.joint_types), em.model_error_factor(q_cal))


def test_a_level_that_does_not_grow_and_where_the_model_error_is_not_measured(er4u):
    """A variogram's level (``reach_floor``) stays at the calibration postures and the rest
    grows, out to the distance the folds measured it and held there; beyond it it is flagged,
    in the summary and its line."""
    rng = np.random.default_rng(4)
    em0 = _error_model(er4u, rng)
    span = er4u.limits[:, 1] - er4u.limits[:, 0]
    q_cal = rng.uniform(er4u.limits[:, 0], er4u.limits[:, 1], (4, er4u.n))
    q = q_cal[:1].copy()
    q[0, 0] += 0.1 * span[0]  # at the distance 0.1, twice the reference distance
    em = dataclasses.replace(em0, model_error_m=2e-4, reach_postures=q_cal, reach_span=span,
                             reach_distance=0.05, reach_floor=0.25)  # fmt: skip
    assert em.model_error_factor(q_cal) == pytest.approx(np.full(4, 0.25))
    assert em.model_error_factor(q) == pytest.approx([0.25 + 0.75 * 4.0])
    assert not em.unmeasured(q).any()  # no limit (an older file)
    held = dataclasses.replace(em, measured_to=0.08)  # measured out to 0.08: held there
    assert held.model_error_factor(q) == pytest.approx([0.25 + 0.75 * (0.08 / 0.05) ** 2])
    assert held.reach is not None and held.reach.factor(q, er4u.joint_types) == pytest.approx(
        held.model_error_factor(q)
    )
    flat = dataclasses.replace(em, reach_floor=1.0, measured_to=0.08)
    assert flat.model_error_factor(q) == pytest.approx([1.0])
    assert flat.unmeasured(np.vstack([q_cal, q])).tolist() == [False] * 4 + [True]
    # no model error found: beyond the folds' reach still not measured (no fold tested it there)
    none = dataclasses.replace(flat, model_error_m=0.0, reach_distance=0.0)
    assert none.unmeasured(np.vstack([q_cal, q])).tolist() == [False] * 4 + [True]
    assert none.reach is None and np.allclose(none.model_error_factor(q), 1.0)
    assert not dataclasses.replace(none, measured_to=np.inf).unmeasured(q).any()
    summ = workspace_summary(flat, workspace_sample(q_cal, er4u.limits, count=40), q_cal)
    far = summ["workspace"]["model_error_not_measured_share"]
    assert 0 < far <= 1 and "model_error_not_measured_share" not in summ["calibration_postures"]
    assert f"{far:.0%} of the workspace's points (farther" in accuracy_line(summ)


def test_the_line_names_the_edge_s_unmeasured_share_whose_figure_it_gives():
    """The photoneo set's report (session 26's new user): 31 % of the edge's points beyond the
    folds' reach, 100 % of the workspace's; the line gave the edge's 28.882 mm and named only
    the workspace's share, whose figure it does not print."""
    region = {"points": 256, "position_95_mm_max": 6.7338}
    regions = {
        "inside": region,
        "edge": {**region, "position_95_mm_max": 28.8824, "model_error_not_measured_share": 0.3125},
        "workspace": {**region, "model_error_not_measured_share": 1.0},
    }
    line = accuracy_line(regions)
    assert line.startswith("tool point within 6.734 mm (95 %) inside the calibrated region, "
                           "28.882 mm at its edge; the model error is not measured at 31% of the "
                           "edge's points, 100% of the workspace's points (farther")  # fmt: skip
    assert "of the inside's points" not in line
    measured = accuracy_line({**regions, "edge": region, "workspace": region})
    assert "not measured" not in measured
