"""Measurement terms on the board route (selfcal/calibration/board/terms.py): touch-probe points
estimated with the board's images, checked against the simulation's truth.

1. The synthetic lab of tests/integration/synthetic_board.py (the KR 6 R900 with every MCPC
   parameter perturbed by 1 mm / 0.3 deg, an 800x600 lens camera, an 11x8 chessboard; features
   projected with 0.2 px noise, joints read with 0.01 deg of noise), 12 postures, and 30 touches
   of known fixture points by a probe tip on the camera's side of the flange (0.02 mm per
   coordinate) at postures over the whole workspace. The same board calibration with and
   without the probe term; each model's camera positions at 40 held-out postures against the
   truth (board frame).
2. Eye-to-hand, noise-free: a probe tip fixed to the board is found in the board frame.
3. ``selfcal calibrate DS --term probe=touches.csv,...`` end to end on the analytic ChArUco
   scenario (12 postures): calibration.json lists ``sources`` and the probe's section, read back
   as its type, with the tip where the truth puts it.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from synthetic_board import BOARD, CAMERA, ROBOT, H, W, make_lab, postures
from synthetic_features import board_features

from selfcal.calibration.board.robot import calibrate_robot_with_board
from selfcal.calibration.routes import read_calibration
from selfcal.config.scenario import load_scenario
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.terms.probe import ProbeSection, ProbeTerm
from selfcal.transforms import inv_pose, pose_from_vec

SIGMA_M = 2e-5
READ_NOISE = np.radians(0.01)
TIP = np.array([0.03, -0.02, 0.12])  # m, the probe tip in the camera frame
T_FIXTURE_WORLD = pose_from_vec([0.4, -0.1, 0.2, 0.3, -0.2, 0.1])
MONO_CHARUCO = Path(__file__).resolve().parents[2] / "scenarios" / "mono-charuco.toml"


def _touches(model, q, rng):
    """Known fixture points the true tip touches at ``q`` (m), with the touches' noise."""
    T = fk_tool(model, q)
    x = T[:, :3, :3] @ TIP + T[:, :3, 3]
    return x @ T_FIXTURE_WORLD[:3, :3].T + T_FIXTURE_WORLD[:3, 3] + rng.normal(0, SIGMA_M, x.shape)


@pytest.mark.slow  # two board calibrations with their cross-validation: ~11 s
def test_probe_touches_improve_the_board_route_kinematics():
    robot = load_robot(ROBOT)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    lab = make_lab(0)
    rng = np.random.default_rng(1)
    q = postures(lab, 12, seed=5)
    q_read = q + rng.normal(0, READ_NOISE, q.shape)
    feats = board_features(lab.true_model, lab.T_world_board, q, 0.2, 5)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    qt = lo + (hi - lo) * (0.2 + 0.6 * rng.random((30, robot.n)))
    p = _touches(lab.true_model, qt, rng)
    probe = ProbeTerm(qt + rng.normal(0, READ_NOISE, qt.shape), p, np.arange(len(p)), SIGMA_M)
    qv = lo + (hi - lo) * (0.2 + 0.6 * rng.random((40, robot.n)))
    true = inv_pose(lab.T_world_board)[None] @ fk_tool(lab.true_model, qv)

    def error_mm(model) -> float:
        """RMS of the camera positions at the held-out postures (board frame, mm)."""
        d = fk_tool(model, qv)[:, :3, 3] - true[:, :3, 3]
        return 1e3 * float(np.sqrt(np.mean(np.sum(d**2, axis=1))))

    fits = {}
    for name, terms in (("images", ()), ("images + probe", (probe,))):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # identification notes
            fits[name] = calibrate_robot_with_board(BOARD, feats, q_read, nominal, W, H,
                                                    free=CAMERA.free, model="opencv",
                                                    terms=terms)  # fmt: skip
    alone, both = fits["images"], fits["images + probe"]
    e_alone, e_both = error_mm(alone.model), error_mm(both.model)
    print(f"held-out camera positions: images {e_alone:.2f} mm, images + probe {e_both:.3f} mm "
          f"(fair nominal {error_mm(both.nominal.model):.2f} mm)")  # fmt: skip
    assert alone.sections == () and [s.kind for s in both.sections] == ["probe"]
    # the fair nominal fits the probe's own unknowns (fixture, tip) with the kinematics held
    assert [s.kind for s in both.nominal.sections] == ["probe"]
    assert e_both < 0.3 * e_alone  # measured 2.72 against 17.0 mm
    assert e_both < 0.3 * error_mm(both.nominal.model)  # the fair nominal: measured 25.5 mm
    sec = both.sections[0]
    assert isinstance(sec, ProbeSection) and sec.touches == 30
    off = np.linalg.norm(np.asarray(sec.tip_mm) - 1e3 * TIP)
    print(sec.summary(), f"; tip {off:.3f} mm off")
    # the tip in the calibrated camera frame against the true one: measured 1.85 mm (the probe's
    # fit, 0.20 mm RMS, is the touches' joint read noise: 0.01 deg over the arm's reach)
    assert off < 5.0
    assert sec.rms_mm < 0.6  # the probe's fit: measured 0.20 mm


@pytest.mark.slow  # an analytic acquisition and a board calibration through the CLI: ~8 s
def test_calibrate_takes_a_probe_term_from_the_command_line(tmp_path, capsys):
    from selfcal.cli.main import main
    from selfcal.pipeline.run import run_acquire

    s = load_scenario(MONO_CHARUCO, {"noise": {"render": False}, "trajectory": {"poses": 12}})
    ds_dir = tmp_path / "ds"
    run_acquire(s, ds_dir, quiet=True)
    truth, ds = read_truth(ds_dir / "truth.json"), Dataset.open(ds_dir)
    robot = load_robot(ds.robot_source)
    rng = np.random.default_rng(3)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    qt = lo + (hi - lo) * (0.3 + 0.4 * rng.random((25, robot.n)))
    p = 1e3 * _touches(truth.true_model, qt, rng)
    rows = [",".join([*(f"j{j + 1}" for j in range(robot.n)), "x_mm", "y_mm", "z_mm"])]
    rows += [",".join(f"{v:.6f}" for v in [*np.degrees(a), *b]) for a, b in zip(qt, p)]
    (tmp_path / "touches.csv").write_text("\n".join(rows) + "\n")
    spec = f"probe={tmp_path / 'touches.csv'},joint_units=deg,sigma_mm=0.02"
    assert main(["calibrate", str(ds_dir), "-q", "--term", spec]) == 0
    doc = json.loads((ds_dir / "calibration.json").read_text())
    assert doc["sources"] == ["images", "probe"] and doc["probe"]["touches"] == 25
    cal = read_calibration(ds_dir)
    sec = cal.section("probe")  # type: ignore[union-attr]
    assert isinstance(sec, ProbeSection) and sec.sigma_mm == pytest.approx(0.02)
    off = np.linalg.norm(np.asarray(sec.tip_mm) - 1e3 * TIP)
    print(sec.summary(), f"; tip {off:.3f} mm off")
    assert off < 0.75  # measured 0.252 mm


@pytest.mark.slow  # an eye-to-hand calibration with its cross-validation: ~6 s
def test_eye_to_hand_probe_touches_in_the_board_frame_are_exact_without_noise():
    """Eye-to-hand the chain's tool is the board (world: the static camera): a probe tip fixed
    to the board is estimated in the board frame, and noise-free touches and images give the
    truth (the cell of tests/integration/test_eye_to_hand.py)."""
    from selfcal.camera import Pinhole
    from selfcal.io.target_toml import load_target
    from selfcal.sim.static_camera import plan_static_postures, project_views, static_camera_truth

    robot = load_robot("ur5e")
    board = load_target("models/targets/charuco.toml")
    free = ("fx", "mu", "cx", "cy")
    truth = static_camera_truth(robot, board, Pinhole(900.0, 1.0, 326.0, 233.0, 640, 480, free),
                                seed=1)  # fmt: skip
    q = plan_static_postures(truth, 6, 5, seed=0)
    tip_board = np.array([0.02, 0.05, -0.03])  # m, in the board frame
    qt = plan_static_postures(truth, 4, 5, seed=7)  # postures of the kind the images show
    T = truth.T_cam_board(qt)
    x = T[:, :3, :3] @ tip_board + T[:, :3, 3]
    p = x @ T_FIXTURE_WORLD[:3, :3].T + T_FIXTURE_WORLD[:3, 3]
    probe = ProbeTerm(qt, p, np.arange(len(p)), SIGMA_M)
    nominal = nominal_mcpc(robot).with_tool(truth.T_flange_board_nominal)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the two-stage identification's notes
        res = calibrate_robot_with_board(board, project_views(truth, q), q, nominal, 640, 480,
                                         free=free, eye_to_hand=True, terms=[probe])  # fmt: skip
    sec = res.sections[0]
    assert isinstance(sec, ProbeSection)
    print(sec.summary(), f"; reprojection {res.rms_px:.2e} px")
    assert res.rms_px < 1e-8 and sec.rms_mm < 1e-6
    np.testing.assert_allclose(np.asarray(sec.tip_mm), 1e3 * tip_board, atol=1e-6)
    held_out = plan_static_postures(truth, 3, 2, seed=5)
    np.testing.assert_allclose(fk_tool(res.model, held_out), truth.T_cam_board(held_out),
                               atol=1e-6)  # fmt: skip
