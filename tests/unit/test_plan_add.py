"""The prediction with the parameters the selection keeps (selfcal/calibration/board/plan/predict.py)
and the postures added to a dataset (plan/add.py): a held parameter's deviation is an error the
bound alone does not see; with every parameter kept the prediction is the Cramer-Rao bound."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from selfcal.calibration.board.bounds import board_cramer_rao
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.add import (
    DatasetPlan,
    first_halving,
    swap_spares,
    training_sets,
)
from selfcal.calibration.board.plan.greedy import select_greedy
from selfcal.calibration.board.plan.information import board_model, frame_information
from selfcal.calibration.board.plan.predict import (
    estimated_directions,
    kept_by_rank,
    predicted_with_held,
)
from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.camera import project
from selfcal.estimation.joint_report import aligned_tool_weight
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices
from selfcal.target.base import Features
from selfcal.target.placement import board_pose, board_pose_values
from selfcal.transforms import inv_pose

JS = np.full(6, np.radians(0.01))


@pytest.fixture(scope="module")
def setup(ur5e_wrist_plan) -> PlanSetup:
    return ur5e_wrist_plan[0]  # the UR5e cell, shared with the other plan tests (conftest.py)


@pytest.fixture(scope="module")
def plan(ur5e_wrist_plan):
    plan = ur5e_wrist_plan[1]  # 8 of 80 candidates, seed 3, workspace 20
    assert np.array_equal(plan.joint_sigma, JS)
    return plan


@pytest.fixture(scope="module")
def parts(setup, plan):
    model = board_model(setup)
    F = frame_information(setup, plan.q, 0.5, JS).sum(axis=0)
    G = aligned_tool_weight(model, plan.workspace, inv_pose(setup.robot.T_flange_cam))
    free_idx, offsets = kept_by_rank(model, plan.q)
    return model, F, G, free_idx[:-3], offsets  # three inner parameters held


def test_prediction_with_kept_parameters_is_the_board_route_bound(setup, plan, parts):
    model, F, G, free_idx, offsets = parts
    M = estimated_directions(model, free_idx, offsets)
    var = Deviation().variance(model.joint_types)
    got = predicted_with_held(F, G, setup.camera.n_free, M, 0.0 * var)
    ids, pts = setup.board.layout()
    feats = [Features(ids, project(setup.camera, T, pts)) for T in inv_pose(fk_tool(model, plan.q))]
    cr = board_cramer_rao(setup.board, [setup.camera], model, plan.q, [feats], 0.5, joint_sigma=JS,
                          free_idx=free_idx, offset_joints=offsets)  # fmt: skip
    bound = cr.aligned_tool_rms(plan.workspace, inv_pose(setup.robot.T_flange_cam))
    assert got == pytest.approx(bound, rel=1e-4)


def test_a_held_parameter_adds_its_deviation(setup, parts):
    model, F, G, free_idx, offsets = parts
    var = Deviation().variance(model.joint_types)
    n_cam, k = setup.camera.n_free, var.size
    M = estimated_directions(model, free_idx, offsets)
    variance_only = predicted_with_held(F, G, n_cam, M, 0.0 * var)
    # the bias on its own: each deviation fitted by least squares in the whitened data space
    w, V = np.linalg.eigh(F)
    L = V * np.sqrt(np.clip(w, 0, None))  # F = L L^T
    Mf = np.zeros((n_cam + k, n_cam + M.shape[1]))
    Mf[:n_cam, :n_cam], Mf[n_cam:, n_cam:] = np.eye(n_cam), M
    bias2 = 0.0
    for j in np.flatnonzero(var):
        d = np.zeros(n_cam + k)
        d[n_cam + j] = np.sqrt(var[j])
        theta = np.linalg.lstsq(L.T @ Mf, L.T @ d, rcond=None)[0]
        e = (Mf @ theta - d)[n_cam:]
        bias2 += e @ G @ e
    got = predicted_with_held(F, G, n_cam, M, var)
    assert got**2 == pytest.approx(variance_only**2 + bias2, rel=1e-6)
    assert bias2 > 0.3 * variance_only**2  # 0.87 measured: three held parameters, a bias
    # every minimal parameter estimated: the deviation is absorbed, the bound is left
    every = np.eye(k)
    assert predicted_with_held(F, G, n_cam, every, var) == pytest.approx(
        predicted_with_held(F, G, n_cam, every, 0.0 * var), rel=1e-6)  # fmt: skip


def test_the_placement_has_no_deviation(setup):
    from selfcal.calibration.board.nominal_fit import placement_indices

    types = board_model(setup).joint_types
    var = Deviation(2e-3, np.radians(1.0)).variance(types)
    placement = np.isin(minimal_indices(types), placement_indices(len(types)))
    assert placement.sum() >= 6 and np.all(var[placement] == 0)  # board pose, hand-eye
    assert set(np.round(var[~placement], 12)) == {round(np.radians(1.0) ** 2 / 3, 12),
                                                  round(4e-6 / 3, 12)}  # fmt: skip


def test_one_configuration_leaves_the_added_postures_alone(setup, plan):
    q = np.tile(setup.robot.home, (4, 1))
    q[:, 4] += np.radians([0, 10, 20, 30])  # the wrist alone moves
    ids = setup.board.layout()[0]
    dp = DatasetPlan(setup, q, (ids,) * 4, np.zeros(0, np.int64), np.zeros(0, np.int64))
    Ff = frame_information(setup, plan.q[:4], 0.5, JS)
    sets = training_sets(dp, Ff)
    assert len(sets) == 2
    assert np.allclose(sets[0], Ff.sum(axis=0)) and np.allclose(sets[1], 0.0)


def test_a_stack_of_one_start_is_that_start(setup, plan, parts):
    _, _, G, _, _ = parts
    F = frame_information(setup, plan.q, 0.5, JS)
    start = F[:2].sum(axis=0)
    a = select_greedy(F[2:], G, setup.camera.n_free, 3, start=start)
    b = select_greedy(F[2:], G, setup.camera.n_free, 3, start=start[None])
    assert a.tolist() == b.tolist()


def test_board_pose_values_inverts_board_pose(setup):
    T = board_pose(setup.board, np.array([0.4, -0.1, 0.2]), np.radians([10.0, -20.0, 30.0]))
    centre, rpy = board_pose_values(setup.board, T)
    assert np.allclose(centre, [0.4, -0.1, 0.2]) and np.allclose(np.degrees(rpy), [10, -20, 30])


def test_add_needs_a_calibrated_dataset(tmp_path, capsys):
    from selfcal.cli.main import main

    assert main(["plan", "--add", "5", str(tmp_path), "--out", str(tmp_path / "p")]) == 2
    assert "calibrate the dataset first" in capsys.readouterr().err
    assert main(["plan", "--out", str(tmp_path / "p")]) == 2
    assert "--robot, --target, --board-pose" in capsys.readouterr().err


@pytest.mark.parametrize(("fmt", "said"), [
    ("scorbot-selfcal-handeye-calibration", "is a hand-eye calibration from flange poses"),
    ("scorbot-selfcal-calibration", "is not a board calibration"),
])  # fmt: skip
def test_add_names_a_calibration_of_another_route(tmp_path, capsys, fmt, said):
    # a new user's `selfcal plan --add 5` on the ical-charuco set imported with --poses: "not a
    # scorbot-selfcal-board-calibration file (format = 'scorbot-selfcal-handeye-calibration')
    # -- re-run `selfcal calibrate DATASET`", which writes the same hand-eye file again
    from selfcal.cli.main import main

    (tmp_path / "calibration.json").write_text(f'{{"format": "{fmt}", "schema_version": 1}}')
    assert main(["plan", "--add", "5", str(tmp_path), "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    assert said in err and "re-run" not in err, err
    assert "selfcal plan --" in err.split(" -- ", 1)[1]


def test_a_frame_counts_the_features_it_shows(setup, plan):
    ids = setup.board.layout()[0]
    every = frame_information(setup, plan.q[:2], 0.5, JS)
    assert np.array_equal(frame_information(setup, plan.q[:2], 0.5, JS, [ids, ids]), every)
    half = frame_information(setup, plan.q[:2], 0.5, JS, [ids[::2], ids[1::2]])
    alone = frame_information(setup, plan.q[1:2], 0.5, JS, [ids[1::2]])
    assert np.allclose(half[1], alone[0], rtol=1e-12, atol=1e-9 * np.abs(alone).max())
    # read exactly, a frame's information is the sum of its features': halves add up
    even, odd = (
        frame_information(setup, plan.q[:1], 0.5, None, [s]) for s in (ids[::2], ids[1::2])
    )
    whole = frame_information(setup, plan.q[:1], 0.5)
    assert np.allclose(even + odd, whole, rtol=1e-10, atol=1e-10 * np.abs(whole).max())
    assert not np.allclose(even, whole, rtol=0.1)


def test_swaps_take_a_spare_only_where_the_cost_falls_by_the_gain():
    # a toy cost: the set's sum, one spare lowering it by 2 %, one by less than GAIN (1 %)
    values = {0: 1.0, 1: 1.0, 2: 1.0, 3: 0.94, 4: 0.995, 5: 1.5}
    cost = lambda idx: float(sum(values[int(i)] for i in idx))  # noqa: E731
    got = swap_spares(np.array([0, 1, 2]), np.array([5, 4, 3]), cost, np.sort)
    assert got.tolist() == [1, 2, 3]  # 3 swapped in (and ordered); 4 and 5 not
    assert cost(got) <= cost(np.array([0, 1, 2]))
    same = swap_spares(np.array([0, 1, 2]), np.array([4, 5]), cost, np.sort)
    assert same.tolist() == [0, 1, 2]


def test_the_fewest_postures_that_halve_the_error_are_found_in_order():
    # a toy prediction per count (m): 5 postures 1.16 times lower than 1.25, 6 and 8 halve it
    after = {5: 1.08, 6: 0.6, 7: 0.7, 8: 0.3}
    asked: list[int] = []

    def predicted(n: int) -> float:
        asked.append(n)
        return after[n]

    got = first_halving(1.25, 5, predicted, 8)
    assert (got.count, got.after_m, got.tried, got.before_m) == (6, 0.6, 6, 1.25)
    assert asked == [5, 6]  # stopped at the first: no count above it planned
    short = first_halving(1.25, 5, predicted, 5)
    assert short.count is None and np.isnan(short.after_m) and short.tried == 5
    exact = first_halving(1.2, 6, predicted, 8)  # at most half, not below
    assert exact.count == 6


def test_the_halving_line_gives_the_draws_medians_it_judged_by():
    """``selfcal plan --add``'s sixth line names the medians of the forecast's draws (before and
    with the count that halves), not the first line's prediction; no line when K halve it."""
    from types import SimpleNamespace

    from selfcal.calibration.board.plan.add import Halving
    from selfcal.cli.plan_add import halved_words

    def add(halving: Halving) -> SimpleNamespace:  # the first line's figures: not in the words
        return SimpleNamespace(q=np.zeros((5, 6)), before_m=9.0, after_m=8.0, halving=halving)

    six = halved_words(add(Halving(6, 0.0003, 6, 0.0012)), "calib")  # type: ignore[arg-type]
    assert six == ("not predicted to halve the error with 5 added postures (the forecast's "
                   "draws' median 1.200 before); 6 are predicted to (1.200 -> 0.300 mm, the "
                   "draws' medians): selfcal plan --add 6 calib")  # fmt: skip
    none = halved_words(add(Halving(None, float("nan"), 8, 0.0012)), "calib")  # type: ignore[arg-type]
    assert none.endswith("median 1.200 before), nor with any count up to 8 (each planned as 5 are)")
    assert halved_words(add(Halving(5, 0.0006, 5, 0.0012)), "calib") == ""  # type: ignore[arg-type]


def test_the_help_says_what_the_halving_line_costs():
    """`selfcal plan --help` said "the last line and plan.png give the draws" after the halving
    line became the last (review of session 26); it names the draws' line (the sixth since the
    corner noise has its own), the halving line and how many larger counts it plans (HALVE_MORE,
    the one source of that number)."""
    from selfcal.calibration.board.plan.add import HALVE_MORE
    from selfcal.cli.plan import EPILOG

    text = " ".join(EPILOG.split())
    assert "the sixth line and plan.png give the draws" in text
    assert f"up to {HALVE_MORE} larger counts are planned in turn" in text


def test_add_counts_the_parameters_beyond_the_placement_as_calibrate_does(setup, plan):
    """`plan --add` said "kinematic parameters estimated 26 -> 26" of a calibration whose
    `calibrate` line said "14 kinematic parameter(s) beyond the placement identified" (a new
    user's trip, session 28): --add counted the placement's 12. Both now count with
    beyond_placement, from the calibration's identified names."""
    from selfcal.calibration.board.bounds import estimated_parameters
    from selfcal.calibration.board.nominal_fit import beyond_placement, placement_indices
    from selfcal.calibration.board.plan.add import plan_additions
    from selfcal.calibration.board.plan.ground import PlanOptions
    from selfcal.kinematics.mcpc import param_names
    from selfcal.pipeline.board_run import _nominal_text

    model = board_model(setup)
    n = model.n
    place = placement_indices(n)
    inner = [k for k in minimal_indices(model.joint_types) if 0 < k // 6 < n][:5]
    names = [*param_names(place), "offset_j2", "offset_j3", *param_names(np.array(inner))]
    sel = {"identified": names, "held": {}, "chosen": "+ all", "candidates": [
        {"label": "nominal (placement + camera)", "parameters": list(param_names(place))},
        {"label": "+ all", "parameters": names}]}  # fmt: skip
    res = SimpleNamespace(selection=sel, model=model, nominal_rms_px=None, cv_verdict=lambda: "")
    free_idx, offsets = estimated_parameters(res)
    assert len(free_idx) + len(offsets) == 12 + 7
    assert beyond_placement(free_idx, offsets, n) == 7
    assert "; 7 kinematic parameter(s) beyond the placement identified" in _nominal_text(res)
    ids = setup.board.layout()[0]
    dp = DatasetPlan(setup, plan.q, (ids,) * len(plan.q), free_idx, offsets)
    add = plan_additions(dp, 1, PlanOptions(candidates=12, workspace=6, joint_sigma=JS), spare=0)
    assert add.kept_before == 7
    assert add.kept_after == beyond_placement(*add.forecast.kept, n) <= 30
