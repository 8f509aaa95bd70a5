"""What a plan has to beat (selfcal/calibration/board/plan/reference.py, issue #30): the fair
nominal's predicted tool-point error and the chain's as drawn equal an independent computation
(finite differences of the projected corners and the tool point, the placement and camera
fitted by least squares to the pixels a deviation of the chain moves), and `selfcal plan` says
both and whether the plan beats them."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.plan.candidates import candidate_pool
from selfcal.calibration.board.plan.ground import workspace_sample
from selfcal.calibration.board.plan.information import board_model, frame_information
from selfcal.calibration.board.plan.reference import CLEAR_MARGIN, nominal_reference
from selfcal.calibration.board.plan.views import PlanSetup
from selfcal.estimation.joint_report import aligned_tool_weight
from selfcal.io.camera_file import camera_from_fov
from selfcal.io.plan_files import read_plan
from selfcal.io.target_toml import load_target
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices
from selfcal.robot.definition import load_robot, models_dir
from selfcal.target.placement import board_pose
from selfcal.transforms import inv_pose

SIGMA = 0.5  # px


@pytest.fixture(scope="module")
def cell():
    robot = load_robot("ur5e")
    board = load_target(models_dir() / "targets/charuco.toml")
    setup = PlanSetup(robot, camera_from_fov(60.0, 640, 480), board,
                      board_pose(board, np.array([-0.472, -0.133, 0.003])))  # fmt: skip
    q, _ = candidate_pool(setup, 10, seed=2)
    qw = workspace_sample(setup, 12, seed=3)
    return setup, q, qw


def _independent(setup: PlanSetup, q: np.ndarray, qw: np.ndarray, dev: Deviation):
    """(fair nominal, drawn) RMS (m) by finite differences, sharing no code with the plan's
    prediction: the corners' pixels and the workspace's tool points as functions of the flat
    chain parameters and the camera's free ones."""
    model = board_model(setup)
    cam = setup.camera
    _, pts = setup.board.layout()
    x0, c0 = model.params.reshape(-1).copy(), cam.free_values()
    tip = setup.T_tool_tip

    def pixels(x, c):
        T = inv_pose(fk_tool(model.with_params(x), q))  # board -> camera
        X = np.einsum("mij,kj->mki", T[:, :3, :3], pts) + T[:, None, :3, 3]
        return cam.with_free_values(c).project(X).reshape(-1)

    def tips(x):
        return (fk_tool(model.with_params(x), qw) @ tip)[:, :3, 3].reshape(-1)

    def d(f, x, i, h):
        e = np.zeros_like(x)
        e[i] = h
        return (f(x + e) - f(x - e)) / (2 * h)

    place = placement_indices(model.n)
    idx = minimal_indices(model.joint_types)
    held = idx[~np.isin(idx, place)]
    var = dev.variance(model.joint_types)[~np.isin(idx, place)]
    J_cam = np.stack([d(lambda c: pixels(x0, c), c0, i, 1e-6 * max(abs(c0[i]), 1.0))
                      for i in range(len(c0))], axis=1)  # fmt: skip
    J_place = np.stack([d(lambda x: pixels(x, c0), x0, i, 1e-6) for i in place], axis=1)
    J_held = np.stack([d(lambda x: pixels(x, c0), x0, i, 1e-6) for i in held], axis=1)
    T_place = np.stack([d(tips, x0, i, 1e-6) for i in place], axis=1)
    T_held = np.stack([d(tips, x0, i, 1e-6) for i in held], axis=1)
    J_e = np.concatenate([J_cam, J_place], axis=1) / SIGMA
    K = np.linalg.lstsq(J_e, J_held / SIGMA, rcond=None)[0][len(c0) :]  # what the fit absorbs
    p = tips(x0).reshape(-1, 3)
    c = p - p.mean(axis=0)
    rigid = np.zeros((len(p), 3, 6))
    rigid[:, :, :3] = np.eye(3)
    rigid[:, :, 3:] = -np.cross(c[:, :, None], np.eye(3)[None], axis=1)  # w x c = -c x w
    Q = np.linalg.qr(rigid.reshape(-1, 6))[0]

    def ms(A, S):  # mean square over the points of P A (S) A^T P
        PA = A - Q @ (Q.T @ A)
        return float(np.trace(PA @ S @ PA.T)) / len(p)

    C_e = np.linalg.inv(J_e.T @ J_e)[len(c0) :, len(c0) :]
    fair = np.sqrt(ms(T_place @ K - T_held, np.diag(var)) + ms(T_place, C_e))
    # nothing fitted: the placement's minimal parameters deviate too (the simulator draws
    # them), the base's removed by the alignment, the hand-eye's not
    mount = idx[np.isin(idx, place)]
    var_mount = dev.drawn_variance(model.joint_types)[np.isin(idx, place)]
    T_mount = np.stack([d(tips, x0, i, 1e-6) for i in mount], axis=1)
    inner = ms(T_held, np.diag(var))
    return fair, np.sqrt(inner + ms(T_mount, np.diag(var_mount))), np.sqrt(inner)


@pytest.mark.parametrize(
    "dev", [Deviation(), pytest.param(Deviation(1e-4, np.radians(0.05)), marks=pytest.mark.slow)]
)
def test_both_references_equal_an_independent_computation(cell, dev):
    setup, q, qw = cell
    model = board_model(setup)
    F = frame_information(setup, q, SIGMA).sum(axis=0)
    G = aligned_tool_weight(model, qw, setup.T_tool_tip)
    got = nominal_reference(model, F, G, setup.camera.n_free, dev.drawn_variance(model.joint_types))
    fair, drawn, flange = _independent(setup, q, qw, dev)
    assert got.fair_m == pytest.approx(fair, rel=5e-9)  # 1.0e-9 measured (finite differences)
    assert got.drawn_m == pytest.approx(drawn, rel=5e-9)  # 1.4e-12
    # a tool point that the mount's deviation does not move (eye-to-hand's flange): without it
    e2h = nominal_reference(model, F, G, setup.camera.n_free, dev.drawn_variance(model.joint_types),
                            eye_to_hand=True)  # fmt: skip
    assert e2h.drawn_m == pytest.approx(flange, rel=5e-9) and flange < 0.9 * drawn
    assert got.best_m == min(got.fair_m, got.drawn_m) and got.beaten_by(CLEAR_MARGIN * got.best_m)
    assert not got.beaten_by(1.01 * CLEAR_MARGIN * got.best_m)


@pytest.mark.slow
def test_the_plan_says_the_reference_and_whether_it_beats_it(tmp_path, capsys, recwarn):
    from selfcal.cli.main import main

    argv = ["plan", "--robot", "ur5e", "--target", str(models_dir() / "targets/charuco.toml"),
            "--fov-deg", "60", "--resolution", "640x480", "--board-pose", "-472,-133,3",
            "--count", "8", "--candidates", "60", "--out", str(tmp_path / "p"), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    doc = read_plan(tmp_path / "p/plan.json")
    ref = doc["nominal"]
    best = min(ref["fair_nominal_tool_rms_mm"], ref["drawn_tool_rms_mm"])
    assert f"without calibrating the kinematics {best:.3f} mm" in out
    sel = doc["selection"]
    assert doc["beats_nominal"] == (sel["tool_rms_mm"] <= CLEAR_MARGIN * best)
    rival = sel["rival_tool_rms_mm"]
    assert doc["rival_beats_nominal"] == (None if rival is None else rival <= CLEAR_MARGIN * best)
    assert ("NOT predicted to beat it" in out) != doc["beats_nominal"]
    assert doc["verdict"] in out
    # At 8 postures the selection's forecast prefers the pool's first set, which is the random
    # plan, to the greedy choice: the forecast draws the same postures twice (equal medians by
    # construction), and the plan gives no warning that it is "no better than a random plan of
    # 8" (before: "median 1.649 mm ... median 1.649 mm", the plan against itself)
    draws = doc["forecast_draws"]
    assert doc["chosen_by"] == "random set 1 of 7" and "random set 1 of 7 (the random plan)" in out
    assert draws["plan"]["median_mm"] == draws["random"]["median_mm"]
    assert not [w for w in recwarn if "no better than" in str(w.message)]
